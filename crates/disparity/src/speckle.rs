//! Speckle removal: small connected regions of similar disparity are usually wrong matches
//! (OpenCV's `filterSpeckles`; imageproc has no such filter).

use crate::status::{tagged_nan, PixelStatus};
use crate::DisparityMap;

/// Invalidates every 4-connected region of valid pixels (neighbours joined when their
/// disparities differ by at most `max_diff`) with fewer than `max_size` pixels; the removed
/// pixels become NaN (tagged [`PixelStatus::Speckle`] inside the pipeline). Returns how many
/// pixels were removed. `max_size` 0 or 1 removes nothing. O(W·H): one flood fill per region.
pub fn remove_speckles(disparity: &mut DisparityMap, max_size: usize, max_diff: f32) -> usize {
    remove_speckles_keeping_border(disparity, max_size, max_diff, 0, 0)
}

/// [`remove_speckles`], except that a region touching the image border stays when it holds at
/// least `keep_border` pixels (0: never), [`crate::SgmParams::speckle_keep_border`], and that a
/// region reaches across up to `bridge` pixels that were invalid before the filter, in a row or a
/// column, to a pixel within `max_diff` (0: never), [`crate::SgmParams::speckle_bridge`].
pub(crate) fn remove_speckles_keeping_border(
    disparity: &mut DisparityMap,
    max_size: usize,
    max_diff: f32,
    keep_border: usize,
    bridge: usize,
) -> usize {
    if max_size <= 1 {
        return 0;
    }
    let (w, h) = disparity.size();
    let d = disparity.as_mut_slice();
    let mut seen = vec![false; d.len()];
    let mut stack: Vec<u32> = Vec::new();
    let mut region: Vec<u32> = Vec::new();
    let mut removed = 0;
    let at_border = |p: usize| {
        let (x, y) = (p % w, p / w);
        x == 0 || y == 0 || x + 1 == w || y + 1 == h
    };
    for start in 0..d.len() {
        if seen[start] || d[start].is_nan() {
            continue;
        }
        region.clear();
        let mut touches_border = false;
        // Only the first `max_size` members are remembered: a larger region is kept anyway.
        flood_region(d, w, start, max_diff, bridge, &mut seen, &mut stack, |p, _| {
            touches_border |= keep_border > 0 && at_border(p);
            if region.len() < max_size {
                region.push(p as u32);
            }
        });
        let kept_at_border = keep_border > 0 && touches_border && region.len() >= keep_border;
        if region.len() < max_size && !kept_at_border {
            for &p in &region {
                d[p as usize] = tagged_nan(PixelStatus::Speckle);
            }
            removed += region.len();
        }
    }
    removed
}

/// Visits the 4-connected region of valid pixels around `start` in the row-major map `d` (`w`
/// wide) whose neighbours differ by at most `max_diff`, marking each in `seen` and calling `each`
/// with its index and disparity. With `bridge` > 0 a pixel's neighbours also include the first
/// valid pixel beyond up to `bridge` invalid ones to its left, right, top and bottom, counting as
/// invalid only pixels not yet `seen` (invalid before the caller's first region, not removed by
/// it since). The whole region is visited, so no later start sees a part of it. `stack` is
/// scratch space, reused between calls.
#[allow(clippy::too_many_arguments)]
pub(crate) fn flood_region(
    d: &[f32],
    w: usize,
    start: usize,
    max_diff: f32,
    bridge: usize,
    seen: &mut [bool],
    stack: &mut Vec<u32>,
    mut each: impl FnMut(usize, f32),
) {
    let h = d.len() / w;
    seen[start] = true;
    stack.push(start as u32);
    while let Some(p) = stack.pop() {
        let p = p as usize;
        let v = d[p];
        each(p, v);
        let (x, y) = (p % w, p / w);
        // The neighbours: left, right, top, bottom, each as (pixels to the edge, stride, sign).
        let sides = [(x, 1, false), (w - 1 - x, 1, true), (y, w, false), (h - 1 - y, w, true)];
        for (room, stride, forward) in sides {
            let at = |k: usize| if forward { p + k * stride } else { p - k * stride };
            // Across a hole: over invalid pixels not yet seen (invalid before the caller's first
            // region), at most `bridge` of them, to the first valid one.
            let mut k = 1;
            while k <= room && k <= bridge && d[at(k)].is_nan() && !seen[at(k)] {
                k += 1;
            }
            if k <= room {
                let q = at(k);
                if !seen[q] && !d[q].is_nan() && (d[q] - v).abs() <= max_diff {
                    seen[q] = true;
                    stack.push(q as u32);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_islands_go_large_regions_stay() {
        // A 10x10 map at 5 px with a 2x2 island at 20 px and a 3x1 island at 5.5..6.5 (joined
        // to the background: within max_diff of it, so it stays).
        let mut d = DisparityMap::new(10, 10, 5.0);
        for (x, y) in [(2, 2), (3, 2), (2, 3), (3, 3)] {
            d.set(x, y, 20.0);
        }
        d.set(7, 7, 5.5);
        d.set(8, 7, 6.0);
        d.set(0, 9, f32::NAN);
        let removed = remove_speckles(&mut d, 5, 1.0);
        assert_eq!(removed, 4);
        assert!(d.get(2, 2).is_nan() && d.get(3, 3).is_nan());
        assert_eq!(crate::status::status_of(d.get(2, 2)), PixelStatus::Speckle);
        assert_eq!((d.get(7, 7), d.get(8, 7), d.get(0, 0)), (5.5, 6.0, 5.0));
        // A region of exactly max_size pixels stays.
        let mut e = DisparityMap::new(10, 10, 5.0);
        for (x, y) in [(2, 2), (3, 2), (2, 3), (3, 3)] {
            e.set(x, y, 20.0);
        }
        assert_eq!(remove_speckles(&mut e, 4, 1.0), 0);
        assert_eq!(remove_speckles(&mut e, 0, 1.0), 0);
    }

    #[test]
    fn regions_cut_by_the_border_stay_from_their_own_size() {
        // A 12x10 map at 5 px with three islands at 20 px: 2x3 at the left border, 3x3 at the
        // bottom border, 3x3 inside.
        let island = |d: &mut DisparityMap, xs: std::ops::Range<usize>, ys: std::ops::Range<usize>| {
            for y in ys {
                for x in xs.clone() {
                    d.set(x, y, 20.0);
                }
            }
        };
        let map = || {
            let mut d = DisparityMap::new(12, 10, 5.0);
            island(&mut d, 0..2, 2..5);
            island(&mut d, 6..9, 7..10);
            island(&mut d, 4..7, 2..5);
            d
        };
        let mut plain = map();
        assert_eq!(remove_speckles(&mut plain, 20, 1.0), 6 + 9 + 9);
        // Border regions of 6 or more pixels stay: both border islands, not the inner one.
        let mut d = map();
        assert_eq!(remove_speckles_keeping_border(&mut d, 20, 1.0, 6, 0), 9);
        assert!(d.get(5, 3).is_nan());
        assert_eq!((d.get(0, 2), d.get(1, 4), d.get(7, 9)), (20.0, 20.0, 20.0));
        // From 7 pixels the 6-pixel island at the left border goes too.
        let mut d = map();
        assert_eq!(remove_speckles_keeping_border(&mut d, 20, 1.0, 7, 0), 6 + 9);
        assert!(d.get(0, 2).is_nan() && d.get(7, 9) == 20.0);
        // 0 keeps none: the same as remove_speckles.
        let mut d = map();
        assert_eq!(remove_speckles_keeping_border(&mut d, 20, 1.0, 0, 0), 6 + 9 + 9);
    }

    #[test]
    fn holes_up_to_the_bridge_do_not_split_a_region() {
        // A 14x6 map at 5 px with a bar at 20 px (columns 1..13 of rows 2..4) cut by invalid
        // columns, a 2-wide hole at x = 4..6 and a 3-wide one at x = 8..11, into pieces of 6, 4
        // and 4 pixels.
        let map = || {
            let mut d = DisparityMap::new(14, 6, 5.0);
            for y in 2..4 {
                for x in 1..13 {
                    d.set(x, y, if (4..6).contains(&x) || (8..11).contains(&x) { f32::NAN } else { 20.0 });
                }
            }
            d
        };
        // 4-connected (bridge 0): each piece is a region under 8 pixels and goes.
        let mut d = map();
        assert_eq!(remove_speckles_keeping_border(&mut d, 8, 1.0, 0, 0), 14);
        // Bridging 2 px joins the first two pieces (10 pixels: they stay), not the third.
        let mut d = map();
        assert_eq!(remove_speckles_keeping_border(&mut d, 8, 1.0, 0, 2), 4);
        assert_eq!((d.get(1, 2), d.get(7, 3)), (20.0, 20.0));
        assert!(d.get(11, 2).is_nan());
        let mut d = map();
        assert_eq!(remove_speckles_keeping_border(&mut d, 11, 1.0, 0, 2), 14);
        // Bridging 3 px joins all three: 14 pixels. The background (15 px away) joins none.
        let mut d = map();
        assert_eq!(remove_speckles_keeping_border(&mut d, 14, 1.0, 0, 3), 0);
        assert_eq!(remove_speckles_keeping_border(&mut d, 15, 1.0, 0, 3), 14);
        assert_eq!((d.get(0, 2), d.get(13, 3)), (5.0, 5.0));
    }

    #[test]
    fn pixels_removed_by_the_filter_are_not_bridged() {
        // Row 0: a 2-px piece at 9 px, a 1-px island at 30 px (removed), a 2-px piece at 9 px.
        // The island was valid when the filter started, so its hole does not join the pieces.
        let mut d = DisparityMap::from_fn(5, 1, |x, _| if x == 2 { 30.0 } else { 9.0 });
        assert_eq!(remove_speckles_keeping_border(&mut d, 3, 1.0, 0, 3), 5);
        // The same pieces around an invalid pixel are one region of 4.
        let mut d = DisparityMap::from_fn(5, 1, |x, _| if x == 2 { f32::NAN } else { 9.0 });
        assert_eq!(remove_speckles_keeping_border(&mut d, 3, 1.0, 0, 3), 0);
    }

    #[test]
    fn chains_of_small_steps_are_one_region() {
        // A ramp rising 0.5 px per column: one region although the ends differ by 4.5 px.
        let mut d = DisparityMap::from_fn(10, 1, |x, _| x as f32 * 0.5);
        assert_eq!(remove_speckles(&mut d, 10, 1.0), 0);
        assert_eq!(remove_speckles(&mut d, 11, 1.0), 10);
        assert!(d.as_slice().iter().all(|v| v.is_nan()));
    }
}
