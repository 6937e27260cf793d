//! End-to-end tests of `stereo-depth degrade`: the outputs read back with the `image` crate.

mod common;

use std::path::Path;

use common::{run_in, s, write_scene};
use image::DynamicImage;

fn read(path: &Path) -> DynamicImage {
    image::open(path).unwrap_or_else(|e| panic!("cannot read {}: {e}", path.display()))
}

#[test]
fn gain_on_the_right_view_leaves_the_left_untouched() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), 120, 80);
    let run = run_in(
        dir.path(),
        &["degrade", "left.pgm", "right.pgm", "--out", "deg", "--right", "gain=1.5", "--seed", "3"],
    );
    run.assert_success();
    let out = dir.path().join("deg");
    // Printed as given (relative to the working folder).
    assert_eq!(run.printed_path("left"), Some(Path::new("deg").join("left.png")));
    assert_eq!(run.printed_path("right"), Some(Path::new("deg").join("right.png")));

    // 16-bit grey in, 16-bit grey out; the left view byte-for-byte the input.
    let left = match read(&out.join("left.png")) {
        DynamicImage::ImageLuma16(left) => left,
        other => panic!("left is {:?}, want L16", other.color()),
    };
    assert_eq!(left.as_raw().as_slice(), scene.left.as_slice());

    let right = read(&out.join("right.png")).into_luma16();
    let (mut sum_in, mut sum_out, mut clipped) = (0.0, 0.0, 0);
    for (&a, &b) in scene.right.as_slice().iter().zip(right.as_raw()) {
        if a as f64 * 1.5 < 65535.0 {
            assert!((b as f64 - 1.5 * a as f64).abs() <= 1.0, "{a} -> {b}");
            sum_in += a as f64;
            sum_out += b as f64;
        } else {
            assert_eq!(b, 65535, "clipped");
            clipped += 1;
        }
    }
    let ratio = sum_out / sum_in;
    assert!((ratio - 1.5).abs() < 0.001, "mean ratio {ratio} ({clipped} clipped pixels)");
}

#[test]
fn both_views_rgb8_get_independent_noise_and_keep_their_format() {
    let dir = tempfile::tempdir().unwrap();
    // One flat RGB8 image for both views: any difference between the outputs is the noise.
    let flat = image::RgbImage::from_pixel(64, 48, image::Rgb([100, 150, 200]));
    flat.save(dir.path().join("l.png")).unwrap();
    flat.save(dir.path().join("r.png")).unwrap();
    let args = ["degrade", "l.png", "r.png", "--out", "deg", "--both", "noise=6", "--quiet"];
    let run = run_in(dir.path(), &args);
    run.assert_success();
    assert_eq!(run.stdout, "", "--quiet prints nothing");
    let left = read(&dir.path().join("deg/left.png"));
    let right = read(&dir.path().join("deg/right.png"));
    let (DynamicImage::ImageRgb8(left), DynamicImage::ImageRgb8(right)) = (left, right) else {
        panic!("outputs are not RGB8");
    };
    let differing = left.as_raw().iter().zip(right.as_raw()).filter(|(a, b)| a != b).count();
    assert!(differing > left.as_raw().len() * 3 / 4, "views share their noise ({differing} differ)");
    let sd = |img: &image::RgbImage| {
        let d: Vec<f64> =
            img.as_raw().iter().zip(flat.as_raw()).map(|(&a, &b)| a as f64 - b as f64).collect();
        (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt()
    };
    for img in [&left, &right] {
        assert!((sd(img) - 6.0).abs() < 0.6, "noise std {}", sd(img));
    }

    // Same seed, same output; a per-view spec overrides --both.
    let again = run_in(dir.path(), &["degrade", "l.png", "r.png", "--out", "deg2", "--both", "noise=6"]);
    again.assert_success();
    assert_eq!(read(&dir.path().join("deg2/left.png")).into_rgb8(), left);
    let run = run_in(
        dir.path(),
        &["degrade", "l.png", "r.png", "--out", "deg3", "--both", "noise=6", "--left", "noise=0"],
    );
    run.assert_success();
    assert_eq!(read(&dir.path().join("deg3/left.png")).into_rgb8(), flat);
}

#[test]
fn a_bad_spec_is_a_usage_error_naming_the_parameter() {
    let dir = tempfile::tempdir().unwrap();
    write_scene(dir.path(), 40, 30);
    for (spec, word) in
        [("gain=9", "gain"), ("jpeg=0", "jpeg"), ("sharpen=1", "sharpen"), ("gain", "key=value")]
    {
        let run = run_in(dir.path(), &["degrade", "left.pgm", "right.pgm", "--out", "o", "--right", spec]);
        let line = run.assert_error(2);
        assert!(line.contains(word) && line.contains("--right"), "{spec}: {line}");
    }
    assert!(!dir.path().join("o").exists(), "nothing written on a usage error");
}

#[test]
fn a_missing_or_corrupt_input_is_a_runtime_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    write_scene(dir.path(), 40, 30);
    std::fs::write(dir.path().join("junk.png"), b"not a png at all").unwrap();
    for bad in ["missing.png", "junk.png"] {
        let run = run_in(dir.path(), &["degrade", "left.pgm", bad, "--out", "o", "--both", "gain=1.2"]);
        let line = run.assert_error(1);
        assert!(line.contains(bad), "{line}");
        assert!(!dir.path().join("o/left.png").exists(), "no half-written pair");
    }
    let out = dir.path().join("o");
    let run = run_in(dir.path(), &["degrade", "left.pgm", "right.pgm", "--out", s(&out), "--left", "none"]);
    run.assert_success();
}
