//! Calibrated rectification against matching, at 1920×1080 (2.1 MP): the undistort-rectify maps
//! of a distorting rig (computed once per calibration and size), remapping both views (every
//! pair), and matching the pair with the default preset (SGM balanced, the default range for the
//! width). docs/calibration.md has the numbers. `cargo bench --bench rectify`.

use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::{Matrix3, Vector3};
use stereo_disparity::{DisparityRange, GrayImage, Preset, SgmParams};
use stereo_rectify::{rodrigues, CalibFormat, Camera, Rectifier, StereoCalibration};

const SIZE: (usize, usize) = (1920, 1080);

fn calibration() -> StereoCalibration {
    let k = |f: f64, cx: f64, cy: f64| Matrix3::new(f, 0.0, cx, 0.0, f, cy, 0.0, 0.0, 1.0);
    StereoCalibration {
        left: Camera::new(k(1700.0, 955.0, 545.0), vec![-0.12, 0.02, 0.0005, -0.0003, 0.0]),
        right: Camera::new(k(1705.0, 968.0, 536.0), vec![-0.11, 0.018, -0.0004, 0.0002, 0.0]),
        extrinsics: Some((rodrigues(&Vector3::new(0.01, -0.012, 0.005)), Vector3::new(-0.12, 0.001, 0.0))),
        given: None,
        image_size: Some(SIZE),
        mm_per_unit: 1000.0,
        unit_note: String::new(),
        format: CalibFormat::OpenCvYaml,
        paths: vec![],
    }
}

/// A textured pair (a hash texture, the right view shifted by a disparity varying down the image).
fn pair() -> (GrayImage, GrayImage) {
    let (w, h) = SIZE;
    let texture = |x: i64, y: i64| {
        let v = (x.wrapping_mul(0x9E37_79B9) ^ y.wrapping_mul(0x85EB_CA6B)).wrapping_mul(0xC2B2_AE35);
        ((v >> 16) & 0xffff) as u16
    };
    let left = GrayImage::from_fn(w, h, |x, y| texture(x as i64, y as i64));
    let right = GrayImage::from_fn(w, h, |x, y| texture(x as i64 + 40 + (60 * y / h) as i64, y as i64));
    (left, right)
}

fn benches(c: &mut Criterion) {
    let calibration = calibration();
    let (left, right) = pair();
    let rectifier = Rectifier::new(&calibration, SIZE, 0.0).unwrap();
    let mut group = c.benchmark_group("rectify_1920x1080");
    group.sample_size(10).warm_up_time(Duration::from_millis(300)).measurement_time(Duration::from_secs(3));
    group.bench_function("maps", |b| b.iter(|| Rectifier::new(&calibration, SIZE, 0.0).unwrap()));
    group.bench_function("remap_both_views", |b| {
        b.iter(|| rayon::join(|| rectifier.left.remap(&left), || rectifier.right.remap(&right)))
    });
    let params =
        SgmParams { range: DisparityRange::default_for_width(SIZE.0), ..SgmParams::preset(Preset::Balanced) };
    group.bench_function("match_default_preset", |b| {
        b.iter(|| stereo_disparity::sgm(&left, &right, &params).unwrap())
    });
    group.finish();
}

criterion_group!(rectify, benches);
criterion_main!(rectify);
