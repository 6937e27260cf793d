//! Winner-takes-all in one sweep over the row with NEON, both views at once: the scheme of the
//! AVX-512 `fused` kernel (see there) on 8-lane `u16` registers.
//!
//! The right view's running minima live in registers as a window of `nd` lanes, shifted up by
//! one lane per pixel (`EXT` across the registers). The window is laid out top-aligned: lane
//! position `p` holds disparity index `k = p − pad` (`pad = 8·NV − nd`), so disparity `nd − 1`,
//! the one whose right pixel gets no more candidates, is always lane 7 of the last register and
//! leaves by one lane extraction; each pixel's costs are loaded from `pad` entries before its
//! own (the previous pixel's, masked out), so no load reaches past the pixel's `nd` sums.

use std::arch::aarch64::*;

use super::{
    check_left_right, feasible_left, index_from_pixel, tagged_nan, PixelStatus, Selection, WtaScratch,
    NO_MATCH,
};
use crate::winner::refined_offset;

/// Registers of 8 lanes per window array: up to 16, i.e. 128 disparities (more would spill the
/// windows to the stack at every pixel).
const MAX_VECTORS: usize = 16;
const MAX_DISPARITIES: usize = 8 * MAX_VECTORS;

/// Whether [`select_row_neon`] takes rows of `nd` disparities and `width` pixels.
pub(super) fn applies(nd: usize, width: usize) -> bool {
    nd <= MAX_DISPARITIES && width < usize::from(NO_MATCH)
}

/// [`super::select_row`] where [`applies`] holds.
///
/// # Safety
/// The CPU must have NEON; `costs` holds at least `width * nd` entries and `out` at least
/// `width`.
#[target_feature(enable = "neon")]
pub(super) unsafe fn select_row_neon(
    costs: &[u16],
    width: usize,
    nd: usize,
    sel: Selection,
    scratch: &mut WtaScratch,
    out: &mut [f32],
) {
    match nd.div_ceil(8) {
        0 | 1 => sweep::<1>(costs, width, nd, sel, scratch, out),
        2 => sweep::<2>(costs, width, nd, sel, scratch, out),
        3 => sweep::<3>(costs, width, nd, sel, scratch, out),
        4 => sweep::<4>(costs, width, nd, sel, scratch, out),
        5 => sweep::<5>(costs, width, nd, sel, scratch, out),
        6 => sweep::<6>(costs, width, nd, sel, scratch, out),
        7 => sweep::<7>(costs, width, nd, sel, scratch, out),
        8 => sweep::<8>(costs, width, nd, sel, scratch, out),
        9 => sweep::<9>(costs, width, nd, sel, scratch, out),
        10 => sweep::<10>(costs, width, nd, sel, scratch, out),
        11 => sweep::<11>(costs, width, nd, sel, scratch, out),
        12 => sweep::<12>(costs, width, nd, sel, scratch, out),
        13 => sweep::<13>(costs, width, nd, sel, scratch, out),
        14 => sweep::<14>(costs, width, nd, sel, scratch, out),
        15 => sweep::<15>(costs, width, nd, sel, scratch, out),
        _ => sweep::<16>(costs, width, nd, sel, scratch, out),
    }
}

/// Lanes whose disparity index (`index`, signed) lies in `lo..hi`.
#[inline(always)]
unsafe fn in_range(index: int16x8_t, lo: usize, hi: usize) -> uint16x8_t {
    vandq_u16(vcgeq_s16(index, vdupq_n_s16(lo as i16)), vcltq_s16(index, vdupq_n_s16(hi as i16)))
}

/// # Safety
/// As [`select_row_neon`], with `0 < nd <= 8 * NV` and `width < NO_MATCH`.
#[inline]
#[target_feature(enable = "neon")]
unsafe fn sweep<const NV: usize>(
    costs: &[u16],
    width: usize,
    nd: usize,
    sel: Selection,
    scratch: &mut WtaScratch,
    out: &mut [f32],
) {
    assert!(nd > 0 && nd <= 8 * NV && costs.len() >= width * nd && out.len() >= width);
    assert!(width < usize::from(NO_MATCH));
    let lr = sel.lr_max_diff.is_some();
    let min = sel.range.min as i64;
    let uniqueness_limit = (sel.uniqueness_ratio > 0).then(|| 100 + u64::from(sel.uniqueness_ratio));
    let pad = 8 * NV - nd;
    let ones = vdupq_n_u16(u16::MAX);
    let iota: int16x8_t = vld1q_s16([0i16, 1, 2, 3, 4, 5, 6, 7].as_ptr());
    // Lane l of register j holds disparity index 8 j + l − pad.
    let index = |j: usize| vaddq_s16(iota, vdupq_n_s16((8 * j) as i16 - pad as i16));
    // Where every disparity is feasible only register 0's first `pad` lanes (the previous
    // pixel's sums) are not.
    let before_first = vmvnq_u16(in_range(index(0), 0, nd));
    // The right view's running minima and the left pixel each was found at (so the window
    // needs no per-lane disparity register; the pixel gives the disparity back).
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
    let mut staged = [u16::MAX; 8 * MAX_VECTORS];
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
        let mut c: [uint16x8_t; NV] = std::array::from_fn(|j| vld1q_u16(base.add(8 * j)));
        if interior {
            c[0] = vorrq_u16(c[0], before_first);
        } else {
            for (j, c) in c.iter_mut().enumerate() {
                *c = vorrq_u16(*c, vmvnq_u16(in_range(index(j), ks.start, ks.end)));
            }
        }
        if lr {
            let here = vdupq_n_u16(x as u16);
            for j in 0..NV {
                let better = vcltq_u16(c[j], window_cost[j]);
                window_cost[j] = vbslq_u16(better, c[j], window_cost[j]);
                window_pixel[j] = vbslq_u16(better, here, window_pixel[j]);
            }
            // Disparity nd − 1 (right pixel q) gets no more candidates: store it, then shift.
            let q = width as i64 - 1 - x as i64 + min + nd as i64 - 1;
            if (0..width as i64).contains(&q) {
                let found_at = vgetq_lane_u16::<7>(window_pixel[NV - 1]);
                right_index[q as usize] = index_from_pixel(found_at, q, width, min);
            }
            for j in (0..NV).rev() {
                let (below_cost, below_pixel) =
                    if j == 0 { (ones, ones) } else { (window_cost[j - 1], window_pixel[j - 1]) };
                window_cost[j] = vextq_u16::<7>(below_cost, window_cost[j]);
                window_pixel[j] = vextq_u16::<7>(below_pixel, window_pixel[j]);
            }
        }
        out[x] = tagged_nan(PixelStatus::NoMatch);
        if ks.is_empty() {
            continue;
        }
        let mut m = c[0];
        for v in &c[1..] {
            m = vminq_u16(m, *v);
        }
        let best_cost = vminvq_u16(m);
        let target = vdupq_n_u16(best_cost);
        // The lowest feasible index at the minimum (ties go to the lowest disparity). Clamped to
        // `ks.start`: were every feasible sum u16::MAX (no sum of path costs reaches it), the
        // infeasible lanes below would match too.
        let mut best = ks.start;
        for (j, &v) in c.iter().enumerate() {
            let hit = vceqq_u16(v, target);
            if vmaxvq_u16(hit) != 0 {
                let lane = vminvq_u16(vbslq_u16(hit, vreinterpretq_u16_s16(iota), ones));
                best = (8 * j + usize::from(lane)).saturating_sub(pad).max(ks.start);
                break;
            }
        }
        // The uniqueness test of the AVX-512 kernel: ambiguous when a feasible disparity more
        // than one index away from the winner costs at most `threshold` (infeasible lanes read
        // as u16::MAX, above any threshold).
        let ambiguous = uniqueness_limit.is_some_and(|factor| {
            let limit = u64::from(best_cost) * factor;
            limit > 0 && {
                let threshold = vdupq_n_u16(((limit - 1) / 100).min(u64::from(u16::MAX - 1)) as u16);
                let mut any = vdupq_n_u16(0);
                for (j, &v) in c.iter().enumerate() {
                    let far = vmvnq_u16(in_range(index(j), best.saturating_sub(1), best + 2));
                    any = vorrq_u16(any, vandq_u16(far, vcleq_u16(v, threshold)));
                }
                vmaxvq_u16(any) != 0
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
    let mut lanes = [0u16; 8 * MAX_VECTORS];
    for (j, v) in window_pixel.iter().enumerate() {
        // SAFETY: 8 lanes into `lanes[8 j..8 j + 8]`, `j < NV <= MAX_VECTORS`.
        vst1q_u16(lanes.as_mut_ptr().add(8 * j), *v);
    }
    let final_index: [u16; 8 * MAX_VECTORS] = std::array::from_fn(|k| {
        if k < nd {
            index_from_pixel(lanes[k + pad], min - 1 + k as i64, width, min)
        } else {
            0
        }
    });
    check_left_right(sel, &final_index[..nd], right_index, left_best, &mut out[..width]);
}
