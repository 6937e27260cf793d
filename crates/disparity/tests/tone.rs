//! Views exposed differently (gain, vignetting): the matcher maps the right view's tones onto the
//! left's and keeps AD-census' intensity term, on a generated scene with known disparities.

mod common;

use stereo_disparity::{sgm_detailed, DisparityRange, GrayImage, SgmOutput, SgmParams};
use stereo_scene::Scene;

/// A 480×360 scene in 8-bit levels with a little noise.
fn scene() -> Scene {
    common::scene_8bit(1000.0)
}

/// A right view's 8-bit level from the true level and the centred position `(u, v)`.
type Render = dyn Fn(f32, f32, f32) -> f32;

/// `image` with every 8-bit level `v` at `(x, y)` replaced by `render(v, x, y)`, rounded and clipped.
fn degrade(image: &GrayImage, render: impl Fn(f32, f32, f32) -> f32) -> GrayImage {
    let (w, h) = image.size();
    GrayImage::from_fn(w, h, |x, y| {
        let v = f32::from(image.get(x, y)) / 257.0;
        let (u, v2) = ((x as f32 + 0.5) / w as f32 - 0.5, (y as f32 + 0.5) / h as f32 - 0.5);
        (render(v, u, v2).round().clamp(0.0, 255.0) as u16) * 257
    })
}

/// Share (%) of the non-occluded pixels whose disparity is within 1 px of the truth (invalid
/// pixels count as wrong), and the mean absolute error (px) of the valid ones.
fn scores(scene: &Scene, out: &SgmOutput) -> (f64, f64) {
    let (w, h) = out.disparity.size();
    let (mut good, mut total, mut valid, mut error) = (0usize, 0usize, 0usize, 0f64);
    for y in 0..h {
        for x in 48..w {
            if !scene.occluded.get(x, y) {
                total += 1;
                let e = (out.disparity.get(x, y) - scene.gt_left.get(x, y)).abs();
                good += usize::from(e <= 1.0);
                if e.is_finite() {
                    valid += 1;
                    error += f64::from(e);
                }
            }
        }
    }
    (100.0 * good as f64 / total as f64, error / valid as f64)
}

#[test]
fn exposure_and_vignetting_are_corrected_and_the_intensity_term_kept() {
    let scene = scene();
    let params = SgmParams { range: DisparityRange::new(0, 48).unwrap(), ..SgmParams::default() };
    let clean = sgm_detailed(&scene.left, &scene.right, &params).unwrap();
    let a = &clean.adaptation;
    assert!(a.intensity_term && a.corrected_radiometric_difference.is_none(), "{a:?}");
    let clean_scores = scores(&scene, &clean);

    let degradations: [(&str, &Render); 3] = [
        ("gain 0.6", &|v, _, _| 0.6 * v),
        ("bias +30", &|v, _, _| v + 30.0),
        // 40 % fall-off at the corners.
        ("vignetting", &|v, u, w| v * (1.0 - 0.4 * (u * u + w * w) / 0.5)),
    ];
    for (name, render) in degradations {
        let right = degrade(&scene.right, render);
        let out = sgm_detailed(&scene.left, &right, &params).unwrap();
        let a = &out.adaptation;
        assert!(a.radiometric_difference.is_some_and(|d| d > 9.0), "{name}: {a:?}");
        assert!(a.corrected_radiometric_difference.is_some_and(|d| d <= 3.0), "{name}: {a:?}");
        assert!(a.intensity_term, "{name}: {a:?}");
        // As good as on the clean pair (the real pairs' gains are in docs/robustness.md and the
        // degraded accuracy gate).
        let (good, error) = scores(&scene, &out);
        assert!(good >= clean_scores.0 - 0.1, "{name}: {good:.2} % good, clean {:.2} %", clean_scores.0);
        assert!(error <= clean_scores.1 + 0.01, "{name}: mean error {error:.3}, clean {:.3}", clean_scores.1);
    }
}

#[test]
fn a_gamma_or_clipping_leaves_census_alone() {
    let scene = scene();
    let params = SgmParams { range: DisparityRange::new(0, 48).unwrap(), ..SgmParams::default() };
    // A strong gamma: a coloured surface would follow another curve than a grey one.
    let gamma = degrade(&scene.right, |v, _, _| 255.0 * (v / 255.0).powf(2.0));
    // A gain that clips a quarter of the view to white: its texture there is lost.
    let clipped = degrade(&scene.right, |v, _, _| 2.5 * v);
    for (name, right) in [("gamma 2", gamma), ("gain 2.5", clipped)] {
        let a = sgm_detailed(&scene.left, &right, &params).unwrap().adaptation;
        assert!(a.radiometric_difference.is_some_and(|d| d > 9.0), "{name}: {a:?}");
        assert!(!a.intensity_term, "{name}: {a:?}");
    }
}

#[test]
fn shadows_clipped_in_one_view_are_clipped_alike_in_the_other() {
    let scene = scene();
    let params = SgmParams { range: DisparityRange::new(0, 48).unwrap(), ..SgmParams::default() };
    let clean = scores(&scene, &sgm_detailed(&scene.left, &scene.right, &params).unwrap());
    // A bias that clips the right view's darkest tenth or more to black.
    let right = degrade(&scene.right, |v, _, _| v - 60.0);
    let out = sgm_detailed(&scene.left, &right, &params).unwrap();
    let a = &out.adaptation;
    assert!(a.clipped_alike && !a.intensity_term, "{a:?}");
    // Flat where either view was clipped: the strong, edge-aware P2 of weak texture carries the
    // surface across (the default output; the dense one keeps its penalties).
    assert!(a.p2 > params.p2 && a.p2_edge_scale > 0, "{a:?}");
    let (good, _) = scores(&scene, &out);
    assert!(good >= clean.0 - 1.0, "{good:.2} % good, clean {:.2} %", clean.0);
    // The left view clipped instead: the same.
    let left = degrade(&scene.left, |v, _, _| v - 60.0);
    let out = sgm_detailed(&left, &scene.right, &params).unwrap();
    let a = &out.adaptation;
    assert!(a.clipped_alike && a.p2 > params.p2 && a.p2_edge_scale > 0, "{a:?}");
    let dense = SgmParams { fill: true, ..params.clone() };
    let a = sgm_detailed(&left, &scene.right, &dense).unwrap().adaptation;
    assert!(a.clipped_alike && a.p2_edge_scale == 0, "{a:?}");
}

#[test]
fn a_vignetted_left_view_is_corrected_over_its_own_positions() {
    let scene = scene();
    let params = SgmParams { range: DisparityRange::new(0, 48).unwrap(), ..SgmParams::default() };
    let clean = scores(&scene, &sgm_detailed(&scene.left, &scene.right, &params).unwrap());
    // The left lens darkens its corners by 40 %, the right camera is exposed 0.8× as long.
    let left = degrade(&scene.left, |v, u, w| v * (1.0 - 0.4 * (u * u + w * w) / 0.5));
    let right = degrade(&scene.right, |v, _, _| 0.8 * v);
    let out = sgm_detailed(&left, &right, &params).unwrap();
    let a = &out.adaptation;
    // (A disparity that varies little moves a quadratic fall-off into another quadratic, so here
    // a fit over either view's positions serves; the unit tests of the fit and wood2 in
    // docs/robustness.md show where only the left view's does.)
    assert!(a.radiometric_difference.is_some_and(|d| d > 9.0), "{a:?}");
    assert!(a.intensity_term, "{a:?}");
    let (good, error) = scores(&scene, &out);
    assert!(good >= clean.0 - 0.1, "{good:.2} % good, clean {:.2} %", clean.0);
    assert!(error <= clean.1 + 0.01, "mean error {error:.3}, clean {:.3}", clean.1);
}
