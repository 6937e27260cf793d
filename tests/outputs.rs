//! The outputs other tools read (issue 6): point clouds, previews, 16-bit depth and KITTI
//! disparity PNGs, Middlebury calib.txt rigs, disparity-only mode and `info`. Every file is read
//! back with a reader independent of the program (exr, image, ply-rs crates) and checked against
//! the disparity map the program wrote and the formula Z = B·f / ((d + doffs)·p).

mod common;

use std::fs;
use std::path::{Path, PathBuf};

use common::*;
use serde_json::Value;
use stereo_disparity::DisparityMap;

fn stats(path: &Path) -> Value {
    serde_json::from_str(&fs::read_to_string(path).unwrap()).unwrap()
}

fn png16(path: &Path) -> image::ImageBuffer<image::Luma<u16>, Vec<u16>> {
    match image::open(path).unwrap() {
        image::DynamicImage::ImageLuma16(buffer) => buffer,
        other => panic!("{} is {:?}, not 16-bit grey", path.display(), other.color()),
    }
}

/// A vertex: position and colour.
type Vertex = ([f32; 3], [u8; 3]);

/// The vertices of a PLY file as ply-rs reads them: (x, y, z, red, green, blue).
fn read_ply(path: &Path) -> (ply_rs::ply::Header, Vec<Vertex>) {
    use ply_rs::ply::Property;
    let mut file = fs::File::open(path).unwrap();
    let ply = ply_rs::parser::Parser::<ply_rs::ply::DefaultElement>::new().read_ply(&mut file).unwrap();
    let float = |p: &Property| match p {
        Property::Float(v) => *v,
        other => panic!("{other:?} is not a float"),
    };
    let uchar = |p: &Property| match p {
        Property::UChar(v) => *v,
        other => panic!("{other:?} is not a uchar"),
    };
    let vertices = ply.payload["vertex"]
        .iter()
        .map(|v| {
            (
                [float(&v["x"]), float(&v["y"]), float(&v["z"])],
                [uchar(&v["red"]), uchar(&v["green"]), uchar(&v["blue"])],
            )
        })
        .collect();
    (ply.header, vertices)
}

/// Z in metres for disparity `d` of a rig with `baseline_mm`, `focal_px` and `doffs`.
fn z_of(d: f64, baseline_mm: f64, focal_px: f64, doffs: f64) -> Option<f64> {
    (d.is_finite() && d + doffs > 0.0).then(|| baseline_mm * focal_px / (d + doffs) / 1000.0)
}

/// Checks every output of a run against its disparity map and the rig.
fn check_outputs(outputs: &Outputs, baseline_mm: f64, focal_px: f64, doffs: f64, cx: f64, cy: f64) {
    let disparity: DisparityMap = stereo_io::read_pfm(&outputs.pfm).unwrap();
    let (width, height) = disparity.size();
    let exr = read_exr(&outputs.exr);
    assert_eq!((exr.width, exr.height), (width, height));
    let depth_png = png16(&outputs.depth_png);
    let kitti = png16(&outputs.disparity_png);
    assert_eq!(depth_png.dimensions(), (width as u32, height as u32));
    assert_eq!(kitti.dimensions(), (width as u32, height as u32));
    let left = image::open(slanted("left.png")).unwrap().to_rgb8();

    let mut expected_points = Vec::new();
    let mut valid = 0;
    for y in 0..height {
        for x in 0..width {
            let d = disparity.get(x, y) as f64;
            let z = exr.z.get(x, y);
            let (mm, k) =
                (depth_png.get_pixel(x as u32, y as u32).0[0], kitti.get_pixel(x as u32, y as u32).0[0]);
            match z_of(d, baseline_mm, focal_px, doffs) {
                Some(expected) => {
                    valid += 1;
                    assert!(
                        ((z as f64 - expected) / expected).abs() < 1e-6,
                        "({x}, {y}): Z {z}, expected {expected}"
                    );
                    // mm PNG = round(Z · 1000) (within one where the f32 rounding decides).
                    let want = (expected * 1000.0).round();
                    if want <= 65535.0 {
                        assert!((mm as f64 - want).abs() <= 1.0, "({x}, {y}): {mm} mm, expected {want}");
                        assert_eq!(mm as f64, (z as f64 * 1000.0).round(), "({x}, {y})");
                    } else {
                        assert_eq!(mm, 0, "({x}, {y}): too deep for the PNG");
                    }
                    let p = [
                        (x as f64 - cx) * expected / focal_px,
                        (y as f64 - cy) * expected / focal_px,
                        expected,
                    ];
                    expected_points.push((p, left.get_pixel(x as u32, y as u32).0));
                }
                None => {
                    assert!(z.is_nan(), "({x}, {y}): Z {z} for disparity {d}");
                    assert_eq!(mm, 0, "({x}, {y})");
                }
            }
            // KITTI: round(d · 256), 0 = invalid or d <= 0.
            let want = if d.is_finite() && d > 0.0 { (d * 256.0).round() as u16 } else { 0 };
            assert_eq!(k, want, "({x}, {y}): disparity {d}");
        }
    }
    assert!(valid > width * height / 2, "only {valid} valid pixels");

    let (header, vertices) = read_ply(&outputs.points);
    assert_eq!(header.encoding, ply_rs::ply::Encoding::BinaryLittleEndian);
    assert!(
        header.comments.iter().any(|c| c.contains("x right, y down, z forward")),
        "{:?}",
        header.comments
    );
    assert_eq!(vertices.len(), expected_points.len());
    for (i, ((got, colour), (want, want_colour))) in vertices.iter().zip(&expected_points).enumerate() {
        for a in 0..3 {
            let tol = 1e-6 * want[2].abs().max(1.0);
            assert!((got[a] as f64 - want[a]).abs() <= tol, "point {i}: {got:?}, expected {want:?}");
        }
        assert_eq!(colour, want_colour, "point {i}");
    }

    // Preview: the map on top, invalid pixels black, valid ones coloured; a colour bar below.
    let preview = image::open(&outputs.preview).unwrap().to_rgb8();
    assert_eq!(preview.width() as usize, width);
    assert!(preview.height() as usize > height + 10, "no colour bar: {}", preview.height());
    for y in 0..height {
        for x in 0..width {
            let black = preview.get_pixel(x as u32, y as u32).0 == [0, 0, 0];
            assert_eq!(black, exr.z.get(x, y).is_nan(), "preview ({x}, {y})");
        }
    }
}

#[test]
fn every_output_agrees_with_the_disparity_map_and_the_formula() {
    let dir = tempfile::tempdir().unwrap();
    let (run, outputs) = run_slanted(dir.path(), &RIG, &["--sensor-width", "6.4"]);
    for (what, path) in [
        ("depth", &outputs.exr),
        ("disparity", &outputs.pfm),
        ("depth-png", &outputs.depth_png),
        ("disparity-png", &outputs.disparity_png),
        ("points", &outputs.points),
        ("preview", &outputs.preview),
        ("stats", &outputs.stats),
    ] {
        assert_eq!(run.printed_path(what).as_deref(), Some(path.as_path()), "{what}: {}", run.stdout);
    }
    // The slanted rig: 80 mm, 12 mm / 4 µm = 3000 px, principal point at the image centre.
    check_outputs(&outputs, 80.0, 3000.0, 0.0, 143.5, 107.5);

    let stats = stats(&outputs.stats);
    let median = stats["depth_m"]["median"].as_f64().unwrap();
    let p95 = stats["depth_m"]["p95"].as_f64().unwrap();
    // ΔZ = Z² · 1 px / (B · f_px), in mm.
    let resolution = |z: f64| z * z * 1000.0 / (80.0 * 3000.0) * 1000.0;
    let r = &stats["depth_resolution_mm"];
    assert_eq!(r["step_px"], 1.0);
    assert!((r["at_median"].as_f64().unwrap() - resolution(median)).abs() < 1e-9, "{r}");
    assert!((r["at_p95"].as_f64().unwrap() - resolution(p95)).abs() < 1e-9, "{r}");
    let fov = stats["rig"]["horizontal_fov_deg"].as_f64().unwrap();
    assert!((fov - 2.0 * (3.2f64 / 12.0).atan().to_degrees()).abs() < 1e-9, "{fov}");
    assert_eq!(stats["points_written"].as_u64().unwrap() as usize, read_ply(&outputs.points).1.len());
    // Depths beyond 65.535 m are 0 in the PNG, counted in the stats and warned about.
    let too_deep = read_exr(&outputs.exr)
        .z
        .as_slice()
        .iter()
        .filter(|&&z| (z as f64 * 1000.0).round() > 65535.0)
        .count();
    assert_eq!(stats["depth_png_too_deep"], too_deep);
    if too_deep > 0 {
        assert!(run.stderr.contains(&format!("{too_deep} pixels deeper than 65.535 m")), "{}", run.stderr);
    }
    assert!(run.stdout.contains("resolution") && run.stdout.contains("field of view"), "{}", run.stdout);
}

#[test]
fn points_step_subsamples() {
    let dir = tempfile::tempdir().unwrap();
    let (_, outputs) = run_slanted(dir.path(), &RIG, &["--points-step", "3"]);
    let disparity = stereo_io::read_pfm(&outputs.pfm).unwrap();
    let (width, height) = disparity.size();
    let expected = (0..height)
        .step_by(3)
        .flat_map(|y| (0..width).step_by(3).map(move |x| (x, y)))
        .filter(|&(x, y)| disparity.get(x, y).is_finite() && disparity.get(x, y) > 0.0)
        .count();
    assert_eq!(read_ply(&outputs.points).1.len(), expected);
}

fn write_calib(dir: &Path, doffs: f64, width: usize) -> PathBuf {
    let path = dir.join("calib.txt");
    let text = format!(
        "cam0=[3000 0 143.5; 0 3000 107.5; 0 0 1]\ncam1=[3000 0 {}; 0 3000 107.5; 0 0 1]\n\
         doffs={doffs}\nbaseline=80\nwidth={width}\nheight=216\nndisp=64\nisint=0\nvmin=8\nvmax=48\n",
        143.5 + doffs
    );
    fs::write(&path, text).unwrap();
    path
}

#[test]
fn middlebury_calib_gives_the_rig_with_and_without_doffs() {
    for doffs in [0.0, 7.5] {
        let dir = tempfile::tempdir().unwrap();
        let calib = write_calib(dir.path(), doffs, 288);
        // No --max-disparity: ndisp=64 is the search range.
        let (left, right) = (slanted("left.png"), slanted("right.png"));
        let outputs = Outputs::in_dir(dir.path());
        let mut args = vec![s(&left), s(&right), "--calib", s(&calib)];
        args.extend(outputs.args());
        run_in(dir.path(), &args).assert_success();
        // Z = baseline · f / (d + doffs), per pixel.
        check_outputs(&outputs, 80.0, 3000.0, doffs, 143.5, 107.5);
        let stats = stats(&outputs.stats);
        assert_eq!(stats["matcher"]["max_disparity"], 64);
        assert_eq!(stats["rig"]["doffs"], doffs);
        assert_eq!(stats["rig"]["focal_px"], 3000.0);
        assert_eq!(stats["rig"]["focal_mm"], Value::Null);
    }
}

#[test]
fn calib_size_mismatch_and_rig_conflicts_are_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (left, right) = (slanted("left.png"), slanted("right.png"));
    let (l, r) = (s(&left), s(&right));
    let calib = write_calib(dir.path(), 0.0, 300);
    let message = run_in(dir.path(), &[l, r, "--calib", s(&calib)]).assert_error(1).to_string();
    assert!(message.contains("288x216") && message.contains("300x216"), "{message}");

    let cases: [(&[&str], &[&str]); 7] = [
        (
            &["--baseline", "80", "--focal", "12", "--pixel", "4", "--focal-px", "3000"],
            &["--focal", "--focal-px"],
        ),
        (&["--calib", "calib.txt", "--focal-px", "3000"], &["--calib", "--focal-px"]),
        (&["--baseline", "80"], &["missing the focal length"]),
        (&["--focal", "12", "--pixel", "4"], &["missing --baseline"]),
        (&["--baseline", "80", "--focal", "12"], &["--pixel"]),
        (&["--disparity", "d.pfm", "--points", "p.ply"], &["--points needs a rig", "--baseline"]),
        (&["--stats", "s.json"], &["nothing to write", "--disparity"]),
    ];
    for (extra, words) in cases {
        let mut args = vec![l, r];
        args.extend(extra);
        let message = run_in(dir.path(), &args).assert_error(2).to_string();
        for word in words {
            assert!(message.contains(word), "{extra:?}: {message}");
        }
    }
    assert_eq!(list(dir.path()), ["calib.txt"]);
}

#[test]
fn disparity_only_mode_writes_disparity_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let (left, right) = (slanted("left.png"), slanted("right.png"));
    let d = dir.path();
    let run = run_in(
        d,
        &[
            s(&left),
            s(&right),
            "--max-disparity",
            "64",
            "--disparity",
            "d.pfm",
            "--disparity-png",
            "k.png",
            "--preview",
            "v.png",
            "--preview-of",
            "disparity",
            "--stats",
            "s.json",
        ],
    );
    run.assert_success();
    assert!(run.stdout.contains("disparity only"), "{}", run.stdout);
    assert_eq!(list(d), ["d.pfm", "k.png", "s.json", "v.png"]);
    let stats = stats(&d.join("s.json"));
    assert_eq!(stats["depth_m"], Value::Null);
    assert_eq!(stats["rig"], Value::Null);
    assert_eq!(stats["outputs"]["depth"], Value::Null);
    assert!(stats["disparity_px"]["median"].as_f64().unwrap() > 10.0);
    let disparity = stereo_io::read_pfm(&d.join("d.pfm")).unwrap();
    let preview = image::open(d.join("v.png")).unwrap().to_rgb8();
    let (w, h) = disparity.size();
    for y in 0..h {
        for x in 0..w {
            let black = preview.get_pixel(x as u32, y as u32).0 == [0, 0, 0];
            assert_eq!(black, !disparity.get(x, y).is_finite(), "({x}, {y})");
        }
    }
}

#[test]
fn info_describes_every_output() {
    let dir = tempfile::tempdir().unwrap();
    let (_, outputs) = run_slanted(dir.path(), &RIG, &[]);
    let valid = read_ply(&outputs.points).1.len();
    let cases: [(&Path, &[&str]); 7] = [
        (&outputs.exr, &["OpenEXR", "288x216", "Z (depth)", &format!("valid {valid} of 62208 px")]),
        (&outputs.pfm, &["PFM", "288x216"]),
        (&outputs.depth_png, &["PNG", "16-bit grey", "--depth-png (mm)"]),
        (&outputs.disparity_png, &["PNG", "16-bit grey", "KITTI"]),
        (
            &outputs.points,
            &["PLY (binary_little_endian)", &format!("{valid} vertices"), "float x", "uchar red", "bounds"],
        ),
        (&outputs.preview, &["PNG", "8-bit RGB", "colour"]),
        (&outputs.stats, &["statistics", "depth m", "rig: baseline 80"]),
    ];
    for (path, words) in cases {
        let run = run_in(dir.path(), &["info", s(path)]);
        run.assert_success();
        for word in words {
            assert!(run.stdout.contains(word), "{}: no {word:?} in\n{}", path.display(), run.stdout);
        }
    }
    fs::write(dir.path().join("notes.txt"), "hello").unwrap();
    let message = run_in(dir.path(), &["info", "notes.txt"]).assert_error(1).to_string();
    assert!(message.contains("notes.txt") && message.contains("not a file stereo-depth writes"), "{message}");
    let bytes = fs::read(&outputs.points).unwrap();
    fs::write(dir.path().join("cut.ply"), &bytes[..bytes.len() - 7]).unwrap();
    let message = run_in(dir.path(), &["info", "cut.ply"]).assert_error(1).to_string();
    assert!(message.contains("truncated"), "{message}");
    run_in(dir.path(), &["info", "missing.exr"]).assert_error(1);
}

#[test]
fn batch_writes_the_extra_outputs_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    fs::create_dir(&input).unwrap();
    fs::copy(slanted("left.png"), input.join("scene_left.png")).unwrap();
    fs::copy(slanted("right.png"), input.join("scene_right.png")).unwrap();
    let out = dir.path().join("out");
    let mut args = vec!["batch", s(&input), "--out", s(&out), "--max-disparity", "64", "-q"];
    args.extend(RIG);
    args.extend(["--points", "--points-step", "2", "--preview", "--depth-png", "--disparity-png"]);
    run_in(dir.path(), &args).assert_success();
    let outputs = [
        "scene.depth.exr",
        "scene.depth.png",
        "scene.disparity.png",
        "scene.points.ply",
        "scene.preview.png",
        "summary.csv",
        "summary.json",
    ];
    assert_eq!(list(&out), outputs);
    let summary = stats(&out.join("summary.json"));
    assert_eq!(summary["ok"], 1);
    // Complete: skipped. A missing output makes the pair incomplete: redone.
    run_in(dir.path(), &args).assert_success();
    assert_eq!(stats(&out.join("summary.json"))["skipped"], 1);
    fs::remove_file(out.join("scene.preview.png")).unwrap();
    run_in(dir.path(), &args).assert_success();
    assert_eq!(stats(&out.join("summary.json"))["ok"], 1);
    assert_eq!(list(&out), outputs);
}
