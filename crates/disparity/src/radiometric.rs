//! Radiometric preparation of a pair before matching: what makes the cost survive two cameras
//! that do not see alike (exposure, gamma, vignetting, sensor noise).

use rayon::prelude::*;

use crate::tone::{ToneCorrection, ToneSample};
use crate::{DisparityMap, GrayImage, Image};

/// `range` for a pair reduced by `factor` ([`downsample`]): the bounds divided and rounded
/// outwards, at least one disparity.
pub(crate) fn reduced_range(range: crate::DisparityRange, factor: usize) -> crate::DisparityRange {
    let f = factor as i32;
    let min = range.min.div_euclid(f);
    crate::DisparityRange { min, max: (range.max + f - 1).div_euclid(f).max(min + 1) }
}

/// The `factor × factor` box average of `image` (partial blocks at the right and bottom are
/// dropped), 8-bit samples stored ×257 when the input is 8-bit.
pub(crate) fn downsample(image: &GrayImage, factor: usize) -> GrayImage {
    downsample_by(image, factor, factor)
}

/// The `columns × rows` box average of `image`, as [`downsample`] (`columns` 1 and `rows` 2 halves
/// the rows alone). Rows in parallel; each output row sums its input rows column by column
/// first, so the inner loops have no divisions.
pub(crate) fn downsample_by(image: &GrayImage, columns: usize, rows: usize) -> GrayImage {
    let (w, h) = image.size();
    let (columns, rows) = (columns.max(1), rows.max(1));
    let (cw, ch) = (w / columns, h / rows);
    let byte_scaled = crate::census::is_byte_scaled(image);
    let mut data = vec![0u16; cw * ch];
    // Column sums in u32: a block of up to 2^16 samples of 16 bits.
    assert!(columns * rows <= 1 << 16, "downsampling by {columns} x {rows}");
    data.par_chunks_mut(cw.max(1)).enumerate().for_each_init(
        || vec![0u32; cw * columns],
        |sums, (y, out)| {
            sums.fill(0);
            for yy in y * rows..(y + 1) * rows {
                for (c, &v) in sums.iter_mut().zip(image.row(yy)) {
                    *c += u32::from(v);
                }
            }
            // The usual factors with the block size known to the compiler (unrolled sums, a
            // shift for the mean).
            match (columns, rows) {
                (2, 2) => block_means::<2, 4>(sums, out, byte_scaled),
                (3, 3) => block_means::<3, 9>(sums, out, byte_scaled),
                (4, 4) => block_means::<4, 16>(sums, out, byte_scaled),
                (1, 2) => block_means::<1, 2>(sums, out, byte_scaled),
                (2, 4) => block_means::<2, 8>(sums, out, byte_scaled),
                _ => {
                    for (o, block) in out.iter_mut().zip(sums.chunks_exact(columns)) {
                        *o = block_mean(block.iter().sum(), columns * rows, byte_scaled);
                    }
                }
            }
        },
    );
    GrayImage::from_vec(cw, ch, data).expect("cw * ch samples")
}

/// [`downsample_by`]'s output row from its column sums, `F` columns per output sample and `N`
/// samples per block.
#[inline(always)]
fn block_means<const F: usize, const N: usize>(columns: &[u32], out: &mut [u16], byte_scaled: bool) {
    for (o, block) in out.iter_mut().zip(columns.chunks_exact(F)) {
        let block: &[u32; F] = block.try_into().expect("F columns");
        *o = block_mean(block.iter().sum(), N, byte_scaled);
    }
}

/// The rounded mean of `n` samples summing to `sum` (`(s + n / 2) / n`; a shift where `n` is a
/// power of two), for 8-bit samples stored ×257 the mean of the 8-bit values, stored ×257.
#[inline(always)]
fn block_mean(sum: u32, n: usize, byte_scaled: bool) -> u16 {
    let n = n as u32;
    let mean = |s: u32| if n.is_power_of_two() { (s + n / 2) >> n.trailing_zeros() } else { (s + n / 2) / n };
    if byte_scaled {
        (mean(sum / 257) * 257) as u16
    } else {
        mean(sum) as u16
    }
}

/// The largest [`radiometric_difference`] (8-bit grey levels) at which AD-census keeps its
/// intensity term. Measured on the seven Middlebury scenes (docs/robustness.md): clean pairs,
/// noise, JPEG, blur and misalignment stay at or below 6, while a 40 % vignetting in one view
/// reaches 13 or more, and exposure, gamma and bias changes 35 or more.
pub(crate) const MAX_RADIOMETRIC_DIFFERENCE: f32 = 9.0;

/// The largest [`CoarseMatch::census_residual`] (differing bits of the 9×7 census) of a clean
/// pair: measured 4–8 on the seven Middlebury scenes, 10–15 with noise σ 6 or a blur σ 1.5 in
/// one view (docs/robustness.md).
pub(crate) const CLEAN_CENSUS_RESIDUAL: f32 = 8.0;

/// The Gaussian σ (px) of the views census compares when [`CoarseMatch::census_residual`] exceeds
/// [`CLEAN_CENSUS_RESIDUAL`]: measured with σ 0.7 and 1.0 on noise σ 6, blur σ 1.5 and JPEG 50
/// pairs, 1.0 left the fewest scene × class pairs over the targets (docs/robustness.md).
pub(crate) const NOISY_CENSUS_SMOOTHING: f32 = 1.0;

/// The pair matched census-only at a quarter of the resolution (fast preset: 1/64 of the full
/// match's work): what the full match learns about the pair before it runs.
pub(crate) struct CoarseMatch {
    factor: usize,
    left: GrayImage,
    right: GrayImage,
    disparity: crate::DisparityMap,
}

impl CoarseMatch {
    /// `None` when the pair is too small to match at a quarter of its size. `sgm` is the matcher
    /// itself, passed in because it adapts to what this module measures (no import circle).
    pub(crate) fn new(
        left: &GrayImage,
        right: &GrayImage,
        params: &crate::SgmParams,
        sgm: impl FnOnce(&GrayImage, &GrayImage, &crate::SgmParams) -> Result<DisparityMap, crate::Error>,
    ) -> Option<Self> {
        let factor = 4;
        let (l, r) = (downsample(left, factor), downsample(right, factor));
        let (cw, ch) = l.size();
        let crate::DisparityRange { min, max } = reduced_range(params.range, factor);
        if cw < 16 || ch < 16 || (max - min) as usize > cw {
            return None;
        }
        let coarse = crate::SgmParams {
            range: crate::DisparityRange { min, max },
            matching_cost: crate::MatchingCost::Census,
            adapt_to_pair: false,
            paths: crate::PathCount::Four,
            single_pass: true,
            search: crate::Search::Full,
            downscale: crate::Downscale::By(1),
            edge_snap_radius: 0,
            fill: false,
            wmf_radius: 0,
            speckle_size: 0,
            confidence: false,
            max_memory: None,
            // The plain check: the tone fit, the clipping and the noise measurements want the
            // surest pairs, not the most pixels.
            lr_left_neighbour: false,
            ..params.clone()
        };
        let disparity = sgm(&l, &r, &coarse).ok()?;
        Some(CoarseMatch { factor, left: l, right: r, disparity })
    }

    /// The matched coarse pixels: `(x, y, right x)`.
    fn matches(&self) -> impl Iterator<Item = (usize, usize, usize)> + '_ {
        let (cw, ch) = self.left.size();
        (0..ch).flat_map(move |y| {
            (0..cw).filter_map(move |x| {
                let v = self.disparity.get(x, y);
                let xr = x as i64 - v.round() as i64;
                (v.is_finite() && (0..cw as i64).contains(&xr)).then_some((x, y, xr as usize))
            })
        })
    }

    /// How differently the two views render the same surfaces, in 8-bit grey levels: the grey-
    /// level differences of the matched pixels (the box average quiets the noise) per tile of a
    /// 3×3 grid; the largest tile median. A change of exposure, gamma or a vignetting shifts the
    /// medians; a misregistration only widens their spread. `None` when too little matched.
    /// With `correction`, the right view's levels are mapped onto the left's first: what is left
    /// of the difference after [`ToneCorrection::apply`].
    pub(crate) fn radiometric_difference(&self, correction: Option<&ToneCorrection>) -> Option<f32> {
        let (cw, ch) = self.left.size();
        let mut tiles: Vec<Vec<f32>> = vec![Vec::new(); 9];
        for ((x, y, _), s) in self.matches().zip(self.tone_samples()) {
            let b = correction.map_or(s.right, |c| c.predicted_left(&s));
            tiles[(y * 3 / ch) * 3 + x * 3 / cw].push(s.left - b);
        }
        let mut medians = Vec::new();
        for t in tiles.iter_mut().filter(|t| t.len() >= 20) {
            let mid = t.len() / 2;
            medians.push(t.select_nth_unstable_by(mid, f32::total_cmp).1.abs());
        }
        if medians.len() < 5 {
            return None;
        }
        medians.into_iter().max_by(f32::total_cmp)
    }

    /// The matched pixels' grey levels (8-bit units), at their positions in both views
    /// (normalised: the coarse match stands for the full-resolution views).
    pub(crate) fn tone_samples(&self) -> impl Iterator<Item = ToneSample> + '_ {
        let (cw, ch) = self.left.size();
        self.matches().map(move |(x, y, xr)| ToneSample {
            u: (xr as f32 + 0.5) / cw as f32,
            u_left: (x as f32 + 0.5) / cw as f32,
            v: (y as f32 + 0.5) / ch as f32,
            right: f32::from(self.right.get(xr, y)) / 257.0,
            left: f32::from(self.left.get(x, y)) / 257.0,
        })
    }

    /// How noisy the full-resolution census cost is at the true match: the median over the
    /// coarse matches of the smallest Hamming distance within ±`factor` px of the upsampled
    /// coarse disparity (the centre pixel of each coarse block). Sensor noise, JPEG and a
    /// one-sided blur raise it; texture alone barely does. `None` when too little matched.
    ///
    /// Measured both ways, each view's census against the other's nearby ones, and the larger
    /// median kept: the smallest of nine distances is smaller where the searched view is the
    /// sharper (its nearby codes differ more), so one way alone read a blurred left view 1–3 bits
    /// less noisy than the same blur in the right view (docs/robustness.md). Clean pairs read
    /// the same both ways.
    pub(crate) fn census_residual(&self, census_left: &Image<u64>, census_right: &Image<u64>) -> Option<f32> {
        let (w, h) = census_left.size();
        let f = self.factor as i64;
        let (mut forward, mut backward) = (Vec::new(), Vec::new());
        let nearest = |code: u64, other: &Image<u64>, x: i64, y: usize| {
            (x - f..=x + f)
                .filter(|&x| (0..w as i64).contains(&x))
                .map(|x| (code ^ other.get(x as usize, y)).count_ones())
                .min()
        };
        // Every other coarse pixel each way: the median needs a few thousand samples, and each
        // sample reads two census rows far apart (memory bound).
        for (x, y, _) in self.matches().filter(|&(x, y, _)| x % 2 == 0 && y % 2 == 0) {
            let (fx, fy) = (x as i64 * f + f / 2, y * self.factor + self.factor / 2);
            if fx >= w as i64 || fy >= h {
                continue;
            }
            let xr = fx - (self.disparity.get(x, y) * f as f32).round() as i64;
            forward.extend(nearest(census_left.get(fx as usize, fy), census_right, xr, fy));
            if (0..w as i64).contains(&xr) {
                backward.extend(nearest(census_right.get(xr as usize, fy), census_left, fx, fy));
            }
        }
        let median = |mut residuals: Vec<u32>| {
            let mid = residuals.len() / 2;
            (residuals.len() >= 50).then(|| *residuals.select_nth_unstable(mid).1 as f32)
        };
        let forward = median(forward)?;
        Some(median(backward).map_or(forward, |backward| forward.max(backward)))
    }
}

/// The smallest excess share of one view's pixels at the lowest (or highest) level over the
/// other view's read as clipping in that view only: clean pairs differ by less than 1 %, exposure
/// changes that clip 1–2 % are better served by the tone correction, from 4.6 % (gain 1.6) to
/// 35 % (bias −40) clipping the other view alike helped (docs/robustness.md).
pub(crate) const MIN_EXTRA_CLIPPED: f32 = 0.025;

/// Shadows or highlights one view clipped and the other did not (a bias or gain that pushed them
/// past black or white): census would read texture in one view against flat grey in the other.
/// Clipping the other view at the level below (above) which it holds the same share of its pixels
/// makes both flat there alike. Bounds `(low, high)` per view, 16-bit.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Clipping {
    left: (u16, u16),
    right: (u16, u16),
}

impl Clipping {
    /// `None` where neither view holds [`MIN_EXTRA_CLIPPED`] more of its pixels at 0 or 65535.
    pub(crate) fn matching(left: &GrayImage, right: &GrayImage, samples: &[ToneSample]) -> Option<Self> {
        let (hl, hr) = (histogram(left), histogram(right));
        let share = |h: &[f32; 256], lo: bool| if lo { h[0] } else { h[255] };
        let mut c = Clipping { left: (0, u16::MAX), right: (0, u16::MAX) };
        let mut any = false;
        for low in [true, false] {
            let (l, r) = (share(&hl, low), share(&hr, low));
            // The view with fewer clipped pixels is clipped at its level holding the other's share.
            let (bounds, h, target, right_clipped) = if r - l > MIN_EXTRA_CLIPPED {
                (&mut c.left, &hl, r, true)
            } else if l - r > MIN_EXTRA_CLIPPED {
                (&mut c.right, &hr, l, false)
            } else {
                continue;
            };
            any = true;
            // The other view's median level where the coarse match pairs it with clipped pixels;
            // the level holding the same share where too few matched.
            let clipped_at = |v: f32| if low { v < 0.5 } else { v > 254.5 };
            let mut levels: Vec<f32> = samples
                .iter()
                .filter_map(|s| {
                    let (this, other) = if right_clipped { (s.right, s.left) } else { (s.left, s.right) };
                    clipped_at(this).then_some(other)
                })
                .collect();
            let level = if levels.len() >= 20 {
                let mid = levels.len() / 2;
                (levels.select_nth_unstable_by(mid, f32::total_cmp).1.round() as u16) * 257
            } else {
                level_at_share(h, target, low)
            };
            if low {
                bounds.0 = level;
            } else {
                bounds.1 = level;
            }
        }
        any.then_some(c)
    }

    /// Both views clipped to their bounds.
    pub(crate) fn apply(&self, left: &GrayImage, right: &GrayImage) -> (GrayImage, GrayImage) {
        let clip = |image: &GrayImage, (lo, hi): (u16, u16)| {
            let (w, h) = image.size();
            GrayImage::from_vec(w, h, image.as_slice().iter().map(|&v| v.clamp(lo, hi)).collect())
                .expect("same size")
        };
        rayon::join(|| clip(left, self.left), || clip(right, self.right))
    }
}

/// Shares of the pixels per 8-bit level (16-bit samples binned by their high byte).
fn histogram(image: &GrayImage) -> [f32; 256] {
    let mut h = [0f32; 256];
    for &v in image.as_slice() {
        h[usize::from(v >> 8)] += 1.0;
    }
    let n = image.as_slice().len().max(1) as f32;
    h.map(|c| c / n)
}

/// The 16-bit level (an 8-bit level ×257) at or below which (`low`), or at or above which, the
/// histogram `h` holds `share` of the pixels.
fn level_at_share(h: &[f32; 256], share: f32, low: bool) -> u16 {
    let mut sum = 0.0;
    for i in 0..256 {
        let bin = if low { i } else { 255 - i };
        sum += h[bin];
        if sum >= share {
            return bin as u16 * 257;
        }
    }
    if low {
        u16::MAX
    } else {
        0
    }
}

/// JPEG's 8×8 block artefacts: the mean absolute step between neighbours across the block grid's
/// lines (every 8th column and row from the origin) over the mean step midway between them
/// (columns and rows 4 mod 8), sampled on every 4th row and column. 0.93–1.02 for the camera
/// images of the Middlebury scenes, 1.22–1.90 after JPEG at quality 50 (docs/robustness.md).
/// Compressed views carry their blocks at the same place in both images, which census reads as
/// texture at disparity 0.
pub(crate) fn blockiness(image: &GrayImage) -> f32 {
    let (w, h) = image.size();
    if w < 16 || h < 16 {
        return 1.0;
    }
    // Sums of |step| (16-bit units) on the grid lines and midway between them.
    let (mut on, mut off) = (0u64, 0u64);
    let step = |a: u16, b: u16| u64::from(a.abs_diff(b));
    for y in (0..h).step_by(4) {
        let row = image.row(y);
        for x in (8..w).step_by(8) {
            on += step(row[x], row[x - 1]);
            off += step(row[x - 4], row[x - 5]);
        }
    }
    for y in (8..h).step_by(8) {
        let (above, row) = (image.row(y - 1), image.row(y));
        let (mid_above, mid) = (image.row(y - 5), image.row(y - 4));
        for x in (0..w).step_by(4) {
            on += step(row[x], above[x]);
            off += step(mid[x], mid_above[x]);
        }
    }
    if off == 0 {
        return if on == 0 { 1.0 } else { f32::MAX };
    }
    (on as f64 / off as f64) as f32
}

/// A separable Gaussian blur (σ in pixels, radius 3σ, replicated borders) in full 16-bit
/// precision: what census compares on a noisy or one-sidedly blurred pair, so that single noisy
/// pixels flip fewer bits and the two views' sharpness is closer.
pub(crate) fn gaussian_blur(image: &GrayImage, sigma: f32) -> GrayImage {
    let (w, h) = image.size();
    let r = (3.0 * sigma).ceil() as usize;
    let kernel: Vec<f32> = (0..=2 * r)
        .map(|i| {
            let d = i as f32 - r as f32;
            (-d * d / (2.0 * sigma * sigma)).exp()
        })
        .collect();
    let total: f32 = kernel.iter().sum();
    let kernel: Vec<f32> = kernel.iter().map(|k| k / total).collect();
    let mut rows = vec![0f32; w * h];
    rows.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let src = image.row(y);
        for (x, o) in out.iter_mut().enumerate() {
            *o = kernel
                .iter()
                .enumerate()
                .map(|(i, k)| k * f32::from(src[(x + i).saturating_sub(r).min(w - 1)]))
                .sum();
        }
    });
    let mut data = vec![0u16; w * h];
    data.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        for (x, o) in out.iter_mut().enumerate() {
            let v: f32 = kernel
                .iter()
                .enumerate()
                .map(|(i, k)| k * rows[(y + i).saturating_sub(r).min(h - 1) * w + x])
                .sum();
            *o = v.round().clamp(0.0, 65535.0) as u16;
        }
    });
    GrayImage::from_vec(w, h, data).expect("same size")
}

/// An unsharp mask of amount 1, `2·image − blur(image, σ)` (clamped): the edges of a view blurred
/// by about σ steepened again. Applied to a defocused left view, whose blur would otherwise widen
/// every edge the map is drawn on (docs/robustness.md).
pub(crate) fn unsharp_mask(image: &GrayImage, sigma: f32) -> GrayImage {
    let blurred = gaussian_blur(image, sigma);
    let data = image
        .as_slice()
        .iter()
        .zip(blurred.as_slice())
        .map(|(&v, &b)| (2 * i32::from(v) - i32::from(b)).clamp(0, 65535) as u16)
        .collect();
    GrayImage::from_vec(image.width(), image.height(), data).expect("same size")
}

/// The smallest ratio of the two views' [`sharpness`] read as one view being defocused: clean
/// pairs measure 1.0–1.2 on the Middlebury scenes, a Gaussian blur σ 1.5 px in one view 3.8–10
/// (docs/robustness.md).
pub(crate) const MIN_SHARPNESS_RATIO: f64 = 2.0;

/// How much of the estimated relative blur the sharper view receives: on blur σ 1.5 pairs of the
/// seven scenes, 0.65 improved every scene's bad2 (default and `--fill`), 0.7–0.9 did not on
/// cones' `--fill`, 1.0 not on tsukuba (docs/robustness.md); the still slightly sharper view keeps
/// more texture for census.
pub(crate) const MATCHED_BLUR_FRACTION: f32 = 0.65;

/// Sharpness that no gain or bias changes: over tiles, the mean squared gradient (forward
/// differences) over the mean within-tile grey-level variance, away from a 6 px margin of each
/// tile (where a blur of the tile reads its replicated border). 0 for flat tiles. The tiles are
/// given by their [`tile_sums`].
fn sharpness(tiles: impl Iterator<Item = TileSums>) -> f64 {
    let (mut g, mut v2, mut n) = (0f64, 0f64, 0f64);
    for TileSums { gradient, sum, sum_sq, count } in tiles {
        // Integer sums below 2^53 convert exactly.
        let (s, s2, k) = (sum as f64, sum_sq as f64, count as f64);
        g += gradient as f64;
        if k > 0.0 {
            v2 += s2 - s * s / k;
            n += k;
        }
    }
    if n < 100.0 || v2 <= 0.0 {
        0.0
    } else {
        g / v2
    }
}

/// One tile's sums for [`sharpness`]: squared forward differences, samples, squared samples and
/// their count.
struct TileSums {
    gradient: u64,
    sum: u64,
    sum_sq: u64,
    count: u64,
}

/// [`TileSums`] of the `t`×`t` tile of `image` at `(x0, y0)`, read in place.
fn tile_sums(image: &GrayImage, x0: usize, y0: usize, t: usize) -> TileSums {
    let m = 6;
    let mut sums = TileSums { gradient: 0, sum: 0, sum_sq: 0, count: 0 };
    for y in m..t.saturating_sub(m) {
        let (row, below) = (&image.row(y0 + y)[x0..x0 + t], &image.row(y0 + y + 1)[x0..x0 + t]);
        for x in m..t.saturating_sub(m) {
            let v = i64::from(row[x]);
            let (dx, dy) = (i64::from(row[x + 1]) - v, i64::from(below[x]) - v);
            sums.gradient += (dx * dx + dy * dy) as u64;
            sums.sum += v as u64;
            sums.sum_sq += (v * v) as u64;
            sums.count += 1;
        }
    }
    sums
}

/// A one-sided defocus: when one view's [`sharpness`] exceeds the other's by
/// [`MIN_SHARPNESS_RATIO`] or more, which view is sharper (`true`: the left) and the Gaussian σ
/// (px) that brings it to the other's sharpness, found by bisection on a 3×3 grid of 80×80 px
/// tiles of both views (the same tiles in both). Census then compares views of similar sharpness.
pub(crate) fn relative_blur(left: &GrayImage, right: &GrayImage) -> Option<(bool, f32)> {
    let (w, h) = left.size();
    let t = 80.min(w / 3).min(h / 3);
    if t < 24 {
        return None;
    }
    let corners = (0..9).map(|i| ((i % 3) * (w - t) / 2, (i / 3) * (h - t) / 2));
    // Measured in place: most pairs stop at the ratio, and copies cost more than the sums.
    let sl = sharpness(corners.clone().map(|(x0, y0)| tile_sums(left, x0, y0, t)));
    let sr = sharpness(corners.clone().map(|(x0, y0)| tile_sums(right, x0, y0, t)));
    if sl <= 0.0 || sr <= 0.0 || sl.max(sr) / sl.min(sr) < MIN_SHARPNESS_RATIO {
        return None;
    }
    let (left_sharper, sharp, target) = if sl > sr { (true, left, sr) } else { (false, right, sl) };
    let tiles: Vec<GrayImage> =
        corners.map(|(x0, y0)| GrayImage::from_fn(t, t, |x, y| sharp.get(x0 + x, y0 + y))).collect();
    // Sharpness falls monotonically with σ.
    let (mut lo, mut hi) = (0.0f32, 4.0f32);
    for _ in 0..6 {
        let mid = 0.5 * (lo + hi);
        let blurred = tiles.iter().map(|tile| tile_sums(&gaussian_blur(tile, mid), 0, 0, t));
        if sharpness(blurred) > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some((left_sharper, 0.5 * (lo + hi)))
}

#[cfg(test)]
mod tests {
    use super::*;

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

        /// Every pair of column and row factors (square, the rows alone, the rows twice the
        /// columns' ...), 16-bit and 8-bit (×257) samples: the rounded mean of each whole block,
        /// summed plainly.
        #[test]
        fn downsample_is_the_rounded_block_mean(w in 1usize..40, h in 1usize..30, fx in 1usize..7, fy in 1usize..7, bytes in proptest::prelude::any::<bool>(), seed in proptest::prelude::any::<u64>()) {
            let mut s = seed | 1;
            let mut next = move || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s };
            let image = GrayImage::from_fn(w, h, |_, _| {
                let v = next() as u16;
                if bytes { (v & 0xff) * 257 } else { v }
            });
            let small = if fx == fy { downsample(&image, fx) } else { downsample_by(&image, fx, fy) };
            proptest::prop_assert_eq!(small.size(), (w / fx, h / fy));
            let n = (fx * fy) as u64;
            // (A small random 16-bit image can be ×257 throughout by chance.)
            let bytes = image.as_slice().iter().all(|&v| v >> 8 == v & 0xff);
            for (y, x) in (0..h / fy).flat_map(|y| (0..w / fx).map(move |x| (y, x))) {
                let sum: u64 = (0..fx * fy)
                    .map(|i| u64::from(image.get(x * fx + i % fx, y * fy + i / fx)))
                    .sum();
                let expected = if bytes { (sum / 257 + n / 2) / n * 257 } else { (sum + n / 2) / n };
                proptest::prop_assert_eq!(u64::from(small.get(x, y)), expected);
            }
        }
    }

    fn texture(w: usize, h: usize) -> GrayImage {
        GrayImage::from_fn(w, h, |x, y| {
            let v = (x as u64).wrapping_mul(0x9E37_79B9) ^ (y as u64).wrapping_mul(0x85EB_CA6B);
            ((v.wrapping_mul(0xC2B2_AE35) >> 20) & 0xff) as u16 * 257
        })
    }

    #[test]
    fn the_census_residual_does_not_depend_on_which_view_is_blurred() {
        // A "sharp" view whose census codes differ from pixel to pixel, and a "blurred" one whose
        // codes hold across runs of 8 pixels, 6 bits off the sharp view's code at each run's
        // start; matched at disparity 0. Searched in the sharp view, one of nine codes lies near;
        // searched in the blurred one, nearly none: one way alone read 6 against 20+ bits.
        let (w, h) = (128, 32);
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let sharp = Image::from_fn(w, h, |_, _| next() & 0xff_ffff_ffff);
        let blurred = Image::from_fn(w, h, |x, y| sharp.get(x - x % 8, y) ^ 0b11_1111);
        let grey = GrayImage::from_fn(w, h, |_, _| 100 * 257);
        let coarse = CoarseMatch {
            factor: 4,
            left: downsample(&grey, 4),
            right: downsample(&grey, 4),
            disparity: Image::new(w / 4, h / 4, 0.0),
        };
        let left_blurred = coarse.census_residual(&blurred, &sharp).expect("enough matches");
        let right_blurred = coarse.census_residual(&sharp, &blurred).expect("enough matches");
        assert_eq!(left_blurred, right_blurred);
        assert!(left_blurred > 12.0, "{left_blurred}");
    }

    #[test]
    fn the_view_clipped_less_is_clipped_alike() {
        let left = texture(200, 100);
        // Shadows below 40 and highlights above 235 clipped in the right view.
        let right = GrayImage::from_fn(200, 100, |x, y| {
            let v = u32::from((left.get(x, y) / 257).clamp(40, 235) - 40);
            ((v * 255 / 195) * 257) as u16
        });
        let c = Clipping::matching(&left, &right, &[]).expect("the right view is clipped");
        // The left view's levels holding the right's clipped shares: 40 and 235, up to the texture's
        // histogram steps.
        assert!((i32::from(c.left.0 / 257) - 40).abs() <= 2, "{c:?}");
        assert!((i32::from(c.left.1 / 257) - 235).abs() <= 2, "{c:?}");
        assert_eq!(c.right, (0, u16::MAX));
        // Matched pixels decide the level where there are enough.
        let samples: Vec<ToneSample> = (0..40)
            .map(|i| ToneSample { u: 0.5, u_left: 0.5, v: 0.5, left: 30.0 + (i % 3) as f32, right: 0.0 })
            .collect();
        let c = Clipping::matching(&left, &right, &samples).expect("the right view is clipped");
        assert_eq!(c.left.0, 31 * 257);
        // Views clipped alike (or not at all) are left alone.
        assert_eq!(Clipping::matching(&left, &left, &[]), None);
    }

    #[test]
    fn relative_blur_finds_the_defocused_view_and_its_sigma() {
        let sharp = texture(300, 240);
        let soft = gaussian_blur(&sharp, 1.5);
        let (left_sharper, sigma) = relative_blur(&sharp, &soft).expect("one view is blurred");
        assert!(left_sharper);
        assert!((sigma - 1.5).abs() < 0.2, "{sigma}");
        let (left_sharper, _) = relative_blur(&soft, &sharp).expect("one view is blurred");
        assert!(!left_sharper);
        // Equally sharp views, whatever their gain: nothing to match.
        let brighter = GrayImage::from_fn(300, 240, |x, y| sharp.get(x, y) / 2 + 1000);
        assert_eq!(relative_blur(&sharp, &brighter), None);
    }

    #[test]
    fn the_unsharp_mask_steepens_a_blurred_edge_and_keeps_flat_areas() {
        let step = GrayImage::from_fn(64, 8, |x, _| if x < 32 { 10_000 } else { 50_000 });
        let soft = gaussian_blur(&step, 1.5);
        let sharpened = unsharp_mask(&soft, 1.5);
        let steepest = |image: &GrayImage| {
            image.row(4).windows(2).map(|p| i32::from(p[1]) - i32::from(p[0])).max().unwrap()
        };
        // The blurred step rises about 10 400 from column 31 to 32; sharpened, 13 754.
        assert!(steepest(&soft) < 11_000 && steepest(&sharpened) > 13_000, "{}", steepest(&sharpened));
        // Far from the edge both sides keep their level.
        assert_eq!((sharpened.get(2, 4), sharpened.get(61, 4)), (10_000, 50_000));
        let bright = GrayImage::from_fn(64, 8, |x, _| if x < 32 { 0 } else { 65_535 });
        let sharpened = unsharp_mask(&gaussian_blur(&bright, 1.5), 1.5);
        // The overshoot beside a full-range edge is clipped, not wrapped round.
        let row = sharpened.row(4);
        assert!(row[..32].iter().all(|&v| v < 32_768) && row[32..].iter().all(|&v| v > 32_768));
        assert_eq!((row.iter().min(), row.iter().max()), (Some(&0), Some(&65_535)));
    }
}
