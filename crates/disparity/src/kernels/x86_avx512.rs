//! The AVX-512 kernels (x86-64; AVX-512F/BW/VL, some also VPOPCNTDQ or VBMI as their
//! `target_feature` says). Each is the AVX-512 version of the function of the same stem in
//! [`super::scalar`], selected by the dispatch in [`super`] only when the CPU has the features,
//! and proptested against that scalar reference. Imports only [`super::layout`] (and the AVX2
//! horizontal minimum for the 256-bit tails).

use std::arch::x86_64::*;

use super::layout::{
    feasible, interleave, padded_lanes, padded_lanes_u8, AdRows, BandRow, PathIn, PathInU8, BT_PAD,
    JUNK_COST, PAD_U8,
};
use super::x86_avx2::{hmin_epu16_256, hmin_epu8_256};

mod census;
mod median;
mod row;
#[cfg(test)]
pub(super) use census::transpose_64x64;
pub(super) use census::{census_row_avx512, census_row_gfni, census_row_gfni_bytes};
pub(super) use median::median3x3_row_avx512;
pub(super) use row::{row_avx512, row_avx512_vbmi};

/// Minimum of the 32 unsigned 16-bit lanes.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl")]
fn hmin_epu16_512(v: __m512i) -> u16 {
    let m = _mm256_min_epu16(_mm512_castsi512_si256(v), _mm512_extracti64x4_epi64::<1>(v));
    let m = _mm_min_epu16(_mm256_castsi256_si128(m), _mm256_extracti128_si256::<1>(m));
    _mm_extract_epi16::<0>(_mm_minpos_epu16(m)) as u16
}

/// AVX-512BW [`super::path_step`]: 32 disparities per instruction (and a 16-lane step when
/// the padded count is an odd multiple of 16).
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL; lengths as checked by [`super::path_step`].
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl")]
pub(super) unsafe fn path_step_avx512<const N: usize>(
    cost: &[u16],
    p1: u16,
    ins: [PathIn<'_>; N],
    outs: [&mut [u16]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u16; N] {
    let lanes = cost.len();
    let nd = sum.len();
    let p1v = _mm512_set1_epi16(p1 as i16);
    let prev: [*const u16; N] = std::array::from_fn(|i| ins[i].prev.as_ptr());
    let out: [*mut u16; N] = {
        let mut outs = outs;
        std::array::from_fn(|i| outs[i].as_mut_ptr())
    };
    let jump: [__m512i; N] =
        std::array::from_fn(|i| _mm512_set1_epi16(ins[i].prev_min.saturating_add(ins[i].p2) as i16));
    let pmin: [__m512i; N] = std::array::from_fn(|i| _mm512_set1_epi16(ins[i].prev_min as i16));
    let mut mins = [_mm512_set1_epi16(-1); N];
    let mut k = 0;
    while k + 32 <= lanes {
        // SAFETY (all pointer accesses below): `k + 32 <= lanes`, `prev`/`out` have
        // `lanes + 2` entries so offsets `k..k + 34` are in bounds, and the `sum` accesses are
        // masked to the lanes below `nd = sum.len()`.
        let c = _mm512_loadu_si512(cost.as_ptr().add(k).cast());
        let mut total = _mm512_setzero_si512();
        for i in 0..N {
            let v = path_vector!(U16_512, c, prev[i].add(k), out[i].add(k + 1), p1v, jump[i], pmin[i]);
            mins[i] = _mm512_min_epu16(mins[i], v);
            total = _mm512_add_epi16(total, v);
        }
        if k < nd {
            let mask: __mmask32 = if nd - k >= 32 { !0 } else { (1u32 << (nd - k)) - 1 };
            let dst = sum.as_mut_ptr().add(k);
            if accumulate {
                total = _mm512_add_epi16(total, _mm512_maskz_loadu_epi16(mask, dst.cast()));
            }
            _mm512_mask_storeu_epi16(dst.cast(), mask, total);
        }
        k += 32;
    }
    let mut result: [u16; N] = std::array::from_fn(|i| hmin_epu16_512(mins[i]));
    if k < lanes {
        // The last 16 lanes, with 256-bit registers.
        // SAFETY: `k + 16 == lanes`; the same bounds as above.
        let p1v = _mm512_castsi512_si256(p1v);
        let c = _mm256_loadu_si256(cost.as_ptr().add(k).cast());
        let mut total = _mm256_setzero_si256();
        for i in 0..N {
            let (jump, pmin) = (_mm512_castsi512_si256(jump[i]), _mm512_castsi512_si256(pmin[i]));
            let v = path_vector!(U16_256, c, prev[i].add(k), out[i].add(k + 1), p1v, jump, pmin);
            result[i] = result[i].min(hmin_epu16_256(v));
            total = _mm256_add_epi16(total, v);
        }
        if k < nd {
            let mask: __mmask16 = if nd - k >= 16 { !0 } else { (1u16 << (nd - k)) - 1 };
            let dst = sum.as_mut_ptr().add(k);
            if accumulate {
                total = _mm256_add_epi16(total, _mm256_maskz_loadu_epi16(mask, dst.cast()));
            }
            _mm256_mask_storeu_epi16(dst.cast(), mask, total);
        }
    }
    result
}

/// AVX-512BW [`super::argmin`].
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL; `values` is not empty.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl")]
pub(super) unsafe fn argmin_avx512(values: &[u16]) -> (u16, usize) {
    let n = values.len();
    let p = values.as_ptr();
    let ones = _mm512_set1_epi16(-1);
    let mut m = ones;
    let mut k = 0;
    while k < n {
        let mask: __mmask32 = if n - k >= 32 { !0 } else { (1u32 << (n - k)) - 1 };
        // SAFETY: the masked load reads only `values[k..n]`.
        m = _mm512_min_epu16(m, _mm512_mask_loadu_epi16(ones, mask, p.add(k).cast()));
        k += 32;
    }
    let min = hmin_epu16_512(m);
    let mv = _mm512_set1_epi16(min as i16);
    let mut k = 0;
    loop {
        let mask: __mmask32 = if n - k >= 32 { !0 } else { (1u32 << (n - k)) - 1 };
        // SAFETY: as above; the minimum occurs in `values`, so the loop ends before `k >= n`.
        let v = _mm512_mask_loadu_epi16(ones, mask, p.add(k).cast());
        let hit = _mm512_mask_cmpeq_epu16_mask(mask, v, mv);
        if hit != 0 {
            return (min, k + hit.trailing_zeros() as usize);
        }
        k += 32;
    }
}

/// AVX-512BW [`super::keep_smaller`].
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL; lengths as checked by [`super::keep_smaller`].
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl")]
pub(super) unsafe fn keep_smaller_avx512(
    costs: &[u16],
    first_index: u16,
    best: &mut [u16],
    index: &mut [u16],
) {
    let n = costs.len();
    let iota = _mm512_set_epi16(
        31, 30, 29, 28, 27, 26, 25, 24, 23, 22, 21, 20, 19, 18, 17, 16, 15, 14, 13, 12, 11, 10, 9, 8, 7, 6,
        5, 4, 3, 2, 1, 0,
    );
    let mut k = 0;
    while k < n {
        let mask: __mmask32 = if n - k >= 32 { !0 } else { (1u32 << (n - k)) - 1 };
        // SAFETY: every access is masked to entries `k..n` of slices of length `n`.
        let c = _mm512_maskz_loadu_epi16(mask, costs.as_ptr().add(k).cast());
        let b = _mm512_maskz_loadu_epi16(mask, best.as_ptr().add(k).cast());
        let better = _mm512_mask_cmplt_epu16_mask(mask, c, b);
        let ks = _mm512_add_epi16(iota, _mm512_set1_epi16((usize::from(first_index) + k) as i16));
        _mm512_mask_storeu_epi16(best.as_mut_ptr().add(k).cast(), better, c);
        _mm512_mask_storeu_epi16(index.as_mut_ptr().add(k).cast(), better, ks);
        k += 32;
    }
}

/// Lanes `lo..hi` (clamped to `0..n`) of an `n`-lane mask.
#[inline(always)]
fn lanes_between(lo: i64, hi: i64, n: i64) -> u64 {
    let upto = |v: i64| {
        let v = v.clamp(0, n) as u32;
        if v >= 64 {
            u64::MAX
        } else {
            (1u64 << v) - 1
        }
    };
    upto(hi) & !upto(lo)
}

/// The `lanes` costs of pixel `x` from disparity `min_disparity` (`nd` of them real, the rest
/// [`JUNK_COST`]) into `dst`: the body of both cost kernels, a macro so that it is compiled
/// inside each (a `#[target_feature]` function cannot be forced inline).
///
/// Safety (of the expansion): AVX-512F/BW/VL and VPOPCNTDQ; `dst` has `lanes` entries, `lanes`
/// a multiple of 16 and at least `nd`; the AD rows (if any) are `width + 2 * BT_PAD` long.
macro_rules! cost_pixel_avx512 {
    ($left:expr, $right:expr, $x:expr, $min_disparity:expr, $nd:expr, $lanes:expr, $consts:expr, $ad:expr, $dst:expr $(,)?) => {{
        let (left, right, x, min_disparity, nd, lanes): (&[u64], &[u64], usize, i32, usize, usize) =
            ($left, $right, $x, $min_disparity, $nd, $lanes);
        let c: &CostConsts = $consts;
        let ad: &Option<AdRows<'_>> = $ad;
        let dst: *mut u16 = $dst;
        let width = left.len();
        let bt_len = (width + 2 * BT_PAD) as i64;
        let l = _mm512_set1_epi64(left[x] as i64);
        // Disparity index k has its right pixel at first - k: inside the row for k in lo..hi.
        let (lo, hi, first) = feasible(x, width, min_disparity, nd);
        // The BT loads of lanes past `nd` stay inside the pads only when they are fewer than 16.
        let interior = lo == 0 && hi == nd && lanes == padded_lanes(nd);
        // Every census load of the pixel (padding lanes included) inside the row.
        let loads_inside = first + 1 >= lanes as i64 && first < width as i64;
        let bt_left = ad.as_ref().map(|ad| {
            let il = BT_PAD + x;
            (
                _mm256_set1_epi8(ad.left.value[il] as i8),
                _mm256_set1_epi8(ad.left.lo[il] as i8),
                _mm256_set1_epi8(ad.left.hi[il] as i8),
            )
        });
        let mut k = 0;
        while k < lanes {
            // The last block of an odd multiple of 16 lanes needs only its first two loads.
            let half = k + 32 > lanes;
            let count = |j: usize| {
                if half && j >= 2 {
                    return _mm512_setzero_si512();
                }
                // Disparities k + 8j ..= k + 8j + 7 read right[first - k - 8j - 7 ..=
                // first - k - 8j]; lanes whose address is outside the row are not loaded.
                let lowest = first - (k + 8 * j) as i64 - 7;
                let inside = if loads_inside {
                    !0
                } else {
                    lanes_between(-lowest, width as i64 - lowest, 8) as __mmask8
                };
                // SAFETY: the masked load touches only lanes whose address is inside `right`;
                // the pointer is formed with wrapping arithmetic.
                let r =
                    _mm512_maskz_loadu_epi64(inside, right.as_ptr().wrapping_offset(lowest as isize).cast());
                _mm512_popcnt_epi64(_mm512_xor_si512(l, r))
            };
            let packed = _mm512_or_si512(
                _mm512_or_si512(count(0), _mm512_slli_epi64::<16>(count(1))),
                _mm512_or_si512(_mm512_slli_epi64::<32>(count(2)), _mm512_slli_epi64::<48>(count(3))),
            );
            let mut cost = _mm512_permutexvar_epi16(c.unpack, packed);
            if let (Some(ad), Some((lv, llo, lhi))) = (ad, bt_left) {
                // Disparity k reads the reversed right BT rows at `i + k`; the pads of
                // `BT_PAD` entries cover the lanes of interior pixels past `nd`, masks the rest.
                let i = BT_PAD as i64 + width as i64 - 1 - first + k as i64;
                let inside = if interior { !0 } else { lanes_between(-i, bt_len - i, 32) as __mmask32 };
                let load = |row: &[u8]| {
                    // SAFETY: masked to the lanes inside `row` (`bt_len` entries); for interior
                    // pixels `i + 32 <= BT_PAD + width + 30`, inside the padded row.
                    _mm256_maskz_loadu_epi8(inside, row.as_ptr().wrapping_offset(i as isize).cast())
                };
                let (rv, rlo, rhi) = (load(&ad.right.value), load(&ad.right.lo), load(&ad.right.hi));
                let d_lr = _mm256_max_epu8(_mm256_subs_epu8(lv, rhi), _mm256_subs_epu8(rlo, lv));
                let d_rl = _mm256_max_epu8(_mm256_subs_epu8(rv, lhi), _mm256_subs_epu8(llo, rv));
                let bt = _mm512_cvtepu8_epi16(_mm256_min_epu8(d_lr, d_rl));
                cost = _mm512_add_epi16(cost, _mm512_min_epu16(_mm512_mullo_epi16(bt, c.weight), c.cap));
            }
            let cost = if interior && k + 32 <= nd {
                cost
            } else if interior {
                _mm512_mask_mov_epi16(c.junk, ((1u64 << (nd - k)) - 1) as __mmask32, cost)
            } else {
                let feasible = lanes_between(lo as i64 - k as i64, hi as i64 - k as i64, 32) as __mmask32;
                let real = lanes_between(0, nd as i64 - k as i64, 32) as __mmask32;
                _mm512_mask_mov_epi16(c.junk, real, _mm512_mask_mov_epi16(c.worst, feasible, cost))
            };
            // Two 256-bit stores: a pixel's entries start at a multiple of 32 bytes (`lanes`
            // is a multiple of 16), so neither splits a cache line, where one 512-bit store
            // would every other pixel when `lanes` is an odd multiple of 16.
            // SAFETY: `k + 16 <= lanes` (and `k + 32 <= lanes` for the second half), inside
            // this pixel's entries.
            _mm256_storeu_si256(dst.add(k).cast(), _mm512_castsi512_si256(cost));
            if !half {
                _mm256_storeu_si256(dst.add(k + 16).cast(), _mm512_extracti64x4_epi64::<1>(cost));
            }
            k += 32;
        }
    }};
}

/// AVX-512 VPOPCNTQ [`super::cost_row`]: 32 disparities per step, entirely in registers.
/// Four loads of 8 right census strings (ascending addresses, so descending disparities), four
/// popcounts packed into the four 16-bit words of each 64-bit lane by shifts, and one word
/// permutation back to disparity order (no narrowing stores, no reversal per load); then the
/// AD term, the worst cost where the right pixel is outside the row, and a single store.
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL and VPOPCNTDQ; lengths as checked by [`super::cost_row`].
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vpopcntdq")]
pub(super) unsafe fn cost_row_avx512(
    left: &[u64],
    right: &[u64],
    min_disparity: i32,
    nd: usize,
    worst: u16,
    ad: Option<AdRows<'_>>,
    out: &mut [u16],
) {
    let lanes = padded_lanes(nd);
    let consts = CostConsts::new(worst, &ad);
    for x in 0..left.len() {
        // SAFETY: `out` has `width * lanes` entries (checked by the caller).
        cost_pixel_avx512!(
            left,
            right,
            x,
            min_disparity,
            nd,
            lanes,
            &consts,
            &ad,
            out.as_mut_ptr().add(x * lanes),
        );
    }
}

/// AVX-512 VPOPCNTQ [`super::cost_bands`]: [`cost_row_avx512`]'s pixel step over each pixel's
/// own band.
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL and VPOPCNTDQ; lengths as checked by [`super::cost_bands`].
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vpopcntdq")]
pub(super) unsafe fn cost_bands_avx512(
    left: &[u64],
    right: &[u64],
    bands: BandRow<'_>,
    range_max: i32,
    worst: u16,
    ad: Option<AdRows<'_>>,
    out: &mut [u16],
) {
    let consts = CostConsts::new(worst, &ad);
    for x in 0..left.len() {
        let (o, nd, entries) = bands.band(x, range_max);
        // SAFETY: `starts[x] + lanes[x] <= out.len()` and `offsets[x] < range_max` (checked by
        // the caller).
        cost_pixel_avx512!(
            left,
            right,
            x,
            o,
            nd,
            entries.len(),
            &consts,
            &ad,
            out.as_mut_ptr().add(entries.start),
        );
    }
}

/// The constant registers of the cost kernels.
struct CostConsts {
    junk: __m512i,
    worst: __m512i,
    unpack: __m512i,
    weight: __m512i,
    cap: __m512i,
}

impl CostConsts {
    #[inline]
    #[target_feature(enable = "avx512f,avx512bw,avx512vl")]
    unsafe fn new(worst: u16, ad: &Option<AdRows<'_>>) -> Self {
        // Word 4i + j of the packed vector is load j's lane i: disparity k + 8j + 7 - i.
        let unpack = {
            let mut idx = [0i16; 32];
            for (m, v) in idx.iter_mut().enumerate() {
                *v = (4 * (7 - m % 8) + m / 8) as i16;
            }
            _mm512_loadu_si512(idx.as_ptr().cast())
        };
        let (weight, cap) = match ad {
            Some(ad) => (_mm512_set1_epi16(ad.weight as i16), _mm512_set1_epi16(ad.cap as i16)),
            None => (_mm512_setzero_si512(), _mm512_setzero_si512()),
        };
        CostConsts {
            junk: _mm512_set1_epi16(JUNK_COST as i16),
            worst: _mm512_set1_epi16(worst as i16),
            unpack,
            weight,
            cap,
        }
    }
}

/// AVX-512 VPOPCNTQ + VBMI [`super::cost_row_u8`]: [`cost_row_avx512`] with 64 disparities
/// per step and bytes throughout. Eight loads of 8 right census strings, eight popcounts
/// merged pairwise into disparity order by four two-register byte permutations (VBMI; fewer
/// instructions than packing by shifts and permuting once) and three byte blends; the AD term stays in bytes (`min(weight · BT, cap)` is a 128-entry
/// table lookup, one two-register byte permutation, since the cap is at most 127); then the
/// worst cost and padding by masked moves and stores that never split a cache line. The columns
/// whose loads all lie inside the row (all but a band of about `nd` at the left border) run
/// [`cost_columns_u8_lean`], the same steps without the per-pixel bounds and masks, which took
/// most of this kernel's time (docs/perf-notes.md).
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL, VPOPCNTDQ and VBMI; lengths and bounds as checked by
/// [`super::cost_row_u8`].
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vpopcntdq,avx512vbmi")]
pub(super) unsafe fn cost_row_u8_avx512(
    left: &[u64],
    right: &[u64],
    min_disparity: i32,
    nd: usize,
    worst: u16,
    ad: Option<AdRows<'_>>,
    out: &mut [u8],
) {
    let width = left.len();
    let lanes = padded_lanes_u8(nd);
    let consts = U8Consts::new(worst, &ad);
    let U8Consts { pad, worst, unpack, .. } = consts;
    let bt_len = (width + 2 * BT_PAD) as i64;
    // The columns whose census and AD loads all lie inside the row take the lean loop (compiled
    // for up to `LEAN_BLOCKS` blocks of 64 lanes).
    let lean = if lanes <= 64 * LEAN_BLOCKS { lean_columns(width, min_disparity, lanes) } else { 0..0 };
    for x in (0..lean.start).chain(lean.end..width) {
        let census = left[x];
        let l = _mm512_set1_epi64(census as i64);
        // Disparity index k has its right pixel at first - k: inside the row for k in lo..hi.
        let (lo, hi, first) = feasible(x, width, min_disparity, nd);
        let interior = lo == 0 && hi == nd;
        // Every census load of the pixel (padding lanes included) inside the row.
        let loads_inside = first + 1 >= lanes as i64 && first < width as i64;
        let dst = out.as_mut_ptr().add(x * lanes);
        let bt_left = ad.as_ref().map(|ad| {
            let il = BT_PAD + x;
            (
                _mm512_set1_epi8(ad.left.value[il] as i8),
                _mm512_set1_epi8(ad.left.lo[il] as i8),
                _mm512_set1_epi8(ad.left.hi[il] as i8),
            )
        });
        let mut k = 0;
        while k < lanes {
            // The last block of an odd multiple of 32 lanes needs only its first four loads.
            let half = k + 64 > lanes;
            // Bit t: whether address `low + t` is inside the row, `low` the block's lowest.
            let low = first - k as i64 - 63;
            let inside_all = if loads_inside { !0 } else { lanes_between(-low, width as i64 - low, 64) };
            let count = |j: usize| {
                // Disparities k + 8j ..= k + 8j + 7 read right[first - k - 8j - 7 ..=
                // first - k - 8j] (bits 8 (7 - j).. of `inside_all`); lanes whose address is
                // outside the row are not loaded.
                let lowest = low + 8 * (7 - j as i64);
                let inside = (inside_all >> (8 * (7 - j))) as __mmask8;
                // SAFETY: the masked load touches only lanes whose address is inside `right`;
                // the pointer is formed with wrapping arithmetic.
                let r =
                    _mm512_maskz_loadu_epi64(inside, right.as_ptr().wrapping_offset(lowest as isize).cast());
                _mm512_popcnt_epi64(_mm512_xor_si512(l, r))
            };
            let mut cost = hamming_block(count, unpack, half);
            if let (Some(ad), Some((lv, llo, lhi))) = (&ad, bt_left) {
                // Disparity k reads the reversed right BT rows at `i + k`; the pads of
                // `BT_PAD` entries cover the lanes of interior pixels past `nd` (at most 31
                // past it: `block` leaves out the upper half of a half block), masks the rest.
                let block: u64 = if half { u64::from(u32::MAX) } else { u64::MAX };
                let i = BT_PAD as i64 + width as i64 - 1 - first + k as i64;
                let inside = if interior { block } else { lanes_between(-i, bt_len - i, 64) & block };
                let load = |row: &[u8]| {
                    // SAFETY: masked to the lanes inside `row` (`bt_len` entries); for interior
                    // pixels the lanes read end at `i + lanes - k <= BT_PAD + width + 31`,
                    // inside the padded row.
                    _mm512_maskz_loadu_epi8(inside, row.as_ptr().wrapping_offset(i as isize).cast())
                };
                let right_bt = (load(&ad.right.value), load(&ad.right.lo), load(&ad.right.hi));
                cost = add_ad_term(cost, (lv, llo, lhi), right_bt, &consts);
            }
            let cost = if interior && k + 64 <= nd {
                cost
            } else if interior {
                _mm512_mask_mov_epi8(pad, lanes_between(0, nd as i64 - k as i64, 64), cost)
            } else {
                let feasible = lanes_between(lo as i64 - k as i64, hi as i64 - k as i64, 64);
                let real = lanes_between(0, nd as i64 - k as i64, 64);
                _mm512_mask_mov_epi8(pad, real, _mm512_mask_mov_epi8(worst, feasible, cost))
            };
            // SAFETY: `k + 32 <= lanes` (and `k + 64 <= lanes` unless `half`), inside this
            // pixel's entries.
            store_block(dst.add(k), cost, half);
            k += 64;
        }
    }
    macro_rules! lean {
        ($nb:literal, $half:literal) => {
            cost_columns_u8_lean::<$nb, $half>(left, right, min_disparity, nd, &consts, &ad, lean, out)
        };
    }
    match (lanes.div_ceil(64), !lanes.is_multiple_of(64)) {
        _ if lean.is_empty() => {}
        (1, true) => lean!(1, true),
        (1, false) => lean!(1, false),
        (2, true) => lean!(2, true),
        (2, false) => lean!(2, false),
        (3, true) => lean!(3, true),
        (3, false) => lean!(3, false),
        (4, true) => lean!(4, true),
        (4, false) => lean!(4, false),
        _ => unreachable!("lean columns of more than {LEAN_BLOCKS} blocks"),
    }
}

/// The most 64-lane blocks [`cost_columns_u8_lean`] is compiled for (256 disparities); wider
/// rows take the general loop throughout.
const LEAN_BLOCKS: usize = 4;

/// The constant registers of [`cost_row_u8_avx512`].
#[derive(Clone, Copy)]
struct U8Consts {
    pad: __m512i,
    worst: __m512i,
    /// Load j's lane i (byte 8i of its popcounts) is disparity k + 8j + 7 - i; byte m of a pair
    /// of loads (2a, 2a + 1) is disparity k + 16a + m % 16 for the m whose `m / 16 == a`, from
    /// the first (index bit 6 clear) or second load of the pair by bit 3 of m.
    unpack: __m512i,
    /// `min(weight · b, cap)` for b = 0..128 (two registers); BT values are clamped to 127,
    /// where the term is already at the cap (or 0 for weight 0) because the cap is at most 127.
    term_lo: __m512i,
    term_hi: __m512i,
    top: __m512i,
}

impl U8Consts {
    #[inline]
    #[target_feature(enable = "avx512f,avx512bw,avx512vl")]
    fn new(worst: u16, ad: &Option<AdRows<'_>>) -> Self {
        let idx: [u8; 64] = std::array::from_fn(|m| (8 * (7 - m % 8) + 64 * ((m / 8) % 2)) as u8);
        // SAFETY: 64 bytes read from a 64-byte array.
        let unpack = unsafe { _mm512_loadu_si512(idx.as_ptr().cast()) };
        let (term_lo, term_hi) = match ad {
            Some(ad) => {
                let table: [u8; 128] =
                    std::array::from_fn(|b| (u32::from(ad.weight) * b as u32).min(u32::from(ad.cap)) as u8);
                // SAFETY: two 64-byte reads inside the 128-byte table.
                unsafe {
                    (
                        _mm512_loadu_si512(table.as_ptr().cast()),
                        _mm512_loadu_si512(table[64..].as_ptr().cast()),
                    )
                }
            }
            None => (_mm512_setzero_si512(), _mm512_setzero_si512()),
        };
        U8Consts {
            pad: _mm512_set1_epi8(PAD_U8 as i8),
            worst: _mm512_set1_epi8(worst as i8),
            unpack,
            term_lo,
            term_hi,
            top: _mm512_set1_epi8(127),
        }
    }
}

/// The columns `x` of a row of `width` pixels whose every census load (`lanes` of them, padding
/// included, at `x - min_disparity - lanes + 1 ..= x - min_disparity`) lies inside the row: there
/// every disparity is feasible and no load needs a mask.
fn lean_columns(width: usize, min_disparity: i32, lanes: usize) -> std::ops::Range<usize> {
    let w = width as i64;
    let start = (i64::from(min_disparity) + lanes as i64 - 1).clamp(0, w);
    let end = (i64::from(min_disparity) + w).clamp(start, w);
    start as usize..end as usize
}

/// [`cost_row_u8_avx512`] on its [`lean_columns`]: the same instructions on the same values, without
/// the per-pixel bounds (feasible disparities, load masks), for `NB` blocks of 64 lanes, the
/// last one half (32 lanes) when `HALF`.
///
/// # Safety
/// As [`cost_row_u8_avx512`]; `columns` within [`lean_columns`] and `lanes` =
/// `64 * NB - 32 * HALF`.
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vpopcntdq,avx512vbmi")]
#[allow(clippy::too_many_arguments)]
unsafe fn cost_columns_u8_lean<const NB: usize, const HALF: bool>(
    left: &[u64],
    right: &[u64],
    min_disparity: i32,
    nd: usize,
    consts: &U8Consts,
    ad: &Option<AdRows<'_>>,
    columns: std::ops::Range<usize>,
    out: &mut [u8],
) {
    match ad {
        Some(ad) => {
            let (l, r) = (ad.left, ad.right);
            let rows = [&l.value, &l.lo, &l.hi, &r.value, &r.lo, &r.hi].map(|row| row.as_ptr());
            lean_body::<NB, HALF, true>(left, right, min_disparity, nd, consts, rows, columns, out)
        }
        None => lean_body::<NB, HALF, false>(
            left,
            right,
            min_disparity,
            nd,
            consts,
            [std::ptr::null(); 6],
            columns,
            out,
        ),
    }
}

/// The loop of [`cost_columns_u8_lean`], with the AD term when `AD` (its BT rows' pointers in
/// `bt`: left value, lo, hi, then the reversed right rows), so that neither the term's presence
/// nor its rows are looked up per pixel.
///
/// # Safety
/// As [`cost_columns_u8_lean`]; with `AD`, `bt` points at the `width + 2 * BT_PAD` entries of
/// each row.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn lean_body<const NB: usize, const HALF: bool, const AD: bool>(
    left: &[u64],
    right: &[u64],
    min_disparity: i32,
    nd: usize,
    consts: &U8Consts,
    bt: [*const u8; 6],
    columns: std::ops::Range<usize>,
    out: &mut [u8],
) {
    let width = left.len();
    let lanes = 64 * NB - if HALF { 32 } else { 0 };
    let U8Consts { pad, unpack, .. } = *consts;
    // The lanes of each block that hold a disparity; the rest are the pad.
    let real: [u64; NB] = std::array::from_fn(|b| lanes_between(0, nd as i64 - 64 * b as i64, 64));
    let [bt_lv, bt_llo, bt_lhi, bt_rv, bt_rlo, bt_rhi] = bt;
    let out = out.as_mut_ptr();
    for x in columns {
        let l = _mm512_set1_epi64(left[x] as i64);
        let first = x as i64 - i64::from(min_disparity);
        let dst = out.add(x * lanes);
        let il = BT_PAD + x;
        let (lv, llo, lhi) = if AD {
            (
                _mm512_set1_epi8(*bt_lv.add(il) as i8),
                _mm512_set1_epi8(*bt_llo.add(il) as i8),
                _mm512_set1_epi8(*bt_lhi.add(il) as i8),
            )
        } else {
            (pad, pad, pad)
        };
        for (b, &real) in real.iter().enumerate() {
            let k = 64 * b;
            let half = HALF && b + 1 == NB;
            let low = first - k as i64 - 63;
            let count = |j: usize| {
                // SAFETY: `first - lanes + 1 >= 0` and `first < width` on the lean columns, so
                // the 8 strings at `low + 8 (7 - j)` lie inside `right` (for a half block only
                // `j < 4` is read, from `low + 32`).
                let r = _mm512_loadu_si512(right.as_ptr().offset((low + 8 * (7 - j as i64)) as isize).cast());
                _mm512_popcnt_epi64(_mm512_xor_si512(l, r))
            };
            let mut cost = hamming_block(count, unpack, half);
            if AD {
                let block: u64 = if half { u64::from(u32::MAX) } else { u64::MAX };
                let i = BT_PAD as i64 + width as i64 - 1 - first + k as i64;
                // SAFETY: as in [`cost_row_u8_avx512`] for interior pixels: the lanes read end at
                // `i + lanes - k <= BT_PAD + width + 31`, inside the padded row.
                let load = |row: *const u8| _mm512_maskz_loadu_epi8(block, row.offset(i as isize).cast());
                cost = add_ad_term(cost, (lv, llo, lhi), (load(bt_rv), load(bt_rlo), load(bt_rhi)), consts);
            }
            // SAFETY: inside this pixel's `lanes` entries, as in [`cost_row_u8_avx512`].
            store_block(dst.add(k), _mm512_mask_mov_epi8(pad, real, cost), half);
        }
    }
}

/// The census costs of one block of 64 disparities (32 when `half`) of the 8-bit cost row from
/// `count(j)`, the popcounts of load `j` (8 right census strings, descending disparities):
/// loads 2a and 2a + 1 give disparities 16a.. (bytes 16a..16a + 16 of `pair(a)`), the pairs'
/// ranges then put together by byte blends.
#[inline(always)]
unsafe fn hamming_block(count: impl Fn(usize) -> __m512i, unpack: __m512i, half: bool) -> __m512i {
    let pair = |a: usize| _mm512_permutex2var_epi8(count(2 * a), unpack, count(2 * a + 1));
    let low_half = _mm512_mask_blend_epi8(0xffff_0000_ffff_0000, pair(0), pair(1));
    if half {
        low_half
    } else {
        let high_half = _mm512_mask_blend_epi8(0xffff_0000_ffff_0000, pair(2), pair(3));
        _mm512_mask_blend_epi8(0xffff_ffff_0000_0000, low_half, high_half)
    }
}

/// `cost + min(weight · BT, cap)` in bytes, from the left pixel's BT value, lo and hi (`left`,
/// broadcast) and the right pixels' (`right`, one per disparity).
#[inline(always)]
unsafe fn add_ad_term(
    cost: __m512i,
    left: (__m512i, __m512i, __m512i),
    right: (__m512i, __m512i, __m512i),
    consts: &U8Consts,
) -> __m512i {
    let ((lv, llo, lhi), (rv, rlo, rhi)) = (left, right);
    let d_lr = _mm512_max_epu8(_mm512_subs_epu8(lv, rhi), _mm512_subs_epu8(rlo, lv));
    let d_rl = _mm512_max_epu8(_mm512_subs_epu8(rv, lhi), _mm512_subs_epu8(llo, rv));
    let bt = _mm512_min_epu8(_mm512_min_epu8(d_lr, d_rl), consts.top);
    _mm512_add_epi8(cost, _mm512_permutex2var_epi8(consts.term_lo, bt, consts.term_hi))
}

/// Stores a block's costs at `at` (32 of them when `half`): two 256-bit stores where one 512-bit
/// store would split a cache line (rows are 64-byte aligned, pixels a multiple of 32 lanes).
///
/// # Safety
/// `at` has 64 (32 when `half`) writable bytes.
#[inline(always)]
unsafe fn store_block(at: *mut u8, cost: __m512i, half: bool) {
    if half {
        _mm256_storeu_si256(at.cast(), _mm512_castsi512_si256(cost));
    } else if (at as usize).is_multiple_of(64) {
        _mm512_storeu_si512(at.cast(), cost);
    } else {
        _mm256_storeu_si256(at.cast(), _mm512_castsi512_si256(cost));
        _mm256_storeu_si256(at.add(32).cast(), _mm512_extracti64x4_epi64::<1>(cost));
    }
}

/// AVX-512 VBMI [`super::p2_row_u8`], 32 pixels per step: the absolute difference in 16 bits,
/// divided by 257 exactly as `mulhi(d, 0xff01) >> 8` (checked for every `d`), narrowed to bytes,
/// then looked up in the 256-entry table by two two-register byte permutations (index bits 0–6)
/// and a blend on bit 7.
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL and VBMI; `a`, `b` and `out` of equal length.
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vbmi")]
pub(super) unsafe fn p2_row_u8_avx512(table: &[u8; 256], a: &[u16], b: &[u16], out: &mut [u8]) {
    let t: [__m512i; 4] = std::array::from_fn(|i| _mm512_loadu_si512(table.as_ptr().add(64 * i).cast()));
    let by_257 = _mm512_set1_epi16(0xff01u16 as i16);
    let n = out.len();
    let mut i = 0;
    while i < n {
        let m = (n - i).min(32);
        let mask: __mmask32 = if m == 32 { !0 } else { (1u32 << m) - 1 };
        // SAFETY: masked to the `m` entries from `i` of the three slices.
        let va = _mm512_maskz_loadu_epi16(mask, a.as_ptr().add(i).cast());
        let vb = _mm512_maskz_loadu_epi16(mask, b.as_ptr().add(i).cast());
        let step = _mm512_sub_epi16(_mm512_max_epu16(va, vb), _mm512_min_epu16(va, vb));
        let index = _mm512_castsi256_si512(_mm512_cvtepi16_epi8(_mm512_srli_epi16::<8>(_mm512_mulhi_epu16(
            step, by_257,
        ))));
        let low = _mm512_permutex2var_epi8(t[0], index, t[1]);
        let high = _mm512_permutex2var_epi8(t[2], index, t[3]);
        let p2 = _mm512_mask_blend_epi8(_mm512_movepi8_mask(index), low, high);
        _mm256_mask_storeu_epi8(out.as_mut_ptr().add(i).cast(), mask, _mm512_castsi512_si256(p2));
        i += 32;
    }
}

/// AVX-512BW [`super::path_step_u8`]: 64 disparities per instruction (and a 32-lane step
/// when the padded count is an odd multiple of 32). The `u16` sums are formed from the even
/// and odd bytes of each path vector (a mask and a shift, no cross-lane widening) and put
/// back in disparity order by two word permutations per 64 lanes.
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL; lengths as checked by [`super::path_step_u8`].
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl")]
pub(super) unsafe fn path_step_u8_avx512<const N: usize>(
    cost: &[u8],
    p1: u8,
    ins: [PathInU8<'_>; N],
    outs: [&mut [u8]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u8; N] {
    let lanes = cost.len();
    let nd = sum.len();
    let p1v = _mm512_set1_epi8(p1 as i8);
    let low_bytes = _mm512_set1_epi16(0xff);
    let (lo_order, hi_order) = (interleave(0), interleave(32));
    let lo_order = _mm512_loadu_si512(lo_order.as_ptr().cast());
    let hi_order = _mm512_loadu_si512(hi_order.as_ptr().cast());
    let prev: [*const u8; N] = std::array::from_fn(|i| ins[i].prev.as_ptr());
    let out: [*mut u8; N] = {
        let mut outs = outs;
        std::array::from_fn(|i| outs[i].as_mut_ptr())
    };
    let jump: [__m512i; N] =
        std::array::from_fn(|i| _mm512_set1_epi8(ins[i].prev_min.saturating_add(ins[i].p2) as i8));
    let pmin: [__m512i; N] = std::array::from_fn(|i| _mm512_set1_epi8(ins[i].prev_min as i8));
    let mut mins = [_mm512_set1_epi8(-1); N];
    let mut k = 0;
    while k + 64 <= lanes {
        // SAFETY (all pointer accesses below): `k + 64 <= lanes`, `prev`/`out` have
        // `lanes + 2` entries so offsets `k..k + 66` are in bounds, and the `sum` accesses are
        // masked to the lanes below `nd = sum.len()`.
        let c = _mm512_loadu_si512(cost.as_ptr().add(k).cast());
        let (mut even, mut odd) = (_mm512_setzero_si512(), _mm512_setzero_si512());
        for i in 0..N {
            let v = path_vector!(U8_512, c, prev[i].add(k), out[i].add(k + 1), p1v, jump[i], pmin[i]);
            mins[i] = _mm512_min_epu8(mins[i], v);
            even = _mm512_add_epi16(even, _mm512_and_si512(v, low_bytes));
            odd = _mm512_add_epi16(odd, _mm512_srli_epi16::<8>(v));
        }
        for (half, order) in [lo_order, hi_order].into_iter().enumerate() {
            let first = k + 32 * half;
            if first < nd {
                let mut total = _mm512_permutex2var_epi16(even, order, odd);
                let mask: __mmask32 = if nd - first >= 32 { !0 } else { (1u32 << (nd - first)) - 1 };
                let dst = sum.as_mut_ptr().add(first);
                if accumulate {
                    total = _mm512_add_epi16(total, _mm512_maskz_loadu_epi16(mask, dst.cast()));
                }
                _mm512_mask_storeu_epi16(dst.cast(), mask, total);
            }
        }
        k += 64;
    }
    let mut result: [u8; N] = std::array::from_fn(|i| {
        let m = mins[i];
        hmin_epu8_256(_mm256_min_epu8(_mm512_castsi512_si256(m), _mm512_extracti64x4_epi64::<1>(m)))
    });
    if k < lanes {
        // The last 32 lanes, with 256-bit registers: the 16-bit sums by widening.
        // SAFETY: `k + 32 == lanes`; the same bounds as above.
        let p1v = _mm512_castsi512_si256(p1v);
        let c = _mm256_loadu_si256(cost.as_ptr().add(k).cast());
        let mut total = _mm512_setzero_si512();
        for i in 0..N {
            let (jump, pmin) = (_mm512_castsi512_si256(jump[i]), _mm512_castsi512_si256(pmin[i]));
            let v = path_vector!(U8_256, c, prev[i].add(k), out[i].add(k + 1), p1v, jump, pmin);
            result[i] = result[i].min(hmin_epu8_256(v));
            total = _mm512_add_epi16(total, _mm512_cvtepu8_epi16(v));
        }
        if k < nd {
            let mask: __mmask32 = if nd - k >= 32 { !0 } else { (1u32 << (nd - k)) - 1 };
            let dst = sum.as_mut_ptr().add(k);
            if accumulate {
                total = _mm512_add_epi16(total, _mm512_maskz_loadu_epi16(mask, dst.cast()));
            }
            _mm512_mask_storeu_epi16(dst.cast(), mask, total);
        }
    }
    result
}
