//! The AVX2 row kernel of [`crate::kernels::row_u8`]: the path steps of a whole row on 8-bit
//! path costs, with the horizontal path kept in registers (as
//! [`crate::kernels::x86_avx512`]'s row kernels do, 32 lanes per register instead of 64).
//!
//! Stepping pixel by pixel ([`super::path_step_u8_avx2`]) reloads the horizontal path's
//! previous costs three times per register (`d − 1`, `d`, `d + 1`) right after storing them,
//! builds each path's input and looks up its P2 per pixel. Here the horizontal path never
//! leaves the registers (its neighbours come from a 128-bit-lane permutation and a byte
//! alignment), the P2 rows arrive made, and the 16-bit sums of all paths are formed as the sums
//! of the even and the odd bytes (a mask and a shift, no cross-lane widening) and put back in
//! disparity order once per register. The paths continuing from the previous row stay in
//! memory. The results are those of [`crate::kernels::scalar::path_step_u8_scalar`] pixel by
//! pixel.

use std::arch::x86_64::*;

use super::{add_even_odd, hmin_epu8_256, store_even_odd};
use crate::kernels::layout::{FromRow, Trailing};

/// What every pixel step of a row shares.
struct Shape {
    width: usize,
    lanes: usize,
    nd: usize,
    pad: __m256i,
    p1: __m256i,
}

/// A horizontal path's state: its costs at the previous pixel and their minimum (broadcast).
struct Horizontal<const NV: usize> {
    path: [__m256i; NV],
    min: __m256i,
}

/// One path step from the previous vector `prev` (with its `d ∓ 1` neighbours `l`, `r`).
#[inline]
#[target_feature(enable = "avx2")]
fn step(
    p1: __m256i,
    c: __m256i,
    prev: __m256i,
    l: __m256i,
    r: __m256i,
    prev_min: __m256i,
    jump: __m256i,
) -> __m256i {
    path_vector!(U8_256_REGISTERS, c, prev, l, r, p1, jump, prev_min)
}

/// The 32 lanes one below (`d − 1`) and one above (`d + 1`) those of `v`, with `lower` and
/// `upper` the registers holding the lanes below and above it.
#[inline]
#[target_feature(enable = "avx2")]
fn neighbours(lower: __m256i, v: __m256i, upper: __m256i) -> (__m256i, __m256i) {
    // [high 128 bits of lower, low 128 of v] and [high 128 of v, low 128 of upper].
    let down = _mm256_permute2x128_si256::<0x03>(v, lower);
    let up = _mm256_permute2x128_si256::<0x21>(v, upper);
    (_mm256_alignr_epi8::<15>(v, down), _mm256_alignr_epi8::<1>(up, v))
}

/// The minimum of the 32 unsigned bytes of `m`, in every byte (on the horizontal chain: no trip
/// through a general register).
#[inline]
#[target_feature(enable = "avx2")]
fn min_broadcast_epu8(m: __m256i) -> __m256i {
    let m = _mm256_min_epu8(m, _mm256_permute2x128_si256::<0x01>(m, m));
    let m = _mm256_min_epu8(m, _mm256_shuffle_epi32::<0x4e>(m));
    let m = _mm256_min_epu8(m, _mm256_shuffle_epi32::<0xb1>(m));
    // Every dword now holds the minima of the four byte positions; fold them into byte 0,
    // which the shuffle then broadcasts (both 128-bit lanes are alike since the first step).
    let m = _mm256_min_epu8(m, _mm256_srli_epi32::<16>(m));
    let m = _mm256_min_epu8(m, _mm256_srli_epi16::<8>(m));
    _mm256_shuffle_epi8(m, _mm256_setzero_si256())
}

/// The steps of the `i`-th pixel `x` of a row: the horizontal path `h`, then the paths from
/// the previous row, their sum stored (or added) into `sum`.
///
/// # Safety
/// The CPU must have AVX2; lengths as checked by [`crate::kernels::row_u8`], `lanes == 32 * NV`.
/// Always inlined into [`row_avx2`], so that the horizontal path stays in registers.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
unsafe fn pixel<const NV: usize, const K: usize>(
    shape: &Shape,
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
    let Shape { width, lanes, nd, pad, p1 } = *shape;
    let stride = lanes + 2;
    // SAFETY: pixel `x < width` has `lanes = 32 * NV` costs at `x * lanes`.
    let c: [__m256i; NV] =
        std::array::from_fn(|v| unsafe { _mm256_loadu_si256(cost.as_ptr().add(x * lanes + 32 * v).cast()) });
    if i == 0 {
        // Entering the row: the path cost is the matching cost.
        h.path = c;
    } else {
        let jump = _mm256_adds_epu8(h.min, _mm256_set1_epi8(p2[x] as i8));
        let prev = h.path;
        for v in 0..NV {
            let lower = if v == 0 { pad } else { prev[v - 1] };
            let upper = if v + 1 == NV { pad } else { prev[v + 1] };
            let (l, r) = neighbours(lower, prev[v], upper);
            h.path[v] = step(p1, c[v], prev[v], l, r, h.min, jump);
        }
    }
    let mut m = h.path[0];
    for p in &h.path[1..] {
        m = _mm256_min_epu8(m, *p);
    }
    h.min = min_broadcast_epu8(m);
    let mut total: [[__m256i; 2]; NV] = [[_mm256_setzero_si256(); 2]; NV];
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
            let jump = _mm256_set1_epi8(prev_min.saturating_add(from.p2[x]) as i8);
            (jump, _mm256_set1_epi8(prev_min as i8), from.prev.as_ptr().add(f * stride))
        };
        for v in 0..NV {
            let o = if fresh {
                // The path enters the image here.
                c[v]
            } else {
                // SAFETY: entries `32v + {0, 1, 2} .. + 32` of pixel `f`'s `lanes + 2`.
                let at = |o: usize| unsafe { _mm256_loadu_si256(src.add(32 * v + o).cast()) };
                step(p1, c[v], at(1), at(0), at(2), prev_min, jump)
            };
            // SAFETY: the `lanes` entries after pixel `x`'s pad.
            _mm256_storeu_si256(out.add(32 * v).cast(), o);
            m = _mm256_min_epu8(m, o);
            add_even_odd(&mut total[v], o);
        }
        from.out_mins[x] = hmin_epu8_256(m);
    }
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
    let s = &mut sum[x * nd..(x + 1) * nd];
    for (v, &[even, odd]) in total.iter().enumerate() {
        // Registers past the last disparity hold only pads: their sums are not stored.
        if 32 * v < nd {
            store_even_odd(s, 32 * v, even, odd, accumulate);
        }
    }
}

/// AVX2 [`crate::kernels::row_u8`] with the horizontal paths in `NV` registers of 32 lanes.
///
/// # Safety
/// The CPU must have AVX2; lengths as checked by [`crate::kernels::row_u8`], and `lanes == 32 *
/// NV`.
#[target_feature(enable = "avx2")]
#[allow(clippy::too_many_arguments)]
pub(in crate::kernels) unsafe fn row_avx2<const NV: usize, const K: usize>(
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
    let pad = _mm256_set1_epi8(-1);
    let shape = Shape { width, lanes, nd, pad, p1: _mm256_set1_epi8(p1 as i8) };
    let mut h = Horizontal { path: [pad; NV], min: _mm256_setzero_si256() };
    let mut back = Horizontal { path: [pad; NV], min: _mm256_setzero_si256() };
    for i in 0..width {
        let x = if reverse { width - 1 - i } else { i };
        pixel::<NV, K>(&shape, &mut h, i, x, cost, p2, &mut from_row, sum, accumulate, reverse);
        if let Some(t) = &mut trailing {
            pixel::<NV, 0>(&shape, &mut back, i, width - 1 - i, t.cost, t.p2, &mut [], t.sum, true, true);
        }
    }
}
