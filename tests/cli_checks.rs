//! --min-depth/--max-depth, the unit-mistake and ground-truth-scale warnings, and TIFF input.
//! Every output is read back with readers independent of the program (exr, image, ply-rs).

mod common;

use std::fs;
use std::path::Path;

use common::*;
use image::{ImageBuffer, ImageFormat, Luma, Rgb};
use serde_json::Value;
use stereo_disparity::GrayImage;

fn stats(path: &Path) -> Value {
    serde_json::from_str(&fs::read_to_string(path).unwrap()).unwrap()
}

/// The z of every vertex of a PLY point cloud, as ply-rs reads it.
fn ply_depths(path: &Path) -> Vec<f32> {
    use ply_rs::ply::Property;
    let mut file = fs::File::open(path).unwrap();
    let ply = ply_rs::parser::Parser::<ply_rs::ply::DefaultElement>::new().read_ply(&mut file).unwrap();
    ply.payload["vertex"]
        .iter()
        .map(|v| match &v["z"] {
            Property::Float(z) => *z,
            other => panic!("z is {other:?}, not a float"),
        })
        .collect()
}

fn png16(path: &Path) -> ImageBuffer<Luma<u16>, Vec<u16>> {
    match image::open(path).unwrap() {
        image::DynamicImage::ImageLuma16(buffer) => buffer,
        other => panic!("{} is {:?}, not 16-bit grey", path.display(), other.color()),
    }
}

#[test]
fn depth_limits_cut_every_output() {
    let (min, max) = (6.0f64, 12.0f64);
    let dir = tempfile::tempdir().unwrap();
    let (_, all) = run_slanted(dir.path(), &RIG, &[]);
    let all_disparity = stereo_io::read_pfm(&all.pfm).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let (run, cut) = run_slanted(dir.path(), &RIG, &["--min-depth", "6", "--max-depth", "12"]);
    assert!(run.stderr.is_empty(), "{}", run.stderr);
    assert!(run.stdout.contains("depth limits  6 .. 12 m:"), "{}", run.stdout);

    let disparity = stereo_io::read_pfm(&cut.pfm).unwrap();
    let (width, height) = disparity.size();
    let z = read_exr(&cut.exr).z;
    let depth_png = png16(&cut.depth_png);
    let kitti = png16(&cut.disparity_png);
    let preview = image::open(&cut.preview).unwrap().to_rgb8();
    let (mut valid, mut removed) = (0usize, 0usize);
    for y in 0..height {
        for x in 0..width {
            let (d, before, zv) = (disparity.get(x, y), all_disparity.get(x, y), z.get(x, y));
            let (mm, k) =
                (depth_png.get_pixel(x as u32, y as u32).0[0], kitti.get_pixel(x as u32, y as u32).0[0]);
            let black = preview.get_pixel(x as u32, y as u32).0 == [0, 0, 0];
            if d.is_finite() {
                // Kept pixels are untouched, and their depth is within the limits everywhere.
                assert_eq!(d, before, "({x}, {y})");
                let expected = DEPTH_PER_DISPARITY / f64::from(d);
                assert!((min..=max).contains(&expected), "({x}, {y}): disparity {d} is {expected} m");
                assert!(zv >= min as f32 && zv <= max as f32, "({x}, {y}): Z {zv}");
                assert!((6000..=12000).contains(&mm), "({x}, {y}): {mm} mm");
                assert_ne!(k, 0, "({x}, {y})");
                assert!(!black, "({x}, {y})");
                valid += 1;
            } else {
                assert!(zv.is_nan(), "({x}, {y}): Z {zv} without a disparity");
                assert_eq!((mm, k), (0, 0), "({x}, {y})");
                assert!(black, "preview ({x}, {y})");
                if before.is_finite() {
                    let was = DEPTH_PER_DISPARITY / f64::from(before);
                    assert!(!(min..=max).contains(&was), "({x}, {y}): {was} m was cut");
                    removed += 1;
                }
            }
        }
    }
    // The box (45 px, 5.3 m) and the far part of the plane (below 20 px, beyond 12 m) are cut.
    assert!(disparity.get(165, 105).is_nan() && all_disparity.get(165, 105).is_finite());
    assert!(valid > width * height / 10 && removed > width * height / 10, "{valid} kept, {removed} cut");

    let points = ply_depths(&cut.points);
    assert_eq!(points.len(), valid);
    assert!(points.iter().all(|&z| z >= min as f32 && z <= max as f32), "a point outside the limits");

    let stats = stats(&cut.stats);
    assert_eq!(stats["valid_pixels"], valid);
    assert!(stats["depth_m"]["min"].as_f64().unwrap() >= min, "{}", stats["depth_m"]);
    assert!(stats["depth_m"]["max"].as_f64().unwrap() <= max, "{}", stats["depth_m"]);
    assert_eq!(stats["points_written"], valid);
    let limits = &stats["depth_limits"];
    assert_eq!(limits["cut_pixels"], removed, "{limits}");
    assert_eq!((limits["min_m"].as_f64(), limits["max_m"].as_f64()), (Some(min), Some(max)));
    // 240 / 12 = 20 px and 240 / 6 = 40 px.
    assert_eq!(
        (limits["disparity_min_px"].as_f64(), limits["disparity_max_px"].as_f64()),
        (Some(20.0), Some(40.0))
    );
    // Without the flags: no depth_limits.
    assert!(self::stats(&all.stats)["depth_limits"].is_null());
}

#[test]
fn a_far_limit_alone_keeps_the_near_box() {
    let dir = tempfile::tempdir().unwrap();
    let (_, cut) = run_slanted(dir.path(), &RIG, &["--max-depth", "10"]);
    let z = read_exr(&cut.exr).z;
    assert!(z.as_slice().iter().all(|&z| z.is_nan() || (z > 0.0 && z <= 10.0)));
    assert!(z.get(165, 105) < 6.0, "the box at 5.3 m is kept: {}", z.get(165, 105));
    let points = ply_depths(&cut.points);
    assert!(!points.is_empty() && points.iter().all(|&z| z > 0.0 && z <= 10.0));
    let limits = &stats(&cut.stats)["depth_limits"];
    assert!(limits["min_m"].is_null() && limits["disparity_max_px"].is_null(), "{limits}");
    assert!(limits["cut_pixels"].as_u64().unwrap() > 0, "{limits}");
}

#[test]
fn depth_limits_apply_to_batch_pairs() {
    let dir = tempfile::tempdir().unwrap();
    let (input, out) = (dir.path().join("in"), dir.path().join("out"));
    fs::create_dir(&input).unwrap();
    fs::copy(slanted("left.png"), input.join("a_left.png")).unwrap();
    fs::copy(slanted("right.png"), input.join("a_right.png")).unwrap();
    let mut args = vec!["batch", s(&input), "--out", s(&out), "--max-disparity", "64", "--quiet"];
    args.extend(RIG);
    args.extend(["--points", "--stats", "--min-depth", "7", "--max-depth", "9.5"]);
    run_in(dir.path(), &args).assert_success();
    let z = read_exr(&out.join("a.depth.exr")).z;
    assert!(z.as_slice().iter().any(|z| z.is_finite()));
    assert!(z.as_slice().iter().all(|&z| z.is_nan() || (7.0..=9.5).contains(&z)));
    let points = ply_depths(&out.join("a.points.ply"));
    assert!(!points.is_empty() && points.iter().all(|z| (7.0..=9.5).contains(z)));
    assert!(stats(&out.join("a.stats.json"))["depth_limits"]["cut_pixels"].as_u64().unwrap() > 0);
}

#[test]
fn depth_limits_are_usage_errors_without_a_rig_or_when_invalid() {
    let dir = tempfile::tempdir().unwrap();
    let (left, right) = (slanted("left.png"), slanted("right.png"));
    let pair = |extra: &[&str]| {
        let mut args = vec![s(&left), s(&right), "--disparity", "d.pfm"];
        args.extend(extra);
        run_in(dir.path(), &args)
    };
    let err = pair(&["--max-depth", "10"]).assert_error(2).to_string();
    assert!(err.contains("--max-depth needs a rig") && err.contains("--baseline"), "{err}");
    let err = pair(&["--min-depth", "1"]).assert_error(2).to_string();
    assert!(err.contains("--min-depth needs a rig"), "{err}");
    let mut rig = RIG.to_vec();
    for (extra, needle) in [
        (&["--max-depth", "0"][..], "invalid --max-depth 0 m"),
        (&["--min-depth", "-2"], "invalid --min-depth -2 m"),
        (&["--min-depth", "nan"], "invalid --min-depth NaN m"),
        (&["--max-depth", "inf"], "invalid --max-depth inf m"),
        (&["--min-depth", "5", "--max-depth", "2"], "--min-depth 5 m must be below --max-depth 2 m"),
    ] {
        rig.truncate(RIG.len());
        rig.extend(extra);
        let err = pair(&rig).assert_error(2).to_string();
        assert!(err.contains(needle), "{extra:?}: {err}");
        let mut batch = vec!["batch", s(dir.path()), "--out", "out"];
        batch.extend(&rig);
        let err = run_in(dir.path(), &batch).assert_error(2).to_string();
        assert!(err.contains(needle), "batch {extra:?}: {err}");
    }
    assert_eq!(list(dir.path()), Vec::<String>::new(), "nothing is written");
}

/// Runs data/slanted with a rig; asserts success, the outputs, and returns stderr.
fn warned(rig: &[&str]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let (run, outputs) = run_slanted(dir.path(), rig, &[]);
    assert!(outputs.exr.is_file() && outputs.stats.is_file());
    run.stderr
}

#[test]
fn a_baseline_in_metres_is_warned_about() {
    let stderr = warned(&["--baseline", "0.08", "--focal", "12", "--pixel", "4"]);
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        stderr.starts_with("stereo-depth: warning: --baseline 0.08 mm is below 1 mm")
            && stderr.contains("--baseline 80"),
        "{stderr}"
    );
    // 1 mm itself is a possible (micro) rig.
    let stderr = warned(&["--baseline", "1", "--focal-px", "3000"]);
    assert!(!stderr.contains("--baseline"), "{stderr}");
}

#[test]
fn a_pixel_pitch_above_100_um_is_warned_about() {
    // (A few mismatched pixels lie beyond the depth PNG's 65.535 m: that warning may come too.)
    let stderr = warned(&["--baseline", "80", "--focal", "12000", "--pixel", "4000"]);
    assert_eq!(stderr.lines().filter(|l| l.contains("--pixel")).count(), 1, "{stderr}");
    assert!(stderr.starts_with("stereo-depth: warning: --pixel 4000 µm is above 100 µm"), "{stderr}");
    let stderr = warned(&["--baseline", "80", "--focal", "300", "--pixel", "100"]);
    assert!(!stderr.contains("--pixel"), "{stderr}");
}

#[test]
fn a_calib_baseline_below_1_mm_is_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    let calib = dir.path().join("calib.txt");
    fs::write(
        &calib,
        "cam0=[3000 0 143.5; 0 3000 107.5; 0 0 1]\ncam1=[3000 0 143.5; 0 3000 107.5; 0 0 1]\n\
         doffs=0\nbaseline=0.08\nwidth=288\nheight=216\nndisp=64\n",
    )
    .unwrap();
    let stderr = warned(&["--calib", s(&calib)]);
    assert!(
        stderr.contains(&format!("warning: {}: baseline 0.08 mm is below 1 mm", calib.display())),
        "{stderr}"
    );
}

#[test]
fn batch_and_calc_warn_about_the_rig_units() {
    let dir = tempfile::tempdir().unwrap();
    let (input, out) = (dir.path().join("in"), dir.path().join("out"));
    fs::create_dir(&input).unwrap();
    fs::copy(slanted("left.png"), input.join("a_left.png")).unwrap();
    fs::copy(slanted("right.png"), input.join("a_right.png")).unwrap();
    let args = ["batch", s(&input), "--out", s(&out), "--max-disparity", "64", "--quiet"];
    let run =
        run_in(dir.path(), &[&args[..], &["--baseline", "0.2", "--focal", "12", "--pixel", "4"]].concat());
    run.assert_success();
    assert!(out.join("a.depth.exr").is_file());
    assert_eq!(run.stderr.matches("warning: --baseline 0.2 mm is below 1 mm").count(), 1, "{}", run.stderr);

    // A Middlebury scene's own calib.txt with the baseline in metres: warned once, naming it.
    let scene = input.join("mb/scene1");
    fs::create_dir_all(&scene).unwrap();
    fs::copy(slanted("left.png"), scene.join("im0.png")).unwrap();
    fs::copy(slanted("right.png"), scene.join("im1.png")).unwrap();
    fs::write(
        scene.join("calib.txt"),
        "cam0=[3000 0 143.5; 0 3000 107.5; 0 0 1]\ncam1=[3000 0 143.5; 0 3000 107.5; 0 0 1]\n\
         doffs=0\nbaseline=0.08\nwidth=288\nheight=216\nndisp=64\n",
    )
    .unwrap();
    fs::remove_file(input.join("a_left.png")).unwrap();
    let run = run_in(dir.path(), &["batch", s(&input), "--out", s(&out), "--quiet"]);
    run.assert_success();
    assert!(out.join("mb/scene1/im0.depth.exr").is_file());
    let needle = format!("warning: {}: baseline 0.08 mm is below 1 mm", scene.join("calib.txt").display());
    assert_eq!(run.stderr.matches(&needle).count(), 1, "{}", run.stderr);

    let run = run_in(dir.path(), &["calc", "--baseline", "80", "--focal", "12", "--pixel", "250"]);
    run.assert_success();
    assert!(run.stdout.contains("m"), "{}", run.stdout);
    assert!(
        run.stderr.starts_with("stereo-depth: warning: --pixel 250 µm is above 100 µm"),
        "{}",
        run.stderr
    );
    let run = run_in(dir.path(), &["calc", "--baseline", "0.5", "--focal", "12", "--pixel", "4"]);
    run.assert_success();
    assert!(run.stderr.contains("warning: --baseline 0.5 mm is below 1 mm"), "{}", run.stderr);
    let run = run_in(dir.path(), &["calc", "--baseline", "80", "--focal", "12", "--pixel", "4"]);
    assert!(run.assert_success().stderr.is_empty(), "{}", run.stderr);
}

#[test]
fn eval_warns_about_8_bit_ground_truth_without_a_scale() {
    let dir = tempfile::tempdir().unwrap();
    // A constant 20 px estimate, against ground truth stored x4 (Middlebury 2003).
    let est = dir.path().join("est.pfm");
    stereo_io::write_pfm(&est, &stereo_disparity::DisparityMap::new(16, 8, 20.0)).unwrap();
    let gt8 = dir.path().join("gt8.png");
    ImageBuffer::<Luma<u8>, _>::from_pixel(16, 8, Luma([80u8])).save(&gt8).unwrap();
    let gt16 = dir.path().join("gt16.png");
    ImageBuffer::<Luma<u16>, _>::from_pixel(16, 8, Luma([80u16])).save(&gt16).unwrap();
    let gt_tif = dir.path().join("gt8.tif");
    ImageBuffer::<Luma<u8>, _>::from_pixel(16, 8, Luma([80u8])).save(&gt_tif).unwrap();

    for gt in [&gt8, &gt_tif] {
        let run = run_in(dir.path(), &["eval", s(&est), s(gt)]);
        run.assert_success();
        assert!(run.stdout.contains("128 px with ground truth"), "{}", run.stdout);
        assert_eq!(run.stderr.lines().count(), 1, "{}", run.stderr);
        assert!(
            run.stderr.starts_with(&format!("stereo-depth: warning: {}: 8-bit ground truth", gt.display()))
                && run.stderr.contains("--gt-scale 4"),
            "{}",
            run.stderr
        );
    }
    let quiet = |args: &[&str]| {
        let run = run_in(dir.path(), args);
        assert!(run.assert_success().stderr.is_empty(), "{args:?}: {}", run.stderr);
    };
    quiet(&["eval", s(&est), s(&gt8), "--gt-scale", "4"]);
    quiet(&["eval", s(&est), s(&gt8), "--gt-scale", "1"]);
    quiet(&["eval", s(&est), s(&gt16)]);
    quiet(&["eval", s(&est), s(&est)]);
}

/// A rendered scene's views as 8-bit samples (the top byte: PNG and TIFF then hold the same).
fn to8(image: &GrayImage) -> Vec<u8> {
    image.as_slice().iter().map(|&v| (v >> 8) as u8).collect()
}

/// Writes `image` in `kind` (grey8, grey16, rgb8, rgb16) as `path` (format from the extension).
fn save(path: &Path, image: &GrayImage, kind: &str) {
    let (w, h) = (image.width() as u32, image.height() as u32);
    let format = ImageFormat::from_path(path).unwrap();
    let grey16 = image.as_slice().to_vec();
    let result = match kind {
        "grey8" => {
            ImageBuffer::<Luma<u8>, _>::from_raw(w, h, to8(image)).unwrap().save_with_format(path, format)
        }
        "grey16" => {
            ImageBuffer::<Luma<u16>, _>::from_raw(w, h, grey16).unwrap().save_with_format(path, format)
        }
        "rgb8" => {
            let rgb: Vec<u8> = to8(image).iter().flat_map(|&v| [v, v / 2, 255 - v]).collect();
            ImageBuffer::<Rgb<u8>, _>::from_raw(w, h, rgb).unwrap().save_with_format(path, format)
        }
        "rgb16" => {
            let rgb: Vec<u16> = grey16.iter().flat_map(|&v| [v, v / 3, 65535 - v]).collect();
            ImageBuffer::<Rgb<u16>, _>::from_raw(w, h, rgb).unwrap().save_with_format(path, format)
        }
        other => panic!("{other}"),
    };
    result.unwrap();
}

#[test]
fn tiff_inputs_give_the_same_disparity_as_png() {
    let dir = tempfile::tempdir().unwrap();
    let params = stereo_scene::SceneParams { width: 160, height: 96, ..Default::default() };
    let scene = stereo_scene::render(&params);
    for kind in ["grey8", "grey16", "rgb8", "rgb16"] {
        let mut outputs = Vec::new();
        for ext in ["png", "tif", "tiff"] {
            let (left, right) =
                (dir.path().join(format!("l-{kind}.{ext}")), dir.path().join(format!("r-{kind}.{ext}")));
            save(&left, &scene.left, kind);
            save(&right, &scene.right, kind);
            let (pfm, kitti) =
                (dir.path().join(format!("{kind}-{ext}.pfm")), dir.path().join(format!("{kind}-{ext}.png")));
            let args = [
                s(&left),
                s(&right),
                "--max-disparity",
                "48",
                "--disparity",
                s(&pfm),
                "--disparity-png",
                s(&kitti),
            ];
            let run = run_in(dir.path(), &args);
            assert!(run.assert_success().stderr.is_empty(), "{}", run.stderr);
            outputs.push((fs::read(&pfm).unwrap(), fs::read(&kitti).unwrap()));
        }
        // The TIFF's header says what the PNG's does.
        let header = stereo_io::probe_image(&dir.path().join(format!("l-{kind}.tif"))).unwrap();
        assert_eq!(header.format, "TIFF");
        assert_eq!(header.bits_per_channel, if kind.ends_with("16") { 16 } else { 8 }, "{kind}");
        assert_eq!((header.width, header.height), (160, 96));
        let map = stereo_io::decode_pfm(&outputs[0].0, Path::new("png.pfm")).unwrap();
        let valid = map.as_slice().iter().filter(|d| d.is_finite()).count();
        assert!(valid > 160 * 96 / 2, "{kind}: only {valid} valid pixels");
        assert!(outputs[1] == outputs[0], "{kind}: .tif disparity differs from the PNG run's");
        assert!(outputs[2] == outputs[0], "{kind}: .tiff disparity differs from the PNG run's");
    }
}

#[test]
fn a_16_bit_tiff_keeps_16_bit_samples() {
    let dir = tempfile::tempdir().unwrap();
    let samples: Vec<u16> = (0..12u16).map(|i| i * 5000 + 3).collect();
    let path = dir.path().join("g.tif");
    ImageBuffer::<Luma<u16>, _>::from_raw(4, 3, samples.clone()).unwrap().save(&path).unwrap();
    let grey = stereo_io::load_gray(&path).unwrap();
    assert_eq!(grey.as_slice(), &samples[..]);
}

#[test]
fn corrupt_tiffs_are_one_line_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let scene =
        stereo_scene::render(&stereo_scene::SceneParams { width: 96, height: 64, ..Default::default() });
    let (left, right) = (dir.path().join("left.tif"), dir.path().join("right.tif"));
    save(&left, &scene.left, "grey16");
    save(&right, &scene.right, "grey16");
    let bytes = fs::read(&left).unwrap();
    let mut cases: Vec<(&str, Vec<u8>)> = [8, 64, bytes.len() / 2, bytes.len() - 40]
        .iter()
        .map(|&n| ("truncated", bytes[..n].to_vec()))
        .collect();
    // The magic of a TIFF, then garbage.
    cases.push(("garbage", [&b"II*\0"[..], &[0xFF; 60]].concat()));
    for (what, bytes) in cases {
        let bad = dir.path().join("bad.tif");
        fs::write(&bad, &bytes).unwrap();
        for args in [
            vec![s(&bad), s(&right), "--disparity", "d.pfm"],
            vec![s(&left), s(&bad), "--disparity", "d.pfm"],
            vec!["info", s(&bad)],
        ] {
            let run = run_in(dir.path(), &args);
            let err = run.assert_error(1);
            assert!(err.contains("bad.tif"), "{what} {} bytes, {args:?}: {err}", bytes.len());
        }
        let err = stereo_io::load_gray(&bad).unwrap_err().to_string();
        assert!(err.contains("bad.tif") && err.contains("TIFF"), "{what}: {err}");
        assert!(!dir.path().join("d.pfm").exists());
    }
}

#[test]
fn tiff_headers_are_checked_against_max_pixels() {
    let dir = tempfile::tempdir().unwrap();
    let scene =
        stereo_scene::render(&stereo_scene::SceneParams { width: 96, height: 64, ..Default::default() });
    let (left, right) = (dir.path().join("left.tiff"), dir.path().join("right.tiff"));
    save(&left, &scene.left, "grey8");
    save(&right, &scene.right, "grey8");
    let run = run_in(dir.path(), &[s(&left), s(&right), "--disparity", "d.pfm", "--max-pixels", "1000"]);
    let err = run.assert_error(1);
    assert!(err.contains("left.tiff") && err.contains("--max-pixels"), "{err}");
}

#[test]
fn batch_finds_tiff_pairs() {
    let dir = tempfile::tempdir().unwrap();
    let (input, out) = (dir.path().join("in"), dir.path().join("out"));
    fs::create_dir_all(input.join("cam/left")).unwrap();
    fs::create_dir_all(input.join("cam/right")).unwrap();
    let scene =
        stereo_scene::render(&stereo_scene::SceneParams { width: 96, height: 64, ..Default::default() });
    save(&input.join("a_left.tif"), &scene.left, "grey16");
    save(&input.join("a_right.tif"), &scene.right, "grey16");
    save(&input.join("cam/left/0001.TIFF"), &scene.left, "rgb8");
    save(&input.join("cam/right/0001.TIFF"), &scene.right, "rgb8");
    let mut args = vec!["batch", s(&input), "--out", s(&out), "--max-disparity", "48", "--quiet"];
    args.extend(RIG);
    let run = run_in(dir.path(), &args);
    run.assert_success();
    assert!(out.join("a.depth.exr").is_file(), "{:?}", list(&out));
    assert!(out.join("cam/0001.depth.exr").is_file(), "{:?}", list(&out));
}
