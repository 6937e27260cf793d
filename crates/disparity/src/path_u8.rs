//! The SGM path step on 8-bit path costs: 64 disparities per AVX-512 instruction instead of 32,
//! and half the memory traffic for the path state.
//!
//! A path cost is `L(p, d) = C(p, d) + (min(L(p-r, d), L(p-r, d±1) + P1, m + P2) - m)` with
//! `m = min_k L(p-r, k)`: the bracket lies in `0..=P2`, so every path cost lies in
//! `0..=C_max + P2`. When that bound is at most [`MAX_PATH_COST`] the 8-bit step computes exactly
//! what the 16-bit step ([`crate::simd::path_step`]) does, lane for lane (the bracket is formed
//! before the cost is added, so nothing saturates), and the sums (still `u16`) and everything
//! after them are bit-identical. Lanes past the last disparity hold 255, above every real path
//! cost, so they never win a minimum or (plus P1) change a real lane.

use crate::simd::{Level, PathIn};

/// The largest path cost the 8-bit step represents exactly (255 marks the padding lanes).
pub(crate) const MAX_PATH_COST: u16 = 254;

/// Disparities are padded to whole blocks of this many `u8` lanes (one AVX2 register, half an
/// AVX-512 one).
pub(crate) const LANES_U8: usize = 32;

/// Pad at both ends of a path-cost vector and value of the lanes past the last disparity.
pub(crate) const PAD_U8: u8 = u8::MAX;

/// Disparity count rounded up to whole blocks of [`LANES_U8`].
pub(crate) fn padded_lanes_u8(nd: usize) -> usize {
    nd.div_ceil(LANES_U8).max(1) * LANES_U8
}

/// Whether the 8-bit step is exact for matching costs up to `max_cost` and penalties `p1`,
/// `max_p2` (the largest P2 of the edge-adaptive table).
pub(crate) fn fits(max_cost: u16, p1: u16, max_p2: u16) -> bool {
    u32::from(max_cost) + u32::from(max_p2.max(p1)) <= u32::from(MAX_PATH_COST)
}

/// Word indices that interleave the even-lane and odd-lane words of a 2×32-word pair back into
/// lane order (for `_mm512_permutex2var_epi16`): result word `m` is disparity `base + m`, taken
/// from the even words (indices 0..32) or the odd words (32..64) at position `(base + m) / 2`.
#[cfg(target_arch = "x86_64")]
pub(crate) fn interleave(base: usize) -> [i16; 32] {
    std::array::from_fn(|m| {
        let d = base + m;
        (if d.is_multiple_of(2) { d / 2 } else { 32 + d / 2 }) as i16
    })
}

/// One path's input for an 8-bit step.
pub(crate) type PathInU8<'a> = PathIn<'a, u8>;

/// The 8-bit costs of one pixel: `narrow[k] = wide[k]` for the `nd` disparities, [`PAD_U8`] for
/// the padding lanes (`narrow.len()` is a multiple of [`LANES_U8`]). The costs must fit in `u8`.
#[cfg(test)]
pub(crate) fn narrow_costs(wide: &[u16], nd: usize, narrow: &mut [u8]) {
    for (k, n) in narrow.iter_mut().enumerate() {
        *n = if k < nd { wide[k] as u8 } else { PAD_U8 };
    }
}

/// [`crate::simd::path_step`] on 8-bit path costs (exact when [`fits`] holds for the costs and
/// penalties; see the module documentation). `cost.len()` is a multiple of [`LANES_U8`], `prev`
/// and `out` have `cost.len() + 2` entries, `sum.len() <= cost.len()`.
#[inline(always)]
pub(crate) fn path_step_u8<const N: usize>(
    level: Level,
    cost: &[u8],
    p1: u8,
    ins: [PathInU8<'_>; N],
    outs: [&mut [u8]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u8; N] {
    let lanes = cost.len();
    assert!(lanes.is_multiple_of(LANES_U8) && sum.len() <= lanes);
    for i in 0..N {
        assert!(ins[i].prev.len() == lanes + 2 && outs[i].len() == lanes + 2);
    }
    match level {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Level::Avx512` is only chosen when the CPU has AVX-512F/BW/VL, and the lengths
        // the kernel reads and writes were checked above.
        Level::Avx512 => unsafe { x86::path_step_u8_avx512(cost, p1, ins, outs, sum, accumulate) },
        _ => path_step_u8_scalar(cost, p1, ins, outs, sum, accumulate),
    }
}

/// The readable reference of [`path_step_u8`].
pub(crate) fn path_step_u8_scalar<const N: usize>(
    cost: &[u8],
    p1: u8,
    ins: [PathInU8<'_>; N],
    outs: [&mut [u8]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u8; N] {
    let mut mins = [u8::MAX; N];
    let nd = sum.len();
    for (i, out) in outs.into_iter().enumerate() {
        let PathIn { prev, prev_min, p2 } = ins[i];
        let jump = prev_min.saturating_add(p2);
        let (prev, out) = (&prev[..cost.len() + 2], &mut out[1..=cost.len()]);
        for (k, (&c, o)) in cost.iter().zip(out.iter_mut()).enumerate() {
            let best =
                prev[k + 1].min(prev[k].saturating_add(p1)).min(prev[k + 2].saturating_add(p1)).min(jump);
            *o = c.saturating_add(best.wrapping_sub(prev_min));
        }
        mins[i] = out.iter().copied().fold(u8::MAX, u8::min);
        for (s, &v) in sum.iter_mut().zip(&out[..nd]) {
            *s = if i == 0 && !accumulate { u16::from(v) } else { s.wrapping_add(u16::from(v)) };
        }
    }
    mins
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    use super::{interleave, PathInU8};

    /// Minimum of the 32 unsigned 8-bit lanes.
    #[inline]
    #[target_feature(enable = "avx512f,avx512bw,avx512vl")]
    fn hmin_epu8_256(v: __m256i) -> u8 {
        let m = _mm_min_epu8(_mm256_castsi256_si128(v), _mm256_extracti128_si256::<1>(v));
        // Pairs of bytes to words (the smaller byte of each pair), then the word minimum.
        let m = _mm_min_epu8(m, _mm_srli_epi16::<8>(m));
        let m = _mm_and_si128(m, _mm_set1_epi16(0xff));
        _mm_extract_epi16::<0>(_mm_minpos_epu16(m)) as u8
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
                let l = _mm512_loadu_si512(prev[i].add(k).cast());
                let m = _mm512_loadu_si512(prev[i].add(k + 1).cast());
                let r = _mm512_loadu_si512(prev[i].add(k + 2).cast());
                let near = _mm512_adds_epu8(_mm512_min_epu8(l, r), p1v);
                let best = _mm512_min_epu8(_mm512_min_epu8(m, near), jump[i]);
                let v = _mm512_adds_epu8(c, _mm512_sub_epi8(best, pmin[i]));
                _mm512_storeu_si512(out[i].add(k + 1).cast(), v);
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
                let l = _mm256_loadu_si256(prev[i].add(k).cast());
                let m = _mm256_loadu_si256(prev[i].add(k + 1).cast());
                let r = _mm256_loadu_si256(prev[i].add(k + 2).cast());
                let near = _mm256_adds_epu8(_mm256_min_epu8(l, r), p1v);
                let best = _mm256_min_epu8(_mm256_min_epu8(m, near), _mm512_castsi512_si256(jump[i]));
                let v = _mm256_adds_epu8(c, _mm256_sub_epi8(best, _mm512_castsi512_si256(pmin[i])));
                _mm256_storeu_si256(out[i].add(k + 1).cast(), v);
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
}

/// [`narrow_costs`] for a whole row (`wide` with `wide_lanes` entries per pixel, `narrow` with
/// `narrow_lanes`): the reference of [`crate::simd::cost_row_u8`], which makes the 8-bit row
/// directly.
#[cfg(test)]
pub(crate) fn narrow_row(wide: &[u16], wide_lanes: usize, nd: usize, narrow: &mut [u8], narrow_lanes: usize) {
    assert!(nd <= wide_lanes && nd <= narrow_lanes && narrow_lanes.is_multiple_of(LANES_U8));
    assert_eq!(wide.len() / wide_lanes, narrow.len() / narrow_lanes);
    for (w, n) in wide.chunks_exact(wide_lanes).zip(narrow.chunks_exact_mut(narrow_lanes)) {
        narrow_costs(w, nd, n);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simd::{path_step_scalar, supported_levels, PAD};
    use proptest::prelude::*;

    /// Random path inputs whose values obey the 8-bit bound: costs up to `max_cost`, previous
    /// path costs within `0..=max_cost + p2` (as the recurrence produces), padded as the
    /// aggregation pads them.
    fn case() -> impl Strategy<Value = (usize, usize, u16, u16, u16, Vec<u64>, bool)> {
        (
            1usize..200,
            0.0f64..1.0,
            1u16..60,
            1u16..120,
            10u16..140,
            prop::collection::vec(any::<u64>(), 4),
            any::<bool>(),
        )
            .prop_map(|(nd, frac, p1, p2, max_cost, seeds, acc)| {
                let nd_sum = ((nd as f64 * frac) as usize).clamp(1, nd);
                (nd, nd_sum, p1, p2, max_cost, seeds, acc)
            })
            .prop_filter("8-bit bound", |&(_, _, p1, p2, max_cost, _, _)| fits(max_cost, p1, p2))
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// The 8-bit step equals the 16-bit reference step lane for lane (sums, path costs and
        /// minima) whenever the values fit, on every level this CPU runs.
        #[test]
        fn u8_step_equals_the_u16_step((nd, nd_sum, p1, p2, max_cost, seeds, acc) in case()) {
            let mut state = seeds[0] | 1;
            let mut next = move |bound: u16| {
                state ^= state << 13;
                state ^= state >> 7;
                state ^= state << 17;
                (state % (u64::from(bound) + 1)) as u16
            };
            let lanes16 = crate::simd::padded_lanes(nd);
            let lanes8 = padded_lanes_u8(nd);
            let cost16: Vec<u16> = (0..lanes16).map(|k| if k < nd { next(max_cost) } else { crate::simd::JUNK_COST }).collect();
            let mut cost8 = vec![0u8; lanes8];
            narrow_costs(&cost16, nd, &mut cost8);
            // Two paths: one continuing (previous costs with their true minimum), one starting.
            let prev_min = next(max_cost);
            let prev16: Vec<u16> = (0..lanes16 + 2)
                .map(|k| match k {
                    0 => PAD,
                    k if k > nd => if k == lanes16 + 1 { PAD } else { crate::simd::JUNK_COST },
                    _ => prev_min + next(max_cost + p2 - prev_min),
                })
                .collect();
            let prev_min = prev16[1..=nd].iter().copied().min().unwrap();
            let prev8: Vec<u8> = (0..lanes8 + 2).map(|k| if (1..=nd).contains(&k) { prev16[k] as u8 } else { PAD_U8 }).collect();
            let zero16 = vec![0u16; lanes16 + 2];
            let zero8 = vec![0u8; lanes8 + 2];
            let sum0: Vec<u16> = (0..nd_sum).map(|_| next(1000)).collect();

            let ins16 = [PathIn { prev: &prev16, prev_min, p2 }, PathIn { prev: &zero16, prev_min: 0, p2: 0 }];
            let (mut a16, mut b16) = (vec![0u16; lanes16 + 2], vec![0u16; lanes16 + 2]);
            let mut sum16 = sum0.clone();
            let mins16 = path_step_scalar(&cost16, p1, ins16, [&mut a16, &mut b16], &mut sum16, acc);

            for level in supported_levels() {
                let ins8 = [
                    PathInU8 { prev: &prev8, prev_min: prev_min as u8, p2: p2 as u8 },
                    PathInU8 { prev: &zero8, prev_min: 0, p2: 0 },
                ];
                let (mut a8, mut b8) = (vec![0u8; lanes8 + 2], vec![0u8; lanes8 + 2]);
                let mut sum8 = sum0.clone();
                let mins8 = path_step_u8(level, &cost8, p1 as u8, ins8, [&mut a8, &mut b8], &mut sum8, acc);
                prop_assert_eq!(&sum8, &sum16, "{:?} sums", level);
                prop_assert_eq!(mins8.map(u16::from), mins16, "{:?} minima", level);
                for (out8, out16) in [(&a8, &a16), (&b8, &b16)] {
                    let real8: Vec<u16> = out8[1..=nd].iter().map(|&v| u16::from(v)).collect();
                    prop_assert_eq!(&real8[..], &out16[1..=nd], "{:?} path costs", level);
                    prop_assert!(out8[nd + 1..=lanes8].iter().all(|&v| v == PAD_U8), "{:?} padding", level);
                }
            }
        }
    }
}
