//! Presets, the dense `--fill` output and `eval-folder`, end to end on the sample scene.

mod common;

use std::fs;

use common::{run_in, s, slanted};

/// A Middlebury-style scene folder (`im0.png`, `im1.png`, `disp0GT.pfm`, `calib.txt`) made from
/// the sample scene.
fn middlebury_folder(root: &std::path::Path) -> std::path::PathBuf {
    let scene = root.join("slanted");
    fs::create_dir_all(&scene).unwrap();
    fs::copy(slanted("left.png"), scene.join("im0.png")).unwrap();
    fs::copy(slanted("right.png"), scene.join("im1.png")).unwrap();
    fs::copy(slanted("disp0GT.pfm"), scene.join("disp0GT.pfm")).unwrap();
    fs::write(
        scene.join("calib.txt"),
        "cam0=[3000 0 143.5; 0 3000 107.5; 0 0 1]\ncam1=[3000 0 143.5; 0 3000 107.5; 0 0 1]\n\
         doffs=0\nbaseline=80\nwidth=288\nheight=216\nndisp=64\n",
    )
    .unwrap();
    scene
}

fn json(text: &str) -> serde_json::Value {
    serde_json::from_str(text).unwrap_or_else(|e| panic!("not JSON ({e}): {text}"))
}

#[test]
fn eval_folder_scores_like_the_pair_command_and_eval() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("scenes");
    let scene = middlebury_folder(&root);
    let run = run_in(dir.path(), &["eval-folder", s(&root), "--json"]);
    run.assert_success();
    let folder = json(&run.stdout);
    let scenes = folder["scenes"].as_array().unwrap();
    assert_eq!(scenes.len(), 1);
    assert_eq!(scenes[0]["ndisp"], 64, "ndisp comes from calib.txt");

    // The same matcher through the pair command, scored by `eval`: identical metrics.
    let pfm = dir.path().join("d.pfm");
    run_in(
        dir.path(),
        &[
            s(&scene.join("im0.png")),
            s(&scene.join("im1.png")),
            "--max-disparity",
            "64",
            "--disparity",
            s(&pfm),
        ],
    )
    .assert_success();
    let eval = run_in(dir.path(), &["eval", s(&pfm), s(&scene.join("disp0GT.pfm")), "--json"]);
    eval.assert_success();
    let single = json(&eval.stdout);
    for key in ["bad1", "bad2", "bad4", "density"] {
        assert_eq!(scenes[0]["metrics"][key], single["metrics"][key], "{key}");
    }
    assert_eq!(folder["average"]["bad2"], single["metrics"]["bad2"]);

    let table = run_in(dir.path(), &["eval-folder", s(&root)]);
    table.assert_success();
    assert!(table.stdout.lines().any(|l| l.starts_with("slanted")), "{}", table.stdout);
    assert!(table.stdout.lines().any(|l| l.starts_with("average")), "{}", table.stdout);
}

#[test]
fn fill_gives_a_dense_map_that_scores_better() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("scenes");
    middlebury_folder(&root);
    let score = |extra: &[&str]| {
        let mut args = vec!["eval-folder", s(&root), "--json"];
        args.extend(extra);
        let run = run_in(dir.path(), &args);
        run.assert_success();
        json(&run.stdout)["scenes"][0]["metrics"].clone()
    };
    let sparse = score(&[]);
    let dense = score(&["--fill"]);
    assert_eq!(dense["density"].as_f64().unwrap(), 100.0);
    assert!(sparse["density"].as_f64().unwrap() < 100.0);
    // Holes count as errors: filling the occlusion bands from the background side must win.
    let (b_sparse, b_dense) = (sparse["bad2"].as_f64().unwrap(), dense["bad2"].as_f64().unwrap());
    assert!(b_dense < b_sparse, "bad2 with --fill {b_dense} is not below {b_sparse}");
}

#[test]
fn presets_are_reported_and_only_for_sgm() {
    let dir = tempfile::tempdir().unwrap();
    let stats = dir.path().join("s.json");
    let (l, r) = (slanted("left.png"), slanted("right.png"));
    let base = [s(&l), s(&r), "--max-disparity", "64", "--disparity", "d.pfm", "--stats", s(&stats)];
    let mut fast = base.to_vec();
    fast.extend(["--preset", "fast"]);
    run_in(dir.path(), &fast).assert_success();
    let matcher = json(&fs::read_to_string(&stats).unwrap())["matcher"].clone();
    assert_eq!((matcher["paths"].as_u64(), matcher["single_pass"].as_bool()), (Some(3), Some(true)));

    let mut accurate = base.to_vec();
    accurate.extend(["--preset", "accurate", "--fill"]);
    run_in(dir.path(), &accurate).assert_success();
    let matcher = json(&fs::read_to_string(&stats).unwrap())["matcher"].clone();
    assert!(matcher["weighted_median_radius"].as_u64().unwrap() > 0);
    assert_eq!(matcher["fill"].as_bool(), Some(true));

    let mut bm = base.to_vec();
    bm.extend(["--matcher", "bm", "--preset", "accurate"]);
    let err = run_in(dir.path(), &bm);
    assert!(err.assert_error(2).contains("--preset"));

    // Edge snapping: on by default, reported, and --edge-snap 0 turns it off.
    run_in(dir.path(), &base).assert_success();
    let matcher = json(&fs::read_to_string(&stats).unwrap())["matcher"].clone();
    assert_eq!(matcher["edge_snap_radius"].as_u64(), Some(5));
    let snapped = stereo_io::read_pfm(&dir.path().join("d.pfm")).unwrap();
    let mut off = base.to_vec();
    off.extend(["--edge-snap", "0"]);
    run_in(dir.path(), &off).assert_success();
    let matcher = json(&fs::read_to_string(&stats).unwrap())["matcher"].clone();
    assert_eq!(matcher["edge_snap_radius"].as_u64(), Some(0));
    let unsnapped = stereo_io::read_pfm(&dir.path().join("d.pfm")).unwrap();
    let same = |a: f32, b: f32| a == b || (a.is_nan() && b.is_nan());
    let moved = snapped.as_slice().iter().zip(unsnapped.as_slice()).filter(|&(&a, &b)| !same(a, b)).count();
    assert!(moved > 0, "snapping changed no pixel of the sample's box edges");
    let mut bm = base.to_vec();
    bm.extend(["--matcher", "bm", "--edge-snap", "3"]);
    assert!(run_in(dir.path(), &bm).assert_error(2).contains("--edge-snap"));
}

#[test]
fn confidence_and_disparity_channels_and_min_confidence() {
    let dir = tempfile::tempdir().unwrap();
    let (l, r) = (slanted("left.png"), slanted("right.png"));
    let (exr, pfm) = (dir.path().join("d.exr"), dir.path().join("d.pfm"));
    let mut args = vec![s(&l), s(&r), "--max-disparity", "64", "-o", s(&exr), "--disparity", s(&pfm)];
    args.extend(common::RIG);
    args.extend(["--confidence", "--exr-disparity"]);
    run_in(dir.path(), &args).assert_success();

    let mut names = stereo_io::exr_channel_names(&exr).unwrap();
    names.sort();
    assert_eq!(names, ["Z", "confidence", "disparity"]);
    let z = stereo_io::read_exr_channel(&exr, "Z").unwrap();
    let confidence = stereo_io::read_exr_channel(&exr, "confidence").unwrap();
    let disparity = stereo_io::read_exr_channel(&exr, "disparity").unwrap();
    let from_pfm = stereo_io::read_pfm(&pfm).unwrap();
    let same = |a: f32, b: f32| a == b || (a.is_nan() && b.is_nan());
    assert!(disparity.as_slice().iter().zip(from_pfm.as_slice()).all(|(&a, &b)| same(a, b)));
    assert_eq!(z.size(), confidence.size());
    for (&c, &d) in confidence.as_slice().iter().zip(from_pfm.as_slice()) {
        assert!((0.0..=1.0).contains(&c), "confidence {c}");
        if d.is_nan() {
            assert_eq!(c, 0.0, "no confidence without a disparity");
        }
    }

    // --min-confidence drops exactly the pixels under the threshold.
    let kept = dir.path().join("kept.pfm");
    run_in(
        dir.path(),
        &[s(&l), s(&r), "--max-disparity", "64", "--min-confidence", "0.5", "--disparity", s(&kept)],
    )
    .assert_success();
    let kept = stereo_io::read_pfm(&kept).unwrap();
    for ((&k, &d), &c) in kept.as_slice().iter().zip(from_pfm.as_slice()).zip(confidence.as_slice()) {
        if c >= 0.5 {
            assert!(same(k, d));
        } else {
            assert!(k.is_nan());
        }
    }

    // The channels live in the depth EXR: without a rig, or with block matching, they are refused.
    let no_rig = run_in(dir.path(), &[s(&l), s(&r), "--confidence", "--disparity", "x.pfm"]);
    assert!(no_rig.assert_error(2).contains("--confidence"));
    let mut bm = vec![s(&l), s(&r), "--matcher", "bm", "--min-confidence", "0.5", "--disparity", "x.pfm"];
    bm.truncate(8);
    assert!(run_in(dir.path(), &bm).assert_error(2).contains("--min-confidence"));
}

#[test]
fn search_is_chosen_by_flag_and_reported() {
    let dir = tempfile::tempdir().unwrap();
    let (l, r) = (slanted("left.png"), slanted("right.png"));
    let stats = |search: &str| {
        let file = dir.path().join(format!("{search}.json"));
        let run = run_in(
            dir.path(),
            &[
                s(&l),
                s(&r),
                "--max-disparity",
                "64",
                "--search",
                search,
                "--disparity",
                "d.pfm",
                "--stats",
                s(&file),
            ],
        );
        run.assert_success();
        (json(&fs::read_to_string(&file).unwrap()), run.stdout)
    };
    let (full, _) = stats("full");
    assert_eq!(full["matcher"]["search"], "full");
    assert_eq!(full["matcher"]["mean_disparities_searched"], 64.0);
    let (coarse_to_fine, summary) = stats("hierarchical");
    let m = &coarse_to_fine["matcher"];
    assert_eq!((m["search"].as_str(), m["search_levels"].as_u64()), (Some("hierarchical"), Some(1)));
    assert!(m["mean_disparities_searched"].as_f64().unwrap() < 64.0, "{m}");
    assert!(summary.contains("coarse to fine"), "{summary}");
    // 64 disparities: the default searches the whole range.
    let (auto, _) = stats("auto");
    assert_eq!(auto["matcher"]["search"], "full");

    let bad = run_in(dir.path(), &[s(&l), s(&r), "--search", "quick", "--disparity", "d.pfm"]);
    assert!(bad.assert_error(2).contains("--search"), "{}", bad.stderr);
    let bm =
        run_in(dir.path(), &[s(&l), s(&r), "--matcher", "bm", "--search", "full", "--disparity", "d.pfm"]);
    assert!(bm.assert_error(2).contains("search"), "{}", bm.stderr);
}
