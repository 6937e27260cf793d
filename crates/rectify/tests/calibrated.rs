//! Calibration files and calibrated rectification (the comparison with OpenCV itself is
//! `.ci/opencv-rectify.py`).

use std::path::Path;
use std::sync::Arc;

use nalgebra::{Matrix3, Vector3};
use stereo_image::Image;
use stereo_rectify::{
    read_calibration, rodrigues, CalibFormat, CalibrationFile, Camera, Rectifier, RectifierCache,
    StereoCalibration,
};

/// As `cv2.FileStorage` (OpenCV 5) writes a `stereoCalibrate` result.
const OPENCV_YAML: &str = "%YAML 1.2
---
K1: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 520.29999999999995, 0., 318.69999999999999, 0.,
       521.89999999999998, 242.09999999999999, 0., 0., 1. ]
D1: !!opencv-nd-matrix
   sizes: [ 5 ]
   dt: d
   data: [ -0.28000000000000003, 0.089999999999999997,
       0.0011000000000000001, -0.00069999999999999999, -0.012 ]
K2: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 518.10000000000002, 0., 325.19999999999999, 0.,
       519.39999999999998, 236.80000000000001, 0., 0., 1. ]
D2: !!opencv-nd-matrix
   sizes: [ 5 ]
   dt: d
   data: [ -0.27000000000000002, 0.085000000000000006,
       -0.00089999999999999998, 0.00040000000000000002, -0.01 ]
R: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 0.99975501294389313, -0.0071252536999211139,
       -0.020955783289294341, 0.0068732670136397115, 0.99990350509830894,
       -0.012072228157027071, 0.021039778851388139, 0.011925235923362918,
       0.9997075154534234 ]
T: !!opencv-matrix
   rows: 3
   cols: 1
   dt: d
   data: [ -0.1201, 0.0020999999999999999, -0.0012999999999999999 ]
imageSize: !!opencv-matrix
   rows: 2
   cols: 1
   dt: d
   data: [ 640., 480. ]
";

/// `cv2.stereoRectify(..., flags=CALIB_ZERO_DISPARITY, alpha=0)` of [`OPENCV_YAML`] (OpenCV 5.0).
const OPENCV_P1: [f64; 4] = [504.2798274841975, 0.0, 322.6768379211426, 239.66918182373047];

fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

fn stereo(file: CalibrationFile) -> StereoCalibration {
    match file {
        CalibrationFile::Stereo(c) => *c,
        other => panic!("{other:?}"),
    }
}

#[test]
fn opencv_yaml_matches_opencv() {
    let dir = tempfile::tempdir().unwrap();
    let cal = stereo(read_calibration(&write(dir.path(), "stereo.yaml", OPENCV_YAML)).unwrap());
    assert_eq!(cal.format, CalibFormat::OpenCvYaml);
    assert_eq!(cal.image_size, Some((640, 480)));
    assert_eq!(cal.mm_per_unit, 1000.0);
    let r = Rectifier::new(&cal, (640, 480), 0.0).unwrap();
    let p1 = [r.p1[(0, 0)], r.p1[(0, 1)], r.p1[(0, 2)], r.p1[(1, 2)]];
    for (a, b) in p1.iter().zip(OPENCV_P1) {
        assert!((a - b).abs() < 1e-6, "P1 {p1:?} vs OpenCV {OPENCV_P1:?}");
    }
    assert!((r.rig.baseline_mm - 120.125393).abs() < 1e-5, "{:?}", r.rig);
    assert_eq!(r.rig.doffs, 0.0);
    // Other sizes than the calibration's are refused.
    assert!(Rectifier::new(&cal, (320, 240), 0.0).unwrap_err().contains("calibrated for 640x480"));
}

/// A `cv::fisheye` calibration written by `cv2.FileStorage`, marked `distortion_model: fisheye`.
const FISHEYE_YAML: &str = "%YAML 1.2
---
K1: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 288., 0., 323., 0., 288., 238., 0., 0., 1. ]
D1: !!opencv-matrix
   rows: 4
   cols: 1
   dt: d
   data: [ 0.050000000000000003, -0.01, 0.0030000000000000001,
       -0.00050000000000000001 ]
K2: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 290.88, 0., 316., 0., 291.46175999999997, 243., 0., 0., 1. ]
D2: !!opencv-matrix
   rows: 4
   cols: 1
   dt: d
   data: [ 0.044999999999999998, -0.0080000000000000002, 0.002,
       -0.00040000000000000002 ]
R: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 0.99978750929671234, -0.0050995581365608014,
       -0.019973251139667782, 0.0048995668864076601, 0.99993750273432713,
       -0.010049122835506748, 0.020023248952206064,
       0.0099491272104301753, 0.99975001093730853 ]
T: !!opencv-matrix
   rows: 3
   cols: 1
   dt: d
   data: [ -0.10000000000000001, 0.002, -0.001 ]
distortion_model: fisheye
";

#[test]
fn fisheye_opencv_file_matches_cv_fisheye() {
    let dir = tempfile::tempdir().unwrap();
    let cal = stereo(read_calibration(&write(dir.path(), "fisheye.yaml", FISHEYE_YAML)).unwrap());
    assert_eq!(cal.left.model, stereo_rectify::LensModel::Equidistant);
    let r = Rectifier::new(&cal, (640, 480), 0.0).unwrap();
    // cv2.fisheye.stereoRectify(..., flags=CALIB_ZERO_DISPARITY, balance=0) (OpenCV 5.0).
    let want = [228.83923105274653, 318.9552129937164, 240.70057753040766, -22.889643371107102];
    let got = [r.p1[(0, 0)], r.p1[(0, 2)], r.p1[(1, 2)], r.p2[(0, 3)]];
    for (a, b) in got.iter().zip(want) {
        assert!((a - b).abs() < 1e-6, "{got:?} vs {want:?}");
    }
    let five =
        FISHEYE_YAML.replace("-0.00050000000000000001 ]", "-0.0005, 0.1 ]").replace("rows: 4", "rows: 5");
    let message = read_calibration(&write(dir.path(), "five.yaml", &five)).unwrap_err().to_string();
    assert!(message.contains("D1: 5 coefficients, want 4 (k1 k2 k3 k4) for fisheye"), "{message}");
}

#[test]
fn same_keys_in_xml_json_and_plain_yaml() {
    let dir = tempfile::tempdir().unwrap();
    let yaml = stereo(read_calibration(&write(dir.path(), "a.yaml", OPENCV_YAML)).unwrap());
    let xml = "<?xml version=\"1.0\"?>\n<opencv_storage>\n<K1 type_id=\"opencv-matrix\">\n  <rows>3</rows>\n  <cols>3</cols>\n  <dt>d</dt>\n  <data>\n    520.29999999999995 0. 318.69999999999999 0. 521.89999999999998\n    242.09999999999999 0. 0. 1.</data></K1>\n<D1 type_id=\"opencv-nd-matrix\">\n  <sizes>\n    5</sizes>\n  <dt>d</dt>\n  <data>\n    -0.28000000000000003 0.089999999999999997 0.0011000000000000001\n    -0.00069999999999999999 -0.012</data></D1>\n<K2 type_id=\"opencv-matrix\">\n  <rows>3</rows>\n  <cols>3</cols>\n  <dt>d</dt>\n  <data>\n    518.10000000000002 0. 325.19999999999999 0. 519.39999999999998\n    236.80000000000001 0. 0. 1.</data></K2>\n<D2 type_id=\"opencv-nd-matrix\">\n  <sizes>\n    5</sizes>\n  <dt>d</dt>\n  <data>\n    -0.27000000000000002 0.085000000000000006 -0.00089999999999999998\n    0.00040000000000000002 -0.01</data></D2>\n<R type_id=\"opencv-matrix\">\n  <rows>3</rows>\n  <cols>3</cols>\n  <dt>d</dt>\n  <data>\n    0.99975501294389313 -0.0071252536999211139 -0.020955783289294341\n    0.0068732670136397115 0.99990350509830894 -0.012072228157027071\n    0.021039778851388139 0.011925235923362918 0.9997075154534234</data></R>\n<T type_id=\"opencv-matrix\">\n  <rows>3</rows>\n  <cols>1</cols>\n  <dt>d</dt>\n  <data>\n    -0.1201 0.0021 -0.0013</data></T>\n<imageSize>\n  640 480</imageSize>\n</opencv_storage>\n";
    let from_xml = stereo(read_calibration(&write(dir.path(), "a.xml", xml)).unwrap());
    assert_eq!(from_xml.format, CalibFormat::OpenCvXml);
    assert_eq!((from_xml.left.clone(), from_xml.extrinsics), (yaml.left.clone(), yaml.extrinsics));
    let json = r#"{"image_width": 640, "image_height": 480,
        "K1": [[520.3, 0, 318.7], [0, 521.9, 242.1], [0, 0, 1]], "D1": [-0.28, 0.09, 0.0011, -0.0007, -0.012],
        "K2": [[518.1, 0, 325.2], [0, 519.4, 236.8], [0, 0, 1]], "D2": [-0.27, 0.085, -0.0009, 0.0004, -0.01],
        "R": [0.012, -0.021, 0.007], "T": [-0.1201, 0.0021, -0.0013]}"#;
    let from_json = stereo(read_calibration(&write(dir.path(), "a.json", json)).unwrap());
    assert_eq!(from_json.format, CalibFormat::Json);
    let (r_json, r_yaml) = (from_json.extrinsics.unwrap().0, yaml.extrinsics.unwrap().0);
    assert!((r_json - r_yaml).abs().max() < 1e-9, "a rotation vector is accepted for R");
    let plain = "K1: [[520.3, 0, 318.7], [0, 521.9, 242.1], [0, 0, 1]]\nD1: [-0.28, 0.09, 0.0011, -0.0007, -0.012]\nK2:\n  - [518.1, 0, 325.2]\n  - [0, 519.4, 236.8]\n  - [0, 0, 1]\nD2: []\nR: [1, 0, 0, 0, 1, 0, 0, 0, 1]\nT: [-120, 0, 0]  # mm\n";
    let from_plain = stereo(read_calibration(&write(dir.path(), "plain.yaml", plain)).unwrap());
    assert_eq!(from_plain.mm_per_unit, 1.0);
    assert!(!from_plain.right.has_dist);
    assert_eq!(from_plain.image_size, None);
}

#[test]
fn errors_name_the_file_and_the_key() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("no_k2.yaml", OPENCV_YAML.replace("K2:", "K9:"), "no K2"),
        ("bad_d.yaml", OPENCV_YAML.replace("sizes: [ 5 ]\n   dt: d\n   data: [ -0.28000000000000003, 0.089999999999999997,\n       0.0011000000000000001, -0.00069999999999999999, -0.012 ]", "data: [ 1, 2, 3 ]"), "D1: 3 coefficients"),
        ("bad_r.yaml", OPENCV_YAML.replace("0.99975501294389313,", "1.5,"), "R: not a rotation"),
        ("no_t.yaml", OPENCV_YAML.replace("T:", "X:"), "R without T"),
        ("word.yaml", OPENCV_YAML.replace("-0.1201", "abc"), "T: \"abc\" is not a number"),
        ("random.txt", "hello world\n".to_string(), "neither Middlebury key=value lines"),
    ];
    for (name, text, want) in cases {
        let path = write(dir.path(), name, &text);
        let message = read_calibration(&path).unwrap_err().to_string();
        assert!(message.starts_with(&path.display().to_string()), "{message}");
        assert!(message.contains(want), "{name}: {message}");
        assert!(!message.contains('\n'), "one line: {message}");
    }
    // A Middlebury calib.txt is read as before, and its errors stay its own.
    let mb = write(dir.path(), "calib.txt", "cam0=[100 0 10; 0 100 20; 0 0 1]\nbaseline=50\n");
    assert!(matches!(read_calibration(&mb).unwrap(), CalibrationFile::Middlebury(c) if c.focal_px == 100.0));
    let bad = write(dir.path(), "calib2.txt", "cam0=[100 0 10; 0 100 20]\n");
    assert!(read_calibration(&bad).unwrap_err().to_string().contains("invalid Middlebury calib.txt"));
}

fn ros_file(side: &str, tx: f64) -> String {
    format!(
        "image_width: 640\nimage_height: 480\ncamera_name: narrow_stereo/{side}\ncamera_matrix:\n  rows: 3\n  cols: 3\n  \
         data: [520.3, 0, 318.7, 0, 521.9, 242.1, 0, 0, 1]\ndistortion_model: plumb_bob\ndistortion_coefficients:\n  \
         rows: 1\n  cols: 5\n  data: [-0.28, 0.09, 0.0011, -0.0007, -0.012]\nrectification_matrix:\n  rows: 3\n  cols: 3\n  \
         data: [1, 0, 0, 0, 1, 0, 0, 0, 1]\nprojection_matrix:\n  rows: 3\n  cols: 4\n  \
         data: [480, 0, 320, {tx}, 0, 480, 240, 0, 0, 0, 1, 0]\n"
    )
}

#[test]
fn ros_camera_info_pair() {
    let dir = tempfile::tempdir().unwrap();
    let left = write(dir.path(), "left.yaml", &ros_file("left", 0.0));
    let alone = read_calibration(&left).unwrap_err().to_string();
    assert!(alone.contains("other camera's file was not found"), "{alone}");
    write(dir.path(), "right.yaml", &ros_file("right", -57.6));
    for path in [left.clone(), dir.path().join("right.yaml"), dir.path().to_path_buf()] {
        let cal = stereo(read_calibration(&path).unwrap());
        assert_eq!(cal.format, CalibFormat::RosCameraInfo);
        let r = Rectifier::new(&cal, (640, 480), 0.0).unwrap();
        assert!((r.rig.baseline_mm - 120.0).abs() < 1e-9, "{:?}", r.rig);
        assert_eq!((r.rig.focal_px, r.rig.cx, r.rig.cy), (480.0, 320.0, 240.0));
        assert_eq!(cal.paths[0], left);
    }
    // Inconsistent pairs.
    write(dir.path(), "right.yaml", &ros_file("right", 0.0));
    assert!(read_calibration(&left).unwrap_err().to_string().contains("P[0][3] is 0 in both files"));
    write(
        dir.path(),
        "right.yaml",
        &ros_file("right", -57.6).replace("image_width: 640", "image_width: 320"),
    );
    assert!(read_calibration(&left).unwrap_err().to_string().contains("differ from"));
    write(dir.path(), "right.yaml", &ros_file("right", -57.6).replace("plumb_bob", "equidistant"));
    let message = read_calibration(&left).unwrap_err().to_string();
    assert!(message.contains("want 4 (k1 k2 k3 k4) for equidistant"), "{message}");
    write(dir.path(), "right.yaml", &ros_file("right", -57.6).replace("plumb_bob", "kannala"));
    let message = read_calibration(&left).unwrap_err().to_string();
    assert!(message.contains("distortion_model: kannala is not supported"), "{message}");
}

/// A smooth texture with detail at several scales.
fn texture(x: f64, y: f64) -> f64 {
    let v = (0.31 * x + 0.17 * y).sin()
        + (0.23 * x - 0.29 * y).sin()
        + (0.11 * x + 0.41 * y).cos()
        + (0.05 * x - 0.03 * y).sin()
        + (0.13 * x + 0.07 * y).cos();
    32768.0 + 6000.0 * v
}

/// Raw views made by inverse mapping (each raw pixel's rectified position, sampled from the
/// texture) come back as the texture after rectification.
#[test]
fn rectification_undoes_distortion_and_rotation() {
    let (w, h) = (320, 240);
    let k = |f: f64, cx: f64, cy: f64| Matrix3::new(f, 0.0, cx, 0.0, f * 1.01, cy, 0.0, 0.0, 1.0);
    let cal = StereoCalibration {
        left: Camera::new(k(300.0, 158.0, 121.0), vec![-0.25, 0.07, 0.001, -0.0005, -0.01]),
        right: Camera::new(k(302.0, 163.0, 118.0), vec![-0.24, 0.06, -0.0008, 0.0004, -0.008]),
        extrinsics: Some((rodrigues(&Vector3::new(0.01, -0.015, 0.008)), Vector3::new(-0.1, 0.002, -0.001))),
        given: None,
        image_size: Some((w, h)),
        mm_per_unit: 1000.0,
        unit_note: String::new(),
        format: CalibFormat::OpenCvYaml,
        paths: vec![],
    };
    let cache = RectifierCache::new(Arc::new(cal.clone()), 0.0);
    let r = cache.get((w, h)).unwrap();
    assert!(Arc::ptr_eq(&r, &cache.get((w, h)).unwrap()));
    assert_eq!(cache.computed(), 1);

    for (camera, rk, pk, shift) in [(&cal.left, &r.r1, &r.p1, 0.0), (&cal.right, &r.r2, &r.p2, 9.0)] {
        let rr = pk.fixed_view::<3, 3>(0, 0) * rk;
        let raw = Image::from_fn(w, h, |x, y| {
            let (u, v) = camera.undistort_point(x as f64, y as f64, &rr);
            texture(u + shift, v).round() as u16
        });
        let map = if shift == 0.0 { &r.left } else { &r.right };
        let rectified = map.remap(&raw);
        let (mut sum, mut n) = (0.0, 0);
        for y in 10..h - 10 {
            for x in 10..w - 10 {
                sum += (rectified.get(x, y) as f64 - texture(x as f64 + shift, y as f64)).abs();
                n += 1;
            }
        }
        let mean = sum / n as f64;
        // Grey levels of 16 bits over a texture spanning ~±30000: well under 1 %.
        assert!(mean < 150.0, "mean error {mean}");
    }
}
