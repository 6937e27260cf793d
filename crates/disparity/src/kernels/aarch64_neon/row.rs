//! The NEON row kernel of [`crate::kernels::row_u8`]: the path steps of a whole row on 8-bit
//! path costs, with the horizontal path kept in registers (as
//! [`crate::kernels::x86_avx512`]'s row kernels do, 16 lanes per register instead of 64).
//!
//! Stepping pixel by pixel ([`super::path_step_u8_neon`] in the aggregation loop) reloads the
//! horizontal path's previous costs three times per register (`d − 1`, `d`, `d + 1`), stores
//! them again, builds each path's input and looks up its P2 per pixel. Here the horizontal path
//! never leaves the registers (its neighbours come from `EXT`), the P2 rows arrive made, and
//! every register's 16-bit sums are stored once for all four paths. The paths continuing from
//! the previous row stay in memory. Only the registers holding disparities are stepped: a last
//! register of padding (`nd` ≤ 16, 33–48, … in lanes padded to 32) has path costs 255 throughout
//! (cost 255 plus anything saturates), so it is only stored. The results are those of
//! [`crate::kernels::scalar::path_step_u8_scalar`] pixel by pixel.

use std::arch::aarch64::*;

use super::store_sums;
use crate::kernels::layout::{FromRow, Trailing};

/// What every pixel step of a row shares.
struct Shape {
    width: usize,
    lanes: usize,
    nd: usize,
    /// Whether a register of padding lanes follows the `NV` stepped ones (`lanes == 16 * NV + 16`).
    pad_register: bool,
    pad: uint8x16_t,
    p1: uint8x16_t,
}

/// A horizontal path's state: its costs at the previous pixel and their minimum.
struct Horizontal<const NV: usize> {
    path: [uint8x16_t; NV],
    min: u8,
}

/// One path step from the previous vector `prev` (with its `d ∓ 1` neighbours `l`, `r`).
#[inline(always)]
unsafe fn step(
    p1: uint8x16_t,
    c: uint8x16_t,
    prev: uint8x16_t,
    l: uint8x16_t,
    r: uint8x16_t,
    prev_min: uint8x16_t,
    jump: uint8x16_t,
) -> uint8x16_t {
    path_vector!(U8_NEON_REGISTERS, c, prev, l, r, p1, jump, prev_min)
}

/// The steps of the `i`-th pixel `x` of a row: the horizontal path `h`, then the paths from
/// the previous row, their sum stored (or added) into `sum`.
///
/// # Safety
/// NEON; lengths as checked by [`crate::kernels::row_u8`], `nd <= 16 * NV <= lanes`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn pixel<const NV: usize, const K: usize>(
    shape: &Shape,
    h: &mut Horizontal<NV>,
    i: usize,
    x: usize,
    cost: &[u8],
    p2: &[u8],
    from_row: &mut [FromRow<'_>; K],
    sum: &mut [u16],
    accumulate: bool,
) {
    let Shape { width, lanes, nd, pad_register, pad, p1 } = *shape;
    let stride = lanes + 2;
    // SAFETY: pixel `x < width` has `lanes >= 16 * NV` costs at `x * lanes`.
    let c: [uint8x16_t; NV] =
        std::array::from_fn(|v| unsafe { vld1q_u8(cost.as_ptr().add(x * lanes + 16 * v)) });
    if i == 0 {
        // Entering the row: the path cost is the matching cost.
        h.path = c;
    } else {
        let jump = vdupq_n_u8(h.min.saturating_add(p2[x]));
        let prev_min = vdupq_n_u8(h.min);
        let prev = h.path;
        for v in 0..NV {
            let lower = if v == 0 { pad } else { prev[v - 1] };
            let upper = if v + 1 == NV { pad } else { prev[v + 1] };
            let (l, r) = (vextq_u8::<15>(lower, prev[v]), vextq_u8::<1>(prev[v], upper));
            h.path[v] = step(p1, c[v], prev[v], l, r, prev_min, jump);
        }
    }
    let mut m = h.path[0];
    for p in &h.path[1..] {
        m = vminq_u8(m, *p);
    }
    h.min = vminvq_u8(m);
    // The 16-bit sums of the low and the high 8 lanes of each register.
    let mut total: [[uint16x8_t; 2]; NV] =
        std::array::from_fn(|v| [vmovl_u8(vget_low_u8(h.path[v])), vmovl_high_u8(h.path[v])]);
    for from in from_row.iter_mut() {
        let f = x as isize + from.dx;
        let out = from.out.as_mut_ptr().add(x * stride + 1);
        let mut m = pad;
        let fresh = from.prev.is_empty() || f < 0 || f >= width as isize;
        let (jump, prev_min, src) = if fresh {
            (pad, pad, std::ptr::null())
        } else {
            let f = f as usize;
            let prev_min = from.prev_mins[f];
            (
                vdupq_n_u8(prev_min.saturating_add(from.p2[x])),
                vdupq_n_u8(prev_min),
                from.prev.as_ptr().add(f * stride),
            )
        };
        for v in 0..NV {
            let o = if fresh {
                // The path enters the image here.
                c[v]
            } else {
                // SAFETY: entries `16v + {0, 1, 2} .. + 16` of pixel `f`'s `lanes + 2`.
                let at = |o: usize| unsafe { vld1q_u8(src.add(16 * v + o)) };
                step(p1, c[v], at(1), at(0), at(2), prev_min, jump)
            };
            // SAFETY: the `lanes` entries after pixel `x`'s pad.
            vst1q_u8(out.add(16 * v), o);
            m = vminq_u8(m, o);
            total[v][0] = vaddw_u8(total[v][0], vget_low_u8(o));
            total[v][1] = vaddw_high_u8(total[v][1], o);
        }
        if pad_register {
            // SAFETY: the register of padding lanes, `16 * NV + 16 == lanes`.
            vst1q_u8(out.add(16 * NV), pad);
        }
        from.out_mins[x] = vminvq_u8(m);
    }
    let s = &mut sum[x * nd..(x + 1) * nd];
    for (v, &[low, high]) in total.iter().enumerate() {
        let k = 16 * v;
        if k + 16 <= nd {
            // SAFETY: entries k..k + 16 of this pixel's `nd` sums.
            let dst = s.as_mut_ptr().add(k);
            let (low, high) = if accumulate {
                (vaddq_u16(low, vld1q_u16(dst)), vaddq_u16(high, vld1q_u16(dst.add(8))))
            } else {
                (low, high)
            };
            vst1q_u16(dst, low);
            vst1q_u16(dst.add(8), high);
        } else if k < nd {
            store_last_sums(s, k, low, high, accumulate);
        }
    }
}

/// The sums of a register that holds the last disparities and some pads (out of line, so that
/// the loop over the full registers stays short enough to unroll).
#[cold]
#[inline(never)]
#[target_feature(enable = "neon")]
unsafe fn store_last_sums(s: &mut [u16], k: usize, low: uint16x8_t, high: uint16x8_t, accumulate: bool) {
    store_sums(s, k, low, accumulate);
    store_sums(s, k + 8, high, accumulate);
}

/// NEON [`crate::kernels::row_u8`] with the horizontal paths in `NV` registers of 16 lanes.
///
/// # Safety
/// The CPU must have NEON; lengths as checked by [`crate::kernels::row_u8`], and `nd <= 16 * NV
/// <= lanes <= 16 * NV + 16`.
#[target_feature(enable = "neon")]
#[allow(clippy::too_many_arguments)]
pub(in crate::kernels) unsafe fn row_neon<const NV: usize, const K: usize>(
    cost: &[u8],
    lanes: usize,
    nd: usize,
    p1: u8,
    p2: &[u8],
    mut from_row: [FromRow<'_>; K],
    sum: &mut [u16],
    reverse: bool,
    accumulate: bool,
    mut trailing: Option<Trailing<'_>>,
) {
    debug_assert!(nd <= 16 * NV && 16 * NV <= lanes && lanes <= 16 * NV + 16);
    let width = cost.len() / lanes;
    let pad = vdupq_n_u8(u8::MAX);
    let shape = Shape { width, lanes, nd, pad_register: lanes > 16 * NV, pad, p1: vdupq_n_u8(p1) };
    let mut h = Horizontal { path: [pad; NV], min: 0 };
    let mut back = Horizontal { path: [pad; NV], min: 0 };
    for i in 0..width {
        let x = if reverse { width - 1 - i } else { i };
        pixel::<NV, K>(&shape, &mut h, i, x, cost, p2, &mut from_row, sum, accumulate);
        if let Some(t) = &mut trailing {
            pixel::<NV, 0>(&shape, &mut back, i, width - 1 - i, t.cost, t.p2, &mut [], t.sum, true);
        }
    }
}
