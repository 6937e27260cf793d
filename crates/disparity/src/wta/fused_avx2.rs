//! Winner-takes-all in one sweep over the row with AVX2, both views at once: the NEON kernel's
//! scheme ([`super::fused_neon`] on aarch64, itself the AVX-512 `fused` kernel's) on 16-lane
//! `u16` registers.
//!
//! The right view's running minima live in registers as a window of `nd` lanes, shifted up by
//! one lane per pixel (a 128-bit-lane permutation and a byte alignment per register). The window
//! is laid out top-aligned: lane position `p` holds disparity index `k = p − pad` (`pad = 16·NV −
//! nd`), so disparity `nd − 1`, the one whose right pixel gets no more candidates, is always
//! lane 15 of the last register and leaves by one lane extraction; each pixel's costs are loaded
//! from `pad` entries before its own (the previous pixel's, masked out), so no load reaches past
//! the pixel's `nd` sums. The window keeps the left pixel each minimum was found at, not its
//! disparity: one broadcast per pixel instead of a register of indices per 16 lanes.

use std::arch::x86_64::*;

use super::{
    check_left_right, feasible_left, index_from_pixel, tagged_nan, PixelStatus, Selection, WtaScratch,
    NO_MATCH,
};
use crate::kernels::hmin_epu16_256;
use crate::winner::refined_offset;

/// Registers of 16 lanes per window array: up to 8, i.e. 128 disparities. Past 4 the windows no
/// longer fit the 16 registers beside the costs and spill at every pixel, yet the sweep still
/// takes fewer instructions than the generic selection (wood2, 112 disparities: 95.5 against
/// 163.9 million under callgrind) at about its speed.
const MAX_VECTORS: usize = 8;
const MAX_DISPARITIES: usize = 16 * MAX_VECTORS;

/// Whether [`select_row_avx2`] takes rows of `nd` disparities and `width` pixels.
pub(super) fn applies(nd: usize, width: usize) -> bool {
    nd <= MAX_DISPARITIES && width < usize::from(NO_MATCH)
}

/// [`super::select_row`] where [`applies`] holds.
///
/// # Safety
/// The CPU must have AVX2; `costs` holds at least `width * nd` entries and `out` at least
/// `width`.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn select_row_avx2(
    costs: &[u16],
    width: usize,
    nd: usize,
    sel: Selection,
    scratch: &mut WtaScratch,
    out: &mut [f32],
) {
    match nd.div_ceil(16) {
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

/// Lanes whose disparity index (`index`, signed) lies in `lo..hi`.
#[inline]
#[target_feature(enable = "avx2")]
fn in_range(index: __m256i, lo: usize, hi: usize) -> __m256i {
    let above_lo = _mm256_cmpgt_epi16(index, _mm256_set1_epi16(lo as i16 - 1));
    _mm256_and_si256(above_lo, _mm256_cmpgt_epi16(_mm256_set1_epi16(hi as i16), index))
}

/// `v` shifted up by one 16-bit lane, lane 0 taking the last lane of `below`.
#[inline]
#[target_feature(enable = "avx2")]
fn shift_up(below: __m256i, v: __m256i) -> __m256i {
    _mm256_alignr_epi8::<14>(v, _mm256_permute2x128_si256::<0x03>(v, below))
}

/// # Safety
/// As [`select_row_avx2`], with `0 < nd <= 16 * NV` and `width < NO_MATCH`.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn sweep<const NV: usize>(
    costs: &[u16],
    width: usize,
    nd: usize,
    sel: Selection,
    scratch: &mut WtaScratch,
    out: &mut [f32],
) {
    assert!(nd > 0 && nd <= 16 * NV && costs.len() >= width * nd && out.len() >= width);
    assert!(width < usize::from(NO_MATCH));
    let lr = sel.lr_max_diff.is_some();
    let min = sel.range.min as i64;
    let uniqueness_limit = (sel.uniqueness_ratio > 0).then(|| 100 + u64::from(sel.uniqueness_ratio));
    let pad = 16 * NV - nd;
    let ones = _mm256_set1_epi16(-1);
    let iota = _mm256_setr_epi16(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    // Lane l of register j holds disparity index 16 j + l − pad.
    let index = |j: usize| _mm256_add_epi16(iota, _mm256_set1_epi16((16 * j) as i16 - pad as i16));
    // Where every disparity is feasible only register 0's first `pad` lanes (the previous
    // pixel's sums) are not.
    let before_first = _mm256_andnot_si256(in_range(index(0), 0, nd), ones);
    // The right view's running minima and the left pixel each was found at.
    let mut window_cost = [ones; NV];
    let mut window_pixel = [ones; NV];
    let right_index = &mut scratch.right_index[..width];
    let left_best = &mut scratch.left_best[..width];
    right_index.fill(NO_MATCH);
    if width == 0 {
        return;
    }
    // Where the `pad` entries before a pixel's costs would start before `costs` (the first
    // pixel, and the next few when `nd < pad`), its costs are staged after `pad` infeasible ones.
    let mut staged = [u16::MAX; 16 * MAX_VECTORS];
    for x in 0..width {
        let ks = feasible_left(x, width, sel.range);
        let interior = ks.start == 0 && ks.end == nd;
        let base = if x * nd >= pad {
            // SAFETY: entries `x·nd − pad .. x·nd + nd` of `costs` (the `pad` before this
            // pixel's are the previous pixels', masked below).
            costs.as_ptr().add(x * nd - pad)
        } else {
            staged[pad..pad + nd].copy_from_slice(&costs[x * nd..(x + 1) * nd]);
            staged.as_ptr()
        };
        // Infeasible lanes read as u16::MAX: never a winner, never below a window's minimum.
        let mut c: [__m256i; NV] = std::array::from_fn(|j| _mm256_loadu_si256(base.add(16 * j).cast()));
        if interior {
            c[0] = _mm256_or_si256(c[0], before_first);
        } else {
            for (j, c) in c.iter_mut().enumerate() {
                *c = _mm256_or_si256(*c, _mm256_andnot_si256(in_range(index(j), ks.start, ks.end), ones));
            }
        }
        if lr {
            let here = _mm256_set1_epi16(x as i16);
            for j in 0..NV {
                // Lanes where the window's minimum stays (not above the new cost).
                let stays = _mm256_cmpeq_epi16(_mm256_min_epu16(window_cost[j], c[j]), window_cost[j]);
                window_cost[j] = _mm256_min_epu16(window_cost[j], c[j]);
                window_pixel[j] = _mm256_blendv_epi8(here, window_pixel[j], stays);
            }
            // Disparity nd − 1 (right pixel q) gets no more candidates: store it, then shift.
            let q = width as i64 - 1 - x as i64 + min + nd as i64 - 1;
            if (0..width as i64).contains(&q) {
                let found_at = _mm256_extract_epi16::<15>(window_pixel[NV - 1]) as u16;
                right_index[q as usize] = index_from_pixel(found_at, q, width, min);
            }
            for j in (0..NV).rev() {
                let (below_cost, below_pixel) =
                    if j == 0 { (ones, ones) } else { (window_cost[j - 1], window_pixel[j - 1]) };
                window_cost[j] = shift_up(below_cost, window_cost[j]);
                window_pixel[j] = shift_up(below_pixel, window_pixel[j]);
            }
        }
        out[x] = tagged_nan(PixelStatus::NoMatch);
        if ks.is_empty() {
            continue;
        }
        let mut m = c[0];
        for v in &c[1..] {
            m = _mm256_min_epu16(m, *v);
        }
        let best_cost = hmin_epu16_256(m);
        let target = _mm256_set1_epi16(best_cost as i16);
        // The lowest feasible index at the minimum (ties go to the lowest disparity). Clamped to
        // `ks.start`: were every feasible sum u16::MAX (no sum of path costs reaches it), the
        // infeasible lanes below would match too.
        let mut best = ks.start;
        for (j, &v) in c.iter().enumerate() {
            let hit = _mm256_movemask_epi8(_mm256_cmpeq_epi16(v, target)) as u32;
            if hit != 0 {
                let lane = hit.trailing_zeros() as usize / 2;
                best = (16 * j + lane).saturating_sub(pad).max(ks.start);
                break;
            }
        }
        // The uniqueness test of the AVX-512 kernel: ambiguous when a feasible disparity more
        // than one index away from the winner costs at most `threshold` (infeasible lanes read
        // as u16::MAX, above any threshold).
        let ambiguous = uniqueness_limit.is_some_and(|factor| {
            let limit = u64::from(best_cost) * factor;
            limit > 0 && {
                let threshold = _mm256_set1_epi16(((limit - 1) / 100).min(u64::from(u16::MAX - 1)) as i16);
                let mut any = _mm256_setzero_si256();
                for (j, &v) in c.iter().enumerate() {
                    let near = in_range(index(j), best.saturating_sub(1), best + 2);
                    let at_most = _mm256_cmpeq_epi16(_mm256_min_epu16(v, threshold), v);
                    any = _mm256_or_si256(any, _mm256_andnot_si256(near, at_most));
                }
                _mm256_movemask_epi8(any) != 0
            }
        });
        if ambiguous {
            out[x] = tagged_nan(PixelStatus::Ambiguous);
            continue;
        }
        left_best[x] = best as u16;
        let c = &costs[x * nd..(x + 1) * nd];
        out[x] = (min + best as i64) as f32 + refined_offset(c, ks, best, sel.subpixel);
    }
    if !lr {
        return;
    }
    // After the last pixel's shift every lane is final: disparity index k (lane position
    // k + pad) is right pixel q = min − 1 + k.
    let mut lanes = [0u16; 16 * MAX_VECTORS];
    for (j, v) in window_pixel.iter().enumerate() {
        // SAFETY: 16 lanes into `lanes[16 j..16 j + 16]`, `j < NV <= MAX_VECTORS`.
        _mm256_storeu_si256(lanes.as_mut_ptr().add(16 * j).cast(), *v);
    }
    let final_index: [u16; 16 * MAX_VECTORS] = std::array::from_fn(|k| {
        if k < nd {
            index_from_pixel(lanes[k + pad], min - 1 + k as i64, width, min)
        } else {
            0
        }
    });
    check_left_right(sel, &final_index[..nd], right_index, left_best, &mut out[..width]);
}
