//! Known-truth tests of every stage.

use super::*;

/// A random image (uniform samples) of the given depth and channel count.
fn random(width: usize, height: usize, channels: usize, depth: BitDepth, seed: u64) -> Raster {
    let mut rng = ops::SplitMix64::new(seed);
    let max = depth.max_value() as u64 + 1;
    let data = (0..width * height * channels).map(|_| (rng.next_u64() % max) as u16).collect();
    Raster::new(width, height, channels, depth, data).unwrap()
}

/// A flat image at `value`.
fn flat(width: usize, height: usize, channels: usize, depth: BitDepth, value: u16) -> Raster {
    Raster::new(width, height, channels, depth, vec![value; width * height * channels]).unwrap()
}

fn spec(s: &str) -> Degradation {
    s.parse().unwrap()
}

fn mean(r: &Raster) -> f64 {
    r.samples().iter().map(|&v| v as f64).sum::<f64>() / r.samples().len() as f64
}

#[test]
fn neutral_values_are_byte_identical() {
    let neutral = [
        "gain=1",
        "gamma=1",
        "bias=0",
        "vignette=0",
        "noise=0",
        "blur=0",
        "vshift=0",
        "rotate=0",
        "gain=1,gamma=1,bias=0,vignette=0,noise=0,blur=0,vshift=0,rotate=0",
    ];
    for depth in [BitDepth::Eight, BitDepth::Sixteen] {
        for channels in [1, 3] {
            let image = random(37, 23, channels, depth, 1);
            assert_eq!(degrade(&image, &Degradation::default(), 5).unwrap(), image);
            for s in neutral {
                assert_eq!(degrade(&image, &spec(s), 5).unwrap(), image, "{s} {depth:?} {channels}");
            }
        }
    }
}

#[test]
fn zero_warp_is_exact_even_when_not_skipped() {
    let image = random(31, 17, 1, BitDepth::Sixteen, 2);
    let plane = image.to_planes().remove(0);
    assert_eq!(ops::warp(&plane, 31, 17, 0.0, 0.0), plane);
}

#[test]
fn gain_scales_and_clips() {
    let image = random(40, 30, 3, BitDepth::Eight, 3);
    let out = degrade(&image, &spec("gain=2"), 0).unwrap();
    for (&a, &b) in image.samples().iter().zip(out.samples()) {
        assert_eq!(b, (2 * a).min(255), "gain 2 of {a}");
    }
    let out = degrade(&image, &spec("gain=0.6"), 0).unwrap();
    for (&a, &b) in image.samples().iter().zip(out.samples()) {
        assert!((b as f32 - 0.6 * a as f32).abs() <= 0.5 + 1e-3, "gain 0.6 of {a} gave {b}");
    }
}

#[test]
fn bias_is_in_8bit_levels_at_any_depth() {
    let image = flat(8, 8, 1, BitDepth::Sixteen, 100 * 257);
    let out = degrade(&image, &spec("bias=40"), 0).unwrap();
    assert!(out.samples().iter().all(|&v| v == 140 * 257));
    let out = degrade(&flat(8, 8, 1, BitDepth::Eight, 20), &spec("bias=-40"), 0).unwrap();
    assert!(out.samples().iter().all(|&v| v == 0), "clipped at 0");
}

#[test]
fn gamma_is_a_power_law() {
    let image = flat(4, 4, 1, BitDepth::Sixteen, 32768);
    let out = degrade(&image, &spec("gamma=2"), 0).unwrap();
    let want = ((32768.0f64 / 65535.0).powi(2) * 65535.0).round() as u16;
    assert!(out.samples().iter().all(|&v| v.abs_diff(want) <= 1), "{} vs {want}", out.samples()[0]);
}

#[test]
fn vignette_is_one_minus_f_at_the_corners_and_untouched_at_the_centre() {
    let image = flat(21, 11, 1, BitDepth::Sixteen, 60000);
    let out = degrade(&image, &spec("vignette=0.4"), 0).unwrap();
    let corner = (60000.0f32 * 0.6).round() as u16;
    for (x, y) in [(0, 0), (20, 0), (0, 10), (20, 10)] {
        assert_eq!(out.get(x, y, 0), corner);
    }
    assert_eq!(out.get(10, 5, 0), 60000);
    // Monotonic along the middle row, away from the centre.
    assert!((0..10).all(|x| out.get(x, 5, 0) <= out.get(x + 1, 5, 0)));
}

#[test]
fn vshift_of_one_moves_content_down_one_row() {
    let image = random(33, 25, 3, BitDepth::Eight, 4);
    let out = degrade(&image, &spec("vshift=1"), 0).unwrap();
    for y in 1..25 {
        for x in 0..33 {
            for c in 0..3 {
                assert_eq!(out.get(x, y, c), image.get(x, y - 1, c), "({x},{y},{c})");
            }
        }
    }
    // Replicated border: the top row repeats the source's first row.
    assert!((0..33).all(|x| out.get(x, 0, 0) == image.get(x, 0, 0)));
    // Negative shifts move it up.
    let up = degrade(&image, &spec("vshift=-2"), 0).unwrap();
    assert!((0..23).all(|y| (0..33).all(|x| up.get(x, y, 1) == image.get(x, y + 2, 1))));
}

#[test]
fn half_pixel_shift_averages_smooth_content() {
    // On a vertical ramp, cubic interpolation at t = 0.5 is exactly the mean of the neighbours.
    let data = (0..20 * 16).map(|i| ((i / 20) * 1000) as u16).collect();
    let image = Raster::new(20, 16, 1, BitDepth::Sixteen, data).unwrap();
    let out = degrade(&image, &spec("vshift=0.5"), 0).unwrap();
    for y in 2..14 {
        assert_eq!(out.get(7, y, 0), (y as u16 * 1000) - 500, "row {y}");
    }
}

#[test]
fn rotation_turns_about_the_centre() {
    // A small rotation keeps the centre and moves the corners by about r·θ.
    let data = (0..101 * 101).map(|i| ((i % 101) * 600) as u16).collect(); // horizontal ramp
    let image = Raster::new(101, 101, 1, BitDepth::Sixteen, data).unwrap();
    let out = degrade(&image, &spec("rotate=1"), 0).unwrap();
    assert_eq!(out.get(50, 50, 0), image.get(50, 50, 0));
    // Clockwise as displayed: the point 40 px above the centre moves right by 40·sin(1°) ≈ 0.70 px,
    // so the ramp there reads the value from 0.70 px further left.
    let above = out.get(50, 10, 0) as f64;
    let want = (50.0 - 40.0 * 1f64.to_radians().sin()) * 600.0;
    assert!((above - want).abs() < 2.0, "{above} vs {want}");
    let below = out.get(50, 90, 0) as f64;
    let want = (50.0 + 40.0 * 1f64.to_radians().sin()) * 600.0;
    assert!((below - want).abs() < 2.0, "{below} vs {want}");
}

#[test]
fn noise_has_the_requested_sigma_and_zero_mean() {
    for (depth, value) in [(BitDepth::Eight, 128), (BitDepth::Sixteen, 128 * 257)] {
        let image = flat(200, 150, 3, depth, value);
        let out = degrade(&image, &spec("noise=6"), 11).unwrap();
        let scale = depth.max_value() as f64 / 255.0;
        let diffs: Vec<f64> = out.samples().iter().map(|&v| (v as f64 - value as f64) / scale).collect();
        let m = diffs.iter().sum::<f64>() / diffs.len() as f64;
        let sd = (diffs.iter().map(|d| (d - m) * (d - m)).sum::<f64>() / diffs.len() as f64).sqrt();
        assert!(m.abs() < 0.1, "mean {m}");
        assert!((sd - 6.0).abs() < 0.6, "{depth:?}: std {sd}, want 6 within 10 %");
    }
}

#[test]
fn noise_is_seeded() {
    let image = flat(64, 64, 1, BitDepth::Eight, 100);
    let d = spec("noise=4,gain=1.2,jpeg=70");
    let a = degrade(&image, &d, 1).unwrap();
    assert_eq!(a, degrade(&image, &d, 1).unwrap(), "same seed, same image");
    let b = degrade(&image, &d, 2).unwrap();
    let differing = a.samples().iter().zip(b.samples()).filter(|(x, y)| x != y).count();
    assert!(differing > 64 * 64 / 2, "different seeds differ at only {differing} pixels");
    assert_ne!(derive_seed(9, 0), derive_seed(9, 1));
}

#[test]
fn jpeg_100_is_close_and_50_is_lossier() {
    // A smooth colour image with some texture, like a photograph.
    let (w, h) = (96, 64);
    let data = (0..w * h * 3)
        .map(|i| {
            let (p, c) = (i / 3, i % 3);
            let (x, y) = ((p % w) as f32, (p / w) as f32);
            (128.0 + 60.0 * (x / 9.0 + c as f32).sin() + 40.0 * (y / 7.0).cos()) as u16
        })
        .collect();
    let image = Raster::new(w, h, 3, BitDepth::Eight, data).unwrap();
    let mae = |q: &str| {
        let out = degrade(&image, &spec(q), 0).unwrap();
        assert_eq!((out.channels(), out.depth()), (3, BitDepth::Eight));
        let sum: f64 = image.samples().iter().zip(out.samples()).map(|(&a, &b)| a.abs_diff(b) as f64).sum();
        sum / image.samples().len() as f64
    };
    let (q100, q50) = (mae("jpeg=100"), mae("jpeg=50"));
    assert!(q100 < 1.5, "q=100 mean abs error {q100}");
    assert!(q50 > q100, "q=50 ({q50}) not lossier than q=100 ({q100})");
}

#[test]
fn jpeg_of_16_bit_grey_comes_back_as_16_bit_multiples_of_257() {
    let image = random(24, 16, 1, BitDepth::Sixteen, 6);
    let out = degrade(&image, &spec("jpeg=90"), 0).unwrap();
    assert_eq!((out.channels(), out.depth()), (1, BitDepth::Sixteen));
    assert!(out.samples().iter().all(|&v| v % 257 == 0));
}

#[test]
fn blur_preserves_the_mean_and_smooths() {
    let image = random(80, 60, 1, BitDepth::Sixteen, 7);
    let out = degrade(&image, &spec("blur=1.5"), 0).unwrap();
    let (a, b) = (mean(&image), mean(&out));
    assert!((a - b).abs() < 0.005 * 65535.0, "mean {a} -> {b}");
    let var = |r: &Raster, m: f64| r.samples().iter().map(|&v| (v as f64 - m).powi(2)).sum::<f64>();
    assert!(var(&out, b) < 0.2 * var(&image, a), "white noise loses most of its variance");
    // A flat image stays exactly flat (normalised kernel, replicated borders).
    let flat_image = flat(30, 20, 3, BitDepth::Eight, 77);
    assert_eq!(degrade(&flat_image, &spec("blur=1.5"), 0).unwrap(), flat_image);
}

#[test]
fn out_of_range_parameters_are_refused_by_degrade() {
    let image = flat(4, 4, 1, BitDepth::Eight, 1);
    let d = Degradation { gamma: Some(0.0), ..Degradation::default() };
    let err = degrade(&image, &d, 0).unwrap_err().to_string();
    assert!(err.starts_with("gamma: "), "{err}");
}

#[test]
fn gray_image_round_trip_and_png() {
    let image = random(13, 9, 1, BitDepth::Eight, 8);
    let gray = image.to_gray_image();
    assert_eq!(gray.get(3, 4), image.get(3, 4, 0) * 257);
    assert_eq!(Raster::from_gray_image(&gray, BitDepth::Eight), image);
    for depth in [BitDepth::Eight, BitDepth::Sixteen] {
        for channels in [1, 3] {
            let r = random(13, 9, channels, depth, 9);
            assert_eq!(Raster::decode(&r.encode_png().unwrap()).unwrap(), r);
        }
    }
    assert!(Raster::decode(b"not an image").is_err());
}
