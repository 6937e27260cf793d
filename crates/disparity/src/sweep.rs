//! A horizontal SGM path over a whole row on 8-bit path costs, with the path state kept in
//! registers.
//!
//! The per-pixel kernel ([`crate::path_u8::path_step_u8`]) reads the previous pixel's path costs
//! from memory at offsets −1, 0 and +1 lanes right after the previous step stored them. Along a
//! row that is one long dependency chain, and loads straddling two recent vector stores cannot be
//! forwarded from the store buffer, so every pixel waited for its predecessor's stores to reach
//! the cache. Here the path vector never leaves the registers: the `d ± 1` neighbours come from
//! two byte permutations (AVX-512 VBMI) and the path minimum is reduced to a broadcast without a
//! trip through a general register. The results are those of
//! [`crate::path_u8::path_step_u8_scalar`] pixel by pixel.

use crate::path_u8::LANES_U8;
use crate::simd::Level;

/// The most lanes the register kernel keeps (four 64-lane registers); longer vectors take the
/// per-pixel kernel.
const MAX_REGISTER_LANES: usize = 256;

/// Runs one horizontal path over a row and adds its path costs into `sum`.
///
/// `cost` holds `lanes` 8-bit matching costs per pixel ([`crate::path_u8::padded_lanes_u8`]
/// lanes, 255 past the last disparity), `sum` the row's `nd` sums per pixel. The path
/// runs right to left when `reverse`, else left to right; entering pixel `x` from its
/// predecessor costs `p2[x]` for a jump of more than one disparity (`p2[x]` of the first pixel
/// is not read). Returns `false`, touching nothing, when this CPU or this lane count has no
/// register kernel; the caller then steps pixel by pixel.
#[allow(clippy::too_many_arguments)]
pub(crate) fn sweep_u8(
    level: Level,
    cost: &[u8],
    lanes: usize,
    nd: usize,
    p1: u8,
    p2: &[u8],
    sum: &mut [u16],
    reverse: bool,
) -> bool {
    assert!(lanes.is_multiple_of(LANES_U8) && nd <= lanes && lanes > 0);
    let width = cost.len() / lanes;
    assert!(cost.len() == width * lanes && p2.len() == width && sum.len() == width * nd);
    if width == 0 || lanes > MAX_REGISTER_LANES || level != Level::Avx512 {
        return false;
    }
    #[cfg(target_arch = "x86_64")]
    {
        if !std::arch::is_x86_feature_detected!("avx512vbmi") {
            return false;
        }
        // SAFETY: AVX-512 (F/BW/VL, checked by the caller's level) and VBMI are present; the
        // lengths were checked above and `lanes <= 64 * NV` for the chosen `NV`.
        unsafe {
            match lanes.div_ceil(64) {
                1 => x86::sweep_avx512::<1>(cost, lanes, nd, p1, p2, sum, reverse),
                2 => x86::sweep_avx512::<2>(cost, lanes, nd, p1, p2, sum, reverse),
                3 => x86::sweep_avx512::<3>(cost, lanes, nd, p1, p2, sum, reverse),
                _ => x86::sweep_avx512::<4>(cost, lanes, nd, p1, p2, sum, reverse),
            }
        }
        true
    }
    #[cfg(not(target_arch = "x86_64"))]
    false
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

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

    /// AVX-512 VBMI [`super::sweep_u8`] with the path in `NV` registers of 64 lanes.
    ///
    /// # Safety
    /// The CPU must have AVX-512F/BW/VL and VBMI; lengths as checked by [`super::sweep_u8`], and
    /// `64 * (NV - 1) < lanes <= 64 * NV`.
    #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vbmi")]
    pub(super) unsafe fn sweep_avx512<const NV: usize>(
        cost: &[u8],
        lanes: usize,
        nd: usize,
        p1: u8,
        p2: &[u8],
        sum: &mut [u16],
        reverse: bool,
    ) {
        let width = cost.len() / lanes;
        let pad = _mm512_set1_epi8(-1);
        let p1v = _mm512_set1_epi8(p1 as i8);
        // Lanes past `lanes` are loaded as the pad (255), like the pads of the memory layout.
        let load_mask: [__mmask64; NV] = std::array::from_fn(|i| {
            let n = lanes.saturating_sub(64 * i).min(64);
            if n == 64 {
                !0
            } else {
                (1u64 << n) - 1
            }
        });
        // Byte indices for `_mm512_permutex2var_epi8(a, idx, b)` (bit 6 picks `b`): lane j of
        // "d - 1" is lane j - 1 of this register (b), lane 0 the last lane of the one below (a);
        // lane j of "d + 1" is lane j + 1 of this register (a), lane 63 the first of the next (b).
        let below: [u8; 64] = std::array::from_fn(|j| if j == 0 { 63 } else { 64 + j as u8 - 1 });
        let above: [u8; 64] = std::array::from_fn(|j| if j == 63 { 64 } else { j as u8 + 1 });
        let below = _mm512_loadu_si512(below.as_ptr().cast());
        let above = _mm512_loadu_si512(above.as_ptr().cast());
        let sum_blocks = nd.div_ceil(32);
        let sum_mask = |q: usize| -> __mmask32 {
            let n = nd - 32 * q;
            if n >= 32 {
                !0
            } else {
                (1u32 << n) - 1
            }
        };
        let mut path = [pad; NV];
        let mut path_min = _mm512_setzero_si512();
        for i in 0..width {
            let x = if reverse { width - 1 - i } else { i };
            // SAFETY: pixel `x < width` has `lanes` costs at `x * lanes`; the loads are masked to
            // them.
            let c: [__m512i; NV] = std::array::from_fn(|v| unsafe {
                _mm512_mask_loadu_epi8(pad, load_mask[v], cost.as_ptr().add(x * lanes + 64 * v).cast())
            });
            if i == 0 {
                // Entering the row: the path cost is the matching cost.
                path = c;
            } else {
                let jump = _mm512_adds_epu8(path_min, _mm512_set1_epi8(p2[x] as i8));
                let prev = path;
                for v in 0..NV {
                    let lower = if v == 0 { pad } else { prev[v - 1] };
                    let upper = if v + 1 == NV { pad } else { prev[v + 1] };
                    let l = _mm512_permutex2var_epi8(lower, below, prev[v]);
                    let r = _mm512_permutex2var_epi8(prev[v], above, upper);
                    let near = _mm512_adds_epu8(_mm512_min_epu8(l, r), p1v);
                    let best = _mm512_min_epu8(_mm512_min_epu8(prev[v], near), jump);
                    path[v] = _mm512_adds_epu8(c[v], _mm512_sub_epi8(best, path_min));
                }
            }
            let mut m = path[0];
            for p in &path[1..] {
                m = _mm512_min_epu8(m, *p);
            }
            path_min = min_broadcast_epu8(m);
            let s = sum.as_mut_ptr().add(x * nd);
            for q in 0..sum_blocks {
                let v = path[q / 2];
                let half =
                    if q % 2 == 0 { _mm512_castsi512_si256(v) } else { _mm512_extracti64x4_epi64::<1>(v) };
                let mask = sum_mask(q);
                // SAFETY: masked to the `nd` sums of pixel `x`.
                let dst = s.add(32 * q);
                let total =
                    _mm512_add_epi16(_mm512_cvtepu8_epi16(half), _mm512_maskz_loadu_epi16(mask, dst.cast()));
                _mm512_mask_storeu_epi16(dst.cast(), mask, total);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::path_u8::{padded_lanes_u8, path_step_u8_scalar, PAD_U8};
    use crate::simd::{supported_levels, PathIn};
    use proptest::prelude::*;

    /// The readable reference of [`sweep_u8`]: the per-pixel scalar step along the row.
    fn sweep_u8_scalar(
        cost: &[u8],
        lanes: usize,
        nd: usize,
        p1: u8,
        p2: &[u8],
        sum: &mut [u16],
        reverse: bool,
    ) {
        let width = cost.len() / lanes;
        let zero = vec![0u8; lanes + 2];
        let (mut prev, mut cur) = (vec![PAD_U8; lanes + 2], vec![PAD_U8; lanes + 2]);
        let mut prev_min = 0;
        for i in 0..width {
            let x = if reverse { width - 1 - i } else { i };
            let input = if i == 0 {
                PathIn { prev: &zero[..], prev_min: 0, p2: 0 }
            } else {
                PathIn { prev: &prev[..], prev_min, p2: p2[x] }
            };
            let c = &cost[x * lanes..(x + 1) * lanes];
            [prev_min] =
                path_step_u8_scalar(c, p1, [input], [&mut cur[..]], &mut sum[x * nd..(x + 1) * nd], true);
            std::mem::swap(&mut prev, &mut cur);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        #[test]
        fn register_sweep_matches_the_scalar_steps(
            width in 1usize..60, nd in 1usize..=256, max_cost in 1u8..200, p1 in 1u8..30,
            p2_extra in 1u8..60, reverse in any::<bool>(), seed in any::<u64>(),
        ) {
            let lanes = padded_lanes_u8(nd);
            // Within the 8-bit bound: cost + P2 <= 254.
            let max_p2 = (u16::from(p1) + u16::from(p2_extra)).min(254 - u16::from(max_cost)) as u8;
            prop_assume!(max_p2 > p1);
            let mut s = seed | 1;
            let mut next = move || {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                s
            };
            let cost: Vec<u8> = (0..width * lanes)
                .map(|i| if i % lanes < nd { (next() % (u64::from(max_cost) + 1)) as u8 } else { PAD_U8 })
                .collect();
            let p2: Vec<u8> = (0..width).map(|_| p1 + 1 + (next() % u64::from(max_p2 - p1)) as u8).collect();
            let start: Vec<u16> = (0..width * nd).map(|_| (next() % 600) as u16).collect();
            let mut expected = start.clone();
            sweep_u8_scalar(&cost, lanes, nd, p1, &p2, &mut expected, reverse);
            for level in supported_levels() {
                let mut got = start.clone();
                let ran = sweep_u8(level, &cost, lanes, nd, p1, &p2, &mut got, reverse);
                #[cfg(target_arch = "x86_64")]
                if level == Level::Avx512 && lanes <= MAX_REGISTER_LANES && std::arch::is_x86_feature_detected!("avx512vbmi") {
                    prop_assert!(ran, "the register kernel did not run");
                }
                if ran {
                    prop_assert_eq!(&got, &expected, "{:?}", level);
                } else {
                    prop_assert_eq!(&got, &start);
                }
            }
        }
    }
}
