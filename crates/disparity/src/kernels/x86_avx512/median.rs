//! AVX-512 3 × 3 median of a row of a disparity map ([`super::super::median3x3_row`]).

use std::arch::x86_64::*;

use crate::kernels::scalar::median9_network;

/// `f32::total_cmp` order as a signed 32-bit order, 16 lanes (as `scalar::median_key`).
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl")]
fn key(v: __m512i) -> __m512i {
    _mm512_xor_si512(v, _mm512_srli_epi32::<1>(_mm512_srai_epi32::<31>(v)))
}

/// Entry 4 of the median network over the keys `w` whose holes became `low` lowest and the
/// rest highest keys, per lane (as `scalar::median_with_sentinels`).
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl")]
fn with_sentinels(w: &[__m512i; 9], hole: &[__mmask16; 9], low: __m512i) -> __m512i {
    let mut w = *w;
    let (lowest, highest, one) =
        (_mm512_set1_epi32(i32::MIN), _mm512_set1_epi32(i32::MAX), _mm512_set1_epi32(1));
    let mut seen = _mm512_setzero_si512();
    for (entry, &hole) in w.iter_mut().zip(hole) {
        let sentinel = _mm512_mask_blend_epi32(_mm512_cmplt_epi32_mask(seen, low), highest, lowest);
        *entry = _mm512_mask_blend_epi32(hole, *entry, sentinel);
        seen = _mm512_mask_add_epi32(seen, hole, seen, one);
    }
    median9_network!(w, _mm512_min_epi32, _mm512_max_epi32);
    w[4]
}

/// AVX-512 [`super::super::median3x3_row`], 16 pixels per step; returns how many pixels from
/// the row's start it wrote (a multiple of 16), the caller finishes the rest.
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL; each of `rows` at least `out.len() + 2` long.
#[target_feature(enable = "avx512f,avx512bw,avx512vl")]
pub(crate) unsafe fn median3x3_row_avx512(rows: [&[f32]; 3], out: &mut [f32]) -> usize {
    debug_assert!(rows.iter().all(|r| r.len() >= out.len() + 2));
    let (magnitude, infinity) = (_mm512_set1_epi32(0x7fff_ffff), _mm512_set1_epi32(0x7f80_0000));
    let (one, half) = (_mm512_set1_epi32(1), _mm512_set1_ps(0.5));
    let n = out.len() - out.len() % 16;
    for x in (0..n).step_by(16) {
        let mut w = [_mm512_setzero_si512(); 9];
        let mut hole = [0 as __mmask16; 9];
        for (i, (entry, hole)) in w.iter_mut().zip(&mut hole).enumerate() {
            // SAFETY: 16 values from `x + i % 3 <= out.len() - 16 + 2` of a row of at least
            // `out.len() + 2`.
            let v = unsafe { _mm512_loadu_si512(rows[i / 3].as_ptr().add(x + i % 3).cast()) };
            *hole = _mm512_cmpgt_epi32_mask(_mm512_and_si512(v, magnitude), infinity);
            *entry = key(v);
        }
        let any = hole.iter().fold(0, |a, &m| a | m);
        let median = if any == 0 {
            median9_network!(w, _mm512_min_epi32, _mm512_max_epi32);
            _mm512_castsi512_ps(key(w[4]))
        } else {
            let holes = hole.iter().fold(_mm512_setzero_si512(), |c, &m| _mm512_mask_add_epi32(c, m, c, one));
            let upper = _mm512_castsi512_ps(key(with_sentinels(&w, &hole, _mm512_srli_epi32::<1>(holes))));
            let odd = _mm512_test_epi32_mask(holes, one);
            let median = if odd == 0 {
                upper
            } else {
                let low = _mm512_srli_epi32::<1>(_mm512_add_epi32(holes, one));
                let lower = _mm512_castsi512_ps(key(with_sentinels(&w, &hole, low)));
                _mm512_mask_blend_ps(odd, upper, _mm512_mul_ps(half, _mm512_add_ps(lower, upper)))
            };
            // A hole at the centre keeps its value (and payload).
            _mm512_mask_blend_ps(hole[4], median, _mm512_castsi512_ps(key(w[4])))
        };
        // SAFETY: 16 values from `x <= out.len() - 16`.
        unsafe { _mm512_storeu_ps(out.as_mut_ptr().add(x), median) };
    }
    n
}
