//! Far islands: small regions of a disparity map that lie more than twice as far as the scene
//! around them (the "flying points" that survive the left-right check; docs/robustness.md).
//!
//! Near the left border (x below the largest disparity) the true match of a surface can leave the
//! right image; the pixel then takes an interior winner at a small disparity, and where the right
//! view is just as ambiguous (textureless, or the census window leaving the image) the left-right
//! check agrees with it. Such winners form small islands, a few pixels wide, far behind
//! everything around them. A real surface that far behind its surroundings would have to be
//! seen through a hole the size of the island; for islands smaller than
//! [`crate::DENSE_SPECKLE_SIZE`] pixels the matcher cannot tell one from a wrong match, so they are
//! rejected, whatever their position in the image.

use crate::speckle::flood_region;
use crate::status::{tagged_nan, PixelStatus};
use crate::{DisparityMap, DisparityRange};

/// Islands with fewer pixels than this are rejected when far behind their surroundings (the
/// speckle size of the dense preset: a region this small is not trusted there either).
const MAX_ISLAND: usize = crate::DENSE_SPECKLE_SIZE;

/// Neighbours belong to one island when their disparities differ by at most this (as speckles).
const MAX_STEP: f32 = 1.0;

/// The surroundings are summarised on a grid of square tiles this many pixels wide.
const TILE: usize = 16;

/// How far around a pixel its surroundings reach, in tiles, at least (4 tiles: a 144 × 144 px
/// window); at least the largest disparity too, so that an island inside the left band (where
/// little but such islands is valid) also sees the scene beyond it.
const MIN_REACH: usize = 4;

/// Rejects every island (4-connected region of valid pixels whose neighbours differ by at most
/// [`MAX_STEP`]) of fewer than [`MAX_ISLAND`] pixels all of whose disparities are below half the
/// median valid disparity of their surroundings (the window of tiles within [`MIN_REACH`] tiles, and
/// within the largest disparity, of each pixel's tile, which must hold at least [`MAX_ISLAND`] valid pixels): a depth more than twice
/// that of the scene around it. Rejected pixels become `invalid` (a tagged NaN in the SGM
/// pipeline, [`PixelStatus::FarIsland`]). Returns how many were rejected. O(W·H + tiles·D).
pub(crate) fn reject_far_islands(disparity: &mut DisparityMap, range: DisparityRange, invalid: f32) -> usize {
    let (w, h) = disparity.size();
    let bins = range.count();
    if w == 0 || h == 0 || bins == 0 {
        return 0;
    }
    let reference = surroundings(disparity, range);
    let tw = w.div_ceil(TILE);
    let d = disparity.as_mut_slice();
    let far = |p: usize, v: f32| {
        let r = reference[(p / w / TILE) * tw + (p % w) / TILE];
        r > 0.0 && v.is_finite() && 2.0 * v < r
    };

    let mut seen = vec![false; w * h];
    let mut stack: Vec<u32> = Vec::new();
    let mut island: Vec<u32> = Vec::new();
    let mut rejected = 0;
    for start in 0..w * h {
        if seen[start] || !far(start, d[start]) {
            continue;
        }
        // The whole region is visited (and marked) even when it turns out too large or not far
        // everywhere, so that no later start sees only a part of it.
        island.clear();
        let (mut size, mut all_far) = (0usize, true);
        flood_region(d, w, start, MAX_STEP, &mut seen, &mut stack, |p, v| {
            size += 1;
            all_far &= far(p, v);
            if all_far && size < MAX_ISLAND {
                island.push(p as u32);
            }
        });
        if all_far && size < MAX_ISLAND {
            for &p in &island {
                d[p as usize] = invalid;
            }
            rejected += island.len();
        }
    }
    rejected
}

/// [`reject_far_islands`] inside the SGM pipeline: the rejected pixels tagged
/// [`PixelStatus::FarIsland`].
pub(crate) fn reject_far_islands_tagged(disparity: &mut DisparityMap, range: DisparityRange) -> usize {
    reject_far_islands(disparity, range, tagged_nan(PixelStatus::FarIsland))
}

/// Per tile, the median valid disparity in the window of tiles within the reach ([`MIN_REACH`], or the largest disparity) of it (0 when
/// the window holds fewer than [`MAX_ISLAND`] valid pixels): per-tile histograms of the integer
/// disparity, summed over the window through a summed-area table, the median interpolated within
/// its bin.
fn surroundings(disparity: &DisparityMap, range: DisparityRange) -> Vec<f32> {
    let (w, h) = disparity.size();
    let bins = range.count();
    let (tw, th) = (w.div_ceil(TILE), h.div_ceil(TILE));
    // table[((ty * (tw + 1)) + tx) * bins + b]: pixels of bin b in tiles above-left of (tx, ty).
    let stride = (tw + 1) * bins;
    let mut table = vec![0u32; (th + 1) * stride];
    for (y, row) in disparity.as_slice().chunks_exact(w).enumerate() {
        let base = (y / TILE + 1) * stride;
        for (x, &v) in row.iter().enumerate() {
            if v.is_finite() {
                let b = ((v.floor() as i64 - range.min as i64).clamp(0, bins as i64 - 1)) as usize;
                table[base + (x / TILE + 1) * bins + b] += 1;
            }
        }
    }
    for ty in 1..=th {
        for tx in 1..=tw {
            let (cur, up) = (ty * stride + tx * bins, (ty - 1) * stride + tx * bins);
            for b in 0..bins {
                table[cur + b] += table[cur - bins + b] + table[up + b] - table[up - bins + b];
            }
        }
    }
    let reach = MIN_REACH.max((range.max.max(0) as usize).div_ceil(TILE));
    let mut hist = vec![0u32; bins];
    let mut out = vec![0.0f32; tw * th];
    for ty in 0..th {
        let (y0, y1) = (ty.saturating_sub(reach), (ty + reach + 1).min(th));
        for tx in 0..tw {
            let (x0, x1) = (tx.saturating_sub(reach), (tx + reach + 1).min(tw));
            let at = |y: usize, x: usize| y * stride + x * bins;
            let (a, b, c, e) = (at(y1, x1), at(y0, x1), at(y1, x0), at(y0, x0));
            let mut total = 0u64;
            for (i, hb) in hist.iter_mut().enumerate() {
                *hb = table[a + i] + table[e + i] - table[b + i] - table[c + i];
                total += u64::from(*hb);
            }
            if total < MAX_ISLAND as u64 {
                continue;
            }
            let half = total as f32 / 2.0;
            let mut below = 0.0f32;
            for (i, &hb) in hist.iter().enumerate() {
                let n = hb as f32;
                if below + n >= half {
                    out[ty * tw + tx] = range.min as f32 + i as f32 + (half - below) / n;
                    break;
                }
                below += n;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn range(max: i32) -> DisparityRange {
        DisparityRange { min: 0, max }
    }

    #[test]
    fn a_small_far_island_goes_a_near_one_and_a_large_far_region_stay() {
        // A 96x64 scene at 20 px with a 3x4 island at 4 px (far: rejected), a 3x4 island at 12 px
        // (nearer than half: kept) and a 40x20 region at 4 px (too large to be a wrong match).
        let mut d = DisparityMap::new(96, 64, 20.0);
        for y in 10..14 {
            for x in 2..5 {
                d.set(x, y, 4.0);
                d.set(x + 40, y, 12.0);
            }
        }
        for y in 40..60 {
            for x in 50..90 {
                d.set(x, y, 4.0);
            }
        }
        let mut tagged = d.clone();
        assert_eq!(reject_far_islands(&mut d, range(32), f32::NAN), 12);
        assert!((10..14).all(|y| (2..5).all(|x| d.get(x, y).is_nan())));
        assert_eq!((d.get(42, 11), d.get(60, 50), d.get(1, 11)), (12.0, 4.0, 20.0));
        assert_eq!(reject_far_islands_tagged(&mut tagged, range(32)), 12);
        assert_eq!(crate::status::status_of(tagged.get(3, 12)), PixelStatus::FarIsland);
    }

    #[test]
    fn an_island_joined_to_its_surroundings_by_small_steps_stays() {
        // A ramp from the 20 px scene down to 4 px: one region, not an island.
        let mut d = DisparityMap::new(64, 64, 20.0);
        for y in 20..24 {
            for x in 0..17 {
                d.set(x, y, 4.0 + x as f32);
            }
        }
        assert_eq!(reject_far_islands(&mut d, range(32), f32::NAN), 0);
    }

    #[test]
    fn a_scene_of_far_islands_keeps_them() {
        // Islands at 2 px on a sparse map: too few valid pixels around to judge by.
        let mut d = DisparityMap::new(64, 64, f32::NAN);
        for (x, y) in [(3, 3), (30, 30), (50, 10)] {
            d.set(x, y, 2.0);
        }
        assert_eq!(reject_far_islands(&mut d, range(16), f32::NAN), 0);
        // An island less than twice as far as a far scene stays: 1.5 px on a scene at 2.6 px.
        let mut e = DisparityMap::new(64, 64, 2.6);
        e.set(10, 10, 1.5);
        assert_eq!(reject_far_islands(&mut e, range(16), f32::NAN), 0);
        e.set(10, 10, 1.0);
        assert_eq!(reject_far_islands(&mut e, range(16), f32::NAN), 1);
    }
}
