//! Raw pairs with a calibration (docs/calibration.md): the `rectify` command, `--calib` with an
//! OpenCV or ROS calibration in the pair and batch commands. The comparison with OpenCV itself is
//! `.ci/opencv-rectify.py`.

mod common;

use std::fs;
use std::path::Path;

use common::*;
use nalgebra::{Matrix3, Vector3};
use stereo_disparity::Image;
use stereo_rectify::{rodrigues, CalibFormat, Camera, Rectifier, StereoCalibration};

/// ROS camera_info of the sample scene's rig: no distortion, already rectified (focal 3000 px,
/// baseline 80 mm, principal point at the centre of the 288x216 views).
fn ros_file(side: &str) -> String {
    let tx = if side == "right" { -3000.0 * 0.08 } else { 0.0 };
    format!(
        "image_width: 288\nimage_height: 216\ncamera_name: {side}\ncamera_matrix:\n  rows: 3\n  cols: 3\n  \
         data: [3000, 0, 143.5, 0, 3000, 107.5, 0, 0, 1]\ndistortion_model: plumb_bob\n\
         distortion_coefficients:\n  rows: 1\n  cols: 5\n  data: [0, 0, 0, 0, 0]\n\
         rectification_matrix:\n  rows: 3\n  cols: 3\n  data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\n\
         projection_matrix:\n  rows: 3\n  cols: 4\n  data: [3000, 0, 143.5, {tx}, 0, 3000, 107.5, 0, 0, 0, 1, 0]\n"
    )
}

#[test]
fn ros_identity_calibration_gives_the_sample_back() {
    let dir = tempfile::tempdir().unwrap();
    let ros = dir.path().join("ros");
    fs::create_dir(&ros).unwrap();
    fs::write(ros.join("left.yaml"), ros_file("left")).unwrap();
    fs::write(ros.join("right.yaml"), ros_file("right")).unwrap();
    let (left, right) = (slanted("left.png"), slanted("right.png"));

    let out = dir.path().join("rectified");
    let run =
        run_in(dir.path(), &["rectify", s(&left), s(&right), "--calib", "ros/left.yaml", "-o", s(&out)]);
    run.assert_success();
    assert!(run.stdout.contains("ROS camera_info, its own R and P"), "{}", run.stdout);
    assert_eq!(stereo_io::load_gray(&out.join("im0.png")).unwrap(), stereo_io::load_gray(&left).unwrap());
    assert_eq!(stereo_io::load_gray(&out.join("im1.png")).unwrap(), stereo_io::load_gray(&right).unwrap());
    let calib = stereo_io::read_calib(&out.join("calib.txt")).unwrap();
    assert_eq!((calib.focal_px, calib.cx, calib.cy), (3000.0, 143.5, 107.5));
    assert!((calib.baseline_mm.unwrap() - 80.0).abs() < 1e-9);
    assert_eq!((calib.doffs, calib.width, calib.height), (Some(0.0), Some(288), Some(216)));

    // The pair command through the ROS files (given as the right file, and as their folder)
    // matches the sample exactly as through the rig flags.
    let flags = dir.path().join("flags.pfm");
    let mut args = vec![s(&left), s(&right), "--disparity", s(&flags), "--max-disparity", "64", "-q"];
    args.extend(RIG);
    run_in(dir.path(), &args).assert_success();
    for calib in ["ros/right.yaml", "ros"] {
        let via = dir.path().join("ros.pfm");
        let depth = dir.path().join("ros.exr");
        let run = run_in(
            dir.path(),
            &[
                s(&left),
                s(&right),
                "--calib",
                calib,
                "--disparity",
                s(&via),
                "-o",
                s(&depth),
                "--max-disparity",
                "64",
            ],
        );
        run.assert_success();
        assert!(run.stderr.is_empty(), "ROS baselines are metres: no note: {}", run.stderr);
        assert!(run.stdout.contains("rectify"), "the time line shows the rectification: {}", run.stdout);
        let (a, b) = (stereo_io::read_pfm(&flags).unwrap(), stereo_io::read_pfm(&via).unwrap());
        assert!(a.as_slice().iter().zip(b.as_slice()).all(|(x, y)| x == y || (x.is_nan() && y.is_nan())));
        // Metric: Z = f·B / d = 3000 px · 0.08 m / d.
        let z = read_exr(&depth);
        let (x, y) = (160, 100);
        let d = b.get(x, y) as f64;
        assert!((z.z.get(x, y) as f64 - 240.0 / d).abs() < 1e-3 * 240.0 / d);
    }
}

/// A distorting rig whose Bouguet rectification is computed from `R` and `T`.
fn distorting_rig() -> StereoCalibration {
    let k = |f: f64, cx: f64, cy: f64| Matrix3::new(f, 0.0, cx, 0.0, f * 1.005, cy, 0.0, 0.0, 1.0);
    StereoCalibration {
        left: Camera::new(k(260.0, 142.0, 109.0), vec![-0.15, 0.03, 0.0008, -0.0004, 0.0]),
        right: Camera::new(k(262.0, 146.0, 106.0), vec![-0.14, 0.025, -0.0005, 0.0003, 0.0]),
        extrinsics: Some((rodrigues(&Vector3::new(0.008, -0.012, 0.006)), Vector3::new(-80.0, 1.0, -0.5))),
        given: None,
        image_size: Some((288, 216)),
        mm_per_unit: 1.0,
        unit_note: String::new(),
        format: CalibFormat::OpenCvYaml,
        paths: vec![],
    }
}

fn opencv_yaml(cal: &StereoCalibration) -> String {
    let m = |name: &str, rows: usize, cols: usize, v: Vec<f64>| {
        let data: Vec<String> = v.iter().map(|x| format!("{x:e}")).collect();
        format!(
            "{name}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ {} ]\n",
            data.join(", ")
        )
    };
    let k = |c: &Camera| c.k.transpose().iter().copied().collect::<Vec<f64>>();
    let (r, t) = cal.extrinsics.unwrap();
    format!(
        "%YAML:1.0\n---\n{}{}{}{}{}{}imageSize: [ 288, 216 ]\n",
        m("K1", 3, 3, k(&cal.left)),
        m("D1", 1, 5, cal.left.dist[..5].to_vec()),
        m("K2", 3, 3, k(&cal.right)),
        m("D2", 1, 5, cal.right.dist[..5].to_vec()),
        m("R", 3, 3, r.transpose().iter().copied().collect()),
        m("T", 3, 1, t.iter().copied().collect()),
    )
}

/// The raw view whose rectification is `rectified` (each raw pixel's rectified position,
/// sampled bilinearly).
fn raw_view(
    rectified: &Image<u16>,
    camera: &Camera,
    r: &Matrix3<f64>,
    p: &nalgebra::Matrix3x4<f64>,
) -> Image<u8> {
    let rr = p.fixed_view::<3, 3>(0, 0) * r;
    let (w, h) = rectified.size();
    Image::from_fn(w, h, |x, y| {
        let (u, v) = camera.undistort_point(x as f64, y as f64, &rr);
        let (x0, y0) = (u.floor(), v.floor());
        let (ax, ay) = (u - x0, v - y0);
        let at = |x: f64, y: f64| {
            if x >= 0.0 && y >= 0.0 && (x as usize) < w && (y as usize) < h {
                rectified.get(x as usize, y as usize) as f64 / 257.0
            } else {
                0.0
            }
        };
        let value = at(x0, y0) * (1.0 - ax) * (1.0 - ay)
            + at(x0 + 1.0, y0) * ax * (1.0 - ay)
            + at(x0, y0 + 1.0) * (1.0 - ax) * ay
            + at(x0 + 1.0, y0 + 1.0) * ax * ay;
        value.round().clamp(0.0, 255.0) as u8
    })
}

fn bad2(disparity: &Path) -> f64 {
    let est = stereo_io::read_pfm(disparity).unwrap();
    let gt = stereo_io::read_disparity(&slanted("disp0GT.pfm"), 1.0).unwrap();
    stereo_eval::metrics(&est, &gt).unwrap().bad2
}

/// Raw views made from the sample through a distorting rig come back through `--calib`: the
/// rectified pair matches about as well as the sample itself, in the pair and batch commands,
/// and the batch computes the maps once.
#[test]
fn distorted_pair_round_trip_pair_and_batch() {
    let dir = tempfile::tempdir().unwrap();
    let cal = distorting_rig();
    let rectifier = Rectifier::new(&cal, (288, 216), 0.0).unwrap();
    fs::write(dir.path().join("stereo.yaml"), opencv_yaml(&cal)).unwrap();
    let raw = dir.path().join("raw");
    // The sample placed in the rectified frame OpenCV (and stereo-depth) compute for this rig.
    let views = [
        (stereo_io::load_gray(&slanted("left.png")).unwrap(), &cal.left, &rectifier.r1, &rectifier.p1),
        (stereo_io::load_gray(&slanted("right.png")).unwrap(), &cal.right, &rectifier.r2, &rectifier.p2),
    ];
    for scene in ["a", "b"] {
        fs::create_dir_all(raw.join(scene)).unwrap();
        for (name, (view, camera, r, p)) in ["im0.png", "im1.png"].iter().zip(&views) {
            stereo_io::write_png8(&raw.join(scene).join(name), &raw_view(view, camera, r, p)).unwrap();
        }
    }

    let sample = dir.path().join("sample.pfm");
    let (left, right) = (slanted("left.png"), slanted("right.png"));
    run_in(dir.path(), &[s(&left), s(&right), "--disparity", s(&sample), "--max-disparity", "64", "-q"])
        .assert_success();
    let reference = bad2(&sample);

    let rectified = dir.path().join("rt.pfm");
    let run = run_in(
        dir.path(),
        &[
            "raw/a/im0.png",
            "raw/a/im1.png",
            "--calib",
            "stereo.yaml",
            "--disparity",
            s(&rectified),
            "--max-disparity",
            "64",
        ],
    );
    run.assert_success();
    assert!(run.stdout.contains("rectification aligned"), "{}", run.stdout);
    let got = bad2(&rectified);
    assert!(got - reference < 2.0, "round trip bad2 {got:.2} vs {reference:.2}");

    let run = run_in(
        dir.path(),
        &["batch", "raw", "--calib", "stereo.yaml", "--out", "depth", "--disparity", "--max-disparity", "64"],
    );
    run.assert_success();
    assert!(run.stdout.contains("rectification (stereo.yaml): maps computed once"), "{}", run.stdout);
    for scene in ["a", "b"] {
        let got = bad2(&dir.path().join(format!("depth/{scene}/im0.disparity.pfm")));
        assert!(got - reference < 2.0, "batch {scene}: bad2 {got:.2} vs {reference:.2}");
    }
    // The rig is the rectified one, with millimetres taken as they are (|T| ≥ 5).
    assert!(
        run.stderr.contains("stereo.yaml: T (length 80.008) has no unit in the file: taken as millimetres"),
        "{}",
        run.stderr
    );
}

#[test]
fn calibration_errors_are_one_line() {
    let dir = tempfile::tempdir().unwrap();
    let (left, right) = (slanted("left.png"), slanted("right.png"));
    let yaml = opencv_yaml(&distorting_rig());
    fs::write(dir.path().join("no_t.yaml"), yaml.replace("T: ", "X: ")).unwrap();
    fs::write(dir.path().join("small.yaml"), yaml.replace("[ 288, 216 ]", "[ 640, 480 ]")).unwrap();
    fs::write(dir.path().join("calib.txt"), "cam0=[3000 0 144; 0 3000 108; 0 0 1]\nbaseline=80\n").unwrap();
    fs::write(dir.path().join("left.yaml"), ros_file("left")).unwrap();
    let cases: [(&[&str], i32, &str); 6] = [
        (&["--calib", "no_t.yaml"], 1, "no_t.yaml: R without T"),
        (&["--calib", "small.yaml"], 1, "small.yaml: calibrated for 640x480 images, not 288x216"),
        (&["--calib", "left.yaml"], 1, "left.yaml: a ROS camera_info describes one camera"),
        (&["--calib", "missing.yaml"], 1, "missing.yaml"),
        (&["--calib", "no_t.yaml", "--alpha", "2"], 2, "invalid --alpha 2"),
        (
            &["rectify", "--calib", "calib.txt", "-o", "out"],
            1,
            "calib.txt: a Middlebury calib.txt describes an already rectified pair",
        ),
    ];
    for (extra, code, want) in cases {
        let mut args: Vec<&str> = Vec::new();
        if extra[0] == "rectify" {
            args.push("rectify");
        }
        args.extend([s(&left), s(&right)]);
        args.extend(extra.iter().filter(|a| **a != "rectify"));
        let run = run_in(dir.path(), &args);
        let line = run.assert_error(code);
        assert!(line.contains(want), "{args:?}: {line}");
    }
}
