//! The NEON kernels (aarch64: Jetson, Raspberry Pi, Apple silicon, Graviton). Each is the NEON
//! version of the function of the same stem in [`super::scalar`], selected by the dispatch in
//! [`super`] only when the CPU has NEON (every aarch64 Linux CPU does), and proptested against
//! that scalar reference. Imports only [`super::layout`] and [`super::scalar`].
//!
//! 128-bit registers: 8 `u16` or 16 `u8` disparities per instruction in the path steps, 16 Hamming
//! distances from 8 register loads in the cost row (`CNT` per byte, three pairwise additions),
//! 8 pixels per step in the census transform. The 8-bit passes' row kernel is in [`row`].

use std::arch::aarch64::*;

use super::layout::{
    padded_lanes, padded_lanes_u8, AdRows, BandRow, PathIn, PathInU8, Samples, Window, AD_LANE_MASKS, BT_PAD,
};
use super::scalar::{
    census_costs_in_blocks, census_span_scalar, keep_smaller_scalar, offset_in_9x7, pad_window_rows,
    pad_window_rows_high_bytes, window_offsets, HighByteRows,
};

mod median;
mod row;
pub(super) use median::median3x3_row_neon;
pub(super) use row::row_neon;

/// NEON [`super::path_step`]: 8 disparities per instruction ([`path_step_neon_body`]).
///
/// # Safety
/// The CPU must have NEON; lengths as checked by [`super::path_step`].
#[inline]
#[target_feature(enable = "neon")]
pub(super) unsafe fn path_step_neon<const N: usize>(
    cost: &[u16],
    p1: u16,
    ins: [PathIn<'_>; N],
    outs: [&mut [u16]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u16; N] {
    path_step_neon_body(cost, p1, ins, outs, sum, accumulate)
}

/// The body of [`path_step_neon`], inlined into the NEON versions of the aggregation loops
/// (`multiversion!`) as the AVX2 body is into theirs: called once per pixel, a call costs about
/// as much as a short range's step.
///
/// # Safety
/// The CPU must have NEON; lengths as checked by [`super::path_step`].
#[inline(always)]
pub(super) unsafe fn path_step_neon_body<const N: usize>(
    cost: &[u16],
    p1: u16,
    ins: [PathIn<'_>; N],
    outs: [&mut [u16]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u16; N] {
    let lanes = cost.len();
    let p1v = vdupq_n_u16(p1);
    let prev: [*const u16; N] = std::array::from_fn(|i| ins[i].prev.as_ptr());
    let out: [*mut u16; N] = {
        let mut outs = outs;
        std::array::from_fn(|i| outs[i].as_mut_ptr())
    };
    let jump: [uint16x8_t; N] =
        std::array::from_fn(|i| vdupq_n_u16(ins[i].prev_min.saturating_add(ins[i].p2)));
    let pmin: [uint16x8_t; N] = std::array::from_fn(|i| vdupq_n_u16(ins[i].prev_min));
    let mut mins = [vdupq_n_u16(u16::MAX); N];
    let mut k = 0;
    while k < lanes {
        // SAFETY (pointer accesses below): `k + 8 <= lanes` (lanes is a multiple of 16),
        // `prev`/`out` have `lanes + 2` entries, and `sum` is written only below `nd`.
        let c = vld1q_u16(cost.as_ptr().add(k));
        let mut total = vdupq_n_u16(0);
        for i in 0..N {
            let v = path_vector!(U16_NEON, c, prev[i].add(k), out[i].add(k + 1), p1v, jump[i], pmin[i]);
            mins[i] = vminq_u16(mins[i], v);
            total = vaddq_u16(total, v);
        }
        store_sums(sum, k, total, accumulate);
        k += 8;
    }
    std::array::from_fn(|i| vminvq_u16(mins[i]))
}

/// Stores (or with `accumulate` adds) the 8 path-cost sums `total` of disparities `k..k + 8`
/// into `sum`, only those below `sum.len()`.
#[inline(always)]
unsafe fn store_sums(sum: &mut [u16], k: usize, mut total: uint16x8_t, accumulate: bool) {
    let nd = sum.len();
    if k + 8 <= nd {
        // SAFETY: entries k..k + 8 of `sum`.
        let dst = sum.as_mut_ptr().add(k);
        if accumulate {
            total = vaddq_u16(total, vld1q_u16(dst));
        }
        vst1q_u16(dst, total);
    } else if k < nd {
        let mut tmp = [0u16; 8];
        vst1q_u16(tmp.as_mut_ptr(), total);
        for (j, &t) in tmp[..nd - k].iter().enumerate() {
            let d = &mut sum[k + j];
            *d = if accumulate { d.wrapping_add(t) } else { t };
        }
    }
}

/// NEON [`super::path_step_u8`]: 16 disparities per instruction, the 16-bit sums by widening
/// additions (`UADDW`, one per 8 lanes as for the `u16` sums). Inlined into the aggregation
/// loops as [`path_step_neon_body`] is, for the warm-up rows and for vectors longer than the
/// register row kernel ([`row_neon`]) keeps.
///
/// # Safety
/// The CPU must have NEON; lengths as checked by [`super::path_step_u8`].
#[inline(always)]
pub(super) unsafe fn path_step_u8_neon<const N: usize>(
    cost: &[u8],
    p1: u8,
    ins: [PathInU8<'_>; N],
    outs: [&mut [u8]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u8; N] {
    let lanes = cost.len();
    let p1v = vdupq_n_u8(p1);
    let prev: [*const u8; N] = std::array::from_fn(|i| ins[i].prev.as_ptr());
    let out: [*mut u8; N] = {
        let mut outs = outs;
        std::array::from_fn(|i| outs[i].as_mut_ptr())
    };
    let jump: [uint8x16_t; N] =
        std::array::from_fn(|i| vdupq_n_u8(ins[i].prev_min.saturating_add(ins[i].p2)));
    let pmin: [uint8x16_t; N] = std::array::from_fn(|i| vdupq_n_u8(ins[i].prev_min));
    let mut mins = [vdupq_n_u8(u8::MAX); N];
    let mut k = 0;
    while k < lanes {
        // SAFETY (pointer accesses below): `k + 16 <= lanes` (lanes is a multiple of 32) and
        // `prev`/`out` have `lanes + 2` entries; `store_sums` writes only below `nd`.
        let c = vld1q_u8(cost.as_ptr().add(k));
        let (mut low, mut high) = (vdupq_n_u16(0), vdupq_n_u16(0));
        for i in 0..N {
            let v = path_vector!(U8_NEON, c, prev[i].add(k), out[i].add(k + 1), p1v, jump[i], pmin[i]);
            mins[i] = vminq_u8(mins[i], v);
            low = vaddw_u8(low, vget_low_u8(v));
            high = vaddw_high_u8(high, v);
        }
        store_sums(sum, k, low, accumulate);
        store_sums(sum, k + 8, high, accumulate);
        k += 16;
    }
    std::array::from_fn(|i| vminvq_u8(mins[i]))
}

/// [`super::cost_row_u8`] for NEON machines: each pixel's costs made in 8 bits
/// ([`cost_pixel_u8_neon`]: census distances as `CNT` leaves them, the AD term narrowed before
/// it is added), [`super::layout::PAD_U8`] from `nd` on. No `u16` row in between: every cost is at most 255.
///
/// # Safety
/// The CPU must have NEON; lengths and bounds as checked by [`super::cost_row_u8`].
#[target_feature(enable = "neon")]
pub(super) unsafe fn cost_row_u8_neon(
    left: &[u64],
    right: &[u64],
    min_disparity: i32,
    nd: usize,
    worst: u16,
    ad: Option<AdRows<'_>>,
    out: &mut [u8],
) {
    let lanes = padded_lanes_u8(nd);
    for (x, costs) in out.chunks_exact_mut(lanes).enumerate() {
        // SAFETY: as checked by the caller; `costs` holds `padded_lanes_u8(nd)` entries, a
        // multiple of 16.
        cost_pixel_u8_neon(left, right, x, min_disparity, nd, worst as u8, &ad, costs);
    }
}

/// [`cost_pixel_neon`] in 8 bits: the costs of pixel `x` into `costs`.
///
/// # Safety
/// The CPU must have NEON; `costs.len()` is a multiple of 16 and at least `nd`, the BT rows (if
/// any) are padded by [`BT_PAD`].
#[inline]
#[target_feature(enable = "neon")]
#[allow(clippy::too_many_arguments)]
unsafe fn cost_pixel_u8_neon(
    left: &[u64],
    right: &[u64],
    x: usize,
    min_disparity: i32,
    nd: usize,
    worst: u8,
    ad: &Option<AdRows<'_>>,
    costs: &mut [u8],
) {
    // SAFETY: `hamming_bytes_neon` reads 16 strings and writes 16 entries, as the driver
    // allows; the CPU has NEON (this function's precondition).
    let (lo, hi, first) =
        census_costs_in_blocks(left, right, x, min_disparity, nd, worst, costs, |l, r, dst| {
            vst1q_u8(dst, hamming_bytes_neon(l, r))
        });
    if let Some(ad) = ad {
        // SAFETY: as in `cost_pixel_neon`.
        add_ad_u8_neon(ad, costs.as_mut_ptr(), x, left.len(), first, lo, hi);
    }
}

/// NEON [`super::argmin`].
///
/// # Safety
/// The CPU must have NEON; `values` is not empty.
#[inline]
#[target_feature(enable = "neon")]
pub(super) unsafe fn argmin_neon(values: &[u16]) -> (u16, usize) {
    let n = values.len();
    let p = values.as_ptr();
    let mut m = vdupq_n_u16(u16::MAX);
    let mut k = 0;
    while k + 8 <= n {
        // SAFETY: `k + 8 <= n`.
        m = vminq_u16(m, vld1q_u16(p.add(k)));
        k += 8;
    }
    let mut min = vminvq_u16(m);
    for &v in &values[k..] {
        min = min.min(v);
    }
    let mv = vdupq_n_u16(min);
    let mut k = 0;
    while k + 8 <= n {
        // SAFETY: `k + 8 <= n`.
        let eq = vceqq_u16(vld1q_u16(p.add(k)), mv);
        // Each lane's match narrowed to 4 bits of a 64-bit mask, in lane order.
        let bits = vget_lane_u64::<0>(vreinterpret_u64_u8(vshrn_n_u16::<4>(eq)));
        if bits != 0 {
            return (min, k + bits.trailing_zeros() as usize / 8);
        }
        k += 8;
    }
    (min, k + values[k..].iter().position(|&v| v == min).unwrap_or(0))
}

/// NEON [`super::keep_smaller`]: 8 lanes per step, the lanes past the last whole step as in the
/// reference.
///
/// # Safety
/// The CPU must have NEON; lengths as checked by [`super::keep_smaller`].
#[inline]
#[target_feature(enable = "neon")]
pub(super) unsafe fn keep_smaller_neon(costs: &[u16], first_index: u16, best: &mut [u16], index: &mut [u16]) {
    let n = costs.len();
    let iota = vld1q_u16([0u16, 1, 2, 3, 4, 5, 6, 7].as_ptr());
    let mut k = 0;
    while k + 8 <= n {
        // SAFETY: `k + 8 <= n`, the length of all three slices.
        let c = vld1q_u16(costs.as_ptr().add(k));
        let b = vld1q_u16(best.as_ptr().add(k));
        let i = vld1q_u16(index.as_ptr().add(k));
        let better = vcltq_u16(c, b);
        let ks = vaddq_u16(iota, vdupq_n_u16((usize::from(first_index) + k) as u16));
        vst1q_u16(best.as_mut_ptr().add(k), vminq_u16(c, b));
        vst1q_u16(index.as_mut_ptr().add(k), vbslq_u16(better, ks, i));
        k += 8;
    }
    keep_smaller_scalar(&costs[k..], first_index + k as u16, &mut best[k..], &mut index[k..]);
}

/// [`super::cost_row`] for NEON machines: [`cost_pixel_neon`] for each pixel.
///
/// # Safety
/// The CPU must have NEON; lengths as checked by [`super::cost_row`].
#[target_feature(enable = "neon")]
pub(super) unsafe fn cost_row_neon(
    left: &[u64],
    right: &[u64],
    min_disparity: i32,
    nd: usize,
    worst: u16,
    ad: Option<AdRows<'_>>,
    out: &mut [u16],
) {
    let lanes = padded_lanes(nd);
    for (x, costs) in out.chunks_exact_mut(lanes).enumerate() {
        // SAFETY: as checked by the caller; `costs` is pixel `x`'s `lanes` entries.
        cost_pixel_neon(left, right, x, min_disparity, nd, worst, &ad, costs);
    }
}

/// [`super::cost_bands`] for NEON machines: [`cost_pixel_neon`] for each pixel over its own
/// band.
///
/// # Safety
/// The CPU must have NEON; lengths as checked by [`super::cost_bands`].
#[target_feature(enable = "neon")]
pub(super) unsafe fn cost_bands_neon(
    left: &[u64],
    right: &[u64],
    bands: BandRow<'_>,
    range_max: i32,
    worst: u16,
    ad: Option<AdRows<'_>>,
    out: &mut [u16],
) {
    for x in 0..left.len() {
        let (o, nd, entries) = bands.band(x, range_max);
        // SAFETY: `starts[x] + lanes[x] <= out.len()`, `lanes[x]` a multiple of 16 and
        // `offsets[x] < range_max` (checked by the caller).
        cost_pixel_neon(left, right, x, o, nd, worst, &ad, &mut out[entries]);
    }
}

/// Pixel `x`'s costs from disparity `min_disparity` into `costs` (as the scalar reference's
/// pixel): the census Hamming distances by [`census_costs_in_blocks`] with
/// [`hamming_block_neon`], then the AD term ([`add_ad_neon`]).
///
/// # Safety
/// The CPU must have NEON; `costs.len()` is a multiple of 16 and at least `nd`, the BT rows (if
/// any) are padded by [`BT_PAD`].
#[inline]
#[target_feature(enable = "neon")]
#[allow(clippy::too_many_arguments)]
unsafe fn cost_pixel_neon(
    left: &[u64],
    right: &[u64],
    x: usize,
    min_disparity: i32,
    nd: usize,
    worst: u16,
    ad: &Option<AdRows<'_>>,
    costs: &mut [u16],
) {
    // SAFETY: `hamming_block_neon` reads 16 strings and writes 16 entries, as the driver
    // allows; the CPU has NEON (this function's precondition).
    let (lo, hi, first) =
        census_costs_in_blocks(left, right, x, min_disparity, nd, worst, costs, |l, r, dst| {
            hamming_block_neon(l, r, dst)
        });
    if let Some(ad) = ad {
        // SAFETY: `lo..hi` are the feasible disparities of `x`, whose entries start at `costs`
        // (a multiple of 16 long, so every 16-entry block below `hi` is inside it).
        add_ad_neon(ad, costs.as_mut_ptr(), x, left.len(), first, lo, hi);
    }
}

/// Stores the 16 Hamming distances `popcount(l ^ r[15 - i])` for `i` in `0..16` at `dst` (`r`
/// the 16 right census strings from the lowest address, so entry `i` is disparity `k + i`):
/// `CNT` counts each byte, three rounds of pairwise byte additions sum each string's 8 counts
/// (at most 64, so bytes suffice), the bytes are reversed into disparity order and widened.
///
/// # Safety
/// The CPU must have NEON; `r` points at 16 readable `u64`, `dst` at 16 writable `u16`.
#[inline]
#[target_feature(enable = "neon")]
unsafe fn hamming_block_neon(l: u64, r: *const u64, dst: *mut u16) {
    let distances = hamming_bytes_neon(l, r);
    vst1q_u16(dst, vmovl_u8(vget_low_u8(distances)));
    vst1q_u16(dst.add(8), vmovl_high_u8(distances));
}

/// The 16 distances of [`hamming_block_neon`] as bytes, in disparity order.
///
/// # Safety
/// The CPU must have NEON; `r` points at 16 readable `u64`.
#[inline]
#[target_feature(enable = "neon")]
unsafe fn hamming_bytes_neon(l: u64, r: *const u64) -> uint8x16_t {
    let lv = vreinterpretq_u8_u64(vdupq_n_u64(l));
    let count = |i: usize| vcntq_u8(veorq_u8(vld1q_u8(r.add(2 * i).cast()), lv));
    // Strings 4j..4j + 4, two byte sums each; then 8j..8j + 8, four; then all 16 in memory order.
    let q0 = vpaddq_u8(vpaddq_u8(count(0), count(1)), vpaddq_u8(count(2), count(3)));
    let q1 = vpaddq_u8(vpaddq_u8(count(4), count(5)), vpaddq_u8(count(6), count(7)));
    let sums = vpaddq_u8(q0, q1);
    // Lowest address is the highest disparity: reverse the 16 bytes.
    vrev64q_u8(vextq_u8::<8>(sums, sums))
}

/// Calls `block(k, bt, below, upto)` for each 16-disparity block `k..k + 16` (`k` a multiple of
/// 16) that holds feasible disparities of pixel `x`, with `bt` its 16 Birchfield–Tomasi
/// differences (as the AD part of the scalar reference) and the block's feasible lanes
/// `below..upto`.
///
/// # Safety
/// The CPU must have NEON; `lo..hi` are the feasible disparities of `x` and the BT rows are
/// padded by [`BT_PAD`].
#[inline(always)]
unsafe fn for_bt_blocks(
    ad: &AdRows<'_>,
    x: usize,
    width: usize,
    first: i64,
    lo: usize,
    hi: usize,
    mut block: impl FnMut(usize, uint8x16_t, usize, usize),
) {
    if lo >= hi {
        return;
    }
    let il = BT_PAD + x;
    let (lv, llo, lhi) =
        (vdupq_n_u8(ad.left.value[il]), vdupq_n_u8(ad.left.lo[il]), vdupq_n_u8(ad.left.hi[il]));
    let base = BT_PAD as i64 + width as i64 - 1 - first;
    let mut k = lo & !15;
    while k < hi {
        // SAFETY: the right rows are padded by `BT_PAD` (32) entries at both ends, so the 16
        // bytes at `i` (feasible pixels, or at most 15 past them) are inside them.
        let i = (base + k as i64) as usize;
        let rv = vld1q_u8(ad.right.value.as_ptr().add(i));
        let rlo = vld1q_u8(ad.right.lo.as_ptr().add(i));
        let rhi = vld1q_u8(ad.right.hi.as_ptr().add(i));
        let d_lr = vmaxq_u8(vqsubq_u8(lv, rhi), vqsubq_u8(rlo, lv));
        let d_rl = vmaxq_u8(vqsubq_u8(rv, lhi), vqsubq_u8(llo, rv));
        block(k, vminq_u8(d_lr, d_rl), lo.saturating_sub(k), (hi - k).min(16));
        k += 16;
    }
}

/// Adds the AD term `min(weight · BT, cap)` of pixel `x` to its costs at `dst` for the feasible
/// disparities `lo..hi` (as the AD part of the scalar reference), 16 disparities per step.
///
/// # Safety
/// The CPU must have NEON; `dst` points at pixel `x`'s `padded_lanes(nd)` entries, `lo..hi` are
/// its feasible disparities and the BT rows are padded by [`BT_PAD`].
#[inline]
#[target_feature(enable = "neon")]
unsafe fn add_ad_neon(
    ad: &AdRows<'_>,
    dst: *mut u16,
    x: usize,
    width: usize,
    first: i64,
    lo: usize,
    hi: usize,
) {
    let weight = vdupq_n_u16(ad.weight);
    let cap = vdupq_n_u16(ad.cap);
    for_bt_blocks(ad, x, width, first, lo, hi, |k, bt, below, upto| {
        // SAFETY: `below <= 15` and `1 <= upto <= 16`: every read below is inside `AD_LANE_MASKS`.
        let mask = |half: usize| {
            vandq_u16(
                vld1q_u16(AD_LANE_MASKS.as_ptr().add(16 - below + 8 * half)),
                vld1q_u16(AD_LANE_MASKS.as_ptr().add(32 - upto + 8 * half)),
            )
        };
        let term = |half: uint16x8_t| vminq_u16(vmulq_u16(half, weight), cap);
        // SAFETY: `k` is a multiple of 16 below `hi <= lanes` (a multiple of 16), so entries
        // `k..k + 16` are this pixel's; lanes outside `lo..hi` add 0.
        let p = dst.add(k);
        let low = vandq_u16(term(vmovl_u8(vget_low_u8(bt))), mask(0));
        let high = vandq_u16(term(vmovl_high_u8(bt)), mask(1));
        vst1q_u16(p, vaddq_u16(vld1q_u16(p), low));
        vst1q_u16(p.add(8), vaddq_u16(vld1q_u16(p.add(8)), high));
    });
}

/// [`add_ad_neon`] on 8-bit costs: the term (`weight` and BT at most 255, their product exact in
/// 16 bits) is narrowed after the cap (at most [`super::layout::MAX_AD_CAP`]) and added in bytes (every
/// cost is at most 255, as [`super::cost_row_u8`] checks).
///
/// # Safety
/// As [`add_ad_neon`], `dst` at pixel `x`'s `padded_lanes_u8(nd)` entries.
#[inline]
#[target_feature(enable = "neon")]
unsafe fn add_ad_u8_neon(
    ad: &AdRows<'_>,
    dst: *mut u8,
    x: usize,
    width: usize,
    first: i64,
    lo: usize,
    hi: usize,
) {
    debug_assert!(ad.weight <= 255);
    let weight = vdup_n_u8(ad.weight as u8);
    let cap = vdupq_n_u16(ad.cap);
    let lane = vld1q_u8([0u8, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15].as_ptr());
    for_bt_blocks(ad, x, width, first, lo, hi, |k, bt, below, upto| {
        let low = vminq_u16(vmull_u8(vget_low_u8(bt), weight), cap);
        let high = vminq_u16(vmull_u8(vget_high_u8(bt), weight), cap);
        let mut term = vmovn_high_u16(vmovn_u16(low), high);
        if below > 0 || upto < 16 {
            // Lanes outside `lo..hi` add 0.
            let inside =
                vandq_u8(vcgeq_u8(lane, vdupq_n_u8(below as u8)), vcltq_u8(lane, vdupq_n_u8(upto as u8)));
            term = vandq_u8(term, inside);
        }
        // SAFETY: entries `k..k + 16` are this pixel's (as in `add_ad_neon`).
        let p = dst.add(k);
        vst1q_u8(p, vaddq_u8(vld1q_u8(p), term));
    });
}

/// [`super::scalar::census_row_scalar`] with NEON: 8 pixels per step, their bits gathered in four
/// 16-bit accumulators (census bits 0–15, 16–31, 32–47 and 48–63, each filled most significant
/// bit first, as the reference shifts them in; `SLI` shifts and inserts in one instruction) and
/// interleaved into the 64-bit strings at the end; the pixels past the last whole step as in the
/// reference.
///
/// # Safety
/// The CPU must have NEON; lengths as for [`super::scalar::census_row_scalar`].
#[target_feature(enable = "neon")]
pub(super) unsafe fn census_row_neon(
    image: Samples<'_>,
    window: Window,
    y: usize,
    padded: &mut [u16],
    bits: &mut [u64],
) {
    pad_window_rows(image, window, y, padded);
    let width = image.size().0;
    let rx = window.width / 2;
    let pw = width + 2 * rx;
    let centre = image.row(y);
    let n = window.width * window.height - 1;
    let tolerance = vdupq_n_u16(window.tolerance);
    let whole = width - width % 8;
    if (window.width, window.height) == (9, 7) {
        // The default window: with its shape known, each neighbour's offset is a constant plus
        // one of seven multiples of `pw`, so the loops unroll into loads at fixed offsets from
        // seven row pointers instead of reading every offset from a table (tsukuba's whole run
        // 172.2 → 162.4 M instructions under qemu).
        census_steps_neon(padded, centre, 62, tolerance, &mut bits[..whole], |i| offset_in_9x7(i, pw));
    } else {
        let offsets = window_offsets(window, pw);
        census_steps_neon(padded, centre, n, tolerance, &mut bits[..whole], |i| offsets[i]);
    }
    // The rest as the reference does it.
    census_span_scalar(padded, window, centre, whole, bits);
}

/// [`census_row_neon`]'s whole steps of 8 pixels (`bits.len()` a multiple of 8), neighbour `i`
/// of `n` read at `offset(i)` from the pixel in the padded rows.
///
/// # Safety
/// NEON; as [`census_row_neon`]: every `offset(i) + x + 8` within `padded` for `x + 8 <=
/// bits.len() <= centre.len()`.
#[inline(always)]
unsafe fn census_steps_neon(
    padded: &[u16],
    centre: &[u16],
    n: usize,
    tolerance: uint16x8_t,
    bits: &mut [u64],
    offset: impl Fn(usize) -> usize,
) {
    for x in (0..bits.len()).step_by(8) {
        // SAFETY: x + 8 <= width, the length of `centre` and of `bits`; each padded row holds
        // `pw = width + 2 * rx` samples and dx + x + 8 <= 2 * rx + width.
        let threshold = vqsubq_u16(vld1q_u16(centre.as_ptr().add(x)), tolerance);
        let mut acc = [vdupq_n_u16(0); 4];
        // Neighbour i is census bit n - 1 - i: accumulator j takes the neighbours of bits
        // 16j..16j + 16, highest bit (lowest i) first.
        for (j, a) in acc.iter_mut().enumerate().rev() {
            let first = n.saturating_sub(16 * j + 16);
            let end = n.saturating_sub(16 * j);
            let mut v = vdupq_n_u16(0);
            for i in first..end {
                let darker = vcltq_u16(vld1q_u16(padded.as_ptr().add(offset(i) + x)), threshold);
                // (v << 1) | (darker & 1).
                v = vsliq_n_u16::<1>(darker, v);
            }
            *a = v;
        }
        // 32-bit [bits 16–31 : 0–15] and [48–63 : 32–47] for pixels 0–3 and 4–7, then the
        // 64-bit strings two pixels at a time.
        let (lo01, hi01) = (vzip1q_u16(acc[0], acc[1]), vzip2q_u16(acc[0], acc[1]));
        let (lo23, hi23) = (vzip1q_u16(acc[2], acc[3]), vzip2q_u16(acc[2], acc[3]));
        let (a, b) = (vreinterpretq_u32_u16(lo01), vreinterpretq_u32_u16(lo23));
        let (c, d) = (vreinterpretq_u32_u16(hi01), vreinterpretq_u32_u16(hi23));
        let out = bits.as_mut_ptr().add(x);
        vst1q_u64(out, vreinterpretq_u64_u32(vzip1q_u32(a, b)));
        vst1q_u64(out.add(2), vreinterpretq_u64_u32(vzip2q_u32(a, b)));
        vst1q_u64(out.add(4), vreinterpretq_u64_u32(vzip1q_u32(c, d)));
        vst1q_u64(out.add(6), vreinterpretq_u64_u32(vzip2q_u32(c, d)));
    }
}

/// [`census_row_neon`] on the samples' high bytes, for byte-scaled images (8-bit images as
/// loaded, `b · 257`, whose high bytes compare as the samples do): 16 pixels per step instead of
/// 8. Their bits are gathered in eight 8-bit accumulators (census bits 8j..8j + 8 in accumulator
/// j, most significant bit first) and interleaved into the 64-bit strings by three rounds of
/// zips. The last step overlaps the one before it (the same bits written twice), as the GFNI
/// byte kernel's does. The window's tolerance must be a multiple of 257.
///
/// # Safety
/// The CPU must have NEON; the image at least 16 pixels wide; `padded` holds `window.height`
/// rows of `width + 2 · (window.width / 2)` bytes, `bits` is `width` long.
#[target_feature(enable = "neon")]
pub(super) unsafe fn census_row_neon_bytes(
    image: Samples<'_>,
    window: Window,
    y: usize,
    padded: &mut [u8],
    bits: &mut [u64],
) {
    let HighByteRows { pw, centre, n, tolerance } =
        pad_window_rows_high_bytes(image, window, y, padded, bits, 16);
    let centre = &padded[centre..centre + bits.len()];
    let tolerance = vdupq_n_u8(tolerance);
    if (window.width, window.height) == (9, 7) {
        // As in `census_row_neon`: the default window's offsets unroll into constants.
        census_bytes_steps_neon(padded, centre, 62, tolerance, bits, |i| offset_in_9x7(i, pw));
    } else {
        let offsets = window_offsets(window, pw);
        census_bytes_steps_neon(padded, centre, n, tolerance, bits, |i| offsets[i]);
    }
}

/// [`census_row_neon_bytes`]' steps of 16 pixels over the whole row (the last one overlapping),
/// neighbour `i` of `n` read at `offset(i)` from the pixel in the padded rows.
///
/// # Safety
/// NEON; as [`census_row_neon_bytes`]: `bits` and `centre` `width >= 16` long, every
/// `offset(i) + x + 16` within `padded` for `x + 16 <= width`.
#[inline(always)]
unsafe fn census_bytes_steps_neon(
    padded: &[u8],
    centre: &[u8],
    n: usize,
    tolerance: uint8x16_t,
    bits: &mut [u64],
    offset: impl Fn(usize) -> usize,
) {
    let width = bits.len();
    let mut x0 = 0;
    loop {
        let x = x0.min(width - 16);
        // SAFETY: x + 16 <= width, inside the centre row.
        let threshold = vqsubq_u8(vld1q_u8(centre.as_ptr().add(x)), tolerance);
        let mut acc = [vdupq_n_u8(0); 8];
        // Neighbour i is census bit n - 1 - i (as in `census_row_neon`, 8 bits per accumulator).
        for (j, a) in acc.iter_mut().enumerate() {
            let first = n.saturating_sub(8 * j + 8);
            let end = n.saturating_sub(8 * j);
            let mut v = vdupq_n_u8(0);
            for i in first..end {
                // SAFETY: offset + x + 16 <= dy * pw + 2 * rx + width = (dy + 1) * pw.
                let darker = vcltq_u8(vld1q_u8(padded.as_ptr().add(offset(i) + x)), threshold);
                v = vsliq_n_u8::<1>(darker, v);
            }
            *a = v;
        }
        // Bytes to 16-bit pairs (bytes 2k, 2k + 1), to 32-bit quadruples, to 64-bit strings;
        // each round's `zip1` takes the lower half of the pixels it gets, `zip2` the upper.
        let pairs: [[uint16x8_t; 2]; 4] = std::array::from_fn(|k| {
            let (a, b) = (acc[2 * k], acc[2 * k + 1]);
            [vreinterpretq_u16_u8(vzip1q_u8(a, b)), vreinterpretq_u16_u8(vzip2q_u8(a, b))]
        });
        let quads: [[uint32x4_t; 4]; 2] = std::array::from_fn(|k| {
            let (a, b) = (pairs[2 * k], pairs[2 * k + 1]);
            std::array::from_fn(|q| {
                let (lo, hi) = (a[q / 2], b[q / 2]);
                vreinterpretq_u32_u16(if q % 2 == 0 { vzip1q_u16(lo, hi) } else { vzip2q_u16(lo, hi) })
            })
        });
        let out = bits.as_mut_ptr().add(x);
        // Quads q hold pixels 4q..4q + 4: bytes 0–3 in `quads[0]`, 4–7 in `quads[1]`.
        for (q, (&lo, &hi)) in quads[0].iter().zip(&quads[1]).enumerate() {
            // SAFETY: pixels x + 4q .. x + 4q + 4 of `bits`.
            vst1q_u64(out.add(4 * q), vreinterpretq_u64_u32(vzip1q_u32(lo, hi)));
            vst1q_u64(out.add(4 * q + 2), vreinterpretq_u64_u32(vzip2q_u32(lo, hi)));
        }
        x0 += 16;
        if x0 >= width {
            break;
        }
    }
}
