//! AVX2 3 × 3 median of a row of a disparity map ([`super::super::median3x3_row`]): the
//! AVX-512 kernel's network on 8 lanes, with vector masks for the holes. The portable lanes
//! (`scalar::median3x3_row_lanes`) compiled for AVX2 took 2.2 times as long (teddy at the
//! AVX2 level, `perf record` samples over 60 calls: 413 → 186).

use std::arch::x86_64::*;

use crate::kernels::scalar::median9_network;

/// `f32::total_cmp` order as a signed 32-bit order, 8 lanes (as `scalar::median_key`).
#[inline]
#[target_feature(enable = "avx2")]
fn key(v: __m256i) -> __m256i {
    _mm256_xor_si256(v, _mm256_srli_epi32::<1>(_mm256_srai_epi32::<31>(v)))
}

/// Entry 4 of the median network over the keys `w` whose holes (all-ones lanes of `hole`)
/// became `low` lowest and the rest highest keys, per lane (as `scalar::median_with_sentinels`).
#[inline]
#[target_feature(enable = "avx2")]
fn with_sentinels(w: &[__m256i; 9], hole: &[__m256i; 9], low: __m256i) -> __m256i {
    let mut w = *w;
    let (lowest, highest) = (_mm256_set1_epi32(i32::MIN), _mm256_set1_epi32(i32::MAX));
    let mut seen = _mm256_setzero_si256();
    for (entry, &hole) in w.iter_mut().zip(hole) {
        let sentinel = _mm256_blendv_epi8(highest, lowest, _mm256_cmpgt_epi32(low, seen));
        *entry = _mm256_blendv_epi8(*entry, sentinel, hole);
        // An all-ones lane is −1: subtracting it counts the hole.
        seen = _mm256_sub_epi32(seen, hole);
    }
    median9_network!(w, _mm256_min_epi32, _mm256_max_epi32);
    w[4]
}

/// AVX2 [`super::super::median3x3_row`], 8 pixels per step; returns how many pixels from the
/// row's start it wrote (a multiple of 8), the caller finishes the rest.
///
/// # Safety
/// The CPU must have AVX2; each of `rows` at least `out.len() + 2` long.
#[target_feature(enable = "avx2")]
pub(in crate::kernels) unsafe fn median3x3_row_avx2(rows: [&[f32]; 3], out: &mut [f32]) -> usize {
    debug_assert!(rows.iter().all(|r| r.len() >= out.len() + 2));
    let (magnitude, infinity) = (_mm256_set1_epi32(0x7fff_ffff), _mm256_set1_epi32(0x7f80_0000));
    let (one, half) = (_mm256_set1_epi32(1), _mm256_set1_ps(0.5));
    let n = out.len() - out.len() % 8;
    for x in (0..n).step_by(8) {
        let mut w = [_mm256_setzero_si256(); 9];
        let mut hole = [_mm256_setzero_si256(); 9];
        for (i, (entry, hole)) in w.iter_mut().zip(&mut hole).enumerate() {
            // SAFETY: 8 values from `x + i % 3 <= out.len() - 8 + 2` of a row of at least
            // `out.len() + 2`.
            let v = unsafe { _mm256_loadu_si256(rows[i / 3].as_ptr().add(x + i % 3).cast()) };
            *hole = _mm256_cmpgt_epi32(_mm256_and_si256(v, magnitude), infinity);
            *entry = key(v);
        }
        let any = hole.iter().fold(_mm256_setzero_si256(), |a, &m| _mm256_or_si256(a, m));
        let median = if _mm256_testz_si256(any, any) == 1 {
            median9_network!(w, _mm256_min_epi32, _mm256_max_epi32);
            _mm256_castsi256_ps(key(w[4]))
        } else {
            let holes = hole.iter().fold(_mm256_setzero_si256(), |c, &m| _mm256_sub_epi32(c, m));
            let upper = _mm256_castsi256_ps(key(with_sentinels(&w, &hole, _mm256_srli_epi32::<1>(holes))));
            let odd = _mm256_cmpeq_epi32(_mm256_and_si256(holes, one), one);
            let median = if _mm256_testz_si256(odd, odd) == 1 {
                upper
            } else {
                let low = _mm256_srli_epi32::<1>(_mm256_add_epi32(holes, one));
                let lower = _mm256_castsi256_ps(key(with_sentinels(&w, &hole, low)));
                let mean = _mm256_mul_ps(half, _mm256_add_ps(lower, upper));
                _mm256_blendv_ps(upper, mean, _mm256_castsi256_ps(odd))
            };
            // A hole at the centre keeps its value (and payload).
            _mm256_blendv_ps(median, _mm256_castsi256_ps(key(w[4])), _mm256_castsi256_ps(hole[4]))
        };
        // SAFETY: 8 values from `x <= out.len() - 8`.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr().add(x), median) };
    }
    n
}
