//! The AVX2 kernels (x86-64). Each is the AVX2 version of the function of the same stem in
//! [`super::scalar`], selected by the dispatch in [`super`] only when the CPU has AVX2, and
//! proptested against that scalar reference. Imports only [`super::layout`] and [`super::scalar`].

use std::arch::x86_64::*;

use super::layout::{
    padded_lanes, padded_lanes_u8, AdRows, BandRow, PathIn, PathInU8, Samples, Window, AD_LANE_MASKS, BT_PAD,
};
use super::scalar::{
    bt_fill_in_order, census_costs_in_blocks, census_span_scalar, keep_smaller_scalar, pad_window_rows,
    window_offsets,
};

mod median;
mod row;
pub(super) use median::median3x3_row_avx2;
pub(super) use row::row_avx2;

/// Minimum of the 16 unsigned 16-bit lanes.
#[inline]
#[target_feature(enable = "avx2")]
pub(crate) fn hmin_epu16_256(v: __m256i) -> u16 {
    let m = _mm_min_epu16(_mm256_castsi256_si128(v), _mm256_extracti128_si256::<1>(v));
    _mm_extract_epi16::<0>(_mm_minpos_epu16(m)) as u16
}

/// Minimum of the 32 unsigned 8-bit lanes.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) fn hmin_epu8_256(v: __m256i) -> u8 {
    let m = _mm_min_epu8(_mm256_castsi256_si128(v), _mm256_extracti128_si256::<1>(v));
    // Pairs of bytes to words (the smaller byte of each pair), then the word minimum.
    let m = _mm_min_epu8(m, _mm_srli_epi16::<8>(m));
    let m = _mm_and_si128(m, _mm_set1_epi16(0xff));
    _mm_extract_epi16::<0>(_mm_minpos_epu16(m)) as u8
}

/// `total += v` in 16 bits, as the sums of the even and of the odd lanes (a mask and a shift,
/// no cross-lane widening; [`store_even_odd`] puts them back in order).
#[inline]
#[target_feature(enable = "avx2")]
fn add_even_odd(total: &mut [__m256i; 2], v: __m256i) {
    total[0] = _mm256_add_epi16(total[0], _mm256_and_si256(v, _mm256_set1_epi16(0xff)));
    total[1] = _mm256_add_epi16(total[1], _mm256_srli_epi16::<8>(v));
}

/// Stores (or, with `accumulate`, adds) the 32 sums of lanes `k..k + 32` that [`add_even_odd`]
/// gathered into `sum[k..]`, as far as `sum` reaches: the words interleaved back within each
/// 128-bit lane, then the lanes' halves paired.
///
/// # Safety
/// The CPU must have AVX2; `k < sum.len()`.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn store_even_odd(sum: &mut [u16], k: usize, even: __m256i, odd: __m256i, accumulate: bool) {
    let (low, high) = (_mm256_unpacklo_epi16(even, odd), _mm256_unpackhi_epi16(even, odd));
    let ordered =
        [_mm256_permute2x128_si256::<0x20>(low, high), _mm256_permute2x128_si256::<0x31>(low, high)];
    for (half, total) in ordered.into_iter().enumerate() {
        store_sums(sum, k + 16 * half, total, accumulate);
    }
}

/// Stores (or, with `accumulate`, adds) the 16 sums `total` at `sum[k..]`, as far as `sum`
/// reaches. Not a `target_feature` function, so that it inlines into
/// [`path_step_avx2_body`]'s callers (the AVX2 copies of the aggregation loops) as well.
///
/// # Safety
/// The CPU must have AVX2.
#[inline(always)]
unsafe fn store_sums(sum: &mut [u16], k: usize, mut total: __m256i, accumulate: bool) {
    let nd = sum.len();
    if k + 16 <= nd {
        // SAFETY: entries k..k + 16 of `sum`.
        let dst = sum.as_mut_ptr().add(k);
        if accumulate {
            total = _mm256_add_epi16(total, _mm256_loadu_si256(dst.cast()));
        }
        _mm256_storeu_si256(dst.cast(), total);
    } else if k < nd {
        let mut tmp = [0u16; 16];
        _mm256_storeu_si256(tmp.as_mut_ptr().cast(), total);
        for (j, &t) in tmp[..nd - k].iter().enumerate() {
            let d = &mut sum[k + j];
            *d = if accumulate { d.wrapping_add(t) } else { t };
        }
    }
}

/// AVX2 [`super::path_step_u8`]: 32 disparities per instruction, the 16-bit sums from the even
/// and the odd bytes ([`add_even_odd`]). For the warm-up rows and for vectors longer than the
/// register row kernel ([`row_avx2`]) keeps.
///
/// # Safety
/// The CPU must have AVX2; lengths as checked by [`super::path_step_u8`].
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn path_step_u8_avx2<const N: usize>(
    cost: &[u8],
    p1: u8,
    ins: [PathInU8<'_>; N],
    outs: [&mut [u8]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u8; N] {
    let lanes = cost.len();
    let p1v = _mm256_set1_epi8(p1 as i8);
    let prev: [*const u8; N] = std::array::from_fn(|i| ins[i].prev.as_ptr());
    let out: [*mut u8; N] = {
        let mut outs = outs;
        std::array::from_fn(|i| outs[i].as_mut_ptr())
    };
    let jump: [__m256i; N] =
        std::array::from_fn(|i| _mm256_set1_epi8(ins[i].prev_min.saturating_add(ins[i].p2) as i8));
    let pmin: [__m256i; N] = std::array::from_fn(|i| _mm256_set1_epi8(ins[i].prev_min as i8));
    let mut mins = [_mm256_set1_epi8(-1); N];
    let mut k = 0;
    while k < lanes {
        // SAFETY (pointer accesses below): `k + 32 <= lanes` (lanes is a multiple of 32) and
        // `prev`/`out` have `lanes + 2` entries; `store_even_odd` writes only below `nd`.
        let c = _mm256_loadu_si256(cost.as_ptr().add(k).cast());
        let mut total = [_mm256_setzero_si256(); 2];
        for i in 0..N {
            let v = path_vector!(U8_256, c, prev[i].add(k), out[i].add(k + 1), p1v, jump[i], pmin[i]);
            mins[i] = _mm256_min_epu8(mins[i], v);
            add_even_odd(&mut total, v);
        }
        if k < sum.len() {
            store_even_odd(sum, k, total[0], total[1], accumulate);
        }
        k += 32;
    }
    std::array::from_fn(|i| hmin_epu8_256(mins[i]))
}

/// AVX2 [`super::path_step`]: 16 disparities per instruction ([`path_step_avx2_body`] compiled
/// with AVX2).
///
/// # Safety
/// The CPU must have AVX2; lengths as checked by [`super::path_step`].
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn path_step_avx2<const N: usize>(
    cost: &[u16],
    p1: u16,
    ins: [PathIn<'_>; N],
    outs: [&mut [u16]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u16; N] {
    path_step_avx2_body(cost, p1, ins, outs, sum, accumulate)
}

/// The body of [`path_step_avx2`], for [`super::path_step_inlined`]: not a `#[target_feature]`
/// function, so it can be inlined into the AVX2 versions of the aggregation loops
/// (`multiversion!`), which compile it with AVX2. Called once per pixel, the call and its
/// argument arrays cost about as much as the step itself on short disparity ranges. Called from
/// code compiled without AVX2 it is still correct, but its intrinsics become calls.
///
/// # Safety
/// The CPU must have AVX2; lengths as checked by [`super::path_step`].
#[inline(always)]
pub(super) unsafe fn path_step_avx2_body<const N: usize>(
    cost: &[u16],
    p1: u16,
    ins: [PathIn<'_>; N],
    outs: [&mut [u16]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u16; N] {
    let lanes = cost.len();
    let p1v = _mm256_set1_epi16(p1 as i16);
    let prev: [*const u16; N] = std::array::from_fn(|i| ins[i].prev.as_ptr());
    let out: [*mut u16; N] = {
        let mut outs = outs;
        std::array::from_fn(|i| outs[i].as_mut_ptr())
    };
    let jump: [__m256i; N] =
        std::array::from_fn(|i| _mm256_set1_epi16(ins[i].prev_min.saturating_add(ins[i].p2) as i16));
    let pmin: [__m256i; N] = std::array::from_fn(|i| _mm256_set1_epi16(ins[i].prev_min as i16));
    let mut mins = [_mm256_set1_epi16(-1); N];
    let mut k = 0;
    while k < lanes {
        // SAFETY (pointer accesses below): `k + 16 <= lanes` (lanes is a multiple of 16),
        // `prev`/`out` have `lanes + 2` entries, and `store_sums` writes only inside `sum`.
        let c = _mm256_loadu_si256(cost.as_ptr().add(k).cast());
        let mut total = _mm256_setzero_si256();
        for i in 0..N {
            let v = path_vector!(U16_256, c, prev[i].add(k), out[i].add(k + 1), p1v, jump[i], pmin[i]);
            mins[i] = _mm256_min_epu16(mins[i], v);
            total = _mm256_add_epi16(total, v);
        }
        store_sums(sum, k, total, accumulate);
        k += 16;
    }
    std::array::from_fn(|i| hmin_epu16_256(mins[i]))
}

/// AVX2 [`super::argmin`].
///
/// # Safety
/// The CPU must have AVX2; `values` is not empty.
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn argmin_avx2(values: &[u16]) -> (u16, usize) {
    let n = values.len();
    let p = values.as_ptr();
    let mut m = _mm256_set1_epi16(-1);
    let mut k = 0;
    while k + 16 <= n {
        // SAFETY: `k + 16 <= n`.
        m = _mm256_min_epu16(m, _mm256_loadu_si256(p.add(k).cast()));
        k += 16;
    }
    let mut min = hmin_epu16_256(m);
    for &v in &values[k..] {
        min = min.min(v);
    }
    let mv = _mm256_set1_epi16(min as i16);
    let mut k = 0;
    while k + 16 <= n {
        // SAFETY: `k + 16 <= n`.
        let eq = _mm256_cmpeq_epi16(_mm256_loadu_si256(p.add(k).cast()), mv);
        let bits = _mm256_movemask_epi8(eq) as u32;
        if bits != 0 {
            return (min, k + bits.trailing_zeros() as usize / 2);
        }
        k += 16;
    }
    (min, k + values[k..].iter().position(|&v| v == min).unwrap_or(0))
}

/// [`super::cost_row_u8`] for machines without the AVX-512 kernel (AVX2, or AVX-512 without
/// VPOPCNTDQ and VBMI): each pixel's costs made in 8 bits ([`cost_pixel_u8_avx2`]),
/// [`super::layout::PAD_U8`] from `nd` on. No `u16` row in between: every cost is at most 255.
///
/// # Safety
/// The CPU must have AVX2 and POPCNT; lengths and bounds as checked by [`super::cost_row_u8`].
#[target_feature(enable = "avx2,popcnt")]
pub(super) unsafe fn cost_row_u8_avx2(
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
        // multiple of 32.
        cost_pixel_u8_avx2(left, right, x, min_disparity, nd, worst as u8, &ad, costs);
    }
}

/// [`cost_pixel_avx2`] in 8 bits: each block's 16 distances packed to bytes, the AD term
/// narrowed before it is added ([`add_ad_u8_avx2`]).
///
/// # Safety
/// As [`cost_pixel_avx2`], with `costs.len()` a multiple of 16 and at least `nd`.
#[inline]
#[target_feature(enable = "avx2,popcnt")]
#[allow(clippy::too_many_arguments)]
unsafe fn cost_pixel_u8_avx2(
    left: &[u64],
    right: &[u64],
    x: usize,
    min_disparity: i32,
    nd: usize,
    worst: u8,
    ad: &Option<AdRows<'_>>,
    costs: &mut [u8],
) {
    // SAFETY: `hamming_block_avx2` reads 16 strings and the store writes 16 entries, as the
    // driver allows; the CPU has AVX2 (this function's precondition).
    let (lo, hi, first) =
        census_costs_in_blocks(left, right, x, min_disparity, nd, worst, costs, |l, r, dst| {
            let d = hamming_block_avx2(l, r);
            let d = _mm_packus_epi16(_mm256_castsi256_si128(d), _mm256_extracti128_si256::<1>(d));
            _mm_storeu_si128(dst.cast(), d)
        });
    if let Some(ad) = ad {
        // SAFETY: as in `cost_pixel_avx2`.
        add_ad_u8_avx2(ad, costs.as_mut_ptr(), x, left.len(), first, lo, hi);
    }
}

/// AVX2 [`super::keep_smaller`]: 16 lanes per step (`best` takes the unsigned minimum, `index`
/// the new index where the cost is strictly smaller), the lanes past the last whole step as in
/// the reference.
///
/// # Safety
/// The CPU must have AVX2; lengths as checked by [`super::keep_smaller`].
#[inline]
#[target_feature(enable = "avx2")]
pub(super) unsafe fn keep_smaller_avx2(costs: &[u16], first_index: u16, best: &mut [u16], index: &mut [u16]) {
    let n = costs.len();
    let iota = _mm256_setr_epi16(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    let mut k = 0;
    while k + 16 <= n {
        // SAFETY: `k + 16 <= n`, the length of all three slices.
        let c = _mm256_loadu_si256(costs.as_ptr().add(k).cast());
        let b = _mm256_loadu_si256(best.as_ptr().add(k).cast());
        let i = _mm256_loadu_si256(index.as_ptr().add(k).cast());
        // Not better where c >= b, i.e. max(c, b) == c.
        let keep = _mm256_cmpeq_epi16(_mm256_max_epu16(c, b), c);
        let ks = _mm256_add_epi16(iota, _mm256_set1_epi16((usize::from(first_index) + k) as i16));
        _mm256_storeu_si256(best.as_mut_ptr().add(k).cast(), _mm256_min_epu16(c, b));
        _mm256_storeu_si256(index.as_mut_ptr().add(k).cast(), _mm256_blendv_epi8(ks, i, keep));
        k += 16;
    }
    keep_smaller_scalar(&costs[k..], first_index + k as u16, &mut best[k..], &mut index[k..]);
}

/// The AD term `min(weight · BT, cap)` of pixel `x` for its feasible disparities `lo..hi` (as
/// the AD part of [`super::scalar::cost_row_scalar`]), 16 disparities per step: `add(k, term)`
/// gets the terms of disparities `k..k + 16` (`k` a multiple of 16) as 16-bit lanes, 0 outside
/// `lo..hi`.
///
/// # Safety
/// The CPU must have AVX2; `lo..hi` are pixel `x`'s feasible disparities and the BT rows are
/// padded by [`BT_PAD`].
#[inline(always)]
unsafe fn for_ad_blocks(
    ad: &AdRows<'_>,
    x: usize,
    width: usize,
    first: i64,
    lo: usize,
    hi: usize,
    mut add: impl FnMut(usize, __m256i),
) {
    if lo >= hi {
        return;
    }
    let il = BT_PAD + x;
    let (lv, llo, lhi) = (
        _mm_set1_epi8(ad.left.value[il] as i8),
        _mm_set1_epi8(ad.left.lo[il] as i8),
        _mm_set1_epi8(ad.left.hi[il] as i8),
    );
    let weight = _mm256_set1_epi16(ad.weight as i16);
    let cap = _mm256_set1_epi16(ad.cap as i16);
    let base = BT_PAD as i64 + width as i64 - 1 - first;
    let mut k = lo & !15;
    while k < hi {
        let below = lo.saturating_sub(k);
        let upto = (hi - k).min(16);
        // SAFETY: `below <= 15` and `1 <= upto <= 16`: both 16-entry reads are inside `AD_LANE_MASKS`.
        let mask = _mm256_and_si256(
            _mm256_loadu_si256(AD_LANE_MASKS.as_ptr().add(16 - below).cast()),
            _mm256_loadu_si256(AD_LANE_MASKS.as_ptr().add(32 - upto).cast()),
        );
        // SAFETY: as in `add_ad_avx512`, the 16 bytes read at `i` are inside the padded rows.
        let i = (base + k as i64) as usize;
        let rv = _mm_loadu_si128(ad.right.value.as_ptr().add(i).cast());
        let rlo = _mm_loadu_si128(ad.right.lo.as_ptr().add(i).cast());
        let rhi = _mm_loadu_si128(ad.right.hi.as_ptr().add(i).cast());
        let d_lr = _mm_max_epu8(_mm_subs_epu8(lv, rhi), _mm_subs_epu8(rlo, lv));
        let d_rl = _mm_max_epu8(_mm_subs_epu8(rv, lhi), _mm_subs_epu8(llo, rv));
        let bt = _mm256_cvtepu8_epi16(_mm_min_epu8(d_lr, d_rl));
        let term = _mm256_min_epu16(_mm256_mullo_epi16(bt, weight), cap);
        add(k, _mm256_and_si256(term, mask));
        k += 16;
    }
}

/// Adds the AD term of pixel `x` ([`for_ad_blocks`]) to its 16-bit costs at `dst`.
///
/// # Safety
/// The CPU must have AVX2; `dst` points at pixel `x`'s `padded_lanes(nd)` entries, `lo..hi` are
/// its feasible disparities and the BT rows are padded by [`BT_PAD`].
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn add_ad_avx2(
    ad: &AdRows<'_>,
    dst: *mut u16,
    x: usize,
    width: usize,
    first: i64,
    lo: usize,
    hi: usize,
) {
    for_ad_blocks(ad, x, width, first, lo, hi, |k, term| {
        // SAFETY: `k` is a multiple of 16 below `hi <= lanes` (a multiple of 16), so entries
        // `k..k + 16` are this pixel's.
        let p = dst.add(k);
        _mm256_storeu_si256(p.cast(), _mm256_add_epi16(_mm256_loadu_si256(p.cast()), term));
    });
}

/// Adds the AD term of pixel `x` ([`for_ad_blocks`]) to its 8-bit costs at `dst`, each term
/// narrowed before it is added (exact: the 8-bit passes run only where every cost, the term
/// included, is at most 255).
///
/// # Safety
/// The CPU must have AVX2; `dst` points at pixel `x`'s `padded_lanes_u8(nd)` entries, `lo..hi`
/// are its feasible disparities and the BT rows are padded by [`BT_PAD`].
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn add_ad_u8_avx2(
    ad: &AdRows<'_>,
    dst: *mut u8,
    x: usize,
    width: usize,
    first: i64,
    lo: usize,
    hi: usize,
) {
    for_ad_blocks(ad, x, width, first, lo, hi, |k, term| {
        let term = _mm_packus_epi16(_mm256_castsi256_si128(term), _mm256_extracti128_si256::<1>(term));
        // SAFETY: `k` is a multiple of 16 below `hi <= lanes` (a multiple of 32), so entries
        // `k..k + 16` are this pixel's.
        let p = dst.add(k);
        _mm_storeu_si128(p.cast(), _mm_add_epi8(_mm_loadu_si128(p.cast()), term));
    });
}

/// [`super::cost_row`] for AVX2 machines: [`cost_pixel_avx2`] for each pixel.
///
/// # Safety
/// The CPU must have AVX2 and POPCNT; lengths as checked by [`super::cost_row`].
#[target_feature(enable = "avx2,popcnt")]
pub(super) unsafe fn cost_row_avx2(
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
        cost_pixel_avx2(left, right, x, min_disparity, nd, worst, &ad, costs);
    }
}

/// [`super::cost_bands`] for AVX2 machines: [`cost_pixel_avx2`] for each pixel over its own
/// band.
///
/// # Safety
/// The CPU must have AVX2 and POPCNT; lengths as checked by [`super::cost_bands`].
#[target_feature(enable = "avx2,popcnt")]
pub(super) unsafe fn cost_bands_avx2(
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
        cost_pixel_avx2(left, right, x, o, nd, worst, &ad, &mut out[entries]);
    }
}

/// Pixel `x`'s costs from disparity `min_disparity` into `costs` (as
/// [`super::scalar::cost_bands_scalar`]'s pixel): the census Hamming distances by
/// [`census_costs_in_blocks`] with [`hamming_block_avx2`], then the AD term ([`add_ad_avx2`]).
///
/// # Safety
/// The CPU must have AVX2 and POPCNT; `costs.len()` is a multiple of 16 and at least `nd`, the BT
/// rows (if any) are padded by [`BT_PAD`].
#[inline]
#[target_feature(enable = "avx2,popcnt")]
#[allow(clippy::too_many_arguments)]
unsafe fn cost_pixel_avx2(
    left: &[u64],
    right: &[u64],
    x: usize,
    min_disparity: i32,
    nd: usize,
    worst: u16,
    ad: &Option<AdRows<'_>>,
    costs: &mut [u16],
) {
    // SAFETY: `hamming_block_avx2` reads 16 strings and its store writes 16 entries, as the
    // driver allows; the CPU has AVX2 (this function's precondition).
    let (lo, hi, first) =
        census_costs_in_blocks(left, right, x, min_disparity, nd, worst, costs, |l, r, dst| {
            _mm256_storeu_si256(dst.cast(), hamming_block_avx2(l, r))
        });
    if let Some(ad) = ad {
        // SAFETY: `lo..hi` are the feasible disparities of `x`, whose entries start at `costs`
        // (a multiple of 16 long, so every 16-entry block below `hi` is inside it).
        add_ad_avx2(ad, costs.as_mut_ptr(), x, left.len(), first, lo, hi);
    }
}

/// The 16 Hamming distances `popcount(l ^ r[15 - i])` for `i` in `0..16` (`r` the 16 right
/// census strings from the lowest address, so lane `i` is disparity `k + i`), as 16-bit lanes:
/// nibble-table popcounts summed per string by `vpsadbw`, packed down to 16 bits, put in order.
///
/// # Safety
/// The CPU must have AVX2; `r` points at 16 readable `u64`.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn hamming_block_avx2(l: u64, r: *const u64) -> __m256i {
    let nibbles = _mm256_setr_epi8(
        0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4, 0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4,
    );
    let low = _mm256_set1_epi8(0x0f);
    let lv = _mm256_set1_epi64x(l as i64);
    let count = |v: __m256i| {
        let v = _mm256_xor_si256(v, lv);
        let lo = _mm256_shuffle_epi8(nibbles, _mm256_and_si256(v, low));
        let hi = _mm256_shuffle_epi8(nibbles, _mm256_and_si256(_mm256_srli_epi16::<4>(v), low));
        _mm256_sad_epu8(_mm256_add_epi8(lo, hi), _mm256_setzero_si256())
    };
    // Lowest address first: the 64-bit lanes hold disparities k+15..k+12, k+11..k+8, k+7..k+4
    // and k+3..k, each count < 65 in the low 16 bits of its lane.
    let c15 = count(_mm256_loadu_si256(r.cast()));
    let c11 = count(_mm256_loadu_si256(r.add(4).cast()));
    let c7 = count(_mm256_loadu_si256(r.add(8).cast()));
    let c3 = count(_mm256_loadu_si256(r.add(12).cast()));
    // 32-bit units [3 2 7 6 | 1 0 5 4], then 16-bit [3 2 7 6 11 10 15 14 | 1 0 5 4 9 8 13 12].
    let a = _mm256_packus_epi32(c3, c7);
    let b = _mm256_packus_epi32(c11, c15);
    let packed = _mm256_packus_epi32(a, b);
    // Pairs (1 0) (3 2) … in order, then each pair's two words swapped.
    let ordered = _mm256_permutevar8x32_epi32(packed, _mm256_setr_epi32(4, 0, 5, 1, 6, 2, 7, 3));
    let swap = _mm256_setr_epi8(
        2, 3, 0, 1, 6, 7, 4, 5, 10, 11, 8, 9, 14, 15, 12, 13, 2, 3, 0, 1, 6, 7, 4, 5, 10, 11, 8, 9, 14, 15,
        12, 13,
    );
    _mm256_shuffle_epi8(ordered, swap)
}

/// [`bt_fill_in_order`] compiled for AVX2 (eight 32-bit lanes for the divisions by 514).
///
/// # Safety
/// The CPU must have AVX2.
#[target_feature(enable = "avx2")]
pub(super) unsafe fn bt_fill_avx2(row: &[u16], value: &mut [u8], lo: &mut [u8], hi: &mut [u8]) {
    bt_fill_in_order(row, value, lo, hi)
}

/// [`super::scalar::census_row_scalar`] with AVX2: 16 pixels per step, their bits gathered in four 16-bit
/// accumulators (census bits 0–15, 16–31, 32–47 and 48–63, each filled most significant bit
/// first, as the reference shifts them in) and interleaved into the 64-bit strings at the end;
/// the pixels past the last whole step as in the reference.
///
/// # Safety
/// The CPU must have AVX2; lengths as for [`super::scalar::census_row_scalar`].
#[target_feature(enable = "avx2")]
pub(super) unsafe fn census_row_avx2(
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
    let tolerance = _mm256_set1_epi16(window.tolerance as i16);
    let one = _mm256_set1_epi16(1);
    let zero = _mm256_setzero_si256();
    let offsets = window_offsets(window, pw);
    let whole = width - width % 16;
    for x in (0..whole).step_by(16) {
        // SAFETY: x + 16 <= width, the length of `centre` and of `bits`; each padded row holds
        // `pw = width + 2 * rx` samples and dx + x + 16 <= 2 * rx + width.
        let c = _mm256_loadu_si256(centre.as_ptr().add(x).cast());
        let threshold = _mm256_subs_epu16(c, tolerance);
        let mut acc = [zero; 4];
        // Neighbour i is census bit n - 1 - i: accumulator j takes the neighbours of bits
        // 16j..16j + 16, highest bit (lowest i) first.
        for (j, a) in acc.iter_mut().enumerate().rev() {
            let first = n.saturating_sub(16 * j + 16);
            let end = n.saturating_sub(16 * j);
            let mut v = zero;
            for &offset in &offsets[first..end] {
                let neighbour = _mm256_loadu_si256(padded.as_ptr().add(offset + x).cast());
                // neighbour < threshold exactly when threshold - neighbour (saturating) > 0.
                let not_darker = _mm256_cmpeq_epi16(_mm256_subs_epu16(threshold, neighbour), zero);
                v = _mm256_or_si256(_mm256_slli_epi16::<1>(v), _mm256_andnot_si256(not_darker, one));
            }
            *a = v;
        }
        // 32-bit [bits 16–31 : 0–15] and [48–63 : 32–47] for pixels 0–3 | 8–11 and 4–7 | 12–15.
        let (lo01, hi01) = (_mm256_unpacklo_epi16(acc[0], acc[1]), _mm256_unpackhi_epi16(acc[0], acc[1]));
        let (lo23, hi23) = (_mm256_unpacklo_epi16(acc[2], acc[3]), _mm256_unpackhi_epi16(acc[2], acc[3]));
        // 64-bit strings of pixels 0,1 | 8,9; 2,3 | 10,11; 4,5 | 12,13; 6,7 | 14,15.
        let a = _mm256_unpacklo_epi32(lo01, lo23);
        let b = _mm256_unpackhi_epi32(lo01, lo23);
        let c = _mm256_unpacklo_epi32(hi01, hi23);
        let d = _mm256_unpackhi_epi32(hi01, hi23);
        let out = bits.as_mut_ptr().add(x);
        _mm256_storeu_si256(out.cast(), _mm256_permute2x128_si256::<0x20>(a, b));
        _mm256_storeu_si256(out.add(4).cast(), _mm256_permute2x128_si256::<0x20>(c, d));
        _mm256_storeu_si256(out.add(8).cast(), _mm256_permute2x128_si256::<0x31>(a, b));
        _mm256_storeu_si256(out.add(12).cast(), _mm256_permute2x128_si256::<0x31>(c, d));
    }
    // The rest as the reference does it.
    census_span_scalar(padded, window, centre, whole, bits);
}
