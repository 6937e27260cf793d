//! Radiometric preparation of a pair before matching: what makes the cost survive two cameras
//! that do not see alike (exposure, gamma, vignetting, sensor noise).

use crate::GrayImage;

/// The `factor × factor` box average of `image` (partial blocks at the right and bottom are
/// dropped), 8-bit samples stored ×257 when the input is 8-bit.
pub(crate) fn downsample(image: &GrayImage, factor: usize) -> GrayImage {
    let (w, h) = image.size();
    let (cw, ch) = (w / factor, h / factor);
    let byte_scaled = image.as_slice().iter().all(|&v| v % 257 == 0);
    let n = (factor * factor) as u64;
    GrayImage::from_fn(cw, ch, |x, y| {
        let mut sum = 0u64;
        for yy in y * factor..(y + 1) * factor {
            for &v in &image.row(yy)[x * factor..(x + 1) * factor] {
                sum += u64::from(v);
            }
        }
        if byte_scaled {
            (((sum / 257 + n / 2) / n) * 257) as u16
        } else {
            ((sum + n / 2) / n) as u16
        }
    })
}

/// The largest [`radiometric_difference`] (8-bit grey levels) at which AD-census keeps its
/// intensity term. Measured on the seven Middlebury scenes (docs/robustness.md): clean pairs,
/// noise, JPEG, blur and misalignment stay at or below 6, while a 40 % vignetting in one view
/// reaches 13 or more, and exposure, gamma and bias changes 35 or more.
pub(crate) const MAX_RADIOMETRIC_DIFFERENCE: f32 = 9.0;

/// How differently the two views render the same surfaces, in 8-bit grey levels: the pair is
/// matched census-only (blind to radiometry) at a quarter of the resolution (where the box
/// average also quiets the noise), and the grey-level differences of the matched pixels are
/// gathered per tile of a 3×3 grid; the result is the largest tile's median difference. A
/// change of exposure, gamma or a vignetting shifts the medians; a misregistration only widens
/// their spread. `None` when the pair is too small or too little matched to tell.
pub(crate) fn radiometric_difference(
    left: &GrayImage,
    right: &GrayImage,
    params: &crate::SgmParams,
) -> Option<f32> {
    let (w, _) = left.size();
    let factor = 4;
    let (l, r) = (downsample(left, factor), downsample(right, factor));
    let (cw, ch) = l.size();
    let min = params.range.min.div_euclid(factor as i32);
    let max = (params.range.max + factor as i32 - 1).div_euclid(factor as i32).max(min + 1);
    let count = (max - min) as usize;
    if cw < 16 || ch < 16 || count > cw || w < 16 {
        return None;
    }
    let coarse = crate::SgmParams {
        range: crate::DisparityRange { min, max },
        matching_cost: crate::MatchingCost::Census,
        paths: crate::PathCount::Four,
        single_pass: true,
        edge_snap_radius: 0,
        fill: false,
        wmf_radius: 0,
        speckle_size: 0,
        confidence: false,
        max_memory: None,
        ..params.clone()
    };
    let d = crate::sgm(&l, &r, &coarse).ok()?;
    // Signed differences per tile of a 3×3 grid: a radiometric change shifts a tile's median
    // (the same way over the tile), a misregistration only widens its spread.
    let mut tiles: Vec<Vec<f32>> = vec![Vec::new(); 9];
    for y in 0..ch {
        for x in 0..cw {
            let v = d.get(x, y);
            if !v.is_finite() {
                continue;
            }
            let xr = x as i64 - v.round() as i64;
            if xr < 0 || xr >= cw as i64 {
                continue;
            }
            let a = f32::from(l.get(x, y)) / 257.0;
            let b = f32::from(r.get(xr as usize, y)) / 257.0;
            tiles[(y * 3 / ch) * 3 + x * 3 / cw].push(a - b);
        }
    }
    let mut medians = Vec::new();
    for t in tiles.iter_mut().filter(|t| t.len() >= 20) {
        let mid = t.len() / 2;
        medians.push(t.select_nth_unstable_by(mid, f32::total_cmp).1.abs());
    }
    if medians.len() < 5 {
        return None;
    }
    medians.into_iter().max_by(f32::total_cmp)
}
