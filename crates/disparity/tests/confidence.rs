//! The confidence of `sgm_detailed` on a generated scene with known truth: confident pixels are
//! right more often than the others, and filled or invalid pixels have none.

use stereo_disparity::{sgm_detailed, DisparityRange, SgmParams};

#[test]
fn confident_pixels_are_more_often_right() {
    // Noise makes some matches wrong, so there is something for the confidence to tell apart.
    let scene = stereo_scene::render(&stereo_scene::SceneParams { noise: 2500.0, ..Default::default() });
    let params =
        SgmParams { range: DisparityRange::new(0, 48).unwrap(), confidence: true, ..SgmParams::default() };
    let out = sgm_detailed(&scene.left, &scene.right, &params).unwrap();
    let confidence = out.confidence.expect("confidence was asked for");
    let (mut high, mut high_bad, mut low, mut low_bad) = (0usize, 0usize, 0usize, 0usize);
    for (i, (&d, &c)) in out.disparity.as_slice().iter().zip(confidence.as_slice()).enumerate() {
        assert!((0.0..=1.0).contains(&c), "confidence {c}");
        if !d.is_finite() {
            assert_eq!(c, 0.0, "an invalid pixel has no confidence");
            continue;
        }
        let bad = (d - scene.gt_left.as_slice()[i]).abs() > 1.0;
        if c >= 0.5 {
            high += 1;
            high_bad += usize::from(bad);
        } else {
            low += 1;
            low_bad += usize::from(bad);
        }
    }
    let (high_rate, low_rate) = (high_bad as f64 / high as f64, low_bad as f64 / low.max(1) as f64);
    assert!(high > low, "most matched pixels should be confident: {high} vs {low}");
    assert!(low > 0, "the noisy scene should have some unconfident pixels");
    assert!(high_rate * 2.0 < low_rate, "bad rate {high_rate:.4} (confident) vs {low_rate:.4} (not)");
}

#[test]
fn filled_pixels_have_no_confidence() {
    let scene = stereo_scene::render(&stereo_scene::SceneParams::default());
    let params =
        SgmParams { range: DisparityRange::new(0, 48).unwrap(), confidence: true, ..SgmParams::default() }
            .with_fill();
    let out = sgm_detailed(&scene.left, &scene.right, &params).unwrap();
    let confidence = out.confidence.as_ref().unwrap();
    let filled = out.filled_mask();
    let mut n_filled = 0;
    for (&f, &c) in filled.as_slice().iter().zip(confidence.as_slice()) {
        if f == 255 {
            n_filled += 1;
            assert_eq!(c, 0.0);
        }
    }
    assert!(n_filled > 0, "the scene's occlusions are filled");
    assert!(out.disparity.as_slice().iter().all(|d| d.is_finite()));
}
