//! Far islands: small regions of a disparity map that lie (mostly) more than twice as far as the
//! scene around them (the "flying points" that survive the left-right check; docs/robustness.md).
//!
//! Near the left border (x below the largest disparity) the true match of a surface can leave the
//! right image; the pixel then takes an interior winner at a small disparity, and where the right
//! view is just as ambiguous (textureless, or the census window leaving the image) the left-right
//! check agrees with it. Such winners form small islands, a few pixels wide, far behind
//! everything around them. A real surface that far behind its surroundings would have to be
//! seen through a hole the size of the island; for islands smaller than
//! [`crate::DENSE_SPECKLE_SIZE`] pixels the matcher cannot tell one from a wrong match, so they are
//! rejected, whatever their position in the image.
//!
//! On a noisy pair such winners can fill whole stretches of the left band, so that they are the
//! scene the band's own pixels see. A second pass therefore judges the band against the pixels
//! outside it (whose search was complete) and takes larger islands there.

use rayon::prelude::*;

use crate::status::{tagged_nan, PixelStatus};
use crate::{DisparityMap, DisparityRange};

/// Islands with fewer pixels than this are rejected when far behind their surroundings (the
/// speckle size of the dense preset: a region this small is not trusted there either).
const MAX_ISLAND: usize = crate::DENSE_SPECKLE_SIZE;

/// Neighbours belong to one island when their disparities differ by at most this (as speckles)...
const MAX_STEP: f32 = 1.0;

/// ... and by at most this share of the smaller one: one lies at most 25 % farther than the other.
/// Far from the camera a step of 1 px is a jump in depth (from 2 px to 3 px, half the distance),
/// and a constant step let a far island join the scene through a single pixel in between.
const MAX_RELATIVE_STEP: f32 = 0.25;

/// Whether neighbouring disparities `a` and `b` belong to one island.
#[inline(always)]
fn joined(a: f32, b: f32) -> bool {
    (a - b).abs() <= MAX_STEP.min(MAX_RELATIVE_STEP * a.min(b))
}

/// The surroundings are summarised on a grid of square tiles this many pixels wide.
const TILE: usize = 16;

/// How far around a pixel its surroundings reach, in tiles, at least (4 tiles: a 144 × 144 px
/// window); at least the largest disparity too, so that an island inside the left band (where
/// little but such islands is valid) also sees the scene beyond it.
const MIN_REACH: usize = 4;

/// In the left band (x below the largest disparity) islands are judged again against the pixels
/// outside it, up to this share of the band's area (at least [`MAX_ISLAND`] pixels).
const BAND_ISLAND_SHARE: usize = 40;

/// Rejects every island (4-connected region of valid pixels whose neighbours are [`joined`]) of
/// fewer than [`MAX_ISLAND`] pixels at least half of whose disparities are below half the
/// median valid disparity of their surroundings (the window of tiles within [`MIN_REACH`] tiles,
/// and within the largest disparity, of each pixel's tile, which must hold at least
/// [`MAX_ISLAND`] valid pixels): a depth more than twice that of the scene around it.
///
/// Then the same in the left band, where the true match of a surface can leave the right image
/// and a noisy pair fills the band with wrong winners: there the surroundings count only the
/// pixels outside the band (whose search was complete), and an island may hold up to
/// 1/[`BAND_ISLAND_SHARE`] of the band's pixels; only its pixels inside the band count as
/// behind.
///
/// Rejected pixels become `invalid` (a tagged NaN in the SGM pipeline,
/// [`PixelStatus::FarIsland`]). Returns how many were rejected. O(W·H + tiles·D).
pub(crate) fn reject_far_islands(disparity: &mut DisparityMap, range: DisparityRange, invalid: f32) -> usize {
    let (w, h) = disparity.size();
    if w == 0 || h == 0 || range.count() == 0 {
        return 0;
    }
    let band = (range.max.max(0) as usize).min(w);
    let judges_band = band > 0 && band < w;
    // The histograms are counted once: the second pass's (the columns outside the band, after
    // the first pass) are the first's less the band's columns and less what the first rejected.
    let counts = TileCounts::new(disparity, range);
    let band_counts = judges_band.then(|| TileCounts::of_columns(disparity, range, band));
    let scene = Behind { reference: &counts.surroundings(), tiles_wide: w.div_ceil(TILE), columns: w };
    let mut removed = Vec::new();
    let mut rejected = reject_islands(disparity, &scene, MAX_ISLAND, invalid, &mut removed);
    if let Some(band_counts) = band_counts {
        let mut outside_counts = counts;
        outside_counts.subtract(&band_counts);
        for &(p, v) in &removed {
            let p = p as usize;
            if p % w >= band {
                outside_counts.remove(p % w, p / w, v);
            }
        }
        let reference = outside_counts.surroundings();
        let outside = Behind { reference: &reference, tiles_wide: w.div_ceil(TILE), columns: band };
        let max_island = (band * h / BAND_ISLAND_SHARE).max(MAX_ISLAND);
        rejected += reject_islands(disparity, &outside, max_island, invalid, &mut removed);
    }
    rejected
}

/// Which pixels lie behind their surroundings: the median disparity per tile, and the columns
/// (`0..columns`) that are judged at all.
struct Behind<'r> {
    reference: &'r [f32],
    tiles_wide: usize,
    columns: usize,
}

impl Behind<'_> {
    #[inline(always)]
    fn at(&self, x: usize, y: usize, v: f32) -> bool {
        x < self.columns && far_behind(self.reference[(y / TILE) * self.tiles_wide + x / TILE], v)
    }
}

/// Rejects every island of fewer than `max_island` pixels at least half of which lie `behind`.
fn reject_islands(
    disparity: &mut DisparityMap,
    behind: &Behind<'_>,
    max_island: usize,
    invalid: f32,
    removed: &mut Vec<(u32, f32)>,
) -> usize {
    let (w, h) = disparity.size();
    let d = disparity.as_mut_slice();
    let far = |p: usize, v: f32| behind.at(p % w, p / w, v);

    // Per pixel: not visited, visited by the current search, or known to lie in a region that is
    // not an island (too large, or not far enough). A search stops at the first sign that its
    // region is too large (its size, or a pixel known to lie in a region that is not an island)
    // and marks what it visited; a later search that touches such a pixel (joined, so the same
    // region) stops too. An island is always visited whole, by the first search that enters it,
    // so every region gets the verdict a full visit would give, in O(W·H) time overall.
    const UNSEEN: u8 = 0;
    const VISITED: u8 = 1;
    const NOT_ISLAND: u8 = 2;
    let mut state = vec![UNSEEN; w * h];
    let mut stack: Vec<u32> = Vec::new();
    let mut island: Vec<u32> = Vec::new();
    let mut rejected = 0;
    // The pixels that could start an island, found in parallel (row by row), in the order the
    // searches take them. Rejection only turns pixels invalid, which makes no new start.
    // A tile's stretch of a row is tested at once (vectorised) and searched only if it holds one.
    let starts: Vec<u32> = d
        .par_chunks_exact(w)
        .enumerate()
        .flat_map_iter(|(y, row)| {
            let references = &behind.reference[(y / TILE) * behind.tiles_wide..];
            row[..behind.columns].chunks(TILE).zip(references).enumerate().flat_map(
                move |(t, (stretch, &r))| {
                    let any = stretch.iter().fold(false, |any, &v| any | far_behind(r, v));
                    let x0 = t * TILE;
                    // A stretch without a start yields nothing without visiting its pixels.
                    let stretch = if any { stretch } else { &stretch[..0] };
                    stretch
                        .iter()
                        .enumerate()
                        .filter_map(move |(j, &v)| far_behind(r, v).then_some((y * w + x0 + j) as u32))
                },
            )
        })
        .collect();
    for start in starts {
        let start = start as usize;
        if state[start] != UNSEEN {
            continue;
        }
        island.clear();
        stack.clear();
        state[start] = VISITED;
        stack.push(start as u32);
        let mut is_island = true;
        let mut far_pixels = 0;
        'search: while let Some(p) = stack.pop() {
            let p = p as usize;
            let v = d[p];
            island.push(p as u32);
            if island.len() >= max_island {
                is_island = false;
                break;
            }
            far_pixels += usize::from(far(p, v));
            let (px, py) = (p % w, p / w);
            let neighbours = [
                (px > 0).then(|| p - 1),
                (px + 1 < w).then(|| p + 1),
                (py > 0).then(|| p - w),
                (py + 1 < h).then(|| p + w),
            ];
            for q in neighbours.into_iter().flatten() {
                if d[q].is_nan() || !joined(v, d[q]) {
                    continue;
                }
                match state[q] {
                    UNSEEN => {
                        state[q] = VISITED;
                        stack.push(q as u32);
                    }
                    NOT_ISLAND => {
                        is_island = false;
                        break 'search;
                    }
                    _ => {}
                }
            }
        }
        if is_island && 2 * far_pixels >= island.len() {
            for &p in &island {
                removed.push((p, d[p as usize]));
                d[p as usize] = invalid;
            }
            rejected += island.len();
        } else {
            for &p in island.iter().chain(&stack) {
                state[p as usize] = NOT_ISLAND;
            }
        }
    }
    rejected
}

/// Whether disparity `v` lies more than twice as far as the surroundings' median disparity `r`
/// (0: surroundings unknown). Without branches, so that the island starts' test over a stretch
/// of a row is vectorised (`v.abs() < ∞` is `v.is_finite()`).
#[inline(always)]
fn far_behind(r: f32, v: f32) -> bool {
    (r > 0.0) & (v.abs() < f32::INFINITY) & (2.0 * v < r)
}

/// `v.floor() as i64` for a finite `v` within `i64`, without the library call that `f32::floor`
/// becomes on baseline x86-64 (no SSE4.1 rounding): once per pixel.
#[inline(always)]
fn floor(v: f32) -> i64 {
    let t = v as i64;
    t - i64::from((t as f32) > v)
}

/// The histogram bin of the finite disparity `v`: its integer part's place in the range,
/// clamped into it.
#[inline(always)]
fn bin(v: f32, range: DisparityRange) -> usize {
    (floor(v) - range.min as i64).clamp(0, range.count() as i64 - 1) as usize
}

/// [`reject_far_islands`] inside the SGM pipeline: the rejected pixels tagged
/// [`PixelStatus::FarIsland`].
pub(crate) fn reject_far_islands_tagged(disparity: &mut DisparityMap, range: DisparityRange) -> usize {
    reject_far_islands(disparity, range, tagged_nan(PixelStatus::FarIsland))
}

/// Per tile of [`TILE`] × [`TILE`] pixels, how many valid pixels hold each integer disparity of
/// the range (clamped into it), laid out for [`TileCounts::surroundings`]'s summed-area table:
/// `counts[((ty + 1) * (tw + 1) + tx + 1) * bins + b]`, a zero row and column before the tiles.
struct TileCounts {
    counts: Vec<u32>,
    range: DisparityRange,
    tiles: (usize, usize),
}

impl TileCounts {
    /// The counts of every pixel.
    fn new(disparity: &DisparityMap, range: DisparityRange) -> Self {
        Self::of_columns(disparity, range, disparity.width())
    }

    /// The counts of the pixels in columns `0..columns`.
    fn of_columns(disparity: &DisparityMap, range: DisparityRange, columns: usize) -> Self {
        let (w, h) = disparity.size();
        let bins = range.count();
        let (tw, th) = (w.div_ceil(TILE), h.div_ceil(TILE));
        let stride = (tw + 1) * bins;
        let mut counts = vec![0u32; (th + 1) * stride];
        // Each row of tiles counts into its own row of the table.
        counts[stride..].par_chunks_mut(stride).zip(disparity.as_slice().par_chunks(TILE * w)).for_each(
            |(counts, pixels)| {
                for row in pixels.chunks_exact(w) {
                    for (x, &v) in row[..columns].iter().enumerate() {
                        if v.is_finite() {
                            counts[(x / TILE + 1) * bins + bin(v, range)] += 1;
                        }
                    }
                }
            },
        );
        TileCounts { counts, range, tiles: (tw, th) }
    }

    /// Removes the pixels `other` counted (a subset of these).
    fn subtract(&mut self, other: &TileCounts) {
        for (a, b) in self.counts.iter_mut().zip(&other.counts) {
            *a -= b;
        }
    }

    /// Removes the valid pixel `(x, y)` of disparity `v`.
    fn remove(&mut self, x: usize, y: usize, v: f32) {
        let at = ((y / TILE + 1) * (self.tiles.0 + 1) + x / TILE + 1) * self.range.count();
        self.counts[at + bin(v, self.range)] -= 1;
    }

    /// Per tile, the median valid disparity of the counted pixels in the window of tiles within
    /// the reach ([`MIN_REACH`], or the largest disparity) of it (0 when the window holds fewer
    /// than [`MAX_ISLAND`] of them): the tiles' histograms summed over the window through a
    /// summed-area table, the median interpolated within its bin.
    fn surroundings(&self) -> Vec<f32> {
        let (range, (tw, th)) = (self.range, self.tiles);
        let bins = range.count();
        // table[((ty * (tw + 1)) + tx) * bins + b]: pixels of bin b in tiles above-left of (tx, ty).
        let stride = (tw + 1) * bins;
        let mut table = self.counts.clone();
        // The sums over the tiles above and to the left, a row of tiles at a time (separate slices
        // for the row above and this row, so the bins' loop is vectorised).
        for ty in 1..=th {
            let (above, rest) = table.split_at_mut(ty * stride);
            let (up, cur) = (&above[(ty - 1) * stride..], &mut rest[..stride]);
            for tx in 1..=tw {
                let (left, here) = cur.split_at_mut(tx * bins);
                let (left, here) = (&left[(tx - 1) * bins..], &mut here[..bins]);
                let (up_left, up) = (&up[(tx - 1) * bins..tx * bins], &up[tx * bins..(tx + 1) * bins]);
                for b in 0..bins {
                    here[b] += left[b] + up[b] - up_left[b];
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
                let at = |y: usize, x: usize| &table[y * stride + x * bins..y * stride + (x + 1) * bins];
                let (a, b, c, e) = (at(y1, x1), at(y0, x1), at(y1, x0), at(y0, x0));
                for (i, hb) in hist.iter_mut().enumerate() {
                    *hb = a[i] + e[i] - b[i] - c[i];
                }
                let total: u64 = hist.iter().map(|&n| u64::from(n)).sum();
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
}

/// The reference of [`TileCounts::surroundings`]: the medians of the pixels at `from_column` or
/// right of it, counted anew.
#[cfg(test)]
fn surroundings(disparity: &DisparityMap, range: DisparityRange, from_column: usize) -> Vec<f32> {
    let mut counts = TileCounts::new(disparity, range);
    counts.subtract(&TileCounts::of_columns(disparity, range, from_column));
    counts.surroundings()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn range(max: i32) -> DisparityRange {
        DisparityRange { min: 0, max }
    }

    /// The plain search, which visits every region whole: the reference of
    /// [`reject_far_islands`]'s stopping searches.
    fn reject_far_islands_reference(disparity: &mut DisparityMap, range: DisparityRange) -> usize {
        let (w, h) = disparity.size();
        let band = (range.max.max(0) as usize).min(w);
        let mut rejected = whole_visits(disparity, range, 0, w, MAX_ISLAND);
        if band > 0 && band < w {
            let max_island = (band * h / BAND_ISLAND_SHARE).max(MAX_ISLAND);
            rejected += whole_visits(disparity, range, band, band, max_island);
        }
        rejected
    }

    /// One pass of the reference: judged against the pixels from `from_column` on, pixels in
    /// `0..columns` can lie behind.
    fn whole_visits(
        disparity: &mut DisparityMap,
        range: DisparityRange,
        from_column: usize,
        columns: usize,
        max_island: usize,
    ) -> usize {
        let (w, h) = disparity.size();
        let reference = surroundings(disparity, range, from_column);
        let tw = w.div_ceil(TILE);
        let d = disparity.as_mut_slice();
        let far = |p: usize, v: f32| {
            let r = reference[(p / w / TILE) * tw + (p % w) / TILE];
            p % w < columns && r > 0.0 && v.is_finite() && 2.0 * v < r
        };
        let mut seen = vec![false; w * h];
        let mut rejected = 0;
        for start in 0..w * h {
            if seen[start] || !far(start, d[start]) {
                continue;
            }
            // The whole region, breadth first.
            let mut region = vec![start];
            seen[start] = true;
            let mut next = 0;
            while next < region.len() {
                let p = region[next];
                next += 1;
                let (px, py) = (p % w, p / w);
                let neighbours = [
                    (px > 0, p.wrapping_sub(1)),
                    (px + 1 < w, p + 1),
                    (py > 0, p.wrapping_sub(w)),
                    (py + 1 < h, p + w),
                ];
                for (inside, q) in neighbours {
                    if inside && !seen[q] && !d[q].is_nan() && joined(d[p], d[q]) {
                        seen[q] = true;
                        region.push(q);
                    }
                }
            }
            let far_pixels = region.iter().filter(|&&p| far(p, d[p])).count();
            if region.len() < max_island && 2 * far_pixels >= region.len() {
                for &p in &region {
                    d[p] = f32::NAN;
                }
                rejected += region.len();
            }
        }
        rejected
    }

    #[test]
    fn a_large_far_region_in_the_left_band_goes_when_the_scene_beyond_is_near() {
        // 160x400, disparities below 64: band islands up to 64 * 400 / 40 = 640 pixels. A 30x20
        // region at 3 px (600 pixels, too large for the first pass) inside the band goes when the
        // scene is at 40 px, stays when the scene is at 5 px (not twice as far), and a 30x30 one
        // (900 pixels) stays.
        let region = |scene: f32, rows: usize| {
            let mut d = DisparityMap::new(160, 400, scene);
            for y in 100..100 + rows {
                for x in 10..40 {
                    d.set(x, y, 3.0);
                }
            }
            d
        };
        let mut near = region(40.0, 20);
        assert_eq!(reject_far_islands(&mut near, range(64), f32::NAN), 600);
        let mut far_scene = region(5.0, 20);
        assert_eq!(reject_far_islands(&mut far_scene, range(64), f32::NAN), 0);
        let mut large = region(40.0, 30);
        assert_eq!(reject_far_islands(&mut large, range(64), f32::NAN), 0);
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

        /// Random maps of plateaus, ramps, holes and far patches of every size: the stopping
        /// searches reject exactly what visiting every region whole rejects.
        #[test]
        fn stopping_searches_match_whole_visits(w in 8usize..120, h in 8usize..90, seed in proptest::prelude::any::<u64>()) {
            let mut s = seed | 1;
            let mut next = move || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s };
            let mut map = DisparityMap::new(w, h, 30.0);
            for _ in 0..(w * h / 40).max(3) {
                let (x0, y0) = ((next() % w as u64) as usize, (next() % h as u64) as usize);
                let (rw, rh) = (1 + (next() % 30) as usize, 1 + (next() % 30) as usize);
                let kind = next() % 5;
                let base = (next() % 40) as f32;
                for y in y0..(y0 + rh).min(h) {
                    for x in x0..(x0 + rw).min(w) {
                        let v = map.get(x, y);
                        map.row_mut(y)[x] = match kind {
                            0 => f32::NAN,
                            1 => base,
                            2 => base * 0.25,
                            3 => v + 0.5 * (x as f32 - x0 as f32),
                            _ => 2.0 + 0.4 * ((x + y) % 3) as f32,
                        };
                    }
                }
            }
            let r = range(48);
            let (mut fast, mut slow) = (map.clone(), map);
            let a = reject_far_islands(&mut fast, r, f32::NAN);
            let b = reject_far_islands_reference(&mut slow, r);
            proptest::prop_assert_eq!(a, b);
            for (x, y) in fast.as_slice().iter().zip(slow.as_slice()) {
                proptest::prop_assert!(x.to_bits() == y.to_bits() || (x.is_nan() && y.is_nan()));
            }
        }
    }

    #[test]
    fn floor_is_f32_floor() {
        for v in [-3.5f32, -3.0, -0.25, -0.0, 0.0, 0.25, 1.0, 1.999, 2.5, 255.75, -1e-7, 1e-7] {
            assert_eq!(floor(v), v.floor() as i64, "{v}");
        }
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
    fn a_far_island_joined_to_the_scene_only_by_a_jump_in_depth_goes() {
        // A scene at 5 px with a 6x6 island at 2 px whose edge pixel at 3 px touches one at 4 px,
        // which touches the scene: 1 px steps, but each a jump of a third or more in depth, so
        // the island is alone. The 3 and 4 px pixels are not twice as far as the scene: they stay.
        let mut d = DisparityMap::new(64, 64, 5.0);
        for y in 20..26 {
            for x in 20..26 {
                d.set(x, y, 2.0);
            }
        }
        d.set(26, 22, 3.0);
        d.set(27, 22, 4.0);
        assert_eq!(reject_far_islands(&mut d, range(16), f32::NAN), 36);
        assert!(d.get(22, 22).is_nan());
        assert_eq!((d.get(26, 22), d.get(27, 22)), (3.0, 4.0));
    }

    #[test]
    fn an_island_mostly_far_goes_whole_and_one_mostly_near_stays() {
        // Scene at 4.6 px (behind: below 2.3 px). Island A: 12 pixels at 2.0 and 4 at 2.4
        // (joined, a step of 20 % in depth): 12 of 16 behind, rejected whole. Island B: 4 at
        // 2.0 and 12 at 2.4: a quarter behind, kept.
        let mut d = DisparityMap::new(80, 64, 4.6);
        for y in 10..14 {
            for x in 10..14 {
                d.set(x, y, if x == 13 { 2.4 } else { 2.0 });
                d.set(x + 40, y, if x == 13 { 2.0 } else { 2.4 });
            }
        }
        assert_eq!(reject_far_islands(&mut d, range(16), f32::NAN), 16);
        assert!((10..14).all(|y| (10..14).all(|x| d.get(x, y).is_nan())));
        assert!((10..14).all(|y| (50..54).all(|x| !d.get(x, y).is_nan())));
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
