//! Hot SGM kernels with one scalar reference each and `std::arch` versions for AVX2 and
//! AVX-512BW, selected once per process by a cached runtime CPU-feature check.
//!
//! Every SIMD kernel computes exactly what its scalar reference computes (tested on random inputs
//! with proptest on each path the machine supports), so the disparity maps do not depend on the
//! CPU.
//!
//! Layout shared by the kernels: a pixel's path-cost vector is `lanes + 2` `u16` entries, the
//! disparities `0..lanes` at `1..=lanes` and a pad at each end; `lanes` is the disparity count
//! rounded up to [`LANES`]. Lanes at or past the disparity count hold [`JUNK_COST`]-sized
//! values that never win a minimum, so the kernels need no remainder loops.

use std::sync::OnceLock;

use crate::cost::{bt, AdRows, BtRow, BT_PAD};
use crate::path_u8::{padded_lanes_u8, PAD_U8};
use crate::MAX_AD_CAP;

/// Disparities are padded to whole blocks of this many `u16` lanes (one AVX2 register, half an
/// AVX-512 one: the AVX-512 kernels finish an odd block with a 256-bit step).
pub(crate) const LANES: usize = 16;

/// Pad at both ends of a path-cost vector: never the minimum, and `+ P1` cannot overflow.
pub(crate) const PAD: u16 = 0x7fff;

/// Matching cost of the lanes past the last disparity. Path costs in those lanes stay within
/// `JUNK_COST ..= JUNK_COST + P2`, above any real path cost (at most 191 + P2: 64 census bits
/// plus the AD cap) and, plus P1, above any real candidate, so they never change a real lane or
/// a path minimum.
pub(crate) const JUNK_COST: u16 = 0x4000;

/// Disparity count rounded up to whole blocks of [`LANES`].
pub(crate) fn padded_lanes(nd: usize) -> usize {
    nd.div_ceil(LANES).max(1) * LANES
}

/// The instruction set the kernels use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Level {
    Scalar,
    Avx2,
    Avx512,
}

/// What the CPU supports, detected once.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Features {
    pub level: Level,
    /// AVX-512 VPOPCNTQ (for the Hamming costs).
    pub vpopcnt: bool,
}

/// The cached feature check. `STEREO_DISPARITY_SIMD=scalar|avx2|avx512` caps the level (for
/// benchmarks and debugging); it never enables what the CPU lacks.
pub(crate) fn features() -> Features {
    static FEATURES: OnceLock<Features> = OnceLock::new();
    *FEATURES.get_or_init(|| {
        let detected = detect();
        let cap = match std::env::var("STEREO_DISPARITY_SIMD").as_deref() {
            Ok("scalar") => Level::Scalar,
            Ok("avx2") => Level::Avx2,
            _ => Level::Avx512,
        };
        let level = detected.level.min(cap);
        Features { level, vpopcnt: detected.vpopcnt && level == Level::Avx512 }
    })
}

/// All levels this machine can run, lowest first (for tests and benchmarks).
#[allow(dead_code)]
pub(crate) fn supported_levels() -> Vec<Level> {
    let top = detect().level;
    [Level::Scalar, Level::Avx2, Level::Avx512].into_iter().filter(|&l| l <= top).collect()
}

fn detect() -> Features {
    #[cfg(target_arch = "x86_64")]
    {
        let avx2 = is_x86_feature_detected!("avx2");
        let avx512 = is_x86_feature_detected!("avx512f")
            && is_x86_feature_detected!("avx512bw")
            && is_x86_feature_detected!("avx512vl");
        let vpopcnt = avx512 && is_x86_feature_detected!("avx512vpopcntdq");
        let level = if avx512 {
            Level::Avx512
        } else if avx2 {
            Level::Avx2
        } else {
            Level::Scalar
        };
        Features { level, vpopcnt }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        Features { level: Level::Scalar, vpopcnt: false }
    }
}

/// One path's input for a step: the previous pixel's padded path-cost vector and its minimum,
/// and the large-jump penalty for this step. A path that starts here uses an all-zero `prev`
/// with minimum 0, which makes the step return the matching cost itself.
/// (`T` is the path-cost type: `u16` here, `u8` for [`crate::path_u8`].)
#[derive(Clone, Copy)]
pub(crate) struct PathIn<'a, T = u16> {
    pub prev: &'a [T],
    pub prev_min: T,
    pub p2: T,
}

/// One SGM step for `N` paths at one pixel (Hirschmüller 2008, eq. 13):
/// `out[k] = cost[k] + min(prev[k], prev[k±1] + P1, prev_min + P2) - prev_min` for each path;
/// writes the padded `out` vectors (entries `1..=lanes`), adds the `N` path costs of the first
/// `sum.len()` disparities into `sum` (or stores them when `accumulate` is false) and returns
/// each path's minimum.
///
/// `cost.len()` is the padded lane count (a multiple of [`LANES`]); `prev` and `out` have
/// `cost.len() + 2` entries; `sum.len() <= cost.len()`.
#[inline(always)]
pub(crate) fn path_step<const N: usize>(
    level: Level,
    cost: &[u16],
    p1: u16,
    ins: [PathIn<'_>; N],
    outs: [&mut [u16]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u16; N] {
    let lanes = cost.len();
    assert!(lanes.is_multiple_of(LANES) && sum.len() <= lanes);
    for i in 0..N {
        assert!(ins[i].prev.len() == lanes + 2 && outs[i].len() == lanes + 2);
    }
    match level {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Level::Avx512` is only chosen when the CPU has AVX-512F/BW/VL, and the lengths
        // the kernel reads and writes were checked above.
        Level::Avx512 => unsafe { x86::path_step_avx512(cost, p1, ins, outs, sum, accumulate) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Level::Avx2` is only chosen when the CPU has AVX2; lengths checked above.
        Level::Avx2 => unsafe { x86::path_step_avx2(cost, p1, ins, outs, sum, accumulate) },
        _ => path_step_scalar(cost, p1, ins, outs, sum, accumulate),
    }
}

/// The readable reference of [`path_step`].
pub(crate) fn path_step_scalar<const N: usize>(
    cost: &[u16],
    p1: u16,
    ins: [PathIn<'_>; N],
    outs: [&mut [u16]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u16; N] {
    let mut mins = [u16::MAX; N];
    let nd = sum.len();
    for (i, out) in outs.into_iter().enumerate() {
        let PathIn { prev, prev_min, p2 } = ins[i];
        let jump = prev_min.saturating_add(p2);
        let (prev, out) = (&prev[..cost.len() + 2], &mut out[1..=cost.len()]);
        for (k, (&c, o)) in cost.iter().zip(out.iter_mut()).enumerate() {
            let best =
                prev[k + 1].min(prev[k].saturating_add(p1)).min(prev[k + 2].saturating_add(p1)).min(jump);
            *o = c.saturating_add(best).wrapping_sub(prev_min);
        }
        mins[i] = out.iter().copied().fold(u16::MAX, u16::min);
        for (s, &v) in sum.iter_mut().zip(&out[..nd]) {
            *s = if i == 0 && !accumulate { v } else { s.wrapping_add(v) };
        }
    }
    mins
}

/// Matching costs of one row, `lanes` entries per pixel (`out.len() == width * lanes`):
/// `out[x][k] = popcount(left[x] ^ right[x - min_disparity - k])` (plus, with `ad`,
/// `min(weight · BT(x, x - min_disparity - k), cap)`, see [`crate::cost::bt`]) for the
/// disparities `k < nd` whose right pixel is inside the row, `worst` for the other disparities
/// below `nd`, and [`JUNK_COST`] for `nd <= k < lanes`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn cost_row(
    // Only picks among the x86 kernels.
    #[cfg_attr(not(target_arch = "x86_64"), allow(unused_variables))] features: Features,
    left: &[u64],
    right: &[u64],
    min_disparity: i32,
    nd: usize,
    worst: u16,
    ad: Option<AdRows<'_>>,
    out: &mut [u16],
) {
    assert_eq!(left.len(), right.len());
    assert!(nd > 0 && out.len() == left.len() * padded_lanes(nd));
    if let Some(ad) = ad {
        for row in [ad.left, ad.right] {
            assert!(row.value.len() == left.len() + 2 * BT_PAD);
            assert!(row.lo.len() == row.value.len() && row.hi.len() == row.value.len());
        }
    }
    #[cfg(target_arch = "x86_64")]
    if features.vpopcnt {
        // SAFETY: `vpopcnt` is only set when the CPU has AVX-512F/BW/VL and VPOPCNTDQ; lengths were
        // checked above.
        unsafe { x86::cost_row_avx512(left, right, min_disparity, nd, worst, ad, out) };
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if features.level >= Level::Avx2 {
        // SAFETY: AVX2 (which implies POPCNT on every CPU that has it) was detected; lengths were
        // checked above.
        unsafe { x86::cost_row_avx2(left, right, min_disparity, nd, worst, ad, out) };
        return;
    }
    cost_row_scalar(left, right, min_disparity, nd, worst, ad, out)
}

/// The disparity indices `lo..hi` of pixel `x` whose right pixel `x - min_disparity - k` is
/// inside a row of `width` pixels (`lo <= hi <= nd`), and `first = x - min_disparity`.
#[inline(always)]
pub(crate) fn feasible(x: usize, width: usize, min_disparity: i32, nd: usize) -> (usize, usize, i64) {
    let first = x as i64 - min_disparity as i64;
    let hi = (first + 1).clamp(0, nd as i64) as usize;
    let lo = (first - (width as i64 - 1)).clamp(0, hi as i64) as usize;
    (lo, hi, first)
}

/// The readable reference of [`cost_row`].
#[inline(always)]
pub(crate) fn cost_row_scalar(
    left: &[u64],
    right: &[u64],
    min_disparity: i32,
    nd: usize,
    worst: u16,
    ad: Option<AdRows<'_>>,
    out: &mut [u16],
) {
    let width = left.len();
    let lanes = padded_lanes(nd);
    for (x, costs) in out.chunks_exact_mut(lanes).enumerate() {
        let l = left[x];
        // Disparity index k has its right pixel at x - min - k: inside the row for k in lo..hi.
        let (lo, hi, first) = feasible(x, width, min_disparity, nd);
        costs[..lo].fill(worst);
        for (k, c) in costs[lo..hi].iter_mut().enumerate() {
            let xr = (first - (lo + k) as i64) as usize;
            *c = (l ^ right[xr]).count_ones() as u16;
            if let Some(ad) = ad {
                let il = BT_PAD + x;
                let ir = BT_PAD + width - 1 - xr;
                let at = |r: &BtRow, i: usize| (r.value[i], r.lo[i], r.hi[i]);
                let term = u16::from(bt(at(ad.left, il), at(ad.right, ir))) * ad.weight;
                *c += term.min(ad.cap);
            }
        }
        costs[hi..nd].fill(worst);
        costs[nd..].fill(JUNK_COST);
    }
}

/// [`cost_row`] straight to 8 bits, for the 8-bit passes: `out[x][k]` (`out.len() ==
/// width * padded_lanes_u8(nd)`) is the same cost for `k < nd` and [`PAD_U8`] for the padding
/// lanes, i.e. what [`crate::path_u8::narrow_row`] makes of [`cost_row`]'s output, without the
/// `u16` row in between. Every cost fits: census ≤ 64, the AD cap ≤ [`MAX_AD_CAP`] and
/// `worst <= 255` (asserted).
#[allow(clippy::too_many_arguments)]
pub(crate) fn cost_row_u8(
    // Only picks among the x86 kernels.
    #[cfg_attr(not(target_arch = "x86_64"), allow(unused_variables))] features: Features,
    left: &[u64],
    right: &[u64],
    min_disparity: i32,
    nd: usize,
    worst: u16,
    ad: Option<AdRows<'_>>,
    out: &mut [u8],
) {
    assert_eq!(left.len(), right.len());
    assert!(nd > 0 && out.len() == left.len() * padded_lanes_u8(nd));
    assert!(worst <= 255);
    if let Some(ad) = ad {
        assert!(ad.cap <= u16::from(MAX_AD_CAP));
        for row in [ad.left, ad.right] {
            assert!(row.value.len() == left.len() + 2 * BT_PAD);
            assert!(row.lo.len() == row.value.len() && row.hi.len() == row.value.len());
        }
    }
    #[cfg(target_arch = "x86_64")]
    if features.vpopcnt && is_x86_feature_detected!("avx512vbmi") {
        // SAFETY: `vpopcnt` is only set when the CPU has AVX-512F/BW/VL and VPOPCNTDQ, and VBMI
        // was just checked (a cached test); lengths and value bounds were checked above.
        unsafe { x86::cost_row_u8_avx512(left, right, min_disparity, nd, worst, ad, out) };
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if features.level >= Level::Avx2 {
        // SAFETY: AVX2 (which implies POPCNT on every CPU that has it) was detected; lengths were
        // checked above.
        unsafe { x86::cost_row_u8_avx2(left, right, min_disparity, nd, worst, ad, out) };
        return;
    }
    cost_row_u8_scalar(left, right, min_disparity, nd, worst, ad, out)
}

/// The readable reference of [`cost_row_u8`] (the loop of [`cost_row_scalar`] in 8 bits).
#[inline(always)]
pub(crate) fn cost_row_u8_scalar(
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
    for (x, costs) in out.chunks_exact_mut(lanes).enumerate() {
        let l = left[x];
        let (lo, hi, first) = feasible(x, width, min_disparity, nd);
        costs[..lo].fill(worst as u8);
        for (k, c) in costs[lo..hi].iter_mut().enumerate() {
            let xr = (first - (lo + k) as i64) as usize;
            let mut cost = (l ^ right[xr]).count_ones() as u16;
            if let Some(ad) = ad {
                let il = BT_PAD + x;
                let ir = BT_PAD + width - 1 - xr;
                let at = |r: &BtRow, i: usize| (r.value[i], r.lo[i], r.hi[i]);
                cost += (u16::from(bt(at(ad.left, il), at(ad.right, ir))) * ad.weight).min(ad.cap);
            }
            *c = cost as u8;
        }
        costs[hi..nd].fill(worst as u8);
        costs[nd..].fill(PAD_U8);
    }
}

/// The smallest value of a non-empty `values` and the index of its first occurrence.
#[inline(always)]
pub(crate) fn argmin(level: Level, values: &[u16]) -> (u16, usize) {
    assert!(!values.is_empty());
    match level {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Level::Avx512` is only chosen when the CPU has AVX-512F/BW/VL.
        Level::Avx512 => unsafe { x86::argmin_avx512(values) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Level::Avx2` is only chosen when the CPU has AVX2.
        Level::Avx2 => unsafe { x86::argmin_avx2(values) },
        _ => argmin_scalar(values),
    }
}

/// The readable reference of [`argmin`].
pub(crate) fn argmin_scalar(values: &[u16]) -> (u16, usize) {
    let mut best = 0;
    for (k, &v) in values.iter().enumerate() {
        if v < values[best] {
            best = k;
        }
    }
    (values[best], best)
}

/// Right-view winner-takes-all update: for each `j`, if `costs[j] < best[j]` then
/// `best[j] = costs[j]` and `index[j] = first_index + j` (so among equal costs the earliest
/// update stays). All three slices have the same length.
#[inline(always)]
pub(crate) fn keep_smaller(
    level: Level,
    costs: &[u16],
    first_index: u16,
    best: &mut [u16],
    index: &mut [u16],
) {
    assert!(best.len() == costs.len() && index.len() == costs.len());
    assert!(costs.len() + usize::from(first_index) <= usize::from(u16::MAX));
    match level {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Level::Avx512` is only chosen when the CPU has AVX-512F/BW/VL; lengths checked.
        Level::Avx512 => unsafe { x86::keep_smaller_avx512(costs, first_index, best, index) },
        _ => keep_smaller_scalar(costs, first_index, best, index),
    }
}

/// The readable reference of [`keep_smaller`].
pub(crate) fn keep_smaller_scalar(costs: &[u16], first_index: u16, best: &mut [u16], index: &mut [u16]) {
    for (j, ((&c, b), i)) in costs.iter().zip(best.iter_mut()).zip(index.iter_mut()).enumerate() {
        if c < *b {
            *b = c;
            *i = first_index + j as u16;
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod x86 {
    use std::arch::x86_64::*;

    use super::{
        cost_row_scalar, cost_row_u8_scalar, feasible, padded_lanes, padded_lanes_u8, AdRows, PathIn, BT_PAD,
        JUNK_COST, PAD_U8,
    };

    /// Minimum of the 32 unsigned 16-bit lanes.
    #[inline]
    #[target_feature(enable = "avx512f,avx512bw,avx512vl")]
    fn hmin_epu16_512(v: __m512i) -> u16 {
        let m = _mm256_min_epu16(_mm512_castsi512_si256(v), _mm512_extracti64x4_epi64::<1>(v));
        let m = _mm_min_epu16(_mm256_castsi256_si128(m), _mm256_extracti128_si256::<1>(m));
        _mm_extract_epi16::<0>(_mm_minpos_epu16(m)) as u16
    }

    #[inline]
    #[target_feature(enable = "avx2")]
    fn hmin_epu16_256(v: __m256i) -> u16 {
        let m = _mm_min_epu16(_mm256_castsi256_si128(v), _mm256_extracti128_si256::<1>(v));
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
                let l = _mm512_loadu_si512(prev[i].add(k).cast());
                let m = _mm512_loadu_si512(prev[i].add(k + 1).cast());
                let r = _mm512_loadu_si512(prev[i].add(k + 2).cast());
                let near = _mm512_adds_epu16(_mm512_min_epu16(l, r), p1v);
                let best = _mm512_min_epu16(_mm512_min_epu16(m, near), jump[i]);
                let v = _mm512_sub_epi16(_mm512_adds_epu16(c, best), pmin[i]);
                _mm512_storeu_si512(out[i].add(k + 1).cast(), v);
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
                let l = _mm256_loadu_si256(prev[i].add(k).cast());
                let m = _mm256_loadu_si256(prev[i].add(k + 1).cast());
                let r = _mm256_loadu_si256(prev[i].add(k + 2).cast());
                let near = _mm256_adds_epu16(_mm256_min_epu16(l, r), p1v);
                let best = _mm256_min_epu16(_mm256_min_epu16(m, near), _mm512_castsi512_si256(jump[i]));
                let v = _mm256_sub_epi16(_mm256_adds_epu16(c, best), _mm512_castsi512_si256(pmin[i]));
                _mm256_storeu_si256(out[i].add(k + 1).cast(), v);
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

    /// AVX2 [`super::path_step`]: 16 disparities per instruction.
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
        let lanes = cost.len();
        let nd = sum.len();
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
            // SAFETY (pointer accesses below): `k + 16 <= lanes` (lanes is a multiple of 32),
            // `prev`/`out` have `lanes + 2` entries, and `sum` is written only below `nd`.
            let c = _mm256_loadu_si256(cost.as_ptr().add(k).cast());
            let mut total = _mm256_setzero_si256();
            for i in 0..N {
                let l = _mm256_loadu_si256(prev[i].add(k).cast());
                let m = _mm256_loadu_si256(prev[i].add(k + 1).cast());
                let r = _mm256_loadu_si256(prev[i].add(k + 2).cast());
                let near = _mm256_adds_epu16(_mm256_min_epu16(l, r), p1v);
                let best = _mm256_min_epu16(_mm256_min_epu16(m, near), jump[i]);
                let v = _mm256_sub_epi16(_mm256_adds_epu16(c, best), pmin[i]);
                _mm256_storeu_si256(out[i].add(k + 1).cast(), v);
                mins[i] = _mm256_min_epu16(mins[i], v);
                total = _mm256_add_epi16(total, v);
            }
            if k + 16 <= nd {
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
            k += 16;
        }
        std::array::from_fn(|i| hmin_epu16_256(mins[i]))
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
            31, 30, 29, 28, 27, 26, 25, 24, 23, 22, 21, 20, 19, 18, 17, 16, 15, 14, 13, 12, 11, 10, 9, 8, 7,
            6, 5, 4, 3, 2, 1, 0,
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
        let width = left.len();
        let lanes = padded_lanes(nd);
        let junk = _mm512_set1_epi16(JUNK_COST as i16);
        let worst = _mm512_set1_epi16(worst as i16);
        // Word 4i + j of the packed vector is load j's lane i: disparity k + 8j + 7 - i.
        let unpack = {
            let mut idx = [0i16; 32];
            for (m, v) in idx.iter_mut().enumerate() {
                *v = (4 * (7 - m % 8) + m / 8) as i16;
            }
            _mm512_loadu_si512(idx.as_ptr().cast())
        };
        let (weight, cap) = match &ad {
            Some(ad) => (_mm512_set1_epi16(ad.weight as i16), _mm512_set1_epi16(ad.cap as i16)),
            None => (_mm512_setzero_si512(), _mm512_setzero_si512()),
        };
        let bt_len = (width + 2 * BT_PAD) as i64;
        for (x, &census) in left.iter().enumerate() {
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
                    let r = _mm512_maskz_loadu_epi64(
                        inside,
                        right.as_ptr().wrapping_offset(lowest as isize).cast(),
                    );
                    _mm512_popcnt_epi64(_mm512_xor_si512(l, r))
                };
                let packed = _mm512_or_si512(
                    _mm512_or_si512(count(0), _mm512_slli_epi64::<16>(count(1))),
                    _mm512_or_si512(_mm512_slli_epi64::<32>(count(2)), _mm512_slli_epi64::<48>(count(3))),
                );
                let mut cost = _mm512_permutexvar_epi16(unpack, packed);
                if let (Some(ad), Some((lv, llo, lhi))) = (&ad, bt_left) {
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
                    cost = _mm512_add_epi16(cost, _mm512_min_epu16(_mm512_mullo_epi16(bt, weight), cap));
                }
                let cost = if interior && k + 32 <= nd {
                    cost
                } else if interior {
                    _mm512_mask_mov_epi16(junk, ((1u64 << (nd - k)) - 1) as __mmask32, cost)
                } else {
                    let feasible = lanes_between(lo as i64 - k as i64, hi as i64 - k as i64, 32) as __mmask32;
                    let real = lanes_between(0, nd as i64 - k as i64, 32) as __mmask32;
                    _mm512_mask_mov_epi16(junk, real, _mm512_mask_mov_epi16(worst, feasible, cost))
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
        }
    }

    /// AVX-512 VPOPCNTQ + VBMI [`super::cost_row_u8`]: [`cost_row_avx512`] with 64 disparities
    /// per step and bytes throughout. Eight loads of 8 right census strings, eight popcounts
    /// merged pairwise into disparity order by four two-register byte permutations (VBMI; fewer
    /// instructions than packing by shifts and permuting once) and three byte blends; the AD term stays in bytes (`min(weight · BT, cap)` is a 128-entry
    /// table lookup, one two-register byte permutation, since the cap is at most 127); then the
    /// worst cost and padding by masked moves and stores that never split a cache line.
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
        let pad = _mm512_set1_epi8(PAD_U8 as i8);
        let worst = _mm512_set1_epi8(worst as i8);
        // Load j's lane i (byte 8i of its popcounts) is disparity k + 8j + 7 - i; byte m of a
        // pair of loads (2a, 2a + 1) is disparity k + 16a + m % 16 for the m whose `m / 16 == a`,
        // from the first (index bit 6 clear) or second load of the pair by bit 3 of m.
        let unpack = {
            let mut idx = [0u8; 64];
            for (m, v) in idx.iter_mut().enumerate() {
                *v = (8 * (7 - m % 8) + 64 * ((m / 8) % 2)) as u8;
            }
            _mm512_loadu_si512(idx.as_ptr().cast())
        };
        // `min(weight · b, cap)` for b = 0..128; BT values are clamped to 127, where the term is
        // already at the cap (or 0 for weight 0) because the cap is at most 127.
        let (term_lo, term_hi) = match &ad {
            Some(ad) => {
                let table: [u8; 128] =
                    std::array::from_fn(|b| (u32::from(ad.weight) * b as u32).min(u32::from(ad.cap)) as u8);
                (_mm512_loadu_si512(table.as_ptr().cast()), _mm512_loadu_si512(table[64..].as_ptr().cast()))
            }
            None => (_mm512_setzero_si512(), _mm512_setzero_si512()),
        };
        let top = _mm512_set1_epi8(127);
        let bt_len = (width + 2 * BT_PAD) as i64;
        for (x, &census) in left.iter().enumerate() {
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
                    let r = _mm512_maskz_loadu_epi64(
                        inside,
                        right.as_ptr().wrapping_offset(lowest as isize).cast(),
                    );
                    _mm512_popcnt_epi64(_mm512_xor_si512(l, r))
                };
                // Loads 2a and 2a + 1 give disparities k + 16a.. (bytes 16a..16a + 16 of `pair`);
                // the four pairs' ranges are then put together by byte blends.
                let pair = |a: usize| _mm512_permutex2var_epi8(count(2 * a), unpack, count(2 * a + 1));
                let low_half = _mm512_mask_blend_epi8(0xffff_0000_ffff_0000, pair(0), pair(1));
                let mut cost = if half {
                    low_half
                } else {
                    let high_half = _mm512_mask_blend_epi8(0xffff_0000_ffff_0000, pair(2), pair(3));
                    _mm512_mask_blend_epi8(0xffff_ffff_0000_0000, low_half, high_half)
                };
                let block: u64 = if half { u64::from(u32::MAX) } else { u64::MAX };
                if let (Some(ad), Some((lv, llo, lhi))) = (&ad, bt_left) {
                    // Disparity k reads the reversed right BT rows at `i + k`; the pads of
                    // `BT_PAD` entries cover the lanes of interior pixels past `nd` (at most 31
                    // past it: `block` leaves out the upper half of a half block), masks the rest.
                    let i = BT_PAD as i64 + width as i64 - 1 - first + k as i64;
                    let inside = if interior { block } else { lanes_between(-i, bt_len - i, 64) & block };
                    let load = |row: &[u8]| {
                        // SAFETY: masked to the lanes inside `row` (`bt_len` entries); for interior
                        // pixels the lanes read end at `i + lanes - k <= BT_PAD + width + 31`,
                        // inside the padded row.
                        _mm512_maskz_loadu_epi8(inside, row.as_ptr().wrapping_offset(i as isize).cast())
                    };
                    let (rv, rlo, rhi) = (load(&ad.right.value), load(&ad.right.lo), load(&ad.right.hi));
                    let d_lr = _mm512_max_epu8(_mm512_subs_epu8(lv, rhi), _mm512_subs_epu8(rlo, lv));
                    let d_rl = _mm512_max_epu8(_mm512_subs_epu8(rv, lhi), _mm512_subs_epu8(llo, rv));
                    let bt = _mm512_min_epu8(_mm512_min_epu8(d_lr, d_rl), top);
                    cost = _mm512_add_epi8(cost, _mm512_permutex2var_epi8(term_lo, bt, term_hi));
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
                let at = dst.add(k);
                if half {
                    _mm256_storeu_si256(at.cast(), _mm512_castsi512_si256(cost));
                } else if (at as usize).is_multiple_of(64) {
                    _mm512_storeu_si512(at.cast(), cost);
                } else {
                    // Two 256-bit stores, at multiples of 32 bytes in an aligned row: one 512-bit
                    // store there would split a cache line.
                    _mm256_storeu_si256(at.cast(), _mm512_castsi512_si256(cost));
                    _mm256_storeu_si256(at.add(32).cast(), _mm512_extracti64x4_epi64::<1>(cost));
                }
                k += 64;
            }
        }
    }

    /// [`super::cost_row_u8`] for machines without the AVX-512 kernel: the scalar reference
    /// compiled with POPCNT.
    ///
    /// # Safety
    /// The CPU must have AVX2 and POPCNT.
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
        cost_row_u8_scalar(left, right, min_disparity, nd, worst, ad, out)
    }

    /// Lane masks for [`add_ad_avx2`]: 16 entries read from `MASKS[16 - n..]` are set from lane
    /// `n` on; from `MASKS[32 - n..]` below lane `n`.
    static MASKS: [u16; 48] = {
        let mut m = [0u16; 48];
        let mut i = 16;
        while i < 32 {
            m[i] = u16::MAX;
            i += 1;
        }
        m
    };

    /// AVX2 version of [`add_ad_avx512`], 16 disparities per step.
    ///
    /// # Safety
    /// The CPU must have AVX2; otherwise as [`add_ad_avx512`].
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
            // SAFETY: `below <= 15` and `1 <= upto <= 16`: both 16-entry reads are inside `MASKS`.
            let mask = _mm256_and_si256(
                _mm256_loadu_si256(MASKS.as_ptr().add(16 - below).cast()),
                _mm256_loadu_si256(MASKS.as_ptr().add(32 - upto).cast()),
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
            // SAFETY: `k` is a multiple of 16 below `hi <= lanes` (a multiple of 16), so entries
            // `k..k + 16` are this pixel's; lanes outside `lo..hi` add 0.
            let p = dst.add(k);
            let c = _mm256_loadu_si256(p.cast());
            _mm256_storeu_si256(p.cast(), _mm256_add_epi16(c, _mm256_and_si256(term, mask)));
            k += 16;
        }
    }

    /// [`super::cost_row`] for AVX2 machines: the scalar reference compiled with POPCNT.
    ///
    /// # Safety
    /// The CPU must have AVX2 and POPCNT.
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
        cost_row_scalar(left, right, min_disparity, nd, worst, None, out);
        if let Some(ad) = &ad {
            let (width, lanes) = (left.len(), padded_lanes(nd));
            for x in 0..width {
                let (lo, hi, first) = feasible(x, width, min_disparity, nd);
                // SAFETY: `lo..hi` are the feasible disparities of `x`, whose `lanes` entries
                // start at `x * lanes` (`out.len() == width * lanes` was checked).
                add_ad_avx2(ad, out.as_mut_ptr().add(x * lanes), x, width, first, lo, hi);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    #[allow(clippy::type_complexity)]
    fn path_case() -> impl Strategy<Value = (usize, usize, u16, Vec<(Vec<u16>, u16, u16)>, Vec<u16>, bool)> {
        (1usize..=100, 0usize..4).prop_flat_map(|(nd, extra)| {
            let lanes = padded_lanes(nd);
            let nd_sum = nd.saturating_sub(extra).max(1);
            (
                Just(nd),
                Just(nd_sum),
                1u16..200,
                prop::collection::vec(
                    (prop::collection::vec(0u16..9000, lanes + 2), 0u16..4100, 1u16..4000),
                    4,
                ),
                prop::collection::vec(0u16..8000, nd_sum),
                any::<bool>(),
            )
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(300))]

        #[test]
        fn path_step_kernels_match_the_scalar_reference((nd, _nd_sum, p1, paths, sum0, acc) in path_case(),
                                                        costs in prop::collection::vec(0u16..=64, 128)) {
            let lanes = padded_lanes(nd);
            let mut cost = costs[..lanes].to_vec();
            cost[nd..].fill(JUNK_COST);
            let ins: [PathIn; 4] = std::array::from_fn(|i| PathIn { prev: &paths[i].0, prev_min: paths[i].1, p2: paths[i].2 });
            let run = |level: Level| {
                let mut outs = vec![vec![PAD; lanes + 2]; 4];
                let mut sum = sum0.clone();
                let [a, b, c, d] = &mut outs[..] else { unreachable!() };
                let mins = path_step(level, &cost, p1, ins, [&mut a[..], &mut b[..], &mut c[..], &mut d[..]], &mut sum, acc);
                let two = {
                    let mut o2 = vec![vec![PAD; lanes + 2]; 2];
                    let mut s2 = sum0.clone();
                    let [e, f] = &mut o2[..] else { unreachable!() };
                    let m = path_step(level, &cost, p1, [ins[0], ins[1]], [&mut e[..], &mut f[..]], &mut s2, acc);
                    (o2, s2, m)
                };
                (outs, sum, mins, two)
            };
            let reference = run(Level::Scalar);
            for level in supported_levels() {
                prop_assert_eq!(&run(level), &reference, "{:?}", level);
            }
        }

        #[test]
        fn cost_row_kernels_match_the_scalar_reference(width in 1usize..120, nd_frac in 0.0f64..1.0,
                                                       min in -40i32..40, seed in any::<u64>(), worst in 9u16..=64,
                                                       ad in any::<Option<(u8, u8)>>(), step in 1u64..20000) {
            let nd = ((width as f64 * nd_frac) as usize).max(1);
            let mut s = seed | 1;
            let mut next = || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s };
            let left: Vec<u64> = (0..width).map(|_| next()).collect();
            let right: Vec<u64> = (0..width).map(|_| next()).collect();
            // Grey rows: random walks (small steps give BT values below the cap, large ones above).
            let mut walk = |width: usize| {
                let mut v = next() % 65536;
                let mut row = Vec::with_capacity(width);
                for _ in 0..width {
                    let r = next();
                    v = (v + r % step + 65536 - step / 2) % 65536;
                    row.push(v as u16);
                }
                row
            };
            let grey_left = walk(width);
            let grey_right = walk(width);
            let (mut bt_left, mut bt_right) = (BtRow::default(), BtRow::default());
            bt_left.fill(&grey_left, false);
            bt_right.fill(&grey_right, true);
            let ad = ad.map(|(weight, cap)| AdRows {
                left: &bt_left, right: &bt_right, weight: u16::from(weight % 9), cap: u16::from(cap % 128),
            });
            let worst = worst + ad.map_or(0, |a| a.cap);
            let lanes = padded_lanes(nd);
            let mut reference = vec![0u16; width * lanes];
            cost_row_scalar(&left, &right, min, nd, worst, ad, &mut reference);
            let top = features();
            for level in supported_levels() {
                let f = Features { level, vpopcnt: top.vpopcnt && level == Level::Avx512 };
                let mut out = vec![1u16; width * lanes];
                cost_row(f, &left, &right, min, nd, worst, ad, &mut out);
                prop_assert_eq!(&out, &reference, "{:?}", f);
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(400))]

        /// The 8-bit cost row equals the narrowed `u16` row (costs for `k < nd`, [`PAD_U8`]
        /// after) on every level, for widths, disparity counts (multiples of 32 or not, up to
        /// 256) and offsets (negative, past the width) that exercise interior and border pixels,
        /// with and without the AD term.
        #[test]
        fn cost_row_u8_kernels_match_the_narrowed_scalar_reference(
            width in 1usize..200, nd in prop_oneof![1usize..=64, 1usize..=256],
            min in prop_oneof![-8i32..8, -300i32..300], seed in any::<u64>(), worst in 9u16..=64,
            ad in any::<Option<(u8, u8)>>(), step in 1u64..20000,
        ) {
            let mut s = seed | 1;
            let mut next = || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s };
            let left: Vec<u64> = (0..width).map(|_| next()).collect();
            let right: Vec<u64> = (0..width).map(|_| next()).collect();
            let mut walk = |width: usize| {
                let mut v = next() % 65536;
                let mut row = Vec::with_capacity(width);
                for _ in 0..width {
                    let r = next();
                    v = (v + r % step + 65536 - step / 2) % 65536;
                    row.push(v as u16);
                }
                row
            };
            let grey_left = walk(width);
            let grey_right = walk(width);
            let (mut bt_left, mut bt_right) = (BtRow::default(), BtRow::default());
            bt_left.fill(&grey_left, false);
            bt_right.fill(&grey_right, true);
            let ad = ad.map(|(weight, cap)| AdRows {
                left: &bt_left, right: &bt_right, weight: u16::from(weight % 17), cap: u16::from(cap % (MAX_AD_CAP + 1)),
            });
            let worst = worst + ad.map_or(0, |a| a.cap);
            let (lanes, lanes8) = (padded_lanes(nd), padded_lanes_u8(nd));
            let mut wide = vec![0u16; width * lanes];
            cost_row_scalar(&left, &right, min, nd, worst, ad, &mut wide);
            let mut reference = vec![0u8; width * lanes8];
            crate::path_u8::narrow_row(&wide, lanes, nd, &mut reference, lanes8);
            let mut out = vec![1u8; width * lanes8];
            cost_row_u8_scalar(&left, &right, min, nd, worst, ad, &mut out);
            prop_assert_eq!(&out, &reference, "scalar");
            let top = features();
            for level in supported_levels() {
                let f = Features { level, vpopcnt: top.vpopcnt && level == Level::Avx512 };
                // Also at an odd address: the kernel's stores must not depend on alignment.
                for offset in [0, 1] {
                    let mut buf = vec![1u8; width * lanes8 + offset];
                    let out = &mut buf[offset..];
                    cost_row_u8(f, &left, &right, min, nd, worst, ad, out);
                    prop_assert_eq!(&out[..], &reference[..], "{:?} offset {}", f, offset);
                }
            }
        }
    }

    proptest! {
        #[test]
        fn argmin_kernels_match_the_scalar_reference(values in prop::collection::vec(0u16..40, 1..150),
                                                     big in any::<bool>()) {
            let values: Vec<u16> = values.iter().map(|&v| if big { v.wrapping_mul(1700) } else { v }).collect();
            for level in supported_levels() {
                prop_assert_eq!(argmin(level, &values), argmin_scalar(&values), "{:?}", level);
            }
        }

        #[test]
        fn keep_smaller_kernels_match_the_scalar_reference(rows in prop::collection::vec((0u16..30, 0u16..30, 0u16..500), 1..150),
                                                           first in 0u16..1000) {
            let costs: Vec<u16> = rows.iter().map(|r| r.0).collect();
            let best: Vec<u16> = rows.iter().map(|r| r.1).collect();
            let index: Vec<u16> = rows.iter().map(|r| r.2).collect();
            let (mut b0, mut i0) = (best.clone(), index.clone());
            keep_smaller_scalar(&costs, first, &mut b0, &mut i0);
            for level in supported_levels() {
                let (mut b, mut i) = (best.clone(), index.clone());
                keep_smaller(level, &costs, first, &mut b, &mut i);
                prop_assert_eq!((&b, &i), (&b0, &i0), "{:?}", level);
            }
        }
    }

    #[test]
    fn a_start_from_zero_returns_the_cost() {
        let nd = 40;
        let lanes = padded_lanes(nd);
        let mut cost: Vec<u16> = (0..lanes as u16).map(|k| k % 61).collect();
        cost[nd..].fill(JUNK_COST);
        let zero = vec![0u16; lanes + 2];
        for level in supported_levels() {
            let mut out = vec![PAD; lanes + 2];
            let mut sum = vec![0u16; nd];
            let [m] = path_step(
                level,
                &cost,
                10,
                [PathIn { prev: &zero, prev_min: 0, p2: 80 }],
                [&mut out[..]],
                &mut sum,
                false,
            );
            assert_eq!(&out[1..=lanes], &cost[..]);
            assert_eq!(&sum[..], &cost[..nd]);
            assert_eq!(m, 0);
        }
    }
}
