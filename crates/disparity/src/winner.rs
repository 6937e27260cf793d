//! Winner-takes-all pieces shared by block matching ([`crate::bm`]) and SGM ([`crate::wta`]):
//! the winner, the uniqueness test, the range-end rule, the right view's winners, the left-right
//! check and the subpixel fit. Where the two matchers differ they pass a parameter: the cost
//! type (`u32` window sums, `u16` path sums), which pixels and disparities are feasible, whether
//! a tie with the uniqueness bound is ambiguous ([`Ties`]), and whether the left-right check
//! compares disparity indices (SGM) or refined disparities (BM).
//!
//! SGM's AVX-512 fused selection (`wta::fused`) finds winners, runner-ups and the right view in
//! registers; it calls [`left_right_check`] and [`subpixel_offset`] from here and is proptested
//! against the reference built from these functions.

use std::ops::Range;

use crate::kernels::scalar::argmin_scalar;
use crate::{DisparityRange, Subpixel};

/// A matching cost the selection compares: ordered, widened exactly to `u64` for the uniqueness
/// test and converted to `f32` for the subpixel fit.
pub(crate) trait Cost: Copy + Ord + Into<u64> {
    fn to_f32(self) -> f32;
}

impl Cost for u16 {
    #[inline(always)]
    fn to_f32(self) -> f32 {
        f32::from(self)
    }
}

impl Cost for u32 {
    #[inline(always)]
    fn to_f32(self) -> f32 {
        self as f32
    }
}

/// The winning disparity index among `ks` (non-empty): the lowest-cost one, the lowest index
/// among equal costs.
#[inline(always)]
pub(crate) fn winner<C: Cost>(c: &[C], ks: Range<usize>) -> usize {
    ks.start + argmin_scalar(&c[ks]).1
}

/// How the uniqueness test counts a runner-up whose cost is exactly at the bound.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Ties {
    /// `best · (100 + ratio) == second · 100` is unique (SGM).
    Unique,
    /// ... is ambiguous, like OpenCV's StereoBM (BM).
    Ambiguous,
}

/// The uniqueness test: whether a disparity more than one index away from `best` (within `ks`)
/// costs less than `(100 + ratio) %` of the best cost (or as much, with [`Ties::Ambiguous`]).
/// Ratio 0 never rejects.
#[inline(always)]
pub(crate) fn ambiguous<C: Cost>(c: &[C], ks: Range<usize>, best: usize, ratio: u32, ties: Ties) -> bool {
    if ratio == 0 {
        return false;
    }
    let second = ks.filter(|k| k.abs_diff(best) > 1).map(|k| c[k]).min();
    second.is_some_and(|second| {
        let scaled_best = c[best].into() * (100 + u64::from(ratio));
        let scaled_second = second.into() * 100;
        match ties {
            Ties::Unique => scaled_best > scaled_second,
            Ties::Ambiguous => scaled_best >= scaled_second,
        }
    })
}

/// The ends of the searched disparities where a winner only says that the true minimum may lie
/// beyond: the range's first and last disparity, and where the search stopped early at the
/// image edge (`lo` above the first), that edge; the far edge (`hi` below the last) only in the
/// lowest quarter of the range. Such winners are rejected (see `post::reject_range_ends`).
/// In disparities (`f32`, SGM: after the selection, on the map) or disparity indices (`usize`,
/// BM: during the selection).
#[derive(Clone, Copy, Debug)]
pub(crate) struct RangeEnds<T> {
    first: T,
    last: T,
    trusted_edge: T,
}

impl RangeEnds<f32> {
    /// The ends in disparities.
    pub(crate) fn disparities(range: DisparityRange) -> Self {
        RangeEnds {
            first: range.min as f32,
            last: (range.max - 1) as f32,
            trusted_edge: range.min as f32 + (range.count() / 4) as f32,
        }
    }
}

impl RangeEnds<usize> {
    /// The ends in disparity indices `0..count`.
    pub(crate) fn indices(count: usize) -> Self {
        RangeEnds { first: 0, last: count - 1, trusted_edge: count / 4 }
    }
}

impl<T: Copy + PartialOrd> RangeEnds<T> {
    /// Whether the integer winner `d`, searched among `lo..=hi`, is at an end.
    #[inline(always)]
    pub(crate) fn at_end(&self, d: T, lo: T, hi: T) -> bool {
        d == self.first
            || d == self.last
            || (d == lo && lo > self.first)
            || (d == hi && hi < self.trusted_edge)
    }
}

/// An index of the right view's winners: a disparity index, or [`WinnerIndex::NONE`] for a right
/// pixel without a feasible disparity.
pub(crate) trait WinnerIndex: Copy + PartialEq {
    const NONE: Self;
    fn index(self) -> usize;
    fn from_index(k: usize) -> Self;
}

impl WinnerIndex for u16 {
    const NONE: u16 = u16::MAX;
    #[inline(always)]
    fn index(self) -> usize {
        usize::from(self)
    }
    #[inline(always)]
    fn from_index(k: usize) -> Self {
        k as u16
    }
}

impl WinnerIndex for u32 {
    const NONE: u32 = u32::MAX;
    #[inline(always)]
    fn index(self) -> usize {
        self as usize
    }
    #[inline(always)]
    fn from_index(k: usize) -> Self {
        k as u32
    }
}

/// The right view's winner-takes-all from the left view's costs (Hirschmüller's shortcut instead
/// of a second matching), in one forward sweep: right pixel `xr` sees left pixel `xr + min + k`
/// at disparity index `k`. Indexed by `q = width - 1 - xr` (`best` and `index` have `width`
/// entries), one left pixel's candidates are contiguous in `k`; left pixels are visited in
/// increasing `x`, so for equal costs the lowest `k` stays. `costs(x)` are left pixel `x`'s costs
/// by disparity index, `feasible(x)` the indices it searched (empty to skip the pixel); `keep`
/// is the update `if costs[j] < best[j] { best[j] = costs[j]; index[j] = first + j }`.
/// Right pixels without a candidate end with [`WinnerIndex::NONE`].
#[inline(always)]
pub(crate) fn right_view_winners<'c, C: Cost + 'c, I: WinnerIndex>(
    min: i64,
    costs: impl Fn(usize) -> &'c [C],
    feasible: impl Fn(usize) -> Range<usize>,
    mut keep: impl FnMut(&[C], usize, &mut [C], &mut [I]),
    worst: C,
    best: &mut [C],
    index: &mut [I],
) {
    let width = best.len();
    assert_eq!(index.len(), width);
    best.fill(worst);
    index.fill(I::NONE);
    for x in 0..width {
        let ks = feasible(x);
        if ks.is_empty() {
            continue;
        }
        let c = &costs(x)[ks.clone()];
        let q0 = (width as i64 - 1 - x as i64 + min + ks.start as i64) as usize;
        let (b, i) = (&mut best[q0..q0 + c.len()], &mut index[q0..q0 + c.len()]);
        keep(c, ks.start, b, i);
    }
}

/// The `keep` of [`right_view_winners`] for any cost and index type (the `u16` one has SIMD
/// kernels: [`crate::kernels::keep_smaller`]).
#[inline(always)]
pub(crate) fn keep_smaller<C: Cost, I: WinnerIndex>(
    costs: &[C],
    first: usize,
    best: &mut [C],
    index: &mut [I],
) {
    for (j, ((&c, b), i)) in costs.iter().zip(best.iter_mut()).zip(index.iter_mut()).enumerate() {
        if c < *b {
            *b = c;
            *i = I::from_index(first + j);
        }
    }
}

/// The left-right check of a left winner matched to right pixel `xr`: passes when the right
/// view's winner there (`right_index` as [`right_view_winners`] leaves it), taken as
/// `origin + kr`, lies within `max_diff` of `value`. SGM compares indices (`value` the left
/// winner's index, `origin` 0), BM its refined disparity (`origin` the smallest disparity).
/// A failure says whether the right view's value is the larger (an occlusion: a nearer surface
/// hides the pixel there); `false` also where the right pixel is outside or has no winner.
///
/// With `left_neighbour`, a would-be occlusion also passes when the right pixel one to the left,
/// `xr − 1`, agrees: the right view's winners come from the left volume, whose foreground
/// spreads about a pixel into the background beside a depth edge, so right after such an edge
/// the check otherwise rejects background pixels that matched correctly (docs/accuracy.md).
#[inline(always)]
pub(crate) fn left_right_check<I: WinnerIndex>(
    right_index: &[I],
    xr: i64,
    value: f32,
    origin: i64,
    max_diff: f32,
    left_neighbour: bool,
) -> Result<(), bool> {
    let width = right_index.len();
    let right_at = |q: i64| {
        if !(0..width as i64).contains(&q) {
            return None;
        }
        let k = right_index[width - 1 - q as usize];
        (k != I::NONE).then(|| (origin + k.index() as i64) as f32)
    };
    let Some(right) = right_at(xr) else {
        return Err(false);
    };
    if (value - right).abs() <= max_diff {
        return Ok(());
    }
    if left_neighbour && right > value && right_at(xr - 1).is_some_and(|r| (value - r).abs() <= max_diff) {
        return Ok(());
    }
    Err(right > value)
}

/// Sub-pixel offset in `[-0.5, 0.5]` of the cost minimum from the three costs around it.
#[inline]
pub(crate) fn subpixel_offset(method: Subpixel, before: f32, best: f32, after: f32) -> f32 {
    let offset = match method {
        Subpixel::None => 0.0,
        Subpixel::Parabola => {
            let curvature = before - 2.0 * best + after;
            if curvature > 0.0 {
                (before - after) / (2.0 * curvature)
            } else {
                0.0
            }
        }
        Subpixel::Equiangular => {
            let slope = (before - best).max(after - best);
            if slope > 0.0 {
                (before - after) / (2.0 * slope)
            } else {
                0.0
            }
        }
    };
    offset.clamp(-0.5, 0.5)
}

/// The subpixel offset of winner `best` from its neighbours' costs (0 at the ends of `ks`,
/// where a neighbour was not searched).
#[inline(always)]
pub(crate) fn refined_offset<C: Cost>(c: &[C], ks: Range<usize>, best: usize, method: Subpixel) -> f32 {
    if best > ks.start && best + 1 < ks.end {
        subpixel_offset(method, c[best - 1].to_f32(), c[best].to_f32(), c[best + 1].to_f32())
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Right view winners (disparity indices) of an 8-pixel row, stored as the check reads them
    /// (right pixel `xr` at `width − 1 − xr`): background 2 at xr 0–3, foreground 6 from xr 4.
    fn right_row() -> Vec<u16> {
        let by_xr = [2u16, 2, 2, 2, 6, 6, 6, 6];
        by_xr.iter().rev().copied().collect()
    }

    #[test]
    fn the_left_neighbour_rescues_only_would_be_occlusions() {
        let right = right_row();
        // Background 2 matched at the foreground's first right pixel (xr 4): an occlusion for the
        // plain check, passes against xr 3 with the neighbour.
        assert_eq!(left_right_check(&right, 4, 2.0, 0, 1.0, false), Err(true));
        assert_eq!(left_right_check(&right, 4, 2.0, 0, 1.0, true), Ok(()));
        // Two pixels into the foreground, the neighbour is foreground too: still occluded.
        assert_eq!(left_right_check(&right, 5, 2.0, 0, 1.0, true), Err(true));
        // A foreground value against the background (a mismatch, not an occlusion) is never
        // rescued.
        assert_eq!(left_right_check(&right, 3, 6.0, 0, 1.0, true), Err(false));
        // Outside the image, or a neighbour without a winner: no rescue.
        assert_eq!(left_right_check(&right, 8, 2.0, 0, 1.0, true), Err(false));
        let mut holey = right.clone();
        holey[8 - 1 - 3] = u16::NONE;
        assert_eq!(left_right_check(&holey, 4, 2.0, 0, 1.0, true), Err(true));
    }

    #[test]
    fn subpixel_offsets() {
        let v = |x: f32| x.abs();
        assert!((subpixel_offset(Subpixel::Equiangular, v(-1.0), v(0.0), v(1.0)) - 0.0).abs() < 1e-6);
        assert_eq!(subpixel_offset(Subpixel::None, 3.0, 1.0, 2.0), 0.0);
        assert_eq!(subpixel_offset(Subpixel::Parabola, 100.0, 0.0, 0.0), 0.5);
        assert_eq!(refined_offset(&[4u32, 1, 4], 0..3, 1, Subpixel::Parabola), 0.0);
        assert_eq!(refined_offset(&[9u16, 1, 4], 1..3, 1, Subpixel::Parabola), 0.0);
    }

    #[test]
    fn ties_and_range_ends() {
        // best 10, runner-up 11 two indices away: 10 · 110 = 1100 == 11 · 100.
        let c = [10u16, 50, 11];
        assert!(!ambiguous(&c, 0..3, 0, 10, Ties::Unique));
        assert!(ambiguous(&c, 0..3, 0, 10, Ties::Ambiguous));
        assert!(!ambiguous(&c, 0..3, 0, 0, Ties::Ambiguous));
        let ends = RangeEnds::disparities(DisparityRange { min: 0, max: 16 });
        let indices = RangeEnds::indices(16);
        assert!(indices.at_end(0, 0, 15) && indices.at_end(3, 0, 3) && !indices.at_end(4, 0, 4));
        assert!(ends.at_end(0.0, 0.0, 15.0) && ends.at_end(15.0, 0.0, 15.0));
        assert!(ends.at_end(3.0, 3.0, 15.0) && !ends.at_end(4.0, 3.0, 15.0));
        assert!(ends.at_end(3.0, 0.0, 3.0) && !ends.at_end(5.0, 0.0, 5.0));
    }
}
