//! Subpixel refinement on the generator's slanted plane: accuracy and no stair steps.

use stereo_disparity::{sgm, DisparityRange, SgmParams, Subpixel};

/// Errors against the ground truth and the fractional parts of the estimates, over the plane of
/// the generator's scene (no foreground) away from the borders.
fn errors_and_fractions(subpixel: Subpixel) -> (Vec<f64>, Vec<f64>) {
    let params = stereo_scene::SceneParams { foreground: None, ..Default::default() };
    let scene = stereo_scene::render(&params);
    let sgm_params =
        SgmParams { range: DisparityRange::new(0, 32).unwrap(), subpixel, ..SgmParams::default() };
    let d = sgm(&scene.left, &scene.right, &sgm_params).unwrap();
    let (w, h) = d.size();
    let (mut errors, mut fractions) = (Vec::new(), Vec::new());
    for y in 8..h - 8 {
        for x in 40..w - 8 {
            let e = d.get(x, y);
            if e.is_nan() {
                continue;
            }
            errors.push(f64::from(e) - f64::from(scene.gt_left.get(x, y)));
            fractions.push(f64::from(e).rem_euclid(1.0));
        }
    }
    (errors, fractions)
}

fn rms(errors: &[f64]) -> f64 {
    (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt()
}

/// The fullest 0.05-wide bin of the fractional parts around 0, around 0.5 and overall, each
/// relative to the uniform share (1.0 = flat histogram). The plane's disparities sweep evenly
/// through every fraction, so a flat histogram is the truth.
fn histogram_peaks(fractions: &[f64]) -> (f64, f64, f64) {
    let mut bins = [0usize; 20];
    for f in fractions {
        bins[((f * 20.0) as usize).min(19)] += 1;
    }
    let uniform = fractions.len() as f64 / 20.0;
    let at_zero = bins[19].max(bins[0]) as f64 / uniform;
    let at_half = bins[9].max(bins[10]) as f64 / uniform;
    let max = *bins.iter().max().unwrap() as f64 / uniform;
    (at_zero, at_half, max)
}

#[test]
fn default_subpixel_is_accurate_and_has_no_stair_steps_on_a_slanted_plane() {
    let (errors, fractions) = errors_and_fractions(SgmParams::default().subpixel);
    assert!(errors.len() > 40_000, "{} valid", errors.len());
    let rms = rms(&errors);
    let (at_zero, at_half, max) = histogram_peaks(&fractions);
    eprintln!("rms {rms:.3}, fraction peaks: at 0 {at_zero:.2}, at 0.5 {at_half:.2}, max {max:.2}");
    assert!(rms < 0.15, "rms {rms}");
    assert!(at_zero < 1.5 && at_half < 1.5, "peaks at 0: {at_zero}, at 0.5: {at_half}");
}

/// The numbers of docs/accuracy.md: `cargo test -p stereo-disparity --test subpixel -- --ignored --nocapture`.
#[test]
#[ignore]
fn compare_subpixel_methods() {
    for s in [Subpixel::None, Subpixel::Parabola, Subpixel::Equiangular] {
        let (errors, fractions) = errors_and_fractions(s);
        let (z, hf, m) = histogram_peaks(&fractions);
        eprintln!("{s:?}: rms {:.3} peaks 0 {z:.2} 0.5 {hf:.2} max {m:.2}", rms(&errors));
    }
}
