//! NEON 3 × 3 median of a row of a disparity map ([`super::super::median3x3_row`]). The
//! compiler leaves the portable lanes (`scalar::median3x3_row_lanes`) scalar on aarch64; this
//! kernel runs the same network four lanes at a time (tsukuba's whole run 184.9 → 172.2 M
//! instructions under qemu, `scripts/aarch64-count.sh`).

use std::arch::aarch64::*;

use crate::kernels::scalar::median9_network;

/// `f32::total_cmp` order as a signed 32-bit order, four lanes (as `scalar::median_key`).
#[inline]
#[target_feature(enable = "neon")]
fn key(v: int32x4_t) -> int32x4_t {
    veorq_s32(v, vreinterpretq_s32_u32(vshrq_n_u32::<1>(vreinterpretq_u32_s32(vshrq_n_s32::<31>(v)))))
}

/// Entry 4 of the median network over the keys `w` whose holes (all-ones lanes of `hole`)
/// became `low` lowest and the rest highest keys, per lane (as `scalar::median_with_sentinels`).
#[inline]
#[target_feature(enable = "neon")]
fn with_sentinels(w: &[int32x4_t; 9], hole: &[uint32x4_t; 9], low: int32x4_t) -> int32x4_t {
    let mut w = *w;
    let (lowest, highest) = (vdupq_n_s32(i32::MIN), vdupq_n_s32(i32::MAX));
    let mut seen = vdupq_n_s32(0);
    for (entry, &hole) in w.iter_mut().zip(hole) {
        let sentinel = vbslq_s32(vcltq_s32(seen, low), lowest, highest);
        *entry = vbslq_s32(hole, sentinel, *entry);
        // An all-ones lane is −1: subtracting it counts the hole.
        seen = vsubq_s32(seen, vreinterpretq_s32_u32(hole));
    }
    median9_network!(w, vminq_s32, vmaxq_s32);
    w[4]
}

/// NEON [`super::super::median3x3_row`], 4 pixels per step; returns how many pixels from the
/// row's start it wrote (a multiple of 4), the caller finishes the rest.
///
/// # Safety
/// The CPU must have NEON; each of `rows` at least `out.len() + 2` long.
#[target_feature(enable = "neon")]
pub(in crate::kernels) unsafe fn median3x3_row_neon(rows: [&[f32]; 3], out: &mut [f32]) -> usize {
    debug_assert!(rows.iter().all(|r| r.len() >= out.len() + 2));
    let (magnitude, infinity) = (vdupq_n_s32(0x7fff_ffff), vdupq_n_s32(0x7f80_0000));
    let (one, half) = (vdupq_n_s32(1), vdupq_n_f32(0.5));
    let n = out.len() - out.len() % 4;
    for x in (0..n).step_by(4) {
        let mut w = [vdupq_n_s32(0); 9];
        let mut hole = [vdupq_n_u32(0); 9];
        for (i, (entry, hole)) in w.iter_mut().zip(&mut hole).enumerate() {
            // SAFETY: 4 values from `x + i % 3 <= out.len() - 4 + 2` of a row of at least
            // `out.len() + 2`.
            let v = unsafe { vld1q_s32(rows[i / 3].as_ptr().add(x + i % 3).cast()) };
            *hole = vcgtq_s32(vandq_s32(v, magnitude), infinity);
            *entry = key(v);
        }
        let any = hole.iter().fold(vdupq_n_u32(0), |a, &m| vorrq_u32(a, m));
        let median = if vmaxvq_u32(any) == 0 {
            median9_network!(w, vminq_s32, vmaxq_s32);
            vreinterpretq_f32_s32(key(w[4]))
        } else {
            let holes = hole.iter().fold(vdupq_n_s32(0), |c, &m| vsubq_s32(c, vreinterpretq_s32_u32(m)));
            let upper = vreinterpretq_f32_s32(key(with_sentinels(&w, &hole, vshrq_n_s32::<1>(holes))));
            let odd = vtstq_s32(holes, one);
            let median = if vmaxvq_u32(odd) == 0 {
                upper
            } else {
                let low = vshrq_n_s32::<1>(vaddq_s32(holes, one));
                let lower = vreinterpretq_f32_s32(key(with_sentinels(&w, &hole, low)));
                vbslq_f32(odd, vmulq_f32(half, vaddq_f32(lower, upper)), upper)
            };
            // A hole at the centre keeps its value (and payload).
            vbslq_f32(hole[4], vreinterpretq_f32_s32(key(w[4])), median)
        };
        // SAFETY: 4 values from `x <= out.len() - 4`.
        unsafe { vst1q_f32(out.as_mut_ptr().add(x), median) };
    }
    n
}
