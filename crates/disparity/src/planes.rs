//! Dense output: the holes of an image segment filled from the disparity plane its matched
//! pixels lie on.
//!
//! A surface of one colour is usually one plane in disparity space, and the pixels it loses to
//! occlusion or to the checks lie on that plane too. The left view is cut into segments of
//! similar grey (Felzenszwalb and Huttenlocher's graph segmentation, 2004); where most of a
//! segment's matched pixels lie within 1 px of one plane (found by RANSAC, then refitted by
//! least squares), its holes take the plane's disparity. Segments with too few matched pixels
//! or no dominant plane are left to [`crate::fill::fill_invalid`].

use rayon::prelude::*;

use crate::radiometric::{downsample_by, gaussian_blur};
use crate::status::PixelStatus;
use crate::{DisparityMap, DisparityRange, GrayImage, Image};

/// Felzenszwalb's scale `k` (8-bit grey levels × pixels): larger gives larger segments.
const SEGMENT_SCALE: f32 = 400.0;
/// Segments smaller than this (pixels) are merged into their most similar neighbour.
const SEGMENT_MIN_SIZE: usize = 50;
/// Larger views are segmented halved (2×2 means, as often as needed to fit), with the scale
/// and the smallest size reduced alike: the merges are serial (about 0.1 µs per pixel, stop 42), and
/// halving the three largest Middlebury scenes (0.35–0.37 megapixels) cost no accuracy
/// (docs/accuracy.md).
const SEGMENT_MAX_PIXELS: usize = 1 << 18;
/// The smoothing of the left view before segmentation (σ, px).
const SEGMENT_SIGMA: f32 = 0.8;
/// A segment's plane is fitted only if at least this share of its pixels matched.
const MIN_MATCHED_SHARE: f32 = 0.2;
/// ... and at least this many.
const MIN_MATCHED: usize = 6;
/// A matched pixel within this many px of a plane supports it.
const INLIER_DISTANCE: f64 = 1.0;
/// The plane must be supported by at least this share of the segment's matched pixels.
const MIN_INLIER_SHARE: f64 = 0.5;
/// How far (px) a plane may carry a hole's disparity beyond the disparities supporting it.
const EXTRAPOLATION: f32 = 1.0;
/// RANSAC draws of three matched pixels per segment.
const DRAWS: usize = 60;
/// RANSAC counts support on at most about this many of a segment's matched pixels.
const SUPPORT_SAMPLE: usize = 256;

/// Fills the NaN pixels of `disparity` that lie in a segment of `left` whose matched pixels
/// lie on one plane with that plane's disparity (clamped to `range`). Returns how many.
/// `area_reduction`: each pixel of `left` stands for this many of the input view's (a pair reduced
/// before matching).
pub(crate) fn fill_from_segment_planes(
    disparity: &mut DisparityMap,
    status: &Image<u8>,
    left: &GrayImage,
    range: DisparityRange,
    area_reduction: usize,
) -> usize {
    let (w, h) = disparity.size();
    if w < 2 || h < 2 {
        return 0;
    }
    let labels = segment_reduced(left, area_reduction);
    let segments = labels.iter().copied().max().map_or(0, |m| m as usize + 1);
    // Each segment's pixels, in raster order (a counting sort of the labels).
    let mut start = vec![0usize; segments + 1];
    for &l in &labels {
        start[l as usize + 1] += 1;
    }
    for s in 0..segments {
        start[s + 1] += start[s];
    }
    let mut next = start.clone();
    let mut pixels = vec![0u32; w * h];
    for (i, &l) in labels.iter().enumerate() {
        pixels[next[l as usize]] = i as u32;
        next[l as usize] += 1;
    }
    let d = disparity.as_slice();
    let planes: Vec<Option<([f64; 3], f32, f32)>> = (0..segments)
        .into_par_iter()
        .map(|s| fit_plane(&pixels[start[s]..start[s + 1]], d, w, s as u64))
        .collect();
    let (lo, hi) = (range.min as f32, (range.max - 1) as f32);
    let background = row_background(disparity);
    let occluded = |i: usize| PixelStatus::from_code(status.as_slice()[i]) == PixelStatus::Occluded;
    let out = disparity.as_mut_slice();
    let mut count = 0;
    for (i, &l) in labels.iter().enumerate() {
        if out[i].is_nan() {
            if let Some(([a, b, c], seg_lo, seg_hi)) = planes[l as usize] {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                // Within the range and within EXTRAPOLATION of the disparities that support
                // the plane: a slant fitted to a small patch must not run far beyond it.
                let mut v = ((a * x + b * y + c) as f32)
                    .clamp(seg_lo - EXTRAPOLATION, seg_hi + EXTRAPOLATION)
                    .clamp(lo, hi);
                // An occlusion lies behind its neighbours: a segment spanning the foreground
                // too would put it in front.
                if occluded(i) && !background[i].is_nan() {
                    v = v.min(background[i]);
                }
                out[i] = v;
                count += 1;
            }
        }
    }
    count
}

/// Per pixel, the lower of the nearest matched disparities at or left of it and at or right of
/// it on its row (NaN unless both exist): what an occlusion must not lie in front of.
fn row_background(disparity: &DisparityMap) -> Vec<f32> {
    let (w, _) = disparity.size();
    let mut out = vec![f32::NAN; disparity.as_slice().len()];
    out.par_chunks_mut(w).zip(disparity.as_slice().par_chunks(w)).for_each(|(out, row)| {
        let mut carry = f32::NAN;
        for (o, &d) in out.iter_mut().zip(row) {
            carry = if d.is_nan() { carry } else { d };
            *o = carry;
        }
        carry = f32::NAN;
        for (o, &d) in out.iter_mut().zip(row).rev() {
            carry = if d.is_nan() { carry } else { d };
            // A hole with no match on one side (the left band) has no background to compare.
            *o = if o.is_nan() || carry.is_nan() { f32::NAN } else { o.min(carry) };
        }
    });
    out
}

/// [`segment`] of `left` (whose pixels each stand for `area_reduction` of the input view's), halved
/// first while it exceeds [`SEGMENT_MAX_PIXELS`]: each pixel's label is its halved pixel's.
fn segment_reduced(left: &GrayImage, area_reduction: usize) -> Vec<u32> {
    let (w, h) = left.size();
    let fits = |image: &GrayImage| {
        image.width() * image.height() <= SEGMENT_MAX_PIXELS || image.width() < 4 || image.height() < 4
    };
    // The scale and the smallest size are meant for the input view's pixels: a segmented pixel
    // that stands for `area` of them needs the scale divided by √area and the size by area
    // (measured on the Middlebury scenes halved, docs/accuracy.md).
    let parameters = |area: usize| (SEGMENT_SCALE / (area as f32).sqrt(), (SEGMENT_MIN_SIZE / area).max(1));
    if fits(left) {
        let (scale, min_size) = parameters(area_reduction);
        return segment(left, scale, min_size);
    }
    let halve = |image: &GrayImage| downsample_by(image, 2, 2);
    let (mut image, mut level) = (halve(left), 1u32);
    while !fits(&image) {
        image = halve(&image);
        level += 1;
    }
    let (scale, min_size) = parameters(area_reduction << (2 * level));
    let (rw, rh) = image.size();
    let reduced = segment(&image, scale, min_size);
    (0..w * h)
        .map(|i| reduced[((i / w) >> level).min(rh - 1) * rw + ((i % w) >> level).min(rw - 1)])
        .collect()
}

/// The plane `d = a·x + b·y + c` most of the segment's matched pixels lie on, if any.
fn fit_plane(pixels: &[u32], d: &[f32], w: usize, seed: u64) -> Option<([f64; 3], f32, f32)> {
    let matched: Vec<(f64, f64, f64)> = pixels
        .iter()
        .filter(|&&i| !d[i as usize].is_nan())
        .map(|&i| ((i as usize % w) as f64, (i as usize / w) as f64, f64::from(d[i as usize])))
        .collect();
    let n = matched.len();
    if n < MIN_MATCHED || (n as f32) < MIN_MATCHED_SHARE * pixels.len() as f32 {
        return None;
    }
    let sample: Vec<(f64, f64, f64)> = matched.iter().step_by(n.div_ceil(SUPPORT_SAMPLE)).copied().collect();
    let support = |p: &[f64; 3]| {
        sample.iter().filter(|&&(x, y, d)| (p[0] * x + p[1] * y + p[2] - d).abs() < INLIER_DISTANCE).count()
    };
    // A fronto-parallel plane at the median first: it wins ties.
    let mut sorted: Vec<f64> = sample.iter().map(|s| s.2).collect();
    sorted.sort_by(f64::total_cmp);
    let mut best = [0.0, 0.0, sorted[sorted.len() / 2]];
    let mut best_support = support(&best);
    let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut draw = || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % n as u64) as usize
    };
    for _ in 0..DRAWS {
        let (p, q, r) = (matched[draw()], matched[draw()], matched[draw()]);
        if let Some(plane) = solve3([[p.0, p.1, 1.0], [q.0, q.1, 1.0], [r.0, r.1, 1.0]], [p.2, q.2, r.2]) {
            let s = support(&plane);
            if s > best_support {
                best = plane;
                best_support = s;
            }
        }
    }
    if (best_support as f64) < MIN_INLIER_SHARE * sample.len() as f64 {
        return None;
    }
    // Least squares over every matched pixel that supports the best plane.
    let (mut m, mut v) = ([[0.0f64; 3]; 3], [0.0f64; 3]);
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for &(x, y, d) in &matched {
        if (best[0] * x + best[1] * y + best[2] - d).abs() < INLIER_DISTANCE {
            lo = lo.min(d);
            hi = hi.max(d);
            let row = [x, y, 1.0];
            for j in 0..3 {
                for k in 0..3 {
                    m[j][k] += row[j] * row[k];
                }
                v[j] += row[j] * d;
            }
        }
    }
    Some((solve3(m, v).unwrap_or(best), lo as f32, hi as f32))
}

/// Solves `m · p = v` by Cramer's rule; `None` when `m` is (nearly) singular.
fn solve3(m: [[f64; 3]; 3], v: [f64; 3]) -> Option<[f64; 3]> {
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let scale = m.iter().flatten().fold(0.0f64, |a, b| a.max(b.abs()));
    let d = det(&m);
    if scale == 0.0 || d.abs() <= 1e-9 * scale * scale * scale {
        return None;
    }
    let mut p = [0.0; 3];
    for (c, out) in p.iter_mut().enumerate() {
        let mut mc = m;
        for r in 0..3 {
            mc[r][c] = v[r];
        }
        *out = det(&mc) / d;
    }
    Some(p)
}

/// Felzenszwalb–Huttenlocher graph segmentation of `image` (smoothed by σ [`SEGMENT_SIGMA`],
/// 8-connected, edge weights the grey difference in 8-bit levels): a label per pixel, 0-based
/// and dense.
fn segment(image: &GrayImage, scale: f32, min_size: usize) -> Vec<u32> {
    let (w, h) = image.size();
    let smooth = gaussian_blur(image, SEGMENT_SIGMA);
    let g = smooth.as_slice();
    // Weights quantised to 1/16 grey level (rounded; 257 sixteen-bit steps per level) and the
    // edges sorted by a counting sort, as ids `4 * pixel + direction`, without storing them
    // unsorted: their weights are computed twice. Each band of rows is sorted on its own, in
    // parallel; visiting every level band by band is the stable sort of all edges (ties in
    // raster order), so the result does not depend on threads. Memory matters: fresh pages cost
    // more than the arithmetic here.
    let offsets = edge_offsets(w);
    let levels = 255 * EDGE_STEPS as usize + 2;
    let bands: Vec<(Vec<u32>, Vec<u32>)> = (0..SEGMENT_BANDS)
        .into_par_iter()
        .map(|band| {
            let rows = band * h / SEGMENT_BANDS..(band + 1) * h / SEGMENT_BANDS;
            let mut start = vec![0u32; levels + 1];
            for_each_edge(g, w, h, rows.clone(), |_, q| start[q as usize + 1] += 1);
            for k in 0..levels {
                start[k + 1] += start[k];
            }
            let mut sorted = vec![0u32; start[levels] as usize];
            let mut next = start.clone();
            for_each_edge(g, w, h, rows, |id, q| {
                sorted[next[q as usize] as usize] = id;
                next[q as usize] += 1;
            });
            (start, sorted)
        })
        .collect();
    let level_edges = |q: usize| {
        bands.iter().flat_map(move |(start, sorted)| &sorted[start[q] as usize..start[q + 1] as usize])
    };
    let ends = |id: u32| {
        let p = id as usize / 4;
        (p as u32, (p + offsets[id as usize % 4]) as u32)
    };
    let mut sets = DisjointSets::new(w * h, scale);
    for q in 0..levels {
        let weight = q as f32 / EDGE_STEPS as f32;
        for &id in level_edges(q) {
            let (a, b) = ends(id);
            let (ra, rb) = (sets.find(a), sets.find(b));
            if ra != rb && weight <= sets.threshold(ra) && weight <= sets.threshold(rb) {
                let root = sets.union(ra, rb);
                sets.roots[root as usize].threshold = weight + scale / sets.size(root) as f32;
            }
        }
    }
    for q in 0..levels {
        for &id in level_edges(q) {
            let (a, b) = ends(id);
            let (ra, rb) = (sets.find(a), sets.find(b));
            if ra != rb && (sets.size(ra) < min_size as u32 || sets.size(rb) < min_size as u32) {
                sets.union(ra, rb);
            }
        }
    }
    let mut label_of_root = vec![u32::MAX; w * h];
    let mut count = 0u32;
    (0..w * h)
        .map(|p| {
            let r = sets.find(p as u32) as usize;
            if label_of_root[r] == u32::MAX {
                label_of_root[r] = count;
                count += 1;
            }
            label_of_root[r]
        })
        .collect()
}

/// Edge weights are quantised to 1/`EDGE_STEPS` of an 8-bit grey level.
const EDGE_STEPS: u32 = 16;
/// Bands of rows whose edges are sorted in parallel (a fixed count: the order does not depend on
/// threads).
const SEGMENT_BANDS: usize = 8;

/// The index steps from a pixel to its neighbour in each edge direction of a `w`-wide grid:
/// right, down, down-right, down-left.
fn edge_offsets(w: usize) -> [usize; 4] {
    [1, w, w + 1, w - 1]
}

/// Calls `visit(4 * pixel + direction, quantised weight)` for each edge of the 8-connected grid
/// whose first pixel lies in `rows`, in raster order (directions: right, down, down-right,
/// down-left).
#[inline(always)]
fn for_each_edge(
    g: &[u16],
    w: usize,
    h: usize,
    rows: std::ops::Range<usize>,
    mut visit: impl FnMut(u32, u32),
) {
    let quantise = |a: u16, b: u16| (u32::from(a.abs_diff(b)) * EDGE_STEPS * 2 + 257) / (2 * 257);
    let offsets = edge_offsets(w);
    for y in rows {
        for x in 0..w {
            let p = y * w + x;
            let has = [x + 1 < w, y + 1 < h, x + 1 < w && y + 1 < h, x > 0 && y + 1 < h];
            for dir in 0..4 {
                if has[dir] {
                    visit((4 * p + dir) as u32, quantise(g[p], g[p + offsets[dir]]));
                }
            }
        }
    }
}

/// Union–find with union by size and path halving; each set's merge threshold. The parents lie
/// apart from the roots' size and threshold: `find` walks parents at addresses no cache can
/// predict, and a 4-byte array holds more of them per line.
struct DisjointSets {
    parent: Vec<u32>,
    roots: Vec<Root>,
}

#[derive(Clone, Copy)]
struct Root {
    size: u32,
    threshold: f32,
}

impl DisjointSets {
    fn new(n: usize, scale: f32) -> Self {
        DisjointSets { parent: (0..n as u32).collect(), roots: vec![Root { size: 1, threshold: scale }; n] }
    }

    fn find(&mut self, mut a: u32) -> u32 {
        while self.parent[a as usize] != a {
            let grand = self.parent[self.parent[a as usize] as usize];
            self.parent[a as usize] = grand;
            a = grand;
        }
        a
    }

    fn size(&self, root: u32) -> u32 {
        self.roots[root as usize].size
    }

    fn threshold(&self, root: u32) -> f32 {
        self.roots[root as usize].threshold
    }

    /// Joins two roots; returns the new root.
    fn union(&mut self, a: u32, b: u32) -> u32 {
        let (big, small) = if self.size(a) >= self.size(b) { (a, b) } else { (b, a) };
        self.parent[small as usize] = big;
        self.roots[big as usize].size += self.size(small);
        big
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::status::tagged_nan;

    /// A textured grey: a few levels of noise, so segmentation has something to ignore.
    fn texture(x: usize, y: usize) -> u16 {
        ((x * 7 + y * 13) % 5) as u16 * 257
    }

    #[test]
    fn segments_follow_grey_edges() {
        // Left half dark, right half bright, each with a little texture.
        let image =
            GrayImage::from_fn(60, 40, |x, y| if x < 30 { 60 * 257 } else { 180 * 257 } + texture(x, y));
        let labels = segment(&image, SEGMENT_SCALE, SEGMENT_MIN_SIZE);
        let at = |x: usize, y: usize| labels[y * 60 + x];
        assert_ne!(at(10, 20), at(50, 20));
        for y in 0..40 {
            for x in 0..60 {
                let side = if x < 30 { at(10, 20) } else { at(50, 20) };
                // The smoothing blurs the step over a pixel or two on either side.
                if !(28..=31).contains(&x) {
                    assert_eq!(at(x, y), side, "({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn a_large_view_is_segmented_halved() {
        // Over SEGMENT_MAX_PIXELS: segmented at a quarter of the resolution, labels still
        // follow the edge.
        let (w, h) = (1100, 1000);
        assert!(w * h > SEGMENT_MAX_PIXELS);
        let image =
            GrayImage::from_fn(w, h, |x, y| if x < 550 { 60 * 257 } else { 180 * 257 } + texture(x, y));
        let labels = segment_reduced(&image, 1);
        let (dark, bright) = (labels[500 * w + 100], labels[500 * w + 1000]);
        assert_ne!(dark, bright);
        for y in (0..h).step_by(7) {
            // The step blurs over two reduced pixels (8 px) on either side.
            for x in (0..w).filter(|x| !(538..=561).contains(x)) {
                assert_eq!(labels[y * w + x], if x < 550 { dark } else { bright }, "({x}, {y})");
            }
        }
    }

    #[test]
    fn a_reduced_view_is_segmented_at_the_input_scale() {
        // A view matched at half resolution: its pixels stand for four of the input's.
        let image =
            GrayImage::from_fn(90, 70, |x, y| ((x / 9 + y / 7) % 4) as u16 * 40 * 257 + texture(x, y));
        assert_eq!(segment_reduced(&image, 4), segment(&image, SEGMENT_SCALE / 2.0, SEGMENT_MIN_SIZE / 4));
        assert_eq!(segment_reduced(&image, 1), segment(&image, SEGMENT_SCALE, SEGMENT_MIN_SIZE));
    }

    #[test]
    fn holes_take_the_disparity_plane_of_their_segment() {
        // One uniform segment; a slanted plane with holes in a regular pattern and a few outliers.
        let plane = |x: usize, y: usize| 10.0 + 0.05 * x as f32 - 0.02 * y as f32;
        let image = GrayImage::from_fn(80, 60, |x, y| 100 * 257 + texture(x, y));
        let truth = DisparityMap::from_fn(80, 60, plane);
        let mut d = DisparityMap::from_fn(80, 60, |x, y| match (x * 3 + y * 5) % 7 {
            0 | 1 => tagged_nan(PixelStatus::Mismatch),
            2 if x % 11 == 0 => plane(x, y) + 6.0,
            _ => plane(x, y),
        });
        let status = crate::status::untag(&mut d);
        let holes = d.as_slice().iter().filter(|v| v.is_nan()).count();
        let range = DisparityRange::new(0, 32).unwrap();
        assert_eq!(fill_from_segment_planes(&mut d, &status, &image, range, 1), holes);
        for (i, (&got, &want)) in d.as_slice().iter().zip(truth.as_slice()).enumerate() {
            if status.as_slice()[i] != 0 {
                assert!((got - want).abs() < 1e-3, "pixel {i}: {got} against {want}");
            }
        }
    }

    #[test]
    fn an_occlusion_stays_behind_its_neighbours() {
        // One segment holds a foreground at 20 px (x >= 30, most matched pixels) and a background
        // at 8 px (x < 20); the occluded gap between them must not take the foreground's plane.
        let image = GrayImage::new(60, 30, 90 * 257);
        let mut d = DisparityMap::from_fn(60, 30, |x, _| match x {
            0..=19 => 8.0,
            20..=29 => tagged_nan(PixelStatus::Occluded),
            _ => 20.0,
        });
        let status = crate::status::untag(&mut d);
        fill_from_segment_planes(&mut d, &status, &image, DisparityRange::new(0, 32).unwrap(), 1);
        for y in 0..30 {
            for x in 20..30 {
                assert_eq!(d.get(x, y), 8.0, "({x}, {y})");
            }
        }
    }

    #[test]
    fn segments_with_few_matches_or_no_plane_are_left_alone() {
        // Left segment: 10 % matched. Right segment: random disparities, no dominant plane.
        let image = GrayImage::from_fn(60, 40, |x, _| if x < 30 { 40 * 257 } else { 200 * 257 });
        let mut s = 12345u64;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let mut d = DisparityMap::from_fn(60, 40, |x, y| {
            if x < 30 {
                if (x + y * 30) % 10 == 0 {
                    12.0
                } else {
                    tagged_nan(PixelStatus::Mismatch)
                }
            } else if (x + y) % 2 == 0 {
                tagged_nan(PixelStatus::Mismatch)
            } else {
                (next() % 60) as f32 * 0.5
            }
        });
        let status = crate::status::untag(&mut d);
        let before = d.clone();
        assert_eq!(
            fill_from_segment_planes(&mut d, &status, &image, DisparityRange::new(0, 32).unwrap(), 1),
            0
        );
        for (a, b) in d.as_slice().iter().zip(before.as_slice()) {
            assert_eq!(a.to_bits(), b.to_bits());
        }
    }

    #[test]
    fn the_same_fill_on_any_number_of_threads() {
        let image = GrayImage::from_fn(120, 90, |x, y| {
            (((x / 15) * 40 + (y / 18) * 25) % 256) as u16 * 257 + texture(x, y)
        });
        let mut d = DisparityMap::from_fn(120, 90, |x, y| {
            if (x * 7 + y * 3) % 5 == 0 {
                tagged_nan(PixelStatus::Mismatch)
            } else {
                ((x / 15 + y / 18) % 9) as f32 * 2.5 + 0.01 * x as f32
            }
        });
        let status = crate::status::untag(&mut d);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut m = d.clone();
            pool.install(|| {
                fill_from_segment_planes(&mut m, &status, &image, DisparityRange::new(0, 32).unwrap(), 1)
            });
            m
        };
        let (one, four) = (run(1), run(4));
        assert!(
            one.as_slice().iter().filter(|v| v.is_nan()).count()
                < d.as_slice().iter().filter(|v| v.is_nan()).count()
        );
        for (a, b) in one.as_slice().iter().zip(four.as_slice()) {
            assert_eq!(a.to_bits(), b.to_bits());
        }
    }
}
