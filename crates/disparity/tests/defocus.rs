//! One view defocused: census compares the sharper view blurred to nearly match, and a defocused
//! left view, the reference the map is drawn on, is sharpened; on a generated scene with known
//! disparities.

mod common;

use stereo_disparity::{sgm_detailed, DisparityRange, GrayImage, SgmOutput, SgmParams};
use stereo_scene::Scene;

/// `image` blurred by a Gaussian of `sigma` px (replicated borders), rounded to 8-bit levels as a
/// camera would store it.
fn defocus(image: &GrayImage, sigma: f32) -> GrayImage {
    let (w, h) = image.size();
    let r = (3.0 * sigma).ceil() as isize;
    let kernel: Vec<f32> = (-r..=r).map(|d| (-((d * d) as f32) / (2.0 * sigma * sigma)).exp()).collect();
    let total: f32 = kernel.iter().sum();
    let pass = |get: &dyn Fn(isize, isize) -> f32, along_x: bool| {
        Vec::from_iter((0..w * h).map(|i| {
            let (x, y) = ((i % w) as isize, (i / w) as isize);
            let sum: f32 = kernel
                .iter()
                .zip(-r..=r)
                .map(|(k, d)| if along_x { k * get(x + d, y) } else { k * get(x, y + d) })
                .sum();
            sum / total
        }))
    };
    let clamp =
        |x: isize, y: isize| (x.clamp(0, w as isize - 1) as usize, y.clamp(0, h as isize - 1) as usize);
    let rows = pass(
        &|x, y| {
            let (x, y) = clamp(x, y);
            f32::from(image.get(x, y))
        },
        true,
    );
    let both = pass(
        &|x, y| {
            let (x, y) = clamp(x, y);
            rows[y * w + x]
        },
        false,
    );
    GrayImage::from_fn(w, h, |x, y| ((both[y * w + x] / 257.0).round() as u16) * 257)
}

/// Share (%) of the non-occluded pixels within `reach` px of a depth edge (a jump of more than
/// 2 px in the true disparity, left of or below the pixel) whose disparity is within 1 px of the
/// truth, invalid pixels counting as wrong.
fn good_near_edges(scene: &Scene, out: &SgmOutput, reach: usize) -> f64 {
    let (w, h) = out.disparity.size();
    let gt = &scene.gt_left;
    let edge = |x: usize, y: usize| {
        (x + 1 < w && (gt.get(x + 1, y) - gt.get(x, y)).abs() > 2.0)
            || (y + 1 < h && (gt.get(x, y + 1) - gt.get(x, y)).abs() > 2.0)
    };
    let mut near = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            if edge(x, y) {
                for v in y.saturating_sub(reach)..(y + reach + 2).min(h) {
                    for u in x.saturating_sub(reach)..(x + reach + 2).min(w) {
                        near[v * w + u] = true;
                    }
                }
            }
        }
    }
    let (mut good, mut total) = (0usize, 0usize);
    for y in 0..h {
        for x in 48..w {
            if near[y * w + x] && !scene.occluded.get(x, y) {
                total += 1;
                good += usize::from((out.disparity.get(x, y) - gt.get(x, y)).abs() <= 1.0);
            }
        }
    }
    100.0 * good as f64 / total as f64
}

#[test]
fn a_defocused_left_view_is_sharpened() {
    let params = SgmParams { range: DisparityRange::new(0, 48).unwrap(), ..SgmParams::default() };
    let scene = common::scene_8bit(0.0);
    // σ 1.5 leaves the census residual low (plain census); σ 2.5 raises it into the census
    // smoothing, where the right view is also blurred to nearly match. Measured near the depth
    // edges, unsharpened -> sharpened: 75.92 -> 84.32 % and 52.73 -> 65.58 % (the same blur in
    // the right view: 81.31 and 72.57 %).
    for (sigma, smoothing, min_share) in [(1.5, false, 80.0), (2.5, true, 60.0)] {
        let left = defocus(&scene.left, sigma);
        let out = sgm_detailed(&left, &scene.right, &params).unwrap();
        let a = &out.adaptation;
        let Some((false, measured)) = a.relative_blur else { panic!("σ {sigma}: {a:?}") };
        assert!((measured - sigma).abs() < 0.3, "σ {sigma} measured {measured}");
        assert_eq!(a.census_smoothing, smoothing, "{a:?}");
        assert_eq!(a.sharper_view_blur.is_some(), smoothing, "{a:?}");
        let share = good_near_edges(&scene, &out, 3);
        assert!(share >= min_share, "σ {sigma}: {share:.2} % near the edges within 1 px");
    }
}
