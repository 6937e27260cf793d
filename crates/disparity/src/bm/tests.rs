use super::*;
use crate::{DisparityRange, Subpixel};

/// The shared fit on BM's `u32` window costs.
fn subpixel_offset(method: Subpixel, cm: u32, c0: u32, cp: u32) -> f32 {
    crate::winner::subpixel_offset(method, cm as f32, c0 as f32, cp as f32)
}

/// A pseudo-random texture (hash of the coordinates), shifted by `shift` px in the right view.
fn shifted_pair(width: usize, height: usize, shift: usize) -> (GrayImage, GrayImage) {
    let texture = |x: usize, y: usize| {
        let mut z =
            (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (y as u64).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 29)).wrapping_mul(0x94D0_49BB_1331_11EB);
        (z >> 48) as u16
    };
    let left = GrayImage::from_fn(width, height, texture);
    let right = GrayImage::from_fn(width, height, |x, y| texture(x + shift, y));
    (left, right)
}

/// A rendered scene as this crate's image types (the dev-dependency links its own copy of
/// `stereo-disparity`, whose types are distinct).
struct Scene {
    left: GrayImage,
    right: GrayImage,
    gt: Vec<f32>,
    occluded: Vec<bool>,
}

fn scene(params: &stereo_scene::SceneParams) -> Scene {
    let s = stereo_scene::render(params);
    let (w, h) = s.left.size();
    Scene {
        left: GrayImage::from_vec(w, h, s.left.as_slice().to_vec()).unwrap(),
        right: GrayImage::from_vec(w, h, s.right.as_slice().to_vec()).unwrap(),
        gt: s.gt_left.as_slice().to_vec(),
        occluded: s.occluded.as_slice().to_vec(),
    }
}

struct Score {
    /// Of non-occluded pixels whose window fits the image: fraction within 1 px of the truth.
    within_1px: f64,
    /// Of the same pixels: fraction with a disparity.
    valid: f64,
    /// Mean absolute error over valid pixels within 1 px of the truth.
    mean_error: f64,
}

fn score(disparity: &DisparityMap, scene: &Scene, radius: usize) -> Score {
    let (w, h) = disparity.size();
    let (mut total, mut valid, mut good, mut error) = (0usize, 0usize, 0usize, 0.0);
    for y in radius..h - radius {
        for x in radius..w - radius {
            if scene.occluded[y * w + x] {
                continue;
            }
            total += 1;
            let d = disparity.get(x, y);
            if d.is_nan() {
                continue;
            }
            valid += 1;
            let e = (d - scene.gt[y * w + x]).abs();
            if e <= 1.0 {
                good += 1;
                error += e as f64;
            }
        }
    }
    Score {
        within_1px: good as f64 / total as f64,
        valid: valid as f64 / total as f64,
        mean_error: error / good as f64,
    }
}

fn params(cost: BmCost, max: i32) -> BmParams {
    BmParams { range: DisparityRange::new(0, max).unwrap(), cost, ..BmParams::default() }
}

#[test]
fn constant_shift_is_found_everywhere_feasible() {
    let (left, right) = shifted_pair(96, 40, 5);
    for cost in [BmCost::Sad, BmCost::Census] {
        let p = BmParams { subpixel: Subpixel::None, block_size: 7, ..params(cost, 32) };
        let d = block_match(&left, &right, &p).unwrap();
        let r = 3;
        for y in 0..40 {
            for x in 0..96 {
                let v = d.get(x, y);
                let window_fits = (r..40 - r).contains(&y) && (r..96 - r).contains(&x);
                if !window_fits || x < 5 + r {
                    // No window, or the true match's window leaves the right image.
                    assert!(v.is_nan() || !window_fits, "{cost:?} ({x}, {y}): {v}");
                } else if x > 5 + r {
                    // Valid even where only part of the range is feasible (x < 32 + r).
                    assert_eq!(v, 5.0, "{cost:?} ({x}, {y})");
                }
            }
        }
    }
}

#[test]
fn both_costs_match_the_default_scene() {
    let s = scene(&stereo_scene::SceneParams::default());
    for cost in [BmCost::Sad, BmCost::Census] {
        let p = params(cost, 48);
        let d = block_match(&s.left, &s.right, &p).unwrap();
        let sc = score(&d, &s, p.block_size / 2);
        assert!(sc.within_1px >= 0.90, "{cost:?}: {:.3} within 1 px, {:.3} valid", sc.within_1px, sc.valid);
    }
}

#[test]
fn subpixel_refinement_improves_the_slanted_plane() {
    let scene_params = stereo_scene::SceneParams { foreground: None, noise: 100.0, ..Default::default() };
    let s = scene(&scene_params);
    for cost in [BmCost::Sad, BmCost::Census] {
        let error = |subpixel| {
            let p = BmParams { subpixel, ..params(cost, 32) };
            score(&block_match(&s.left, &s.right, &p).unwrap(), &s, p.block_size / 2).mean_error
        };
        let (none, parabola, equiangular) =
            (error(Subpixel::None), error(Subpixel::Parabola), error(Subpixel::Equiangular));
        assert!(none > 0.2, "{cost:?}: integer error {none}");
        assert!(parabola < 0.7 * none, "{cost:?}: parabola {parabola} vs none {none}");
        assert!(equiangular < 0.7 * none, "{cost:?}: equiangular {equiangular} vs none {none}");
    }
}

#[test]
fn checks_invalidate_without_losing_most_pixels() {
    let s = scene(&stereo_scene::SceneParams::default());
    let strict = params(BmCost::Census, 48);
    let loose = BmParams { uniqueness_ratio: 0, lr_max_diff: None, ..strict.clone() };
    let (ds, dl) =
        (block_match(&s.left, &s.right, &strict).unwrap(), block_match(&s.left, &s.right, &loose).unwrap());
    let (w, h) = ds.size();
    let nan = |d: &DisparityMap| d.as_slice().iter().filter(|v| v.is_nan()).count();
    // Without checks only the border (window does not fit) and pixels whose true match lies
    // outside the searched disparities (winners at a range end) are invalid: the left band,
    // where the plane's 8 px leave the right image, the occlusions beside the rectangle, and
    // windows across its edges...
    let r = strict.block_size / 2;
    let across_edge = |i: usize| {
        let (x, y) = ((i % w) as i64, (i / w) as i64);
        let r = r as i64;
        (-r..=r).flat_map(|dy| (-r..=r).map(move |dx| (x + dx, y + dy))).any(|(u, v)| {
            (0..w as i64).contains(&u)
                && (0..h as i64).contains(&v)
                && (s.gt[v as usize * w + u as usize] - s.gt[i]).abs() > 1.0
        })
    };
    let unmatchable = |i: usize| s.occluded[i] || i % w < 8 + 2 * r || across_edge(i);
    for (i, v) in dl.as_slice().iter().enumerate() {
        let (x, y) = (i % w, i / w);
        let window_fits = (r..w - r).contains(&x) && (r..h - r).contains(&y);
        assert!(v.is_nan() != window_fits || (v.is_nan() && unmatchable(i)), "({x}, {y}): {v}");
    }
    // ...with them, occluded pixels (and a few others) go.
    assert!(nan(&ds) > nan(&dl));
    let occluded_valid = (0..w * h)
        .filter(|&i| s.occluded[i] && !ds.as_slice()[i].is_nan() && (ds.as_slice()[i] - s.gt[i]).abs() > 1.0)
        .count();
    let occluded = s.occluded.iter().filter(|&&o| o).count();
    assert!(
        occluded_valid * 3 < occluded,
        "{occluded_valid} of {occluded} occluded pixels got a wrong disparity"
    );
    assert!(score(&ds, &s, r).valid > 0.9);
}

#[test]
fn negative_disparities_are_searched() {
    let (right, left) = shifted_pair(80, 30, 4); // left(x) = right(x + 4): d = -4
    let p = BmParams {
        range: DisparityRange::new(-8, 8).unwrap(),
        subpixel: Subpixel::None,
        ..BmParams::default()
    };
    let d = block_match(&left, &right, &p).unwrap();
    assert_eq!(d.get(40, 15), -4.0);
}

#[test]
fn invalid_input_is_rejected() {
    let (left, right) = shifted_pair(64, 32, 3);
    let ok = params(BmCost::Census, 16);
    let small = GrayImage::new(63, 32, 0);
    assert!(matches!(block_match(&left, &small, &ok), Err(Error::SizeMismatch { .. })));
    let empty = BmParams { range: DisparityRange { min: 5, max: 5 }, ..ok.clone() };
    assert!(matches!(block_match(&left, &right, &empty), Err(Error::EmptyRange { .. })));
    let wide = BmParams { range: DisparityRange { min: 0, max: 65 }, ..ok.clone() };
    assert!(matches!(block_match(&left, &right, &wide), Err(Error::RangeWiderThanImage { .. })));
    for block_size in [0, 1, 2, 10, 257] {
        let bad = BmParams { block_size, ..ok.clone() };
        assert!(
            matches!(
                block_match(&left, &right, &bad),
                Err(Error::InvalidParameter { name: "block size", .. })
            ),
            "block size {block_size}"
        );
    }
    let bad_lr = BmParams { lr_max_diff: Some(f32::NAN), ..ok.clone() };
    assert!(matches!(block_match(&left, &right, &bad_lr), Err(Error::InvalidParameter { .. })));
    let tiny = GrayImage::new(40, 8, 0);
    let tiny_params = BmParams { block_size: 9, ..ok };
    assert!(matches!(block_match(&tiny, &tiny, &tiny_params), Err(Error::ImageTooSmall { .. })));
}

#[test]
fn subpixel_offsets() {
    assert_eq!(subpixel_offset(Subpixel::None, 10, 0, 20), 0.0);
    assert_eq!(subpixel_offset(Subpixel::Parabola, 10, 5, 10), 0.0);
    // A parabola with its minimum at +0.25: c(t) = (t - 0.25)² · 16 at t = -1, 0, 1 -> 25, 1, 9.
    assert!((subpixel_offset(Subpixel::Parabola, 25, 1, 9) - 0.25).abs() < 1e-6);
    // A V with slope 4 and its minimum at -0.25: c(t) = 4|t + 0.25| at -1, 0, 1 -> 3, 1, 5.
    assert!((subpixel_offset(Subpixel::Equiangular, 3, 1, 5) + 0.25).abs() < 1e-6);
    assert_eq!(subpixel_offset(Subpixel::Equiangular, 4, 4, 4), 0.0);
    assert_eq!(subpixel_offset(Subpixel::Parabola, 100, 0, 0), 0.5);
}
