//! Winner-takes-all disparity selection over an aggregated cost volume (`[y][x][d]`), with
//! subpixel refinement, the uniqueness test and the left-right consistency check.

use crate::kernels::{self, Level};
use crate::status::{tagged_nan, PixelStatus};
#[cfg(test)]
use crate::winner::subpixel_offset;
use crate::winner::{ambiguous, left_right_check, refined_offset, right_view_winners, Ties, WinnerIndex};
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
    /// [`crate::SgmParams::lr_left_neighbour`].
    pub lr_left_neighbour: bool,
    pub subpixel: Subpixel,
}

/// The disparity indices `k` (disparity `range.min + k`) for which left pixel `x` has a match
/// inside a right image `width` pixels wide.
#[inline]
pub(crate) fn feasible_left(x: usize, width: usize, range: DisparityRange) -> std::ops::Range<usize> {
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

/// Per-thread buffers of [`select_row`], allocated once per pass.
pub(crate) struct WtaScratch {
    /// Right view, indexed by `width - 1 - xr`: the best cost so far and its disparity index.
    right_cost: Vec<u16>,
    right_index: Vec<u16>,
    /// Left view: each pixel's winning disparity index (fused AVX2, AVX-512 and NEON kernels).
    #[cfg_attr(not(any(target_arch = "x86_64", target_arch = "aarch64")), allow(dead_code))]
    left_best: Vec<u16>,
    /// The winner's cost and its two neighbours' (the winner's own where it has none), for the
    /// subpixel fits done 16 pixels at a time after the row (fused AVX-512 kernel).
    #[cfg_attr(not(target_arch = "x86_64"), allow(dead_code))]
    around: [Vec<u16>; 3],
}

impl WtaScratch {
    pub(crate) fn new(width: usize) -> Self {
        WtaScratch {
            right_cost: vec![0; width],
            right_index: vec![0; width],
            left_best: vec![0; width],
            around: std::array::from_fn(|_| vec![0; width]),
        }
    }

    pub(crate) fn bytes(width: usize) -> usize {
        width.saturating_mul(12)
    }
}

/// Marks a right pixel without any feasible disparity.
const NO_MATCH: u16 = <u16 as WinnerIndex>::NONE;

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
    // Up to 16 disparities AVX-512 CPUs take the AVX2 sweep: a 32-lane register would be half
    // padding.
    #[cfg(target_arch = "x86_64")]
    if kernels::features().level.avx512() && nd > 16 && nd <= fused::MAX_DISPARITIES {
        // SAFETY: the AVX-512 level was detected on this CPU.
        return unsafe { fused::select_row_avx512(costs, width, nd, sel, scratch, out) };
    }
    #[cfg(target_arch = "x86_64")]
    if matches!(kernels::features().level, Level::Avx2 | Level::Avx512) && fused_avx2::applies(nd, width) {
        // SAFETY: both levels are only chosen when the CPU has AVX2 (AVX-512 CPUs have it).
        return unsafe { fused_avx2::select_row_avx2(costs, width, nd, sel, scratch, out) };
    }
    #[cfg(target_arch = "aarch64")]
    if kernels::features().level == Level::Neon && fused_neon::applies(nd, width) {
        // SAFETY: the NEON level is only chosen when the CPU has NEON.
        return unsafe { fused_neon::select_row_neon(costs, width, nd, sel, scratch, out) };
    }
    select_row_levels(costs, width, nd, sel, scratch, out)
}

/// The end of the fused kernels' sweep: stores the right view's final winners (`final_index[k]`,
/// disparity index `k`, is right pixel `min − 1 + k` in `right_index`'s `width − 1 − xr` order),
/// then runs the left-right check on every selected pixel of `out` (winners in `left_best`).
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
fn check_left_right(
    sel: Selection,
    final_index: &[u16],
    right_index: &mut [u16],
    left_best: &[u16],
    out: &mut [f32],
) {
    let (width, min) = (right_index.len(), sel.range.min as i64);
    for (k, &kr) in final_index.iter().enumerate() {
        let q = min - 1 + k as i64;
        if (0..width as i64).contains(&q) {
            right_index[q as usize] = kr;
        }
    }
    let max_diff = sel.lr_max_diff.unwrap_or(f32::INFINITY);
    for (x, o) in out.iter_mut().enumerate() {
        if o.is_nan() {
            continue;
        }
        let best = usize::from(left_best[x]);
        let xr = x as i64 - min - best as i64;
        if let Err(occluded) =
            left_right_check(right_index, xr, best as f32, 0, max_diff, sel.lr_left_neighbour)
        {
            *o = lr_failure(occluded);
        }
    }
}

/// The right view's winner (disparity index) of right pixel `q` (in `right_index`'s `width − 1 −
/// xr` order) from the left pixel `x` it was found at, [`NO_MATCH`] kept: the AVX2 and NEON
/// kernels' windows keep the pixel instead of the index.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
#[inline(always)]
fn index_from_pixel(x: u16, q: i64, width: usize, min: i64) -> u16 {
    if x == NO_MATCH {
        NO_MATCH
    } else {
        // Right pixel xr = width − 1 − q matched left pixel x at disparity min + k = x − xr.
        (i64::from(x) - (width as i64 - 1 - q) - min) as u16
    }
}

#[cfg(target_arch = "x86_64")]
mod fused_avx2;
#[cfg(target_arch = "aarch64")]
mod fused_neon;

kernels::multiversion! {
    /// [`select_row_generic`] compiled for the detected level, with the SIMD kernels inlined.
    fn select_row_levels(
        costs: &[u16],
        width: usize,
        nd: usize,
        sel: Selection,
        scratch: &mut WtaScratch,
        out: &mut [f32],
    ) => select_row_generic;
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
        right_view_winners(
            sel.range.min as i64,
            |x| &costs[x * nd..(x + 1) * nd],
            |x| feasible_left(x, width, sel.range),
            |c, first, best, index| kernels::keep_smaller(level, c, first as u16, best, index),
            u16::MAX,
            &mut scratch.right_cost[..width],
            &mut scratch.right_index[..width],
        );
    }

    for (x, o) in out[..width].iter_mut().enumerate() {
        *o = tagged_nan(PixelStatus::NoMatch);
        let ks = feasible_left(x, width, sel.range);
        if ks.is_empty() {
            continue;
        }
        let c = &costs[x * nd..(x + 1) * nd];
        let best = ks.start + kernels::argmin(level, &c[ks.clone()]).1;
        if ambiguous(c, ks.clone(), best, sel.uniqueness_ratio, Ties::Unique) {
            *o = tagged_nan(PixelStatus::Ambiguous);
            continue;
        }
        let d_int = sel.range.min as i64 + best as i64;
        if let Some(max_diff) = sel.lr_max_diff {
            let right_index = &scratch.right_index[..width];
            if let Err(occluded) = left_right_check(
                right_index,
                x as i64 - d_int,
                best as f32,
                0,
                max_diff,
                sel.lr_left_neighbour,
            ) {
                *o = lr_failure(occluded);
                continue;
            }
        }
        *o = d_int as f32 + refined_offset(c, ks, best, sel.subpixel);
    }
}

/// Winner-takes-all in one sweep over the row with AVX-512BW, both views at once.
///
/// The right view's candidates for right pixel `q = width - 1 - xr` come from the left pixels
/// `x = xr + min + k`: as `x` grows by one the `nd` right pixels it can match move down by one.
/// So the right view's running minima live in registers as a window of `nd` lanes (lane `k` is
/// right pixel `width - 1 - x + min + k`), shifted up by one lane per pixel; the lane that leaves
/// is final and is stored. This replaces a read-modify-write of a memory window that overlaps
/// the previous pixel's by all but one lane, which stalls on store forwarding at every pixel.
/// The left-right check runs in a second, per-pixel loop once every right pixel is final.
#[cfg(target_arch = "x86_64")]
mod fused {
    use std::arch::x86_64::*;

    use super::{check_left_right, feasible_left, tagged_nan, PixelStatus, Selection, WtaScratch, NO_MATCH};
    use crate::Subpixel;

    /// Registers of 32 lanes per window array: up to 8, i.e. 256 disparities.
    const MAX_VECTORS: usize = 8;
    pub(super) const MAX_DISPARITIES: usize = 32 * MAX_VECTORS;

    /// Lanes `lo..hi` of the 32-lane block starting at lane `base`.
    #[inline(always)]
    fn lane_mask(lo: usize, hi: usize, base: usize) -> __mmask32 {
        let lo = lo.clamp(base, base + 32) - base;
        let hi = hi.clamp(base, base + 32) - base;
        let upto = |n: usize| if n >= 32 { u32::MAX } else { (1u32 << n) - 1 };
        upto(hi) & !upto(lo)
    }

    /// [`super::select_row`] for `nd <= MAX_DISPARITIES`.
    ///
    /// # Safety
    /// The CPU must have AVX-512F/BW/VL; `costs` holds at least `width * nd` entries and `out`
    /// at least `width`.
    #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,popcnt")]
    pub(super) unsafe fn select_row_avx512(
        costs: &[u16],
        width: usize,
        nd: usize,
        sel: Selection,
        scratch: &mut WtaScratch,
        out: &mut [f32],
    ) {
        match nd.div_ceil(32) {
            0 | 1 => sweep::<1>(costs, width, nd, sel, scratch, out),
            2 => sweep::<2>(costs, width, nd, sel, scratch, out),
            3 => sweep::<3>(costs, width, nd, sel, scratch, out),
            4 => sweep::<4>(costs, width, nd, sel, scratch, out),
            5 => sweep::<5>(costs, width, nd, sel, scratch, out),
            6 => sweep::<6>(costs, width, nd, sel, scratch, out),
            7 => sweep::<7>(costs, width, nd, sel, scratch, out),
            _ => sweep::<8>(costs, width, nd, sel, scratch, out),
        }
    }

    /// # Safety
    /// As [`select_row_avx512`], with `nd <= 32 * NV`.
    #[inline]
    #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,popcnt")]
    unsafe fn sweep<const NV: usize>(
        costs: &[u16],
        width: usize,
        nd: usize,
        sel: Selection,
        scratch: &mut WtaScratch,
        out: &mut [f32],
    ) {
        assert!(nd <= 32 * NV && costs.len() >= width * nd && out.len() >= width);
        let lr = sel.lr_max_diff.is_some();
        let min = sel.range.min as i64;
        let uniqueness_limit = (sel.uniqueness_ratio > 0).then(|| 100 + u64::from(sel.uniqueness_ratio));
        let ones = _mm512_set1_epi16(-1);
        let iota = _mm512_set_epi16(
            31, 30, 29, 28, 27, 26, 25, 24, 23, 22, 21, 20, 19, 18, 17, 16, 15, 14, 13, 12, 11, 10, 9, 8, 7,
            6, 5, 4, 3, 2, 1, 0,
        );
        // Lane l takes lane 31 of the lower block (index 31) for l = 0, else its own lane l - 1.
        let shift_up = _mm512_add_epi16(iota, _mm512_set1_epi16(31));
        let index: [__m512i; NV] =
            std::array::from_fn(|j| _mm512_add_epi16(iota, _mm512_set1_epi16(32 * j as i16)));
        let mut window_cost = [ones; NV];
        let mut window_index = [ones; NV];
        let right_index = &mut scratch.right_index[..width];
        let left_best = &mut scratch.left_best[..width];
        let around = &mut scratch.around;
        right_index.fill(NO_MATCH);
        let (top_vector, top_lane) = ((nd.max(1) - 1) / 32, (nd.max(1) - 1) % 32);
        let full: [__mmask32; NV] = std::array::from_fn(|j| lane_mask(0, nd, 32 * j));
        for x in 0..width {
            let ks = feasible_left(x, width, sel.range);
            let feasible: [__mmask32; NV] = if ks.start == 0 && ks.end == nd {
                full
            } else {
                std::array::from_fn(|j| lane_mask(ks.start, ks.end, 32 * j))
            };
            // SAFETY: the loads are masked to this pixel's `nd` entries of `costs`.
            let c: [__m512i; NV] = std::array::from_fn(|j| {
                _mm512_mask_loadu_epi16(ones, full[j], costs.as_ptr().add(x * nd + 32 * j).cast())
            });
            if lr {
                for j in 0..NV {
                    let better = _mm512_mask_cmplt_epu16_mask(feasible[j], c[j], window_cost[j]);
                    window_cost[j] = _mm512_mask_mov_epi16(window_cost[j], better, c[j]);
                    window_index[j] = _mm512_mask_mov_epi16(window_index[j], better, index[j]);
                }
                // Lane nd - 1 (right pixel q) gets no more candidates: store it, then shift.
                let q = width as i64 - 1 - x as i64 + min + nd as i64 - 1;
                if (0..width as i64).contains(&q) {
                    let lane0 = right_index.as_mut_ptr().wrapping_offset(q as isize - top_lane as isize);
                    // SAFETY: the store is masked to the one lane that lands on `right_index[q]`.
                    _mm512_mask_storeu_epi16(lane0.cast(), 1 << top_lane, window_index[top_vector]);
                }
                for j in (0..NV).rev() {
                    let (below_cost, below_index) =
                        if j == 0 { (ones, ones) } else { (window_cost[j - 1], window_index[j - 1]) };
                    window_cost[j] = _mm512_permutex2var_epi16(below_cost, shift_up, window_cost[j]);
                    window_index[j] = _mm512_permutex2var_epi16(below_index, shift_up, window_index[j]);
                }
            }
            out[x] = tagged_nan(PixelStatus::NoMatch);
            if ks.is_empty() {
                continue;
            }
            let mut m = ones;
            for j in 0..NV {
                m = _mm512_mask_min_epu16(m, feasible[j], m, c[j]);
            }
            let best_cost = hmin_epu16(m);
            let target = _mm512_set1_epi16(best_cost as i16);
            let mut best = 0;
            for j in 0..NV {
                let hit = _mm512_mask_cmpeq_epu16_mask(feasible[j], c[j], target);
                if hit != 0 {
                    best = 32 * j + hit.trailing_zeros() as usize;
                    break;
                }
            }
            // The uniqueness test of [`ambiguous`] on the registers, without a second
            // horizontal minimum (it would lengthen each pixel's dependency chain): ambiguous
            // when a feasible disparity more than one index away from the winner costs `c` with
            // `c · 100 < best · (100 + ratio)`, i.e. `c <= threshold`. A sum of `u16::MAX` never
            // counts (no sum of path costs reaches it; the reference's "no second" case).
            let ambiguous = uniqueness_limit.is_some_and(|factor| {
                let limit = u64::from(best_cost) * factor;
                limit > 0 && {
                    let threshold =
                        _mm512_set1_epi16(((limit - 1) / 100).min(u64::from(u16::MAX - 1)) as i16);
                    (0..NV).any(|j| {
                        let near_best = lane_mask(best.saturating_sub(1), best + 2, 32 * j);
                        _mm512_mask_cmple_epu16_mask(feasible[j] & !near_best, c[j], threshold) != 0
                    })
                }
            });
            let c = &costs[x * nd..(x + 1) * nd];
            if ambiguous {
                out[x] = tagged_nan(PixelStatus::Ambiguous);
                continue;
            }
            left_best[x] = best as u16;
            let interior = best > ks.start && best + 1 < ks.end;
            let at = c[best];
            let (before, after) = if interior { (c[best - 1], c[best + 1]) } else { (at, at) };
            (around[0][x], around[1][x], around[2][x]) = (before, at, after);
            out[x] = (min + best as i64) as f32;
        }
        if sel.subpixel != Subpixel::None {
            add_subpixel_offsets(sel.subpixel, around, &mut out[..width]);
        }
        if !lr {
            return;
        }
        // After the last pixel's shift every lane is final: lane k is right pixel min - 1 + k.
        let mut lanes = [0u16; 32 * MAX_VECTORS];
        for (j, v) in window_index.iter().enumerate() {
            // SAFETY: 32 lanes into `lanes[32 j..32 j + 32]`, `j < NV <= MAX_VECTORS`.
            _mm512_storeu_si512(lanes.as_mut_ptr().add(32 * j).cast(), *v);
        }
        check_left_right(sel, &lanes[..nd], right_index, left_best, &mut out[..width]);
    }

    /// Adds [`crate::winner::subpixel_offset`] of each pixel's `around` costs to its integer disparity in
    /// `out`, 16 pixels per instruction and with the same floating-point operations in the same
    /// order (so the same roundings); NaN pixels (rejected) keep their tagged NaN. Pixels at the
    /// end of their feasible range carry their own cost as both neighbours, whose fit is 0.
    #[target_feature(enable = "avx512f,avx512bw,avx512vl")]
    fn add_subpixel_offsets(method: Subpixel, around: &[Vec<u16>; 3], out: &mut [f32]) {
        let width = out.len();
        let (zero, half, two) = (_mm512_setzero_ps(), _mm512_set1_ps(0.5), _mm512_set1_ps(2.0));
        let mut x = 0;
        while x < width {
            let n = (width - x).min(16);
            let mask: __mmask16 = if n == 16 { !0 } else { (1u16 << n) - 1 };
            // SAFETY: the loads and the store are masked to pixels `x..x + n` of `width`, which
            // every `around` array and `out` hold.
            let load = |v: &Vec<u16>| unsafe {
                _mm512_cvtepi32_ps(_mm512_cvtepu16_epi32(_mm256_maskz_loadu_epi16(
                    mask,
                    v.as_ptr().add(x).cast(),
                )))
            };
            let (before, best, after) = (load(&around[0]), load(&around[1]), load(&around[2]));
            let offset = match method {
                Subpixel::None => zero,
                Subpixel::Parabola => {
                    let curvature = _mm512_add_ps(_mm512_sub_ps(before, _mm512_mul_ps(two, best)), after);
                    let fit = _mm512_div_ps(_mm512_sub_ps(before, after), _mm512_mul_ps(two, curvature));
                    _mm512_maskz_mov_ps(_mm512_cmp_ps_mask::<_CMP_GT_OQ>(curvature, zero), fit)
                }
                Subpixel::Equiangular => {
                    let slope = _mm512_max_ps(_mm512_sub_ps(before, best), _mm512_sub_ps(after, best));
                    let fit = _mm512_div_ps(_mm512_sub_ps(before, after), _mm512_mul_ps(two, slope));
                    _mm512_maskz_mov_ps(_mm512_cmp_ps_mask::<_CMP_GT_OQ>(slope, zero), fit)
                }
            };
            let offset = _mm512_max_ps(_mm512_min_ps(offset, half), _mm512_sub_ps(zero, half));
            let o = unsafe { _mm512_maskz_loadu_ps(mask, out.as_ptr().add(x)) };
            let valid = _mm512_cmp_ps_mask::<_CMP_ORD_Q>(o, o) & mask;
            unsafe { _mm512_mask_storeu_ps(out.as_mut_ptr().add(x), valid, _mm512_add_ps(o, offset)) };
            x += 16;
        }
    }

    /// Minimum of the 32 unsigned 16-bit lanes.
    #[inline]
    #[target_feature(enable = "avx512f,avx512bw,avx512vl")]
    fn hmin_epu16(v: __m512i) -> u16 {
        let m = _mm256_min_epu16(_mm512_castsi512_si256(v), _mm512_extracti64x4_epi64::<1>(v));
        let m = _mm_min_epu16(_mm256_castsi256_si128(m), _mm256_extracti128_si256::<1>(m));
        _mm_extract_epi16::<0>(_mm_minpos_epu16(m)) as u16
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
                if u64::from(c[best]) * (100 + u64::from(sel.uniqueness_ratio)) > u64::from(second) * 100 {
                    *o = tagged_nan(PixelStatus::Ambiguous);
                    continue;
                }
            }
        }
        let d_int = sel.range.min as i64 + best as i64;
        if let Some(max_diff) = sel.lr_max_diff {
            let xr = x as i64 - d_int;
            let kr = right_best[xr as usize];
            let agrees = |k: usize| k != usize::MAX && (k as f32 - best as f32).abs() <= max_diff;
            let occluded = kr != usize::MAX && kr > best;
            let neighbour =
                sel.lr_left_neighbour && occluded && xr >= 1 && agrees(right_best[xr as usize - 1]);
            if !agrees(kr) && !neighbour {
                *o = lr_failure(occluded);
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

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(256))]
        /// Every selection kernel this CPU runs gives the reference's bits, ties included
        /// (costs from a small range), for any range, border and check.
        #[test]
        fn selection_kernels_match_the_reference(
            width in 1usize..90, nd in 1usize..300, min in -20i32..40, spread in 1u16..40,
            seed in proptest::prelude::any::<u64>(), uniqueness in 0u32..3, lr in proptest::prelude::any::<Option<u8>>(),
            sub in 0u8..3, neighbour in proptest::prelude::any::<bool>(),
        ) {
            let mut state = seed | 1;
            let costs: Vec<u16> = (0..width * nd)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    (state % u64::from(spread)) as u16 * 37
                })
                .collect();
            let sel = Selection {
                range: DisparityRange { min, max: min + nd as i32 },
                uniqueness_ratio: uniqueness * 7,
                lr_max_diff: lr.map(|d| f32::from(d % 4)),
                lr_left_neighbour: neighbour,
                subpixel: [Subpixel::None, Subpixel::Parabola, Subpixel::Equiangular][usize::from(sub)],
            };
            let mut expected = vec![0f32; width];
            crate::wta::select_row_reference(&costs, width, nd, sel, &mut vec![0; width], &mut expected);
            let mut scratch = WtaScratch::new(width);
            let mut runs: Vec<(&str, Vec<f32>)> = Vec::new();
            let mut generic = vec![0f32; width];
            select_row_generic(&costs, width, nd, sel, &mut scratch, &mut generic, Level::Scalar);
            runs.push(("generic", generic));
            let mut dispatched = vec![0f32; width];
            select_row(&costs, width, nd, sel, &mut scratch, &mut dispatched);
            runs.push(("select_row", dispatched));
            #[cfg(target_arch = "x86_64")]
            if kernels::supported_levels().contains(&Level::Avx512) && nd <= fused::MAX_DISPARITIES {
                let mut f = vec![0f32; width];
                // SAFETY: AVX-512 is supported (checked above); the lengths fit.
                unsafe { fused::select_row_avx512(&costs, width, nd, sel, &mut scratch, &mut f) };
                runs.push(("fused", f));
            }
            #[cfg(target_arch = "x86_64")]
            if kernels::supported_levels().contains(&Level::Avx2) && fused_avx2::applies(nd, width) {
                let mut f = vec![0f32; width];
                // SAFETY: AVX2 is supported (checked above); the lengths fit.
                unsafe { fused_avx2::select_row_avx2(&costs, width, nd, sel, &mut scratch, &mut f) };
                runs.push(("fused AVX2", f));
            }
            #[cfg(target_arch = "aarch64")]
            if kernels::supported_levels().contains(&Level::Neon) && fused_neon::applies(nd, width) {
                let mut f = vec![0f32; width];
                // SAFETY: NEON is supported (checked above); the lengths fit.
                unsafe { fused_neon::select_row_neon(&costs, width, nd, sel, &mut scratch, &mut f) };
                runs.push(("fused NEON", f));
            }
            for (name, got) in runs {
                for (x, (a, b)) in got.iter().zip(&expected).enumerate() {
                    proptest::prop_assert!(a.to_bits() == b.to_bits(), "{} pixel {}: {} vs {}", name, x, a, b);
                }
            }
        }
    }

    /// The uniqueness test at its boundary, which random costs seldom hit: a second-best sum of
    /// exactly `best · (100 + ratio) / 100` keeps the pixel, one less rejects it, in every kernel.
    #[test]
    fn uniqueness_boundary_matches_the_reference() {
        let (width, nd) = (40, 24);
        for (second, ambiguous) in [(107u16, false), (106, true)] {
            let costs: Vec<u16> = (0..width * nd)
                .map(|i| match i % nd {
                    9 => 100,
                    10 => 101,
                    17 => second,
                    _ => 500,
                })
                .collect();
            let sel = Selection {
                range: DisparityRange { min: 0, max: nd as i32 },
                uniqueness_ratio: 7,
                lr_max_diff: None,
                lr_left_neighbour: false,
                subpixel: Subpixel::None,
            };
            let mut expected = vec![0f32; width];
            select_row_reference(&costs, width, nd, sel, &mut vec![0; width], &mut expected);
            assert_eq!(expected[30].is_nan(), ambiguous);
            let mut scratch = WtaScratch::new(width);
            let mut got = vec![0f32; width];
            select_row(&costs, width, nd, sel, &mut scratch, &mut got);
            let mut generic = vec![0f32; width];
            select_row_generic(&costs, width, nd, sel, &mut scratch, &mut generic, Level::Scalar);
            for ((a, b), c) in got.iter().zip(&generic).zip(&expected) {
                assert_eq!(a.to_bits(), c.to_bits());
                assert_eq!(b.to_bits(), c.to_bits());
            }
        }
    }

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
