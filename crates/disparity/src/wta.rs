//! Winner-takes-all disparity selection over an aggregated cost volume (`[y][x][d]`), with
//! subpixel refinement, the uniqueness test and the left-right consistency check.

use crate::simd::{self, Level};
use crate::status::{tagged_nan, PixelStatus};
use crate::{DisparityRange, Subpixel};

/// The tagged NaN of a pixel that failed the left-right check: an occlusion when the right
/// view's disparity at the matched pixel is larger (a nearer surface hides the pixel there),
/// a mismatch otherwise.
#[inline]
fn lr_failure(right_disparity_larger: bool) -> f32 {
    tagged_nan(if right_disparity_larger { PixelStatus::Occluded } else { PixelStatus::Mismatch })
}

/// What winner-takes-all keeps and how it refines.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Selection {
    pub range: DisparityRange,
    pub uniqueness_ratio: u32,
    pub lr_max_diff: Option<f32>,
    pub subpixel: Subpixel,
}

/// The disparity indices `k` (disparity `range.min + k`) for which left pixel `x` has a match
/// inside a right image `width` pixels wide.
#[inline]
fn feasible_left(x: usize, width: usize, range: DisparityRange) -> std::ops::Range<usize> {
    let (x, w, min, nd) = (x as i64, width as i64, range.min as i64, range.count() as i64);
    let hi = (x - min + 1).clamp(0, nd);
    let lo = (x - (w - 1) - min).clamp(0, hi);
    lo as usize..hi as usize
}

/// The disparity indices for which right pixel `xr` has a match `xr + d` inside the left image.
#[cfg(test)]
#[inline]
fn feasible_right(xr: usize, width: usize, range: DisparityRange) -> std::ops::Range<usize> {
    let (xr, w, min, nd) = (xr as i64, width as i64, range.min as i64, range.count() as i64);
    // Empty (not reversed) when no disparity fits, e.g. for a range of only negative disparities
    // near the right image's left border.
    let hi = (w - xr - min).clamp(0, nd);
    let lo = (-xr - min).clamp(0, hi);
    lo as usize..hi as usize
}

/// Sub-pixel offset in `[-0.5, 0.5]` of the cost minimum from the three costs around it.
#[inline]
pub(crate) fn subpixel_offset(method: Subpixel, before: f32, best: f32, after: f32) -> f32 {
    let offset = match method {
        Subpixel::None => 0.0,
        Subpixel::Parabola => {
            let curvature = before - 2.0 * best + after;
            if curvature > 0.0 {
                (before - after) / (2.0 * curvature)
            } else {
                0.0
            }
        }
        Subpixel::Equiangular => {
            let slope = (before - best).max(after - best);
            if slope > 0.0 {
                (before - after) / (2.0 * slope)
            } else {
                0.0
            }
        }
    };
    offset.clamp(-0.5, 0.5)
}

/// Per-thread buffers of [`select_row`], allocated once per pass.
pub(crate) struct WtaScratch {
    /// Right view, indexed by `width - 1 - xr`: the best cost so far and its disparity index.
    right_cost: Vec<u16>,
    right_index: Vec<u16>,
}

impl WtaScratch {
    pub(crate) fn new(width: usize) -> Self {
        WtaScratch { right_cost: vec![0; width], right_index: vec![0; width] }
    }

    pub(crate) fn bytes(width: usize) -> usize {
        4 * width
    }
}

/// Marks a right pixel without any feasible disparity.
const NO_MATCH: u16 = u16::MAX;

/// Selects the left-view disparities of one row (`costs` is `[x][d]`) into `out`, NaN where
/// rejected. Equal to [`select_row_reference`] (ties go to the lowest disparity index in both
/// views), with the right view's winners found by one forward sweep instead of a strided gather
/// per right pixel. Needs fewer than 65535 disparities, which the aggregation's `u16` sums imply.
pub(crate) fn select_row(
    costs: &[u16],
    width: usize,
    nd: usize,
    sel: Selection,
    scratch: &mut WtaScratch,
    out: &mut [f32],
) {
    #[cfg(target_arch = "x86_64")]
    {
        match simd::features().level {
            // SAFETY: the level was detected on this CPU.
            Level::Avx512 => return unsafe { select_row_avx512(costs, width, nd, sel, scratch, out) },
            // SAFETY: as above.
            Level::Avx2 => return unsafe { select_row_avx2(costs, width, nd, sel, scratch, out) },
            Level::Scalar => {}
        }
    }
    select_row_generic(costs, width, nd, sel, scratch, out, Level::Scalar)
}

/// [`select_row_generic`] compiled for AVX-512BW, with the SIMD kernels inlined.
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,popcnt")]
unsafe fn select_row_avx512(
    costs: &[u16],
    width: usize,
    nd: usize,
    sel: Selection,
    scratch: &mut WtaScratch,
    out: &mut [f32],
) {
    select_row_generic(costs, width, nd, sel, scratch, out, Level::Avx512)
}

/// [`select_row_generic`] compiled for AVX2.
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,popcnt")]
unsafe fn select_row_avx2(
    costs: &[u16],
    width: usize,
    nd: usize,
    sel: Selection,
    scratch: &mut WtaScratch,
    out: &mut [f32],
) {
    select_row_generic(costs, width, nd, sel, scratch, out, Level::Avx2)
}

#[inline(always)]
fn select_row_generic(
    costs: &[u16],
    width: usize,
    nd: usize,
    sel: Selection,
    scratch: &mut WtaScratch,
    out: &mut [f32],
    level: Level,
) {
    debug_assert!(nd < usize::from(NO_MATCH));
    let costs = &costs[..width * nd];
    if sel.lr_max_diff.is_some() {
        // Right pixel xr = x - min - k collects the candidates (cost, k) of all left pixels x;
        // indexed by q = width - 1 - xr, one left pixel's candidates are contiguous in k. Left
        // pixels are visited in increasing x, so for equal costs the first (lowest k) stays.
        let rc = &mut scratch.right_cost[..width];
        let ri = &mut scratch.right_index[..width];
        rc.fill(u16::MAX);
        ri.fill(NO_MATCH);
        for x in 0..width {
            let ks = feasible_left(x, width, sel.range);
            if ks.is_empty() {
                continue;
            }
            let c = &costs[x * nd..(x + 1) * nd][ks.clone()];
            let q0 = (width as i64 - 1 - x as i64 + sel.range.min as i64 + ks.start as i64) as usize;
            let (rc, ri) = (&mut rc[q0..q0 + c.len()], &mut ri[q0..q0 + c.len()]);
            simd::keep_smaller(level, c, ks.start as u16, rc, ri);
        }
    }

    for (x, o) in out[..width].iter_mut().enumerate() {
        *o = tagged_nan(PixelStatus::NoMatch);
        let ks = feasible_left(x, width, sel.range);
        if ks.is_empty() {
            continue;
        }
        let c = &costs[x * nd..(x + 1) * nd];
        let best = ks.start + simd::argmin(level, &c[ks.clone()]).1;
        if sel.uniqueness_ratio > 0 {
            let second = ks.clone().filter(|k| k.abs_diff(best) > 1).map(|k| c[k]).min();
            if let Some(second) = second {
                if u64::from(c[best]) * u64::from(100 + sel.uniqueness_ratio) > u64::from(second) * 100 {
                    *o = tagged_nan(PixelStatus::Ambiguous);
                    continue;
                }
            }
        }
        let d_int = sel.range.min as i64 + best as i64;
        if let Some(max_diff) = sel.lr_max_diff {
            let xr = x as i64 - d_int;
            let kr = scratch.right_index[width - 1 - xr as usize];
            if kr == NO_MATCH || (kr as f32 - best as f32).abs() > max_diff {
                *o = lr_failure(kr != NO_MATCH && usize::from(kr) > best);
                continue;
            }
        }
        let offset = if best > ks.start && best + 1 < ks.end {
            subpixel_offset(sel.subpixel, f32::from(c[best - 1]), f32::from(c[best]), f32::from(c[best + 1]))
        } else {
            0.0
        };
        *o = d_int as f32 + offset;
    }
}

/// The original row selection, kept as the readable reference of [`select_row`].
#[cfg(test)]
pub(crate) fn select_row_reference(
    costs: &[u16],
    width: usize,
    nd: usize,
    sel: Selection,
    right_best: &mut [usize],
    out: &mut [f32],
) {
    let at = |x: usize, k: usize| costs[x * nd + k];

    if sel.lr_max_diff.is_some() {
        // Right-view winner-takes-all from the same volume: right pixel xr with disparity d is
        // left pixel xr + d (Hirschmüller's shortcut instead of a second aggregation).
        for (xr, best) in right_best.iter_mut().enumerate() {
            let ks = feasible_right(xr, width, sel.range);
            *best = ks
                .clone()
                .min_by_key(|&k| (at((xr as i64 + sel.range.min as i64 + k as i64) as usize, k), k))
                .unwrap_or(usize::MAX);
        }
    }

    for (x, o) in out.iter_mut().enumerate() {
        *o = tagged_nan(PixelStatus::NoMatch);
        let ks = feasible_left(x, width, sel.range);
        if ks.is_empty() {
            continue;
        }
        let c = &costs[x * nd..(x + 1) * nd];
        let mut best = ks.start;
        for k in ks.clone() {
            if c[k] < c[best] {
                best = k;
            }
        }
        if sel.uniqueness_ratio > 0 {
            let second = ks.clone().filter(|k| k.abs_diff(best) > 1).map(|k| c[k]).min();
            if let Some(second) = second {
                if u64::from(c[best]) * u64::from(100 + sel.uniqueness_ratio) > u64::from(second) * 100 {
                    *o = tagged_nan(PixelStatus::Ambiguous);
                    continue;
                }
            }
        }
        let d_int = sel.range.min as i64 + best as i64;
        if let Some(max_diff) = sel.lr_max_diff {
            let xr = x as i64 - d_int;
            let kr = right_best[xr as usize];
            if kr == usize::MAX || (kr as f32 - best as f32).abs() > max_diff {
                *o = lr_failure(kr != usize::MAX && kr > best);
                continue;
            }
        }
        let offset = if best > ks.start && best + 1 < ks.end {
            subpixel_offset(sel.subpixel, f32::from(c[best - 1]), f32::from(c[best]), f32::from(c[best + 1]))
        } else {
            0.0
        };
        *o = d_int as f32 + offset;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn feasible_ranges_respect_the_image_borders() {
        let range = DisparityRange { min: 0, max: 16 };
        assert_eq!(feasible_left(0, 100, range), 0..1);
        assert_eq!(feasible_left(5, 100, range), 0..6);
        assert_eq!(feasible_left(50, 100, range), 0..16);
        assert_eq!(feasible_right(99, 100, range), 0..1);
        assert_eq!(feasible_right(10, 100, range), 0..16);
        let negative = DisparityRange { min: -4, max: 4 };
        assert_eq!(feasible_left(98, 100, negative), 3..8);
        assert_eq!(feasible_right(0, 100, negative), 4..8);
    }

    #[test]
    fn subpixel_fits_find_the_true_minimum_of_symmetric_shapes() {
        // V shape with its tip at +0.25: equiangular is exact.
        let v = |t: f32| (t - 0.25).abs();
        assert!((subpixel_offset(Subpixel::Equiangular, v(-1.0), v(0.0), v(1.0)) - 0.25).abs() < 1e-6);
        // Parabola with its minimum at -0.3: the parabola fit is exact.
        let p = |t: f32| (t + 0.3) * (t + 0.3);
        assert!((subpixel_offset(Subpixel::Parabola, p(-1.0), p(0.0), p(1.0)) + 0.3).abs() < 1e-6);
        assert_eq!(subpixel_offset(Subpixel::None, 3.0, 1.0, 2.0), 0.0);
    }
}
