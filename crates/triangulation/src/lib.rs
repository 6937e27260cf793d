//! Metric depth and 3-D points from disparity for a rectified rig:
//! `Z = B·f / ((d + doffs)·p)`.
//!
//! With the baseline `B` in mm, the focal length `f` in mm, the pixel pitch `p` in µm and the
//! disparity `d` (plus the principal-point offset `doffs`) in pixels, the depth comes out in
//! metres: `Z[m] = B[mm]·f[mm] / ((d + doffs)·p[µm])`, or equivalently
//! `Z[m] = (B[mm] / 1000)·f_px / (d + doffs)` with the focal length in pixels
//! `f_px = f[mm]·1000 / p[µm]`.
//!
//! ```
//! use stereo_triangulation::{depth_map, DepthStats, Rig};
//! use stereo_image::DisparityMap;
//!
//! // 80 mm baseline, 12 mm lens, 4 µm pixels: f = 3000 px.
//! let rig = Rig::from_datasheet(80.0, 12.0, 4.0)?;
//! assert_eq!(rig.focal_px, 3000.0);
//! // 400 px of disparity is 0.6 m away.
//! assert!((rig.depth(400.0).unwrap() - 0.6).abs() < 1e-12);
//! // A zero or negative (or NaN) disparity has no depth.
//! assert_eq!(rig.depth(0.0), None);
//!
//! // Whole maps: NaN disparities become NaN depths.
//! let disparity = DisparityMap::from_vec(2, 1, vec![400.0, f32::NAN])?;
//! let depth = depth_map(&disparity, &rig);
//! assert!((depth.get(0, 0) - 0.6).abs() < 1e-6);
//! assert!(depth.get(1, 0).is_nan());
//!
//! let stats = DepthStats::from_depth(&depth);
//! assert_eq!(stats.valid_pixels, 1);
//! assert_eq!(stats.density_percent, 50.0);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! Camera frame of [`Rig::point`]: x to the right, y down, z forward (along the optical axis),
//! all in metres.

use nalgebra::Point3;
use rayon::prelude::*;
use stereo_image::{DisparityMap, Image};

pub mod design;

/// Invalid rig parameters.
///
/// Displays as e.g. `invalid baseline: -80 mm (must be a finite number > 0 mm)`.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    #[error("invalid {name}: {value} {unit} (must be {expected})")]
    InvalidParameter {
        /// The parameter, e.g. `"baseline"`.
        name: &'static str,
        /// The rejected value.
        value: f64,
        /// The unit of `value`, e.g. `"mm"`.
        unit: &'static str,
        /// The accepted range, e.g. `"a finite number > 0 mm"`.
        expected: &'static str,
    },
}

fn positive(
    name: &'static str,
    value: f64,
    unit: &'static str,
    expected: &'static str,
) -> Result<f64, Error> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(Error::InvalidParameter { name, value, unit, expected })
    }
}

fn finite(name: &'static str, value: f64, unit: &'static str) -> Result<f64, Error> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(Error::InvalidParameter { name, value, unit, expected: "a finite number" })
    }
}

/// A rectified stereo rig.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Rig {
    /// Distance between the optical centres, mm.
    pub baseline_mm: f64,
    /// Focal length in pixels (`focal_mm * 1000 / pixel_um`).
    pub focal_px: f64,
    /// Disparity offset between the principal points (Middlebury's `doffs`), pixels.
    pub doffs: f64,
    /// Principal point `(cx, cy)` in pixels; `None` means the centre of the pixel grid,
    /// see [`Rig::principal_point_for`].
    pub principal_point: Option<(f64, f64)>,
}

impl Rig {
    /// A rig from datasheet values: baseline and focal length in mm, pixel pitch in µm.
    ///
    /// All three must be finite and > 0. `doffs` is 0 and the principal point is the image
    /// centre; change them with [`Rig::with_doffs`] and [`Rig::with_principal_point`].
    pub fn from_datasheet(baseline_mm: f64, focal_mm: f64, pixel_um: f64) -> Result<Self, Error> {
        let baseline_mm = positive("baseline", baseline_mm, "mm", "a finite number > 0 mm")?;
        let focal_mm = positive("focal length", focal_mm, "mm", "a finite number > 0 mm")?;
        let pixel_um = positive("pixel size", pixel_um, "µm", "a finite number > 0 µm")?;
        Self::from_focal_px(baseline_mm, focal_mm * 1000.0 / pixel_um)
    }

    /// A rig from the baseline in mm and the focal length in pixels (both finite and > 0).
    pub fn from_focal_px(baseline_mm: f64, focal_px: f64) -> Result<Self, Error> {
        Ok(Rig {
            baseline_mm: positive("baseline", baseline_mm, "mm", "a finite number > 0 mm")?,
            focal_px: positive("focal length", focal_px, "px", "a finite number > 0 px")?,
            doffs: 0.0,
            principal_point: None,
        })
    }

    /// The same rig with the disparity offset `doffs` in pixels (finite), added to every
    /// disparity before triangulating: Middlebury's `doffs`, the x-difference of the principal
    /// points `cx_right - cx_left`.
    pub fn with_doffs(self, doffs: f64) -> Result<Self, Error> {
        Ok(Rig { doffs: finite("disparity offset", doffs, "px")?, ..self })
    }

    /// The same rig with an explicit principal point `(cx, cy)` in pixels (both finite).
    pub fn with_principal_point(self, cx: f64, cy: f64) -> Result<Self, Error> {
        let cx = finite("principal point x", cx, "px")?;
        let cy = finite("principal point y", cy, "px")?;
        Ok(Rig { principal_point: Some((cx, cy)), ..self })
    }

    /// The principal point for an image of `width × height` pixels: the explicit one if set,
    /// else the centre of the pixel grid `((width - 1) / 2, (height - 1) / 2)` (pixel `x`
    /// covers `[x - 0.5, x + 0.5]`, so this is the geometric image centre).
    pub fn principal_point_for(&self, width: usize, height: usize) -> (f64, f64) {
        self.principal_point.unwrap_or(((width as f64 - 1.0) / 2.0, (height as f64 - 1.0) / 2.0))
    }

    /// Depth in metres for disparity `d` pixels; `None` when `d` is not finite,
    /// `d + doffs <= 0`, or the depth would overflow.
    pub fn depth(&self, d: f64) -> Option<f64> {
        let denom = d + self.doffs;
        if !d.is_finite() || denom.is_nan() || denom <= 0.0 {
            return None;
        }
        // Dividing by 1000 last keeps exact datasheet products exact (80·3000/(400·1000) = 0.6).
        let z = self.baseline_mm * self.focal_px / (denom * 1000.0);
        (z.is_finite() && z > 0.0).then_some(z)
    }

    /// The 3-D point (metres, x right, y down, z forward) seen at pixel `(x, y)` with
    /// disparity `d` in an image of `size = (width, height)` (used for the default principal
    /// point, see [`Rig::principal_point_for`]). `None` where [`Rig::depth`] is `None`.
    ///
    /// `X = (x - cx)·Z / f_px`, `Y = (y - cy)·Z / f_px`.
    pub fn point(&self, x: f64, y: f64, d: f64, size: (usize, usize)) -> Option<Point3<f64>> {
        let z = self.depth(d)?;
        let (cx, cy) = self.principal_point_for(size.0, size.1);
        Some(Point3::new((x - cx) * z / self.focal_px, (y - cy) * z / self.focal_px, z))
    }

    /// Depth change in metres for a disparity change of `disparity_step_px` pixels at depth
    /// `z_m` metres: `ΔZ ≈ Z²·Δd / (B·f_px)` with `B` in metres (the first-order term of
    /// `Z(d) = B·f_px / d`). E.g. a quarter-pixel step of a 80 mm / 3000 px rig at 0.6 m is
    /// 0.375 mm.
    pub fn depth_resolution(&self, z_m: f64, disparity_step_px: f64) -> f64 {
        z_m * z_m * disparity_step_px * 1000.0 / (self.baseline_mm * self.focal_px)
    }
}

/// The depth map (metres, NaN where invalid) of a disparity map: pixels whose
/// [`Rig::depth`] is `None`, or whose depth does not fit an `f32`, are NaN, so the map never
/// holds infinite, zero or negative depths. Rows are computed in parallel.
pub fn depth_map(disparity: &DisparityMap, rig: &Rig) -> Image<f32> {
    let (width, height) = disparity.size();
    let mut out = Image::new(width, height, f32::NAN);
    if width == 0 {
        return out;
    }
    out.as_mut_slice().par_chunks_mut(width).zip(disparity.as_slice().par_chunks(width)).for_each(
        |(dst, src)| {
            for (z, &d) in dst.iter_mut().zip(src) {
                *z = match rig.depth(f64::from(d)) {
                    Some(z) => {
                        let z = z as f32;
                        if z.is_finite() && z > 0.0 {
                            z
                        } else {
                            f32::NAN
                        }
                    }
                    None => f32::NAN,
                };
            }
        },
    );
    out
}

/// A triangulated pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Pixel column.
    pub x: usize,
    /// Pixel row.
    pub y: usize,
    /// Disparity at the pixel, pixels.
    pub disparity: f32,
    /// Camera-frame position in metres (x right, y down, z forward).
    pub position: Point3<f64>,
}

/// The 3-D points of every `step`-th pixel (in both directions, starting at `(0, 0)`) that has a
/// depth, row by row. A `step` of 0 is treated as 1.
pub fn points(disparity: &DisparityMap, rig: &Rig, step: usize) -> Vec<Point> {
    let step = step.max(1);
    let size = disparity.size();
    let mut out = Vec::new();
    for y in (0..size.1).step_by(step) {
        let row = disparity.row(y);
        for x in (0..size.0).step_by(step) {
            let d = row[x];
            if let Some(position) = rig.point(x as f64, y as f64, f64::from(d), size) {
                out.push(Point { x, y, disparity: d, position });
            }
        }
    }
    out
}

/// The `p`-th percentile (0..=100) of ascending `sorted`, by linear interpolation between the
/// closest ranks: position `h = (n - 1)·p / 100`, value
/// `v[⌊h⌋] + (h - ⌊h⌋)·(v[⌊h⌋ + 1] - v[⌊h⌋])` (NumPy's default `"linear"` method).
/// `None` when `sorted` is empty.
pub fn percentile(sorted: &[f64], p: f64) -> Option<f64> {
    let n = sorted.len();
    if n == 0 {
        return None;
    }
    let h = (n - 1) as f64 * p.clamp(0.0, 100.0) / 100.0;
    let lo = h.floor() as usize;
    let hi = (lo + 1).min(n - 1);
    let frac = h - lo as f64;
    Some(sorted[lo] + frac * (sorted[hi] - sorted[lo]))
}

/// [`percentile`] of unsorted `values`, found by selection (`O(n)` instead of a full sort; the
/// order of `values` changes). Equal to `percentile` of the sorted values.
pub fn percentile_unsorted(values: &mut [f64], p: f64) -> Option<f64> {
    let n = values.len();
    if n == 0 {
        return None;
    }
    let h = (n - 1) as f64 * p.clamp(0.0, 100.0) / 100.0;
    let lo = h.floor() as usize;
    let frac = h - lo as f64;
    let (_, &mut at_lo, above) = values.select_nth_unstable_by(lo, f64::total_cmp);
    // The next rank is the smallest value above the `lo`-th.
    let at_hi = above.iter().copied().min_by(f64::total_cmp).unwrap_or(at_lo);
    Some(at_lo + frac * (at_hi - at_lo))
}

/// Ascending `u32` keys in `f32::total_cmp` order.
#[inline(always)]
fn order_key(v: f32) -> u32 {
    let bits = v.to_bits();
    if bits >> 31 == 1 {
        !bits
    } else {
        bits | 1 << 31
    }
}

/// The sample of an [`order_key`].
fn from_order_key(key: u32) -> f32 {
    f32::from_bits(if key >> 31 == 1 { key & !(1 << 31) } else { !key })
}

/// Samples per parallel task of the statistics' passes.
const STATS_CHUNK: usize = 1 << 15;

/// The valid samples of a map counted per bucket of the top 16 bits of their [`order_key`], and
/// their smallest and largest keys: one parallel pass.
struct KeyHistogram {
    counts: Vec<u32>,
    n: usize,
    low: u32,
    high: u32,
}

impl KeyHistogram {
    fn empty() -> Self {
        KeyHistogram { counts: vec![0; 1 << 16], n: 0, low: u32::MAX, high: 0 }
    }

    fn of(samples: &[f32], valid: &(impl Fn(f32) -> bool + Sync)) -> Self {
        samples
            .par_chunks(STATS_CHUNK)
            .fold(Self::empty, |mut h, chunk| {
                for &v in chunk {
                    if valid(v) {
                        let key = order_key(v);
                        h.counts[(key >> 16) as usize] += 1;
                        h.n += 1;
                        h.low = h.low.min(key);
                        h.high = h.high.max(key);
                    }
                }
                h
            })
            .reduce(Self::empty, |mut a, b| {
                for (a, b) in a.counts.iter_mut().zip(&b.counts) {
                    *a += b;
                }
                KeyHistogram {
                    n: a.n + b.n,
                    low: a.low.min(b.low),
                    high: a.high.max(b.high),
                    counts: a.counts,
                }
            })
    }
}

/// [`percentile`] at each of `ps` of the unsorted `values`, in `f32` (the samples' own type; the
/// interpolation is in `f64` as in [`percentile`], so the results are the same).
#[cfg(test)]
fn percentiles_unsorted<const N: usize>(values: &[f32], ps: [f64; N]) -> [Option<f64>; N] {
    let all = |_: f32| true;
    percentiles_of(values, &all, &KeyHistogram::of(values, &all), ps)
}

/// [`percentile`] at each of `ps` of the samples of `samples` that are `valid`, found by a radix
/// selection: `histogram` tells which bucket of keys holds each rank needed, a second pass
/// gathers those buckets' samples, and each rank is selected among its bucket's samples alone
/// (instead of partitioning every sample for every rank).
fn percentiles_of<const N: usize>(
    samples: &[f32],
    valid: &(impl Fn(f32) -> bool + Sync),
    histogram: &KeyHistogram,
    ps: [f64; N],
) -> [Option<f64>; N] {
    let (n, counts) = (histogram.n, &histogram.counts);
    let mut out = [None; N];
    if n == 0 {
        return out;
    }
    // Samples below each bucket.
    let mut below = vec![0usize; 1 << 16];
    let mut total = 0usize;
    for (b, &c) in below.iter_mut().zip(counts) {
        *b = total;
        total += c as usize;
    }
    let bucket_of = |rank: usize| below.partition_point(|&b| b <= rank) - 1;
    // Each percentile's position between the ranks ⌊h⌋ and ⌊h⌋ + 1.
    let positions = ps.map(|p| (n - 1) as f64 * p.clamp(0.0, 100.0) / 100.0);
    // The buckets of the ranks asked for, gathered once each (in any order: a rank's value does
    // not depend on it).
    let mut buckets: Vec<usize> = positions
        .iter()
        .flat_map(|&h| [h.floor() as usize, (h.floor() as usize + 1).min(n - 1)])
        .map(bucket_of)
        .collect();
    buckets.sort_unstable();
    buckets.dedup();
    let (first, last) = (buckets[0], buckets[buckets.len() - 1]);
    let gather = |mut members: Vec<Vec<f32>>, chunk: &[f32]| {
        for &v in chunk {
            let b = (order_key(v) >> 16) as usize;
            // Most samples lie outside the gathered buckets' span: one test rejects them.
            if (first..=last).contains(&b) && valid(v) {
                if let Ok(i) = buckets.binary_search(&b) {
                    members[i].push(v);
                }
            }
        }
        members
    };
    let mut members: Vec<Vec<f32>> =
        samples.par_chunks(STATS_CHUNK).fold(|| vec![Vec::new(); buckets.len()], gather).reduce(
            || vec![Vec::new(); buckets.len()],
            |mut a, b| {
                for (a, b) in a.iter_mut().zip(b) {
                    a.extend(b);
                }
                a
            },
        );
    let mut rank_value = |rank: usize| {
        let b = bucket_of(rank);
        let i = buckets.binary_search(&b).expect("every rank's bucket was gathered");
        let (_, &mut v, _) = members[i].select_nth_unstable_by(rank - below[b], f32::total_cmp);
        v
    };
    for (i, &h) in positions.iter().enumerate() {
        let lo = h.floor() as usize;
        let frac = h - lo as f64;
        let at_lo = rank_value(lo);
        let at_hi = if lo + 1 < n { rank_value(lo + 1) } else { at_lo };
        out[i] = Some(f64::from(at_lo) + frac * (f64::from(at_hi) - f64::from(at_lo)));
    }
    out
}

/// Statistics of the valid samples of a map: a depth map ([`DepthStats`], metres, valid = finite
/// and > 0) or a disparity map ([`DisparityStats`], pixels, valid = finite, negative included).
/// Values are `None` when no pixel is valid. Percentiles (and the median) interpolate linearly
/// between closest ranks, see [`percentile`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct MapStats {
    pub width: usize,
    pub height: usize,
    pub valid_pixels: usize,
    pub total_pixels: usize,
    /// `100 · valid_pixels / total_pixels` (0 for an empty map).
    pub density_percent: f64,
    pub min: Option<f64>,
    pub max: Option<f64>,
    pub mean: Option<f64>,
    pub median: Option<f64>,
    pub p5: Option<f64>,
    pub p95: Option<f64>,
}

/// Statistics of a depth map (metres).
pub type DepthStats = MapStats;

/// Statistics of a disparity map (pixels).
pub type DisparityStats = MapStats;

impl MapStats {
    /// Statistics of `depth` (metres, NaN / non-positive = invalid).
    pub fn from_depth(depth: &Image<f32>) -> Self {
        Self::of_valid(depth, |v| v.is_finite() && v > 0.0)
    }

    /// Statistics of `disparity` (pixels, NaN / infinite = invalid).
    pub fn from_disparity(disparity: &DisparityMap) -> Self {
        Self::of_valid(disparity, f32::is_finite)
    }

    fn of_valid(image: &Image<f32>, valid: impl Fn(f32) -> bool + Sync) -> Self {
        let (width, height) = image.size();
        let samples = image.as_slice();
        // The sum in the samples' order (one thread), beside the parallel count of the
        // percentiles' buckets and the extremes; then a pass that gathers the buckets the
        // percentiles fall in (a radix selection: a sort of every valid pixel cost more than the
        // triangulation itself).
        let (sum, histogram) = rayon::join(
            || samples.iter().copied().filter(|&v| valid(v)).map(f64::from).sum::<f64>(),
            || KeyHistogram::of(samples, &valid),
        );
        let total_pixels = width * height;
        let valid_pixels = histogram.n;
        let density_percent =
            if total_pixels == 0 { 0.0 } else { 100.0 * valid_pixels as f64 / total_pixels as f64 };
        let mean = (valid_pixels > 0).then(|| sum / valid_pixels as f64);
        let min = (valid_pixels > 0).then(|| f64::from(from_order_key(histogram.low)));
        let max = (valid_pixels > 0).then(|| f64::from(from_order_key(histogram.high)));
        let [median, p5, p95] = percentiles_of(samples, &valid, &histogram, [50.0, 5.0, 95.0]);
        MapStats {
            width,
            height,
            valid_pixels,
            total_pixels,
            density_percent,
            min,
            max,
            mean,
            median,
            p5,
            p95,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    #[test]
    fn datasheet_examples() {
        let rig = Rig::from_datasheet(80.0, 12.0, 4.0).unwrap();
        assert_eq!(rig.focal_px, 3000.0);
        assert!(close(rig.depth(400.0).unwrap(), 0.6, 1e-12));
        let rig = Rig::from_datasheet(200.0, 6.0, 2.5).unwrap();
        assert_eq!(rig.focal_px, 2400.0);
        assert!(close(rig.depth(150.0).unwrap(), 3.2, 1e-12));
    }

    #[test]
    fn from_focal_px_matches_datasheet() {
        let a = Rig::from_datasheet(80.0, 12.0, 4.0).unwrap();
        let b = Rig::from_focal_px(80.0, 3000.0).unwrap();
        assert_eq!(a, b);
    }

    #[test]
    fn invalid_parameters_are_named() {
        let e = Rig::from_datasheet(-80.0, 12.0, 4.0).unwrap_err();
        assert_eq!(e.to_string(), "invalid baseline: -80 mm (must be a finite number > 0 mm)");
        let e = Rig::from_datasheet(80.0, 0.0, 4.0).unwrap_err();
        assert_eq!(e.to_string(), "invalid focal length: 0 mm (must be a finite number > 0 mm)");
        let e = Rig::from_datasheet(80.0, 12.0, f64::NAN).unwrap_err();
        assert_eq!(e.to_string(), "invalid pixel size: NaN µm (must be a finite number > 0 µm)");
        let e = Rig::from_datasheet(f64::INFINITY, 12.0, 4.0).unwrap_err();
        assert!(matches!(e, Error::InvalidParameter { name: "baseline", .. }));
        let e = Rig::from_focal_px(80.0, -1.0).unwrap_err();
        assert_eq!(e.to_string(), "invalid focal length: -1 px (must be a finite number > 0 px)");
        let rig = Rig::from_focal_px(80.0, 3000.0).unwrap();
        let e = rig.clone().with_doffs(f64::NAN).unwrap_err();
        assert_eq!(e.to_string(), "invalid disparity offset: NaN px (must be a finite number)");
        let e = rig.clone().with_principal_point(1.0, f64::NEG_INFINITY).unwrap_err();
        assert!(matches!(e, Error::InvalidParameter { name: "principal point y", .. }));
        assert!(rig.with_principal_point(f64::NAN, 1.0).is_err());
    }

    #[test]
    fn depth_rejects_bad_disparities_and_uses_doffs() {
        let rig = Rig::from_focal_px(80.0, 3000.0).unwrap();
        assert_eq!(rig.depth(0.0), None);
        assert_eq!(rig.depth(-1.0), None);
        assert_eq!(rig.depth(f64::NAN), None);
        assert_eq!(rig.depth(f64::INFINITY), None);
        assert_eq!(rig.depth(1e-320), None, "overflowing depth");
        let rig = rig.with_doffs(100.0).unwrap();
        // 80·3000 / (300 + 100) / 1000 = 0.6
        assert!(close(rig.depth(300.0).unwrap(), 0.6, 1e-12));
        assert_eq!(rig.depth(-100.0), None);
        assert!(close(rig.depth(-50.0).unwrap(), 4.8, 1e-12));
    }

    #[test]
    fn depth_map_marks_invalid_as_nan() {
        let rig = Rig::from_datasheet(80.0, 12.0, 4.0).unwrap();
        let d =
            DisparityMap::from_vec(3, 2, vec![400.0, 0.0, -3.0, f32::NAN, f32::INFINITY, f32::MIN_POSITIVE])
                .unwrap();
        let z = depth_map(&d, &rig);
        assert_eq!(z.size(), (3, 2));
        assert!(close(f64::from(z.get(0, 0)), 0.6, 1e-7));
        for (x, y) in [(1, 0), (2, 0), (0, 1), (1, 1), (2, 1)] {
            assert!(z.get(x, y).is_nan(), "({x}, {y}) = {}", z.get(x, y));
        }
        let empty = depth_map(&DisparityMap::new(0, 4, 1.0), &rig);
        assert_eq!(empty.size(), (0, 4));
    }

    #[test]
    fn no_depth_or_point_where_d_plus_doffs_is_not_positive() {
        // A negative doffs puts small positive disparities behind the camera: d = 7 and d = 8
        // (d + doffs = -1 and 0) and d = 4 have no depth, in the map nor as points.
        let rig = Rig::from_focal_px(80.0, 3000.0).unwrap().with_doffs(-8.0).unwrap();
        let d = DisparityMap::from_vec(4, 1, vec![7.0, 8.0, 9.0, 4.0]).unwrap();
        assert_eq!((rig.depth(7.0), rig.depth(8.0), rig.depth(4.0)), (None, None, None));
        let z = depth_map(&d, &rig);
        assert!(z.get(0, 0).is_nan() && z.get(1, 0).is_nan() && z.get(3, 0).is_nan());
        // 80 · 3000 / (9 - 8) / 1000 = 240 m.
        assert!(close(f64::from(z.get(2, 0)), 240.0, 1e-6));
        let points = points(&d, &rig, 1);
        assert_eq!(points.iter().map(|p| p.x).collect::<Vec<_>>(), [2]);
        assert!(points.iter().all(|p| p.position.z.is_finite() && p.position.z > 0.0));
        // A tiny positive d + doffs gives a huge but finite depth; one beyond f32 is NaN in the
        // map, never infinite.
        let rig = Rig::from_focal_px(80.0, 3000.0).unwrap().with_doffs(-1.0).unwrap();
        let d = DisparityMap::from_vec(1, 1, vec![1.0 + f32::EPSILON]).unwrap();
        let far = rig.depth(f64::from(1.0 + f32::EPSILON)).unwrap();
        assert!(far > 1e8 && far.is_finite(), "{far}");
        assert!(depth_map(&d, &rig).get(0, 0) > 1e8);
        let d = DisparityMap::from_vec(1, 1, vec![f32::MIN_POSITIVE]).unwrap();
        let rig = Rig::from_focal_px(80.0, 3000.0).unwrap();
        assert!(rig.depth(f64::from(f32::MIN_POSITIVE)).is_some(), "finite in f64");
        assert!(depth_map(&d, &rig).get(0, 0).is_nan(), "but infinite in f32");
    }

    #[test]
    fn depth_map_on_many_rows_matches_rig_depth() {
        let rig = Rig::from_datasheet(200.0, 6.0, 2.5).unwrap().with_doffs(1.5).unwrap();
        let d = DisparityMap::from_fn(37, 53, |x, y| (x * 7 + y * 3) as f32 - 20.0);
        let z = depth_map(&d, &rig);
        for y in 0..53 {
            for x in 0..37 {
                match rig.depth(f64::from(d.get(x, y))) {
                    Some(e) => assert_eq!(z.get(x, y), e as f32),
                    None => assert!(z.get(x, y).is_nan()),
                }
            }
        }
    }

    #[test]
    fn points_use_pixel_grid_centre() {
        let rig = Rig::from_focal_px(80.0, 3000.0).unwrap();
        assert_eq!(rig.principal_point_for(5, 3), (2.0, 1.0));
        assert_eq!(rig.principal_point_for(640, 480), (319.5, 239.5));
        // Centre pixel: on the optical axis.
        let p = rig.point(2.0, 1.0, 400.0, (5, 3)).unwrap();
        assert!(close(p.x, 0.0, 1e-15) && close(p.y, 0.0, 1e-15) && close(p.z, 0.6, 1e-12));
        // 300 px right of and 150 px below the centre at 0.6 m: X = 300·0.6/3000 = 0.06.
        let p = rig.point(302.0, 151.0, 400.0, (5, 3)).unwrap();
        assert!(close(p.x, 0.06, 1e-12) && close(p.y, 0.03, 1e-12) && close(p.z, 0.6, 1e-12));
        let p = rig.point(0.0, 0.0, 400.0, (5, 3)).unwrap();
        assert!(close(p.x, -2.0 * 0.6 / 3000.0, 1e-15) && p.y < 0.0);
        assert_eq!(rig.point(0.0, 0.0, f64::NAN, (5, 3)), None);

        let rig = rig.with_principal_point(10.0, 20.0).unwrap();
        let p = rig.point(10.0, 20.0, 400.0, (5, 3)).unwrap();
        assert_eq!((p.x, p.y), (0.0, 0.0));
    }

    #[test]
    fn points_skip_invalid_and_step() {
        let rig = Rig::from_focal_px(80.0, 3000.0).unwrap();
        let d = DisparityMap::from_fn(4, 3, |x, y| if (x + y) % 3 == 0 { f32::NAN } else { 400.0 });
        let all = points(&d, &rig, 1);
        assert_eq!(all.len(), 12 - 4);
        assert!(all.iter().all(|p| (p.x + p.y) % 3 != 0 && close(p.position.z, 0.6, 1e-12)));
        assert_eq!(all[0].x, 1);
        assert_eq!(all[0].y, 0);
        assert_eq!(points(&d, &rig, 0), all);
        // step 2 visits (0,0) (NaN), (2,0), (0,2) and (2,2).
        let sub: Vec<_> = points(&d, &rig, 2).iter().map(|p| (p.x, p.y)).collect();
        assert_eq!(sub, vec![(2, 0), (0, 2), (2, 2)]);
    }

    #[test]
    fn depth_resolution_by_hand() {
        let rig = Rig::from_datasheet(80.0, 12.0, 4.0).unwrap();
        // 0.36 m² · 1 px / (0.08 m · 3000 px) = 0.0015 m, = |dZ/dd| at d = 400.
        assert!(close(rig.depth_resolution(0.6, 1.0), 0.0015, 1e-15));
        assert!(close(rig.depth_resolution(0.6, 0.25), 0.000375, 1e-15));
        let rig = Rig::from_datasheet(200.0, 6.0, 2.5).unwrap();
        // 3.2² · 0.25 / (0.2 · 2400) = 2.56 / 480 = 0.0053333…
        assert!(close(rig.depth_resolution(3.2, 0.25), 2.56 / 480.0, 1e-15));
        // Agrees with the finite difference of depth().
        let fd = rig.depth(150.0).unwrap() - rig.depth(150.001).unwrap();
        assert!(close(rig.depth_resolution(3.2, 0.001), fd, 1e-7));
    }

    #[test]
    fn percentile_linear_interpolation() {
        let v = [1.0, 2.0, 3.0, 4.0, 10.0];
        assert_eq!(percentile(&v, 0.0), Some(1.0));
        assert_eq!(percentile(&v, 100.0), Some(10.0));
        assert_eq!(percentile(&v, 50.0), Some(3.0));
        // h = 4·0.05 = 0.2 -> 1 + 0.2·1
        assert!(close(percentile(&v, 5.0).unwrap(), 1.2, 1e-12));
        // h = 4·0.95 = 3.8 -> 4 + 0.8·6
        assert!(close(percentile(&v, 95.0).unwrap(), 8.8, 1e-12));
        assert_eq!(percentile(&[1.0, 2.0], 50.0), Some(1.5));
        assert_eq!(percentile(&[7.0], 95.0), Some(7.0));
        assert_eq!(percentile(&[], 50.0), None);
    }

    #[test]
    fn selected_percentiles_equal_sorted_ones() {
        // A fixed pseudo-random sequence with repeats, several lengths and percentiles.
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for n in [1usize, 2, 3, 10, 101, 1000] {
            let values: Vec<f64> = (0..n)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    (state % 50) as f64 * 0.25 - 3.0
                })
                .collect();
            let mut sorted = values.clone();
            sorted.sort_unstable_by(f64::total_cmp);
            for p in [0.0, 5.0, 33.3, 50.0, 95.0, 100.0] {
                let mut scratch = values.clone();
                assert_eq!(percentile_unsorted(&mut scratch, p), percentile(&sorted, p), "n {n} p {p}");
            }
        }
        assert_eq!(percentile_unsorted(&mut [], 50.0), None);
    }

    #[test]
    fn percentiles_in_one_pass_equal_sorted_ones() {
        // Repeats, signed zeros, several lengths, percentiles in any order.
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        for n in [1usize, 2, 3, 4, 10, 21, 101, 1000, 4097] {
            let values: Vec<f32> = (0..n)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    match state % 7 {
                        0 => -0.0,
                        1 => 0.0,
                        _ => (state % 61) as f32 * 0.37 - 5.0,
                    }
                })
                .collect();
            let mut sorted: Vec<f64> = values.iter().map(|&v| f64::from(v)).collect();
            sorted.sort_unstable_by(f64::total_cmp);
            for ps in [[50.0, 5.0, 95.0], [0.0, 100.0, 50.0], [95.0, 95.0, 5.0], [33.3, 66.6, 99.9]] {
                let got = percentiles_unsorted(&values, ps);
                for (p, g) in ps.iter().zip(got) {
                    assert_eq!(
                        g.map(f64::to_bits),
                        percentile(&sorted, *p).map(f64::to_bits),
                        "n {n} p {p} of {ps:?}"
                    );
                }
            }
        }
        assert_eq!(percentiles_unsorted(&[], [50.0]), [None]);
    }

    #[test]
    fn map_stats_equal_a_sort_of_the_valid_samples() {
        // Maps larger than a parallel task's chunk (several partial histograms merged), with
        // holes, infinities, signed zeros and negatives: every statistic equals the sorted
        // reference's, bit for bit (the mean summed in the samples' order as before).
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for (w, h) in [(1, 1), (7, 3), (301, 257), (640, 111)] {
            let data: Vec<f32> = (0..w * h)
                .map(|_| {
                    state ^= state << 13;
                    state ^= state >> 7;
                    state ^= state << 17;
                    match state % 11 {
                        0 => f32::NAN,
                        1 => f32::INFINITY,
                        2 => -0.0,
                        3 => 0.0,
                        _ => (state % 100_003) as f32 * 0.013 - 30.0,
                    }
                })
                .collect();
            let image = Image::from_vec(w, h, data.clone()).unwrap();
            for (stats, valid) in [
                (MapStats::from_disparity(&image), &(|v: f32| v.is_finite()) as &dyn Fn(f32) -> bool),
                (MapStats::from_depth(&image), &|v: f32| v.is_finite() && v > 0.0),
            ] {
                let values: Vec<f32> = data.iter().copied().filter(|&v| valid(v)).collect();
                let mut sorted: Vec<f64> = values.iter().map(|&v| f64::from(v)).collect();
                sorted.sort_unstable_by(f64::total_cmp);
                let bits = |v: Option<f64>| v.map(f64::to_bits);
                assert_eq!(stats.valid_pixels, values.len());
                assert_eq!(bits(stats.min), bits(sorted.first().copied()));
                assert_eq!(bits(stats.max), bits(sorted.last().copied()));
                let mean = (!values.is_empty())
                    .then(|| values.iter().map(|&v| f64::from(v)).sum::<f64>() / values.len() as f64);
                assert_eq!(bits(stats.mean), bits(mean));
                for (got, p) in [(stats.median, 50.0), (stats.p5, 5.0), (stats.p95, 95.0)] {
                    assert_eq!(bits(got), bits(percentile(&sorted, p)), "{w}x{h} p{p}");
                }
            }
        }
    }

    #[test]
    fn depth_stats_by_hand() {
        let z = Image::from_vec(3, 3, vec![4.0, f32::NAN, 1.0, 2.0, 0.0, 10.0, -1.0, 3.0, f32::INFINITY])
            .unwrap();
        let s = DepthStats::from_depth(&z);
        assert_eq!((s.width, s.height, s.valid_pixels, s.total_pixels), (3, 3, 5, 9));
        assert!(close(s.density_percent, 500.0 / 9.0, 1e-12));
        assert_eq!(s.min, Some(1.0));
        assert_eq!(s.max, Some(10.0));
        assert_eq!(s.mean, Some(4.0));
        assert_eq!(s.median, Some(3.0));
        assert!(close(s.p5.unwrap(), 1.2, 1e-12));
        assert!(close(s.p95.unwrap(), 8.8, 1e-12));

        let json = serde_json::to_value(&s).unwrap();
        assert_eq!(json["valid_pixels"], 5);
        assert_eq!(json["median"], 3.0);

        let none = DepthStats::from_depth(&Image::new(2, 2, f32::NAN));
        assert_eq!((none.valid_pixels, none.density_percent), (0, 0.0));
        assert_eq!(
            (none.min, none.max, none.mean, none.median, none.p5, none.p95),
            (None, None, None, None, None, None)
        );
        assert!(serde_json::to_value(&none).unwrap()["median"].is_null());
        let empty = DepthStats::from_depth(&Image::new(0, 0, 1.0));
        assert_eq!((empty.total_pixels, empty.density_percent), (0, 0.0));
    }

    #[test]
    fn disparity_stats_by_hand() {
        let d = DisparityMap::from_vec(2, 3, vec![-2.0, f32::NAN, 0.0, 6.0, 2.0, f32::NEG_INFINITY]).unwrap();
        let s = DisparityStats::from_disparity(&d);
        assert_eq!((s.valid_pixels, s.total_pixels), (4, 6));
        assert!(close(s.density_percent, 400.0 / 6.0, 1e-12));
        assert_eq!((s.min, s.max), (Some(-2.0), Some(6.0)));
        assert_eq!(s.mean, Some(1.5));
        // sorted -2, 0, 2, 6: h = 1.5 -> 1.0
        assert_eq!(s.median, Some(1.0));
        // h = 0.15 -> -2 + 0.15·2 = -1.7; h = 2.85 -> 2 + 0.85·4 = 5.4
        assert!(close(s.p5.unwrap(), -1.7, 1e-12));
        assert!(close(s.p95.unwrap(), 5.4, 1e-12));
    }

    #[test]
    fn rig_serializes() {
        let rig = Rig::from_datasheet(80.0, 12.0, 4.0).unwrap();
        let json = serde_json::to_value(&rig).unwrap();
        assert_eq!(json["focal_px"], 3000.0);
        assert!(json["principal_point"].is_null());
    }
}
