//! The path steps of a whole row on 8-bit path costs, with the horizontal path kept in
//! registers.
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

use crate::kernels::layout::LANES_U8;
use crate::kernels::Level;

/// The most lanes the register kernel keeps (four 64-lane registers); longer vectors take the
/// per-pixel kernel.
const MAX_REGISTER_LANES: usize = 256;

/// A path continuing from the previous row of the pass: from pixel `x + dx` of that row into
/// pixel `x`.
pub(crate) struct FromRow<'a, T = u8> {
    /// The previous row's path costs (`lanes + 2` per pixel, the disparities at `1..=lanes`) and
    /// minima; both empty when the path enters the image on this row.
    pub prev: &'a [T],
    pub prev_mins: &'a [T],
    /// Column of the source pixel relative to `x` (−1, 0 or 1); outside the row the path enters
    /// the image at `x`.
    pub dx: isize,
    /// P2 for entering each pixel along this path.
    pub p2: &'a [T],
    /// This row's path costs and minima, laid out as `prev`.
    pub out: &'a mut [T],
    pub out_mins: &'a mut [T],
}

/// A second, independent row run in the same loop as a [`row_u8`] row: the horizontal path
/// alone, right to left, added into `sum`. Its dependency chain overlaps the first row's, so
/// each fills the other's latency (the single-pass aggregation runs the ← path of one row beside
/// the →, ↓ paths of the next).
pub(crate) struct Trailing<'a, T = u8> {
    pub cost: &'a [T],
    pub p2: &'a [T],
    pub sum: &'a mut [u16],
}

/// Whether [`row_u8`] has a kernel for this level and lane count.
pub(crate) fn row_u8_available(level: Level, lanes: usize) -> bool {
    level.avx512() && lanes <= MAX_REGISTER_LANES
}

/// Runs one row of a pass: the horizontal path (right to left when `reverse`, else left to
/// right; entering pixel `x` from its predecessor costs `p2[x]`, the first pixel's entry is not
/// read) and the `K` paths from the previous row, storing (or, with `accumulate`, adding) the sum
/// of their path costs into `sum` (`nd` per pixel).
///
/// `cost` holds `lanes` 8-bit matching costs per pixel ([`crate::kernels::layout::padded_lanes_u8`]
/// lanes, 255 past the last disparity). With `trailing`, that row's ← path runs in the same loop.
/// Returns `false`, touching nothing, when this CPU or this lane count has no register kernel;
/// the caller then steps pixel by pixel.
#[allow(clippy::too_many_arguments)]
// Elsewhere there is no register kernel: only the lengths are checked before returning `false`.
#[cfg_attr(not(target_arch = "x86_64"), allow(unused_variables))]
pub(crate) fn row_u8<const K: usize>(
    level: Level,
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
) -> bool {
    assert!(lanes.is_multiple_of(LANES_U8) && nd <= lanes && lanes > 0);
    let width = cost.len() / lanes;
    assert!(cost.len() == width * lanes && p2.len() == width && sum.len() == width * nd);
    let stride = lanes + 2;
    for path in &from_row {
        assert!(path.prev.is_empty() || (path.prev.len() == width * stride && path.prev_mins.len() == width));
        assert!(path.dx.abs() <= 1 && path.p2.len() == width);
        assert!(path.out.len() == width * stride && path.out_mins.len() == width);
    }
    if let Some(t) = &trailing {
        assert!(t.cost.len() == cost.len() && t.p2.len() == width && t.sum.len() == sum.len());
    }
    if width == 0 || !row_u8_available(level, lanes) {
        return false;
    }
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: AVX-512 F/BW/VL is present (the level is only chosen when it is); the lengths
        // were checked above and `lanes <= 64 * NV` for the chosen `NV`.
        // Tests turn the VBMI kernel off to cover the other one on CPUs that have both.
        #[cfg(test)]
        let allowed = !tests::NO_VBMI.with(|n| n.get());
        #[cfg(not(test))]
        let allowed = true;
        let vbmi = allowed && std::arch::is_x86_feature_detected!("avx512vbmi");
        macro_rules! run {
            ($nv:literal) => {
                // SAFETY: AVX-512 F/BW/VL is present (the level is only chosen when it is), VBMI
                // was detected for the VBMI kernel; the lengths were checked above and
                // `64 * ($nv - 1) < lanes <= 64 * $nv`.
                unsafe {
                    if vbmi {
                        x86::row_avx512_vbmi::<$nv, K>(
                            cost, lanes, nd, p1, p2, from_row, sum, reverse, accumulate, trailing,
                        )
                    } else {
                        x86::row_avx512::<$nv, K>(
                            cost, lanes, nd, p1, p2, from_row, sum, reverse, accumulate, trailing,
                        )
                    }
                }
            };
        }
        match lanes.div_ceil(64) {
            1 => run!(1),
            2 => run!(2),
            3 => run!(3),
            _ => run!(4),
        }
        true
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    use super::{FromRow, Trailing};
    use crate::kernels::layout::interleave;

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
        let near = _mm512_adds_epu8(_mm512_min_epu8(l, r), p1);
        let best = _mm512_min_epu8(_mm512_min_epu8(prev, near), jump);
        _mm512_adds_epu8(c, _mm512_sub_epi8(best, prev_min))
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
    fn neighbours_vbmi(
        lower: __m512i,
        v: __m512i,
        upper: __m512i,
        order: &[__m512i; 2],
    ) -> (__m512i, __m512i) {
        (_mm512_permutex2var_epi8(lower, order[0], v), _mm512_permutex2var_epi8(v, order[1], upper))
    }

    /// The steps of the `i`-th pixel `x` of a row: the horizontal path `h`, then the paths from
    /// the previous row, their sum stored (or added) into `sum`.
    ///
    /// # Safety
    /// The CPU must have AVX-512F/BW/VL; lengths as checked by [`super::row_u8`]. Always
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

    /// AVX-512 [`super::row_u8`] with the horizontal paths in `NV` registers of 64 lanes.
    ///
    /// # Safety
    /// The CPU must have AVX-512F/BW/VL; lengths as checked by [`super::row_u8`], and
    /// `64 * (NV - 1) < lanes <= 64 * NV`.
    #[target_feature(enable = "avx512f,avx512bw,avx512vl")]
    #[allow(clippy::too_many_arguments)]
    pub(super) unsafe fn row_avx512<const NV: usize, const K: usize>(
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
    pub(super) unsafe fn row_avx512_vbmi<const NV: usize, const K: usize>(
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
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernels::layout::{padded_lanes_u8, PathIn, PAD_U8};
    use crate::kernels::scalar::path_step_u8_scalar;
    use crate::kernels::supported_levels;
    use proptest::prelude::*;
    use std::cell::Cell;

    thread_local! {
        /// Turns the VBMI kernel off (to test the other one on CPUs that have both).
        pub(super) static NO_VBMI: Cell<bool> = const { Cell::new(false) };
    }

    /// The readable reference of [`row_u8`]: the per-pixel scalar step along the row, returning
    /// the paths' new costs and minima.
    #[allow(clippy::too_many_arguments)]
    fn row_u8_scalar<const K: usize>(
        cost: &[u8],
        lanes: usize,
        nd: usize,
        p1: u8,
        p2: &[u8],
        from_row: &mut [FromRow<'_>; K],
        sum: &mut [u16],
        reverse: bool,
        accumulate: bool,
    ) {
        let width = cost.len() / lanes;
        let stride = lanes + 2;
        let zero = vec![0u8; stride];
        let (mut prev, mut cur) = (vec![PAD_U8; stride], vec![PAD_U8; stride]);
        let mut prev_min = 0;
        for i in 0..width {
            let x = if reverse { width - 1 - i } else { i };
            let c = &cost[x * lanes..(x + 1) * lanes];
            let s = &mut sum[x * nd..(x + 1) * nd];
            let input = if i == 0 {
                PathIn { prev: &zero[..], prev_min: 0, p2: 0 }
            } else {
                PathIn { prev: &prev[..], prev_min, p2: p2[x] }
            };
            [prev_min] = path_step_u8_scalar(c, p1, [input], [&mut cur[..]], s, accumulate);
            std::mem::swap(&mut prev, &mut cur);
            for from in from_row.iter_mut() {
                let f = x as isize + from.dx;
                let input = if from.prev.is_empty() || f < 0 || f >= width as isize {
                    PathIn { prev: &zero[..], prev_min: 0, p2: 0 }
                } else {
                    let f = f as usize;
                    PathIn {
                        prev: &from.prev[f * stride..(f + 1) * stride],
                        prev_min: from.prev_mins[f],
                        p2: from.p2[x],
                    }
                };
                let out = &mut from.out[x * stride..(x + 1) * stride];
                [from.out_mins[x]] = path_step_u8_scalar(c, p1, [input], [out], s, true);
            }
        }
    }

    fn xorshift(seed: u64) -> impl FnMut() -> u64 {
        let mut s = seed | 1;
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]

        #[test]
        fn register_rows_match_the_scalar_steps(
            width in 1usize..50, nd in 1usize..=256, max_cost in 1u8..200, p1 in 1u8..30,
            p2_extra in 1u8..60, reverse in any::<bool>(), accumulate in any::<bool>(), paths in 0usize..4,
            first_row in any::<bool>(), seed in any::<u64>(),
        ) {
            let lanes = padded_lanes_u8(nd);
            let stride = lanes + 2;
            // Within the 8-bit bound: cost + P2 <= 254.
            let max_p2 = (u16::from(p1) + u16::from(p2_extra)).min(254 - u16::from(max_cost)) as u8;
            prop_assume!(max_p2 > p1);
            let mut next = xorshift(seed);
            let cost: Vec<u8> = (0..width * lanes)
                .map(|i| if i % lanes < nd { (next() % (u64::from(max_cost) + 1)) as u8 } else { PAD_U8 })
                .collect();
            let penalties = |next: &mut dyn FnMut() -> u64| -> Vec<u8> {
                (0..width).map(|_| p1 + 1 + (next() % u64::from(max_p2 - p1)) as u8).collect()
            };
            let p2 = penalties(&mut next);
            // Previous rows as the recurrence leaves them: path costs up to cost + P2, pads 255.
            let prev: Vec<Vec<u8>> = (0..3)
                .map(|_| {
                    (0..width * stride)
                        .map(|i| {
                            let k = i % stride;
                            if k == 0 || k > nd { PAD_U8 } else { (next() % (u64::from(max_cost) + u64::from(max_p2) + 1)) as u8 }
                        })
                        .collect()
                })
                .collect();
            let mins: Vec<Vec<u8>> = prev.iter().map(|p| p.chunks(stride).map(|c| *c.iter().min().unwrap()).collect()).collect();
            let from_p2: Vec<Vec<u8>> = (0..3).map(|_| penalties(&mut next)).collect();
            let start: Vec<u16> = (0..width * nd).map(|_| (next() % 600) as u16).collect();
            let run = |level: Option<Level>| {
                let mut outs = vec![vec![7u8; width * stride]; 3];
                let mut out_mins = vec![vec![0u8; width]; 3];
                let mut s = start.clone();
                let mut o = outs.iter_mut();
                let mut om = out_mins.iter_mut();
                let mut from = |k: usize| FromRow {
                    prev: if first_row { &[] } else { &prev[k][..] },
                    prev_mins: if first_row { &[] } else { &mins[k][..] },
                    dx: [0, -1, 1][k],
                    p2: &from_p2[k],
                    out: o.next().unwrap(),
                    out_mins: om.next().unwrap(),
                };
                let ran = match (paths, level) {
                    (0, None) => { row_u8_scalar::<0>(&cost, lanes, nd, p1, &p2, &mut [], &mut s, reverse, accumulate); true }
                    (0, Some(l)) => row_u8::<0>(l, &cost, lanes, nd, p1, &p2, [], &mut s, reverse, accumulate, None),
                    (1, None) => { row_u8_scalar(&cost, lanes, nd, p1, &p2, &mut [from(0)], &mut s, reverse, accumulate); true }
                    (1, Some(l)) => row_u8(l, &cost, lanes, nd, p1, &p2, [from(0)], &mut s, reverse, accumulate, None),
                    (_, None) => { row_u8_scalar(&cost, lanes, nd, p1, &p2, &mut [from(0), from(1), from(2)], &mut s, reverse, accumulate); true }
                    (_, Some(l)) => row_u8(l, &cost, lanes, nd, p1, &p2, [from(0), from(1), from(2)], &mut s, reverse, accumulate, None),
                };
                (ran, s, outs, out_mins)
            };
            let (_, expected, expected_outs, expected_mins) = run(None);
            for (level, no_vbmi) in supported_levels().into_iter().flat_map(|l| [(l, false), (l, true)]) {
                NO_VBMI.with(|n| n.set(no_vbmi));
                let (ran, got, outs, out_mins) = run(Some(level));
                NO_VBMI.with(|n| n.set(false));
                if row_u8_available(level, lanes) {
                    prop_assert!(ran, "the register kernel did not run");
                }
                if ran {
                    prop_assert_eq!(&got, &expected, "{:?} sums", level);
                    let k = if paths == 0 { 0 } else if paths == 1 { 1 } else { 3 };
                    for p in 0..k {
                        for x in 0..width {
                            // Only the disparity lanes are written (the pads keep what was there).
                            let (a, b) = (&outs[p][x * stride + 1..x * stride + 1 + lanes], &expected_outs[p][x * stride + 1..x * stride + 1 + lanes]);
                            prop_assert_eq!(a, b, "{:?} path {} pixel {}", level, p, x);
                        }
                        prop_assert_eq!(&out_mins[p], &expected_mins[p], "{:?} path {} minima", level, p);
                    }
                } else {
                    prop_assert_eq!(&got, &start);
                }
            }
        }
    }
}
