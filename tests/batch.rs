//! End-to-end runs of `stereo-depth batch` and `batch-merge` on folders built in a temporary
//! directory: small rendered scenes written as PNG in every layout, the repo's data/slanted, a
//! corrupt PNG and a size-mismatched pair.

mod common;

use std::collections::BTreeSet;
use std::fs;
use std::path::{Path, PathBuf};

use common::*;
use serde_json::Value;
use stereo_disparity::GrayImage;

const W: usize = 96;
const H: usize = 64;
/// Small images, small search: fast tests.
const MATCH: [&str; 2] = ["--max-disparity", "16"];

/// A rendered 96x64 scene (disparities 8..~15 px), varied by `seed`.
fn scene(seed: u64, width: usize, height: usize) -> stereo_scene::Scene {
    let params = stereo_scene::SceneParams {
        width,
        height,
        seed,
        plane: (8.0, 0.03, 0.01),
        foreground: Some(stereo_scene::Foreground {
            rect: stereo_scene::Rect { x0: 30.5, y0: 18.5, x1: 62.5, y1: 44.5 },
            disparity: 14.0,
        }),
        supersampling: 2,
        ..stereo_scene::SceneParams::default()
    };
    stereo_scene::render(&params)
}

fn write_png(path: &Path, image: &GrayImage) {
    fs::create_dir_all(path.parent().unwrap()).unwrap();
    let buffer = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(
        image.width() as u32,
        image.height() as u32,
        image.as_slice().to_vec(),
    )
    .unwrap();
    buffer.save(path).unwrap();
}

/// Writes a rendered pair as `root/left` and `root/right` (relative paths).
fn put_pair(root: &Path, left: &str, right: &str, seed: u64) {
    let scene = scene(seed, W, H);
    write_png(&root.join(left), &scene.left);
    write_png(&root.join(right), &scene.right);
}

fn batch(cwd: &Path, args: &[&str]) -> Run {
    let mut all = vec!["batch"];
    all.extend(args);
    run_in(cwd, &all)
}

fn with_rig<'a>(args: &[&'a str]) -> Vec<&'a str> {
    let mut all = args.to_vec();
    all.extend(RIG);
    all.extend(MATCH);
    all
}

fn read_json(path: &Path) -> Value {
    let text = fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).unwrap()
}

/// `name -> status` of a summary's rows.
fn statuses(summary: &Value) -> Vec<(String, String)> {
    summary["rows"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| (r["name"].as_str().unwrap().to_string(), r["status"].as_str().unwrap().to_string()))
        .collect()
}

fn row<'a>(summary: &'a Value, name: &str) -> &'a Value {
    summary["rows"].as_array().unwrap().iter().find(|r| r["name"] == name).unwrap_or_else(|| {
        panic!("no row {name} in {summary:#}");
    })
}

/// The depth map written for a pair is a readable EXR with one channel Z, equal to
/// `B·f / ((d + doffs)·p)` of the disparity written beside it, and the disparities are close to
/// the ground truth.
#[track_caller]
fn check_outputs(out: &Path, name: &str, depth_per_disparity: f64, doffs: f64) {
    let exr = read_exr(&out.join(format!("{name}.depth.exr")));
    assert_eq!(exr.channels, ["Z"]);
    assert_eq!((exr.width, exr.height), (W, H));
    let disparity = stereo_io::read_pfm(&out.join(format!("{name}.disparity.pfm"))).unwrap();
    let gt = scene(0, W, H).gt_left; // every seed has the same geometry
    let (mut valid, mut close) = (0, 0);
    for y in 0..H {
        for x in 0..W {
            let (z, d) = (exr.z.get(x, y) as f64, disparity.get(x, y) as f64);
            if d.is_finite() && d + doffs > 0.0 {
                let expected = depth_per_disparity / (d + doffs);
                assert!(((z - expected) / expected).abs() < 1e-4, "{name} ({x}, {y}): Z {z} for d {d}");
                valid += 1;
                close += usize::from((d - gt.get(x, y) as f64).abs() <= 1.0);
            } else {
                assert!(z.is_nan(), "{name} ({x}, {y}): Z {z} without a disparity");
            }
        }
    }
    assert!(valid > W * H / 2, "{name}: only {valid} valid pixels");
    assert!(close as f64 >= 0.85 * valid as f64, "{name}: {close} of {valid} within 1 px of the truth");
    let stats = read_json(&out.join(format!("{name}.stats.json")));
    assert_eq!(stats["valid_pixels"], exr.z.as_slice().iter().filter(|z| z.is_finite()).count());
}

/// One folder with every layout, a corrupt image, a size-mismatched pair and an unpaired image.
fn mixed_input(root: &Path) {
    put_pair(root, "folders/left/a.png", "folders/right/a.png", 1);
    put_pair(root, "folders/left/b.png", "folders/right/b.png", 2);
    put_pair(root, "suffix/c_left.png", "suffix/c_right.png", 3);
    put_pair(root, "suffix/d_L.png", "suffix/d_R.png", 4);
    put_pair(root, "kitti/image_2/000000_10.png", "kitti/image_3/000000_10.png", 5);
    put_pair(root, "mb/scene1/im0.png", "mb/scene1/im1.png", 6);
    // The calib.txt agrees with the rig flags (3000 px = 12 mm / 4 µm, baseline 80 mm).
    fs::write(
        root.join("mb/scene1/calib.txt"),
        "cam0=[3000 0 47.5; 0 3000 31.5; 0 0 1]\ncam1=[3000 0 47.5; 0 3000 31.5; 0 0 1]\n\
         doffs=0\nbaseline=80\nwidth=96\nheight=64\nndisp=16\n",
    )
    .unwrap();
    // A corrupt left image and a size-mismatched pair.
    put_pair(root, "bad/x_left.png", "bad/x_right.png", 7);
    fs::write(root.join("bad/x_left.png"), b"\x89PNG\r\n\x1a\nthis is not really a PNG").unwrap();
    let small = scene(8, 80, H);
    write_png(&root.join("bad/y_left.png"), &scene(8, W, H).left);
    write_png(&root.join("bad/y_right.png"), &small.right);
    // Images that pair with nothing, and files that are not images.
    put_pair(root, "folders/left/lonely.png", "elsewhere/ignored.txt.png", 9);
    fs::write(root.join("folders/notes.txt"), "not an image").unwrap();
}

const GOOD: [&str; 6] =
    ["folders/a", "folders/b", "kitti/000000_10", "mb/scene1/im0", "suffix/c", "suffix/d"];
const BAD: [&str; 2] = ["bad/x", "bad/y"];

#[test]
fn every_layout_is_processed_failures_are_reported_and_runs_resume() {
    let dir = tempfile::tempdir().unwrap();
    let (input, out) = (dir.path().join("in"), dir.path().join("out"));
    mixed_input(&input);
    let args = with_rig(&[s(&input), "--out", s(&out), "--disparity", "--stats"]);

    // First run: the good pairs are written, the bad ones reported, exit status 1.
    let run = batch(dir.path(), &args);
    assert_eq!(run.code, Some(1), "stdout:\n{}\nstderr:\n{}", run.stdout, run.stderr);
    assert!(run.stderr.contains("stereo-depth: 2 of 8 pairs failed"), "{}", run.stderr);
    assert!(run.stderr.contains("unpaired image folders/left/lonely.png: no right image"), "{}", run.stderr);
    assert!(run.stderr.contains("unpaired image elsewhere/ignored.txt.png"), "{}", run.stderr);
    assert!(!run.stderr.contains("notes.txt"), "{}", run.stderr);
    assert_eq!(run.printed_path("summary").as_deref(), Some(out.join("summary.json").as_path()));

    let summary = read_json(&out.join("summary.json"));
    let mut expected: Vec<(String, String)> = GOOD
        .iter()
        .map(|n| (n.to_string(), "ok".to_string()))
        .chain(BAD.iter().map(|n| (n.to_string(), "failed".to_string())))
        .collect();
    expected.sort();
    assert_eq!(statuses(&summary), expected);
    assert_eq!((summary["ok"].as_u64(), summary["failed"].as_u64()), (Some(6), Some(2)));
    assert_eq!(summary["unpaired"].as_array().unwrap().len(), 2);
    let corrupt = row(&summary, "bad/x")["error"].as_str().unwrap().to_string();
    assert!(corrupt.contains("x_left.png"), "{corrupt}");
    let mismatch = row(&summary, "bad/y")["error"].as_str().unwrap().to_string();
    assert!(mismatch.contains("96x64") && mismatch.contains("80x64"), "{mismatch}");
    for name in GOOD {
        check_outputs(&out, name, DEPTH_PER_DISPARITY, 0.0);
        let r = row(&summary, name);
        assert!(r["density_percent"].as_f64().unwrap() > 50.0, "{r}");
        assert!(r["median_depth_m"].as_f64().unwrap() > 10.0, "{r}");
        for key in ["load_ms", "match_ms", "triangulate_ms", "write_ms", "total_ms"] {
            assert!(r[key].as_f64().is_some(), "{key}: {r}");
        }
    }
    assert_eq!(row(&summary, "mb/scene1/im0")["layout"], "middlebury");
    assert_eq!(row(&summary, "kitti/000000_10")["layout"], "kitti");
    // Failed pairs leave nothing behind; the layout is mirrored; no temporary files.
    assert_eq!(list(&out.join("bad")), Vec::<String>::new());
    assert_eq!(list(&out.join("suffix")).len(), 6);
    let csv = fs::read_to_string(out.join("summary.csv")).unwrap();
    assert_eq!(csv.lines().count(), 9, "{csv}");
    assert!(csv.starts_with("index,name,status,error,"), "{csv}");
    assert!(csv.lines().any(|l| l.contains(",bad/x,failed,")), "{csv}");

    // Second run: every good pair is skipped and left untouched; the bad ones fail again.
    let depth_a = out.join("folders/a.depth.exr");
    let modified = fs::metadata(&depth_a).unwrap().modified().unwrap();
    let run = batch(dir.path(), &args);
    assert_eq!(run.code, Some(1), "{}", run.stderr);
    let summary = read_json(&out.join("summary.json"));
    for name in GOOD {
        let r = row(&summary, name);
        assert_eq!(r["status"], "skipped", "{r}");
        // Metrics come from the stats file of the earlier run.
        assert!(r["density_percent"].as_f64().is_some(), "{r}");
    }
    assert_eq!(fs::metadata(&depth_a).unwrap().modified().unwrap(), modified);

    // An incomplete pair (an output missing, as after an interrupted run) is redone, alone.
    fs::remove_file(out.join("suffix/c.stats.json")).unwrap();
    let run = batch(dir.path(), &args);
    assert_eq!(run.code, Some(1), "{}", run.stderr);
    let summary = read_json(&out.join("summary.json"));
    assert_eq!(row(&summary, "suffix/c")["status"], "ok");
    assert_eq!(summary["ok"], 1);
    assert_eq!(summary["skipped"], 5);
    check_outputs(&out, "suffix/c", DEPTH_PER_DISPARITY, 0.0);

    // --overwrite redoes everything.
    let mut overwrite = with_rig(&[s(&input), "--out", s(&out), "--disparity", "--stats", "--overwrite"]);
    let run = batch(dir.path(), &overwrite);
    assert_eq!(run.code, Some(1), "{}", run.stderr);
    let summary = read_json(&out.join("summary.json"));
    assert_eq!(summary["ok"], 6);
    assert_ne!(fs::metadata(&depth_a).unwrap().modified().unwrap(), modified);

    // Without the bad pairs, exit status 0.
    fs::remove_dir_all(input.join("bad")).unwrap();
    overwrite.push("--quiet");
    let run = batch(dir.path(), &overwrite);
    run.assert_success();
    assert!(!run.stderr.contains("failed"), "{}", run.stderr);
}

#[test]
fn middlebury_calib_gives_the_rig_and_the_disparity_range() {
    let dir = tempfile::tempdir().unwrap();
    let (input, out) = (dir.path().join("in"), dir.path().join("out"));
    put_pair(&input, "Art/im0.png", "Art/im1.png", 1);
    fs::write(
        input.join("Art/calib.txt"),
        "cam0=[2000 0 40; 0 2000 30; 0 0 1]\ncam1=[2000 0 42.5; 0 2000 30; 0 0 1]\n\
         doffs=2.5\nbaseline=160\nwidth=96\nheight=64\nndisp=16\nisint=0\nvmin=8\nvmax=15\n",
    )
    .unwrap();
    // No rig flags at all: everything comes from calib.txt.
    let run = batch(dir.path(), &[s(&input), "--out", s(&out), "--disparity", "--stats"]);
    run.assert_success();
    // Z [m] = baseline [mm] * f [px] / (d + doffs) / 1000.
    check_outputs(&out, "Art/im0", 160.0 * 2000.0 / 1000.0, 2.5);
    let stats = read_json(&out.join("Art/im0.stats.json"));
    assert_eq!(stats["matcher"]["max_disparity"], 16);
    assert_eq!(stats["rig"]["focal_px"], 2000.0);
    assert_eq!(stats["rig"]["baseline_mm"], 160.0);
    assert_eq!(stats["rig"]["doffs"], 2.5);
    assert_eq!(stats["rig"]["principal_point"], serde_json::json!([40.0, 30.0]));
    assert!(stats["rig"]["focal_mm"].is_null());

    // A flag takes precedence over calib.txt.
    let run = batch(
        dir.path(),
        &[
            s(&input),
            "--out",
            s(&out),
            "--disparity",
            "--stats",
            "--overwrite",
            "--baseline",
            "80",
            "--doffs",
            "0",
        ],
    );
    run.assert_success();
    check_outputs(&out, "Art/im0", 80.0 * 2000.0 / 1000.0, 0.0);

    // A calib.txt for another image size fails the pair.
    fs::write(
        input.join("Art/calib.txt"),
        "cam0=[2000 0 40; 0 2000 30; 0 0 1]\nbaseline=160\nwidth=192\nheight=128\n",
    )
    .unwrap();
    let run = batch(dir.path(), &[s(&input), "--out", s(&out), "--overwrite", "--max-disparity", "16"]);
    assert_eq!(run.code, Some(1));
    let summary = read_json(&out.join("summary.json"));
    let error = row(&summary, "Art/im0")["error"].as_str().unwrap().to_string();
    assert!(error.contains("calib.txt is for 192x128"), "{error}");

    // Pairs without calib.txt need the rig flags: a usage error before any work.
    put_pair(&input, "plain_left.png", "plain_right.png", 2);
    let run = batch(dir.path(), &[s(&input), "--out", s(&dir.path().join("out2"))]);
    let message = run.assert_error(2);
    assert!(message.contains("plain") && message.contains("--baseline"), "{message}");
    assert!(!dir.path().join("out2").exists());
}

#[test]
fn pattern_pairs_other_names() {
    let dir = tempfile::tempdir().unwrap();
    let (input, out) = (dir.path().join("in"), dir.path().join("out"));
    put_pair(&input, "p_a.png", "p_b.png", 1);
    put_pair(&input, "sub/q_a.png", "sub/q_b.png", 2);
    put_pair(&input, "left/r.png", "right/r.png", 3);
    let run = batch(
        dir.path(),
        &with_rig(&[s(&input), "--out", s(&out), "--pattern", "{name}_a.png:{name}_b.png"]),
    );
    run.assert_success();
    let summary = read_json(&out.join("summary.json"));
    let names: Vec<String> = statuses(&summary).into_iter().map(|(n, _)| n).collect();
    assert_eq!(names, ["p", "sub/q"]);
    assert!(out.join("sub/q.depth.exr").is_file());
    // The layouts are not searched with --pattern: left/r.png and right/r.png are unpaired.
    assert!(run.stderr.contains("unpaired image left/r.png: does not match --pattern"), "{}", run.stderr);

    let run = batch(dir.path(), &with_rig(&[s(&input), "--out", s(&out), "--pattern", "{name}.png"]));
    assert!(run.assert_error(2).contains("--pattern"));
}

#[test]
fn list_prints_the_plan_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (input, out) = (dir.path().join("in"), dir.path().join("out"));
    mixed_input(&input);
    let before = list(&input);
    let run = batch(dir.path(), &with_rig(&[s(&input), "--out", s(&out), "--stats", "--list"]));
    run.assert_success();
    assert!(!out.exists(), "--list created {}", out.display());
    assert_eq!(list(&input), before);
    let process: Vec<&str> = run.stdout.lines().filter(|l| l.starts_with("process\t")).collect();
    assert_eq!(process.len(), 8, "{}", run.stdout);
    assert!(
        process.iter().any(|l| l.contains("mb/scene1/im0\tmiddlebury (calib.txt)")
            && l.contains(&format!("{}", out.join("mb/scene1/im0.stats.json").display()))),
        "{}",
        run.stdout
    );
    assert_eq!(run.stdout.lines().filter(|l| l.starts_with("unpaired\t")).count(), 2, "{}", run.stdout);
    assert!(
        run.stdout.contains("8 pairs: 8 to process, 0 complete (skipped); 2 unpaired images"),
        "{}",
        run.stdout
    );

    // With a shard: only its pairs.
    let run = batch(dir.path(), &with_rig(&[s(&input), "--out", s(&out), "--list", "--shard", "1/3"]));
    run.assert_success();
    assert_eq!(run.stdout.lines().filter(|l| l.starts_with("process\t")).count(), 3, "{}", run.stdout);
    assert!(run.stdout.contains("summary.shard-1-of-3.json"), "{}", run.stdout);
    assert!(!out.exists());
}

#[test]
fn shards_cover_every_pair_exactly_once_and_merge() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    let names: Vec<String> = (0..9).map(|i| format!("s{i}")).collect();
    for (i, name) in names.iter().enumerate() {
        put_pair(&input, &format!("{name}_left.png"), &format!("{name}_right.png"), i as u64);
    }
    for n in [1usize, 2, 3, 7] {
        let out = dir.path().join(format!("out{n}"));
        let mut seen: Vec<String> = Vec::new();
        for k in 0..n {
            let shard = format!("{k}/{n}");
            let run = batch(
                dir.path(),
                &with_rig(&[s(&input), "--out", s(&out), "--shard", &shard, "--jobs", "1"]),
            );
            run.assert_success();
            let summary = read_json(&out.join(format!("summary.shard-{k}-of-{n}.json")));
            assert_eq!(summary["shard"], shard);
            assert_eq!(summary["total_pairs"], 9);
            seen.extend(statuses(&summary).into_iter().map(|(name, _)| name));
        }
        let unique: BTreeSet<&String> = seen.iter().collect();
        assert_eq!(seen.len(), names.len(), "N = {n}: {seen:?}");
        assert_eq!(unique.into_iter().cloned().collect::<Vec<_>>(), names, "N = {n}");
        assert!(!out.join("summary.json").exists());

        let run = run_in(dir.path(), &["batch-merge", s(&out)]);
        run.assert_success();
        let merged = read_json(&out.join("summary.json"));
        let merged_names: Vec<String> = statuses(&merged).into_iter().map(|(name, _)| name).collect();
        assert_eq!(merged_names, names, "N = {n}");
        assert_eq!(merged["ok"], 9);
        let indices: Vec<u64> =
            merged["rows"].as_array().unwrap().iter().map(|r| r["index"].as_u64().unwrap()).collect();
        assert_eq!(indices, (0..9).collect::<Vec<u64>>());
        assert_eq!(fs::read_to_string(out.join("summary.csv")).unwrap().lines().count(), 10);
        for name in &names {
            assert!(out.join(format!("{name}.depth.exr")).is_file());
        }
    }

    // A missing shard is an error, and nothing is merged.
    let out = dir.path().join("out3");
    fs::remove_file(out.join("summary.json")).unwrap();
    fs::remove_file(out.join("summary.shard-1-of-3.json")).unwrap();
    let run = run_in(dir.path(), &["batch-merge", s(&out)]);
    let message = run.assert_error(1);
    assert!(message.contains("missing the summaries of shard(s) 1 of 3"), "{message}");
    assert!(!out.join("summary.json").exists());

    // Bad shard specs are usage errors.
    for bad in ["3/3", "1", "a/2", "0/0"] {
        let run = batch(dir.path(), &with_rig(&[s(&input), "--out", s(&out), "--shard", bad]));
        assert!(run.assert_error(2).contains("--shard"), "{bad}");
    }
}

#[test]
fn slanted_in_a_batch_equals_the_pair_command() {
    let dir = tempfile::tempdir().unwrap();
    let (input, out) = (dir.path().join("in"), dir.path().join("out"));
    for side in ["left", "right"] {
        fs::create_dir_all(input.join(side)).unwrap();
        fs::copy(slanted(&format!("{side}.png")), input.join(side).join("slanted.png")).unwrap();
    }
    let run = batch(
        dir.path(),
        &[s(&input), "--out", s(&out), "--baseline", "80", "--focal", "12", "--pixel", "4"],
    );
    run.assert_success();
    let single: PathBuf = dir.path().join("single.exr");
    let mut args =
        vec![s(&input.join("left/slanted.png")).to_string(), s(&input.join("right/slanted.png")).to_string()];
    args.extend(RIG.iter().map(|a| a.to_string()));
    args.extend(["-o".to_string(), s(&single).to_string()]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    run_in(dir.path(), &args).assert_success();
    let (a, b) = (read_exr(&out.join("slanted.depth.exr")), read_exr(&single));
    assert_eq!((a.width, a.height), (288, 216));
    let same = a.z.as_slice().iter().zip(b.z.as_slice()).all(|(x, y)| x == y || (x.is_nan() && y.is_nan()));
    assert!(same, "batch and pair depth maps differ");
}
