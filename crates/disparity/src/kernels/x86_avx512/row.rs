//! The AVX-512 row kernels of [`crate::kernels::row_u8`]: the path steps of a whole row on 8-bit
//! path costs, with the horizontal path kept in registers.
//!
//! The per-pixel kernel ([`crate::kernels::path_step_u8`]) reads the previous pixel's path costs
//! from memory at offsets −1, 0 and +1 lanes right after the previous step stored them. Along a
//! row the horizontal path is one long dependency chain, and loads straddling two recent vector
//! stores cannot be forwarded from the store buffer, so every pixel waited for its predecessor's
//! stores to reach the cache. Here the horizontal path vector never leaves the registers: its
//! `d ± 1` neighbours come from in-register byte shifts and its minimum is reduced to a broadcast
//! without a trip through a general register. The paths continuing from the previous row (read
//! long after they were stored) stay in memory. The results are those of
//! [`crate::kernels::scalar::path_step_u8_scalar`] pixel by pixel.

use std::arch::x86_64::*;

use crate::kernels::layout::{interleave, FromRow, Trailing};

/// The minimum of the 64 unsigned bytes of `m`, in every byte.
#[inline]
#[target_feature(enable = "avx512f,avx512bw")]
fn min_broadcast_epu8(m: __m512i) -> __m512i {
    let m = _mm512_min_epu8(m, _mm512_shuffle_i64x2::<0x4e>(m, m));
    let m = _mm512_min_epu8(m, _mm512_shuffle_i64x2::<0xb1>(m, m));
    let m = _mm512_min_epu8(m, _mm512_shuffle_epi32::<0x4e>(m));
    let m = _mm512_min_epu8(m, _mm512_shuffle_epi32::<0xb1>(m));
    let m = _mm512_min_epu8(m, _mm512_rol_epi32::<16>(m));
    // Every word now holds the minimum pair; the low byte of `min(m, m >> 8)` is its
    // minimum, which byte 0 of each 128-bit lane then broadcasts.
    let m = _mm512_min_epu8(m, _mm512_srli_epi16::<8>(m));
    _mm512_shuffle_epi8(m, _mm512_setzero_si512())
}

/// The 64 lanes one below (`d - 1`) and one above (`d + 1`) those of `v`, with `lower` and
/// `upper` the registers holding the lanes below and above it: a 128-bit-lane rotation
/// (`valignq`) then a byte alignment within 128-bit lanes (`vpalignr`).
#[inline]
#[target_feature(enable = "avx512f,avx512bw")]
fn neighbours(lower: __m512i, v: __m512i, upper: __m512i) -> (__m512i, __m512i) {
    // [top 128 bits of lower, low 384 bits of v] and [high 384 bits of v, low 128 of upper].
    let down = _mm512_alignr_epi64::<6>(v, lower);
    let up = _mm512_alignr_epi64::<2>(upper, v);
    (_mm512_alignr_epi8::<15>(v, down), _mm512_alignr_epi8::<1>(up, v))
}

/// What every pixel step of a row shares.
struct Shape<const NV: usize> {
    width: usize,
    lanes: usize,
    nd: usize,
    pad: __m512i,
    p1: __m512i,
    /// Lanes past `lanes` are loaded as the pad (255), like the pads of the memory layout.
    lane_mask: [__mmask64; NV],
    /// [`interleave`] orders of the low and high 32 lanes.
    order: [__m512i; 2],
    /// Byte indices of the lanes below and above, for [`neighbours_vbmi`].
    shift: [__m512i; 2],
}

/// A horizontal path's state: its costs at the previous pixel and their minimum (broadcast).
struct Horizontal<const NV: usize> {
    path: [__m512i; NV],
    min: __m512i,
}

/// One path step from the previous vector `prev` (with its `d ∓ 1` neighbours `l`, `r`).
#[inline]
#[target_feature(enable = "avx512f,avx512bw")]
fn step(
    p1: __m512i,
    c: __m512i,
    prev: __m512i,
    l: __m512i,
    r: __m512i,
    prev_min: __m512i,
    jump: __m512i,
) -> __m512i {
    path_vector!(U8_512_REGISTERS, c, prev, l, r, p1, jump, prev_min)
}

/// `total += v` in 16 bits, as the sums of the even and of the odd lanes (a mask and a shift,
/// no cross-lane widening; [`interleave`] puts them back in order once per pixel).
#[inline]
#[target_feature(enable = "avx512f,avx512bw")]
fn add_even_odd(total: &mut [__m512i; 2], v: __m512i) {
    total[0] = _mm512_add_epi16(total[0], _mm512_and_si512(v, _mm512_set1_epi16(0xff)));
    total[1] = _mm512_add_epi16(total[1], _mm512_srli_epi16::<8>(v));
}

/// The minimum of the 64 unsigned bytes of `m` (off the horizontal chain: fewer shuffles than
/// [`min_broadcast_epu8`]).
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl")]
fn hmin_epu8(m: __m512i) -> u8 {
    let m = _mm256_min_epu8(_mm512_castsi512_si256(m), _mm512_extracti64x4_epi64::<1>(m));
    let m = _mm_min_epu8(_mm256_castsi256_si128(m), _mm256_extracti128_si256::<1>(m));
    let m = _mm_min_epu8(m, _mm_srli_epi16::<8>(m));
    let m = _mm_and_si128(m, _mm_set1_epi16(0xff));
    _mm_extract_epi16::<0>(_mm_minpos_epu16(m)) as u8
}

/// [`neighbours`] with one VBMI byte permutation each.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vbmi")]
fn neighbours_vbmi(lower: __m512i, v: __m512i, upper: __m512i, order: &[__m512i; 2]) -> (__m512i, __m512i) {
    (_mm512_permutex2var_epi8(lower, order[0], v), _mm512_permutex2var_epi8(v, order[1], upper))
}

/// The steps of the `i`-th pixel `x` of a row: the horizontal path `h`, then the paths from
/// the previous row, their sum stored (or added) into `sum`.
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL; lengths as checked by [`crate::kernels::row_u8`]. Always
/// inlined into [`row_avx512`] (hence no `target_feature` of its own), so that the
/// horizontal path stays in registers from pixel to pixel.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn pixel<const NV: usize, const K: usize, const VBMI: bool>(
    shape: &Shape<NV>,
    h: &mut Horizontal<NV>,
    i: usize,
    x: usize,
    cost: &[u8],
    p2: &[u8],
    from_row: &mut [FromRow<'_>; K],
    sum: &mut [u16],
    accumulate: bool,
    reverse: bool,
) {
    let Shape { width, lanes, nd, pad, p1, lane_mask, order, shift } = *shape;
    let stride = lanes + 2;
    // SAFETY: pixel `x < width` has `lanes` costs at `x * lanes`; the loads are masked to
    // them.
    let c: [__m512i; NV] = std::array::from_fn(|v| unsafe {
        _mm512_mask_loadu_epi8(pad, lane_mask[v], cost.as_ptr().add(x * lanes + 64 * v).cast())
    });
    if i == 0 {
        // Entering the row: the path cost is the matching cost.
        h.path = c;
    } else {
        let jump = _mm512_adds_epu8(h.min, _mm512_set1_epi8(p2[x] as i8));
        let prev = h.path;
        for v in 0..NV {
            let lower = if v == 0 { pad } else { prev[v - 1] };
            let upper = if v + 1 == NV { pad } else { prev[v + 1] };
            let (l, r) = if VBMI {
                neighbours_vbmi(lower, prev[v], upper, &shift)
            } else {
                neighbours(lower, prev[v], upper)
            };
            h.path[v] = step(p1, c[v], prev[v], l, r, h.min, jump);
        }
    }
    let mut m = h.path[0];
    for p in &h.path[1..] {
        m = _mm512_min_epu8(m, *p);
    }
    h.min = min_broadcast_epu8(m);
    // The 16-bit sums of the even and the odd lanes of each register.
    let mut total: [[__m512i; 2]; NV] = [[_mm512_setzero_si512(); 2]; NV];
    for (t, &v) in total.iter_mut().zip(&h.path) {
        add_even_odd(t, v);
    }
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
            let jump = _mm512_set1_epi8(prev_min.saturating_add(from.p2[x]) as i8);
            (jump, _mm512_set1_epi8(prev_min as i8), from.prev.as_ptr().add(f * stride))
        };
        for v in 0..NV {
            let o = if fresh {
                // The path enters the image here.
                c[v]
            } else {
                // SAFETY: lane j of register v reads entries `64v + j + {0, 1, 2}` of pixel
                // `f`'s `lanes + 2`; the masks keep `64v + j < lanes`.
                let at = |o: usize| unsafe {
                    _mm512_mask_loadu_epi8(pad, lane_mask[v], src.add(64 * v + o).cast())
                };
                step(p1, c[v], at(1), at(0), at(2), prev_min, jump)
            };
            // SAFETY: masked to the `lanes` entries after pixel `x`'s pad.
            _mm512_mask_storeu_epi8(out.add(64 * v).cast(), lane_mask[v], o);
            m = _mm512_min_epu8(m, o);
            add_even_odd(&mut total[v], o);
        }
        from.out_mins[x] = hmin_epu8(m);
    }
    let s = sum.as_mut_ptr().add(x * nd);
    if accumulate {
        // The sums were stored a while ago: ask for the ones a few pixels ahead.
        let ahead = if reverse { x.wrapping_sub(6) } else { x + 6 };
        if ahead < width {
            let line = sum.as_ptr().add(ahead * nd).cast::<i8>();
            for b in (0..2 * nd).step_by(64) {
                _mm_prefetch::<_MM_HINT_T0>(line.add(b));
            }
        }
    }
    for q in 0..nd.div_ceil(32) {
        let n = nd - 32 * q;
        let mask: __mmask32 = if n >= 32 { !0 } else { (1u32 << n) - 1 };
        // SAFETY: masked to the `nd` sums of pixel `x`.
        let dst = s.add(32 * q);
        let [even, odd] = total[q / 2];
        let mut t = _mm512_permutex2var_epi16(even, order[q % 2], odd);
        if accumulate {
            t = _mm512_add_epi16(t, _mm512_maskz_loadu_epi16(mask, dst.cast()));
        }
        _mm512_mask_storeu_epi16(dst.cast(), mask, t);
    }
}

/// AVX-512 [`crate::kernels::row_u8`] with the horizontal paths in `NV` registers of 64 lanes.
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL; lengths as checked by [`crate::kernels::row_u8`], and
/// `64 * (NV - 1) < lanes <= 64 * NV`.
#[target_feature(enable = "avx512f,avx512bw,avx512vl")]
#[allow(clippy::too_many_arguments)]
pub(in crate::kernels) unsafe fn row_avx512<const NV: usize, const K: usize>(
    cost: &[u8],
    lanes: usize,
    nd: usize,
    p1: u8,
    p2: &[u8],
    from_row: [FromRow<'_>; K],
    sum: &mut [u16],
    reverse: bool,
    accumulate: bool,
    trailing: Option<Trailing<'_>>,
) {
    row_body::<NV, K, false>(cost, lanes, nd, p1, p2, from_row, sum, reverse, accumulate, trailing)
}

/// [`row_avx512`] with VBMI byte permutations for the `d ± 1` neighbours.
///
/// # Safety
/// As [`row_avx512`], and the CPU must have AVX-512 VBMI.
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vbmi")]
#[allow(clippy::too_many_arguments)]
pub(in crate::kernels) unsafe fn row_avx512_vbmi<const NV: usize, const K: usize>(
    cost: &[u8],
    lanes: usize,
    nd: usize,
    p1: u8,
    p2: &[u8],
    from_row: [FromRow<'_>; K],
    sum: &mut [u16],
    reverse: bool,
    accumulate: bool,
    trailing: Option<Trailing<'_>>,
) {
    row_body::<NV, K, true>(cost, lanes, nd, p1, p2, from_row, sum, reverse, accumulate, trailing)
}

/// The body of [`row_avx512`] and [`row_avx512_vbmi`], inlined into each.
///
/// # Safety
/// As [`row_avx512`] (and [`row_avx512_vbmi`] with `VBMI`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn row_body<const NV: usize, const K: usize, const VBMI: bool>(
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
    let width = cost.len() / lanes;
    let pad = _mm512_set1_epi8(-1);
    let lane_mask = std::array::from_fn(|v| {
        let n = lanes.saturating_sub(64 * v).min(64);
        if n == 64 {
            !0
        } else {
            (1u64 << n) - 1
        }
    });
    let load = |i: &[i16; 32]| _mm512_loadu_si512(i.as_ptr().cast());
    let order = [load(&interleave(0)), load(&interleave(32))];
    // Lane j of "d - 1" is lane j - 1 of this register (index 64 + j - 1: the second
    // operand), lane 0 the last lane of the one below (63); lane j of "d + 1" is lane j + 1
    // of this register, lane 63 the first lane of the one above (64).
    let below: [u8; 64] = std::array::from_fn(|j| if j == 0 { 63 } else { 63 + j as u8 });
    let above: [u8; 64] = std::array::from_fn(|j| j as u8 + 1);
    let shift = [_mm512_loadu_si512(below.as_ptr().cast()), _mm512_loadu_si512(above.as_ptr().cast())];
    let p1 = _mm512_set1_epi8(p1 as i8);
    let shape = Shape::<NV> { width, lanes, nd, pad, p1, lane_mask, order, shift };
    let mut h = Horizontal { path: [pad; NV], min: _mm512_setzero_si512() };
    let mut back = Horizontal { path: [pad; NV], min: _mm512_setzero_si512() };
    for i in 0..width {
        let x = if reverse { width - 1 - i } else { i };
        pixel::<NV, K, VBMI>(&shape, &mut h, i, x, cost, p2, &mut from_row, sum, accumulate, reverse);
        if let Some(t) = &mut trailing {
            pixel::<NV, 0, VBMI>(
                &shape,
                &mut back,
                i,
                width - 1 - i,
                t.cost,
                t.p2,
                &mut [],
                t.sum,
                true,
                true,
            );
        }
    }
}
