//! The right view's grey levels mapped onto the left's, learnt from the pair's own matches: a tone
//! curve (exposure, gain, gamma, bias) and a smooth attenuation field (vignetting). With it the AD term
//! of AD-census compares like with like on a pair whose views were exposed differently, instead
//! of being dropped (docs/robustness.md).

use rayon::prelude::*;

use crate::GrayImage;

/// One matched pixel pair, in 8-bit grey levels, at its positions in the right view (`u`, `v`)
/// and in the left one (`u_left`, `v`), normalised to `0..1` (so that a coarse match fits the
/// full-resolution views).
#[derive(Clone, Copy, Debug)]
pub(crate) struct ToneSample {
    pub u: f32,
    pub u_left: f32,
    pub v: f32,
    pub right: f32,
    pub left: f32,
}

/// Right-view levels over which [`ToneCorrection::expansion`] measures the curve's slope.
const STRETCH: usize = 16;
/// Quantiles the tone curve passes through.
const KNOTS: usize = 64;
/// Matched pairs the tone curve needs.
const MIN_SAMPLES: usize = 200;
/// Tiles per side of the grid whose median attenuations the smooth field is fitted to.
const GAIN_TILES: usize = 8;
/// Samples a tile needs for its median attenuation.
const MIN_TILE_SAMPLES: usize = 12;
/// Rounds of fitting the curve with the attenuation fixed, then the attenuation with the curve fixed.
const ROUNDS: usize = 3;

/// The shape of a vignetting: any quadratic surface, or radial about the centre of a `W×H`
/// image (`aspect` W/H).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Vignetting {
    Quadratic,
    Radial { aspect: f32 },
}

/// The view whose vignetting the attenuation follows, over its own positions. Each lens darkens
/// its own view's corners: an attenuation fitted over the right view's positions is off by each
/// pixel's disparity where the left view is the vignetted one (wood2, 112 disparities in 653
/// columns: bad2 20.0 against 13.9 with the right view vignetted alike; docs/robustness.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum AttenuatedView {
    Left,
    Right,
}

/// `left ≈ curve(right) / attenuation(u, v)`: the right view's tones mapped onto the left's. A
/// vignetting attenuates the light towards the corners about quadratically in the distance from
/// the centre, so the attenuation (not its inverse) is the quadratic surface.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct ToneCorrection {
    /// The left view's level for each right-view level `0..=255`.
    curve: [f32; 256],
    /// The right view's attenuation relative to the left's, `c0 + c1·u + c2·v + c3·u² + c4·v² +
    /// c5·u·v` (`u`, `v` centred, −0.5..0.5, positions in [`ToneCorrection::view`]).
    attenuation: [f32; 6],
    /// Where the attenuation's positions lie; with [`AttenuatedView::Left`], [`ToneCorrection::apply`]
    /// multiplies the left view by it instead of dividing the right one.
    view: AttenuatedView,
}

impl ToneCorrection {
    /// The correction fitted to `samples`, a vignetting (if any) over `view`'s positions; `None`
    /// when too few bins or tiles hold samples to fit.
    pub(crate) fn fit(
        samples: &[ToneSample],
        vignetting: Option<Vignetting>,
        view: AttenuatedView,
    ) -> Option<Self> {
        let samples: Vec<&ToneSample> =
            samples.iter().filter(|s| s.right.is_finite() && s.left.is_finite()).collect();
        if samples.len() < MIN_SAMPLES {
            return None;
        }
        // The right levels do not change between rounds: sorted once.
        let mut right: Vec<f32> = samples.iter().map(|s| s.right).collect();
        right.sort_unstable_by(f32::total_cmp);
        let mut correction = ToneCorrection {
            curve: std::array::from_fn(|i| i as f32),
            attenuation: [1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            view,
        };
        let left = |c: &ToneCorrection| samples.iter().map(|s| s.left * c.attenuation_at(s)).collect();
        for _ in 0..if vignetting.is_some() { ROUNDS } else { 0 } {
            correction.curve = fit_curve(&right, left(&correction))?;
            correction.attenuation = fit_attenuation(&samples, &correction.curve, vignetting?, view)?;
        }
        correction.curve = fit_curve(&right, left(&correction))?;
        Some(correction)
    }

    /// The attenuation at normalised position `(u, v)`.
    fn attenuation(&self, u: f32, v: f32) -> f32 {
        let (x, y) = (u - 0.5, v - 0.5);
        let g = &self.attenuation;
        // A wild fit far from the samples must not flip or zero the levels.
        (g[0] + g[1] * x + g[2] * y + g[3] * x * x + g[4] * y * y + g[5] * x * y).max(0.05)
    }

    /// The attenuation at a sample's position in [`ToneCorrection::view`].
    fn attenuation_at(&self, s: &ToneSample) -> f32 {
        self.attenuation(position(s, self.view), s.v)
    }

    /// The left view's level (8-bit units) the correction predicts for a sample's right level.
    pub(crate) fn predicted_left(&self, s: &ToneSample) -> f32 {
        (self.curve_at(s.right) / self.attenuation_at(s)).clamp(0.0, 255.0)
    }

    /// The median of `|predicted − left|` over the samples neither view holds clipped (8-bit
    /// levels); `None` without such samples.
    pub(crate) fn median_residual(&self, samples: &[ToneSample]) -> Option<f32> {
        let unclipped = |l: f32| l > 2.0 && l < 253.0;
        let mut residuals: Vec<f32> = samples
            .iter()
            .filter(|s| unclipped(s.right) && unclipped(s.left))
            .map(|s| (self.predicted_left(s) - s.left).abs())
            .collect();
        let mid = residuals.len() / 2;
        (!residuals.is_empty()).then(|| *residuals.select_nth_unstable_by(mid, f32::total_cmp).1)
    }

    /// The curve at a fractional right-view level (8-bit units).
    fn curve_at(&self, level: f32) -> f32 {
        let l = level.clamp(0.0, 255.0);
        let i = (l as usize).min(254);
        let t = l - i as f32;
        self.curve[i] + t * (self.curve[i + 1] - self.curve[i])
    }

    /// The largest local slope of the curve between the 1st and the 99th percentile of the
    /// matched right levels (over [`STRETCH`]-level stretches): how much the correction stretches the right
    /// view's levels apart, and with them its quantisation steps and noise.
    pub(crate) fn expansion(&self, samples: &[ToneSample]) -> f32 {
        let (lo, hi) = level_span(samples);
        (lo..hi.saturating_sub(STRETCH).max(lo + 1).min(255))
            .map(|r| {
                let end = (r + STRETCH).min(255);
                (self.curve[end] - self.curve[r]) / (end - r) as f32
            })
            .fold(0.0, f32::max)
    }

    /// How far the curve is from a straight line between the 1st and the 99th percentile of the
    /// matched right levels: the largest deviation (8-bit levels) from its least-squares line.
    /// A gain, a bias or a vignetting is a straight line; a gamma is not.
    pub(crate) fn nonlinearity(&self, samples: &[ToneSample]) -> f32 {
        let (lo, hi) = level_span(samples);
        let points: Vec<(f64, f64)> = (lo..=hi).map(|r| (r as f64, f64::from(self.curve[r]))).collect();
        let n = points.len() as f64;
        let (mx, my) =
            (points.iter().map(|p| p.0).sum::<f64>() / n, points.iter().map(|p| p.1).sum::<f64>() / n);
        let sxx: f64 = points.iter().map(|p| (p.0 - mx) * (p.0 - mx)).sum();
        let sxy: f64 = points.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
        let slope = if sxx > 0.0 { sxy / sxx } else { 0.0 };
        points.iter().map(|p| (p.1 - my - slope * (p.0 - mx)).abs()).fold(0.0, f64::max) as f32
    }

    /// The views as the intensity term compares them: the right one mapped by the curve onto the
    /// left's tones, and the attenuation undone where it lies, dividing the right view or
    /// multiplying the left one (`None`: the left view as given). Each in its own scale (8-bit
    /// levels stored ×257 stay so).
    pub(crate) fn apply(&self, left: &GrayImage, right: &GrayImage) -> (Option<GrayImage>, GrayImage) {
        let in_right = self.view == AttenuatedView::Right;
        let right = map_view(right, |level, u, v| {
            let c = self.curve_at(level);
            if in_right {
                c / self.attenuation(u, v)
            } else {
                c
            }
        });
        let left = (!in_right).then(|| map_view(left, |level, u, v| level * self.attenuation(u, v)));
        (left, right)
    }
}

/// A sample's position along the rows in `view`.
fn position(s: &ToneSample, view: AttenuatedView) -> f32 {
    match view {
        AttenuatedView::Left => s.u_left,
        AttenuatedView::Right => s.u,
    }
}

/// `image` with every sample mapped by `f(level, u, v)` (8-bit units, normalised position),
/// clamped to `0..=255`, in `image`'s scale.
fn map_view(image: &GrayImage, f: impl Fn(f32, f32, f32) -> f32 + Sync) -> GrayImage {
    let (w, h) = image.size();
    let byte_scaled = crate::census::is_byte_scaled(image);
    let mut data = vec![0u16; w * h];
    data.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let v = (y as f32 + 0.5) / h as f32;
        for (x, (o, &r)) in out.iter_mut().zip(image.row(y)).enumerate() {
            let l = f(f32::from(r) / 257.0, (x as f32 + 0.5) / w as f32, v).clamp(0.0, 255.0);
            *o = if byte_scaled { l.round() as u16 * 257 } else { (l * 257.0).round() as u16 };
        }
    });
    GrayImage::from_vec(w, h, data).expect("same size")
}

/// The 1st and the 99th percentile of the samples' right levels (whole levels, at least one apart).
fn level_span(samples: &[ToneSample]) -> (usize, usize) {
    let mut levels: Vec<f32> = samples.iter().map(|s| s.right).collect();
    if levels.is_empty() {
        return (0, 255);
    }
    let n = levels.len();
    let lo = *levels.select_nth_unstable_by(n / 100, f32::total_cmp).1;
    let hi = *levels.select_nth_unstable_by(n - 1 - n / 100, f32::total_cmp).1;
    let lo = (lo.round() as usize).min(254);
    (lo, (hi.round() as usize).clamp(lo + 1, 255))
}

/// The monotone curve that maps the right levels of matched pairs (`right`, sorted) onto their
/// left levels (`left`, in any order) of the same rank (quantile matching: the matched pixels
/// show both views the same surfaces, so their two level distributions differ only by the curve,
/// and mismatched pairs, which blur a per-level median towards the mean, barely move the
/// quantiles); linear between [`KNOTS`] quantiles and beyond them with the mean slope of the
/// outermost few. `None` where the quantiles
/// hold fewer than two right levels.
fn fit_curve(right: &[f32], mut left: Vec<f32>) -> Option<[f32; 256]> {
    left.sort_unstable_by(f32::total_cmp);
    let n = right.len();
    // Knots: (right level, left level), one per quantile; equal right levels merged.
    let mut knots: Vec<(f32, f32)> = Vec::with_capacity(KNOTS);
    let mut merged = 1.0;
    for k in 0..KNOTS {
        let i = ((k as f32 + 0.5) / KNOTS as f32 * n as f32) as usize;
        let (r, l) = (right[i.min(n - 1)], left[i.min(n - 1)]);
        match knots.last_mut() {
            Some(last) if last.0 == r => {
                merged += 1.0;
                last.1 += (l - last.1) / merged;
            }
            _ => {
                knots.push((r, l));
                merged = 1.0;
            }
        }
    }
    if knots.len() < 2 {
        return None;
    }
    let at = |k: usize| knots[k];
    let slope =
        |a: (f32, f32), b: (f32, f32)| if b.0 > a.0 { ((b.1 - a.1) / (b.0 - a.0)).max(0.0) } else { 0.0 };
    let n = knots.len();
    // Beyond the knots: the mean slope over the outermost few (one stretch is noisy where few
    // samples are).
    let reach = 3.min(n - 1);
    let (low, high) = (slope(at(0), at(reach)), slope(at(n - 1 - reach), at(n - 1)));
    let mut curve = [0f32; 256];
    let mut k = 0;
    for (level, c) in curve.iter_mut().enumerate() {
        let x = level as f32;
        *c = if x <= knots[0].0 {
            knots[0].1 - low * (knots[0].0 - x)
        } else if x >= knots[n - 1].0 {
            knots[n - 1].1 + high * (x - knots[n - 1].0)
        } else {
            while knots[k + 1].0 < x {
                k += 1;
            }
            let (a, b) = (at(k), at(k + 1));
            a.1 + slope(a, b) * (x - a.0)
        };
        // Not capped at 255: the attenuation may scale the curve's levels down again.
        *c = c.max(0.0);
    }
    Some(curve)
}

/// The attenuation: the median of `curve(right) / left` per tile of a [`GAIN_TILES`]² grid, then
/// the quadratic surface through the tiles' medians (least squares weighted by their samples),
/// scaled to 1 at the median tile. `None` when fewer than 6 tiles have samples.
fn fit_attenuation(
    samples: &[&ToneSample],
    curve: &[f32; 256],
    model: Vignetting,
    view: AttenuatedView,
) -> Option<[f32; 6]> {
    let n = GAIN_TILES;
    let mut tiles: Vec<Vec<f32>> = vec![Vec::new(); n * n];
    // Each tile's sample positions summed: its median stands at their centroid, not at the tile's
    // centre (matches gather where the texture is, and the attenuation changes across a tile).
    let mut centroids = vec![(0f64, 0f64); n * n];
    for s in samples {
        // Clipped or nearly black samples say nothing about the attenuation.
        let c = curve[(s.right.round() as usize).min(255)];
        if s.right > 2.0 && s.right < 253.0 && s.left >= 16.0 {
            let u = position(s, view);
            let (tx, ty) = (((u * n as f32) as usize).min(n - 1), ((s.v * n as f32) as usize).min(n - 1));
            tiles[ty * n + tx].push(c / s.left);
            centroids[ty * n + tx].0 += f64::from(u);
            centroids[ty * n + tx].1 += f64::from(s.v);
        }
    }
    // Rows of the normal equations: (u, v, median attenuation, weight).
    let mut points = Vec::new();
    for (t, &(su, sv)) in tiles.iter_mut().zip(&centroids) {
        if t.len() >= MIN_TILE_SAMPLES {
            let (u, v) = ((su / t.len() as f64) as f32, (sv / t.len() as f64) as f32);
            let mid = t.len() / 2;
            let g = *t.select_nth_unstable_by(mid, f32::total_cmp).1;
            points.push((u - 0.5, v - 0.5, g, t.len() as f32));
        }
    }
    if points.len() < 6 {
        return None;
    }
    let basis = |x: f32, y: f32| [1.0, x, y, x * x, y * y, x * y];
    let mut coefficients = match model {
        Vignetting::Quadratic => {
            let mut a = [[0f64; 7]; 6];
            for &(x, y, g, w) in &points {
                let b = basis(x, y);
                for r in 0..6 {
                    for c in 0..6 {
                        a[r][c] += f64::from(w * b[r] * b[c]);
                    }
                    a[r][6] += f64::from(w * b[r] * g);
                }
            }
            solve(a)?
        }
        Vignetting::Radial { aspect } => {
            // `c0 + k·ρ²`, ρ² = 4(x²·A² + y²)/(A² + 1): 1 at the corners of a W×H image, A = W/H.
            let a2 = aspect * aspect;
            let (sx, sy) = (4.0 * a2 / (a2 + 1.0), 4.0 / (a2 + 1.0));
            let (mut s00, mut s01, mut s11, mut t0, mut t1) = (0f64, 0f64, 0f64, 0f64, 0f64);
            for &(x, y, g, w) in &points {
                let (r, w, g) = (f64::from(sx * x * x + sy * y * y), f64::from(w), f64::from(g));
                s00 += w;
                s01 += w * r;
                s11 += w * r * r;
                t0 += w * g;
                t1 += w * g * r;
            }
            let det = s00 * s11 - s01 * s01;
            if det.abs() < 1e-12 {
                return None;
            }
            let (c0, k) = (((t0 * s11 - t1 * s01) / det) as f32, ((s00 * t1 - s01 * t0) / det) as f32);
            [c0, 0.0, 0.0, k * sx, k * sy, 0.0]
        }
    };
    let mut fitted: Vec<f32> = points
        .iter()
        .map(|&(x, y, _, _)| basis(x, y).iter().zip(&coefficients).map(|(b, c)| b * c).sum())
        .collect();
    let mid = fitted.len() / 2;
    let scale = *fitted.select_nth_unstable_by(mid, f32::total_cmp).1;
    if scale.is_nan() || scale <= 0.0 {
        return None;
    }
    for c in &mut coefficients {
        *c /= scale;
    }
    Some(coefficients)
}

/// Gaussian elimination with partial pivoting of the augmented 6×7 system; `None` if singular.
fn solve(mut a: [[f64; 7]; 6]) -> Option<[f32; 6]> {
    for col in 0..6 {
        let pivot = (col..6).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[pivot][col].abs() < 1e-12 {
            return None;
        }
        a.swap(col, pivot);
        let pivot_row = a[col];
        for (row, r) in a.iter_mut().enumerate() {
            if row != col {
                let f = r[col] / pivot_row[col];
                for (v, p) in r[col..].iter_mut().zip(&pivot_row[col..]) {
                    *v -= f * p;
                }
            }
        }
    }
    Some(std::array::from_fn(|i| (a[i][6] / a[i][i]) as f32))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples of a textured scene on a 60×40 grid: the right view rendered by `render`.
    fn samples(render: impl Fn(f32, f32, f32) -> f32) -> Vec<ToneSample> {
        let mut out = Vec::new();
        for y in 0..40 {
            for x in 0..60 {
                let (u, v) = ((x as f32 + 0.5) / 60.0, (y as f32 + 0.5) / 40.0);
                let h = (x as u32).wrapping_mul(2_654_435_761) ^ (y as u32).wrapping_mul(2_246_822_519);
                let left = 10.0 + (h >> 8) as f32 % 236.0;
                let right = render(left, u, v).round().clamp(0.0, 255.0);
                out.push(ToneSample { u, u_left: u, v, left, right });
            }
        }
        out
    }

    /// The largest error of the corrected levels against the left levels, where one right level
    /// stands for at most `spread` left levels (elsewhere the rounding of the right view, not the
    /// fit, limits the accuracy); unclipped samples only.
    fn worst_error(s: &[ToneSample], c: &ToneCorrection) -> f32 {
        s.iter()
            .filter(|s| s.right > 0.0 && s.right < 255.0)
            .map(|s| (c.predicted_left(s) - s.left).abs())
            .fold(0.0, f32::max)
    }

    #[test]
    fn gain_and_bias_are_undone_and_read_as_straight() {
        for render in [&(|l: f32, _, _| l * 0.6) as &dyn Fn(f32, f32, f32) -> f32, &|l, _, _| 0.8 * l + 40.0]
        {
            let s = samples(render);
            let c = ToneCorrection::fit(&s, None, AttenuatedView::Right).expect("enough samples");
            // A right level stands for up to 1.7 left levels at gain 0.6.
            assert!(worst_error(&s, &c) < 2.0, "{}", worst_error(&s, &c));
            assert!(c.nonlinearity(&s) < 2.0, "{}", c.nonlinearity(&s));
        }
        let c = ToneCorrection::fit(&samples(|l, _, _| l * 0.6), None, AttenuatedView::Right)
            .expect("enough samples");
        let expansion = c.expansion(&samples(|l, _, _| l * 0.6));
        assert!((expansion - 1.0 / 0.6).abs() < 0.2, "{expansion}");
    }

    #[test]
    fn a_gamma_is_undone_where_the_levels_allow_and_reads_as_curved() {
        for (gamma, curved) in [(2.0f32, 35.0), (0.5, 25.0)] {
            let s = samples(|l, _, _| 255.0 * (l / 255.0).powf(gamma));
            let c = ToneCorrection::fit(&s, None, AttenuatedView::Right).expect("enough samples");
            // Above left level 60 a right level stands for at most 2 left levels.
            let worst = s
                .iter()
                .filter(|s| s.left > 60.0)
                .map(|s| (c.predicted_left(s) - s.left).abs())
                .fold(0.0, f32::max);
            assert!(worst < 3.0, "gamma {gamma}: {worst}");
            assert!(c.nonlinearity(&s) > curved, "gamma {gamma}: {}", c.nonlinearity(&s));
        }
    }

    #[test]
    fn vignetting_is_undone() {
        // 40 % fall-off at the corners, as `stereo-degrade` makes it.
        let s = samples(|l, u, v| l * (1.0 - 0.4 * ((u - 0.5).powi(2) + (v - 0.5).powi(2)) / 0.5));
        let c = ToneCorrection::fit(&s, Some(Vignetting::Quadratic), AttenuatedView::Right)
            .expect("enough samples");
        assert!(worst_error(&s, &c) < 3.0, "{}", worst_error(&s, &c));
        // A radial fall-off about the centre (the samples' grid is square in u, v).
        let radial = ToneCorrection::fit(&s, Some(Vignetting::Radial { aspect: 1.0 }), AttenuatedView::Right)
            .expect("enough samples");
        assert!(worst_error(&s, &radial) < 3.0, "{}", worst_error(&s, &radial));
        // The curve alone cannot follow it.
        let curve_only = ToneCorrection::fit(&s, None, AttenuatedView::Right).expect("enough samples");
        assert!(worst_error(&s, &curve_only) > 20.0, "{}", worst_error(&s, &curve_only));
        // The views alike: the identity, up to the fit.
        let s = samples(|l, _, _| l);
        let c = ToneCorrection::fit(&s, Some(Vignetting::Quadratic), AttenuatedView::Right)
            .expect("enough samples");
        assert!(worst_error(&s, &c) < 1.5, "{}", worst_error(&s, &c));
    }

    #[test]
    fn vignetting_is_undone_where_the_matches_cluster() {
        // Matches only in the top-left 12×8 of every 30×20 block of a 120×80 grid (texture in
        // patches): each tile's median then belongs to its samples' centroid, not to its centre.
        let mut s = Vec::new();
        for (x, y) in (0..80).flat_map(|y| (0..120).map(move |x| (x, y))) {
            if x % 30 < 12 && y % 20 < 8 {
                let (u, v) = ((x as f32 + 0.5) / 120.0, (y as f32 + 0.5) / 80.0);
                let h = (x as u32).wrapping_mul(2_654_435_761) ^ (y as u32).wrapping_mul(2_246_822_519);
                let left = 10.0 + (h >> 8) as f32 % 236.0;
                let right = left * (1.0 - 0.4 * ((u - 0.5).powi(2) + (v - 0.5).powi(2)) / 0.5);
                s.push(ToneSample { u, u_left: u, v, left, right: right.round() });
            }
        }
        let c = ToneCorrection::fit(&s, Some(Vignetting::Quadratic), AttenuatedView::Right)
            .expect("enough samples");
        // 22 grey levels with the medians at the tiles' centres.
        assert!(worst_error(&s, &c) < 2.0, "{}", worst_error(&s, &c));
    }

    #[test]
    fn a_vignetted_left_view_is_fitted_over_its_own_positions() {
        // The left view vignetted 40 % at the corners, the right one brighter by 1.3; each match
        // lies 5–25 % of the width to the right in the left view (its disparity).
        let mut s = Vec::new();
        for (x, y) in (0..80).flat_map(|y| (0..120).map(move |x| (x, y))) {
            let h = (x as u32).wrapping_mul(2_654_435_761) ^ (y as u32).wrapping_mul(2_246_822_519);
            let (u, v) = ((x as f32 + 0.5) / 120.0, (y as f32 + 0.5) / 80.0);
            let u_left = u + 0.05 + 0.2 * ((h >> 4) % 100) as f32 / 100.0;
            if u_left >= 1.0 {
                continue;
            }
            let surface = 10.0 + (h >> 8) as f32 % 180.0;
            let left = surface * (1.0 - 0.4 * ((u_left - 0.5).powi(2) + (v - 0.5).powi(2)) / 0.5);
            s.push(ToneSample { u, u_left, v, left: left.round(), right: (1.3 * surface).round() });
        }
        // The 90th percentile: the fit extrapolates into the left view's sparsely matched far
        // corners either way.
        let worst = |view| {
            let c = ToneCorrection::fit(&s, Some(Vignetting::Quadratic), view).expect("enough samples");
            let mut errors: Vec<f32> = s.iter().map(|t| (c.predicted_left(t) - t.left).abs()).collect();
            let at = errors.len() * 9 / 10;
            *errors.select_nth_unstable_by(at, f32::total_cmp).1
        };
        let (left, right) = (worst(AttenuatedView::Left), worst(AttenuatedView::Right));
        // Measured: 1.6 against 4.5 grey levels.
        assert!(left < 2.0, "left {left}");
        assert!(right > 2.5 * left, "right {right}, left {left}");
        // Applied, the left view is brightened towards its corners and the right one only mapped
        // by the curve: the same surface (77 near the left's corner, at u 0.15, v 0.1: 100
        // vignetted by 0.77) then reads alike in both views, there and at the centre.
        let c = ToneCorrection::fit(&s, Some(Vignetting::Quadratic), AttenuatedView::Left).expect("fit");
        let left_view =
            GrayImage::from_fn(100, 60, |x, y| if (x, y) == (15, 6) { 77 * 257 } else { 100 * 257 });
        let right_view = GrayImage::from_fn(100, 60, |_, _| 130 * 257);
        let (corrected_left, corrected_right) = c.apply(&left_view, &right_view);
        let corrected_left = corrected_left.expect("the left view carries the attenuation");
        let (corner, centre) = (corrected_left.get(15, 6) / 257, corrected_left.get(50, 30) / 257);
        let right_level = corrected_right.get(7, 7) / 257;
        assert!(corner.abs_diff(right_level) <= 2, "corner {corner}, right {right_level}");
        assert!(centre.abs_diff(right_level) <= 2, "centre {centre}, right {right_level}");
    }

    #[test]
    fn the_applied_correction_keeps_the_scale() {
        let c = ToneCorrection::fit(&samples(|l, _, _| l * 0.5), None, AttenuatedView::Right)
            .expect("enough samples");
        let right = GrayImage::from_fn(16, 8, |x, _| (x as u16 * 8) * 257);
        let (left, out) = c.apply(&right, &right);
        assert!(left.is_none(), "no vignetting: the left view stays as given");
        assert!(out.as_slice().iter().all(|&v| v % 257 == 0));
        assert!((i32::from(out.get(15, 4) / 257) - 240).abs() <= 2, "{}", out.get(15, 4) / 257);
        // 16-bit views stay 16-bit.
        let deep = GrayImage::from_fn(16, 8, |x, _| x as u16 * 2000 + 7);
        let (_, out) = c.apply(&deep, &deep);
        assert!((f32::from(out.get(10, 4)) - 2.0 * 20007.0).abs() < 2.0 * 257.0, "{}", out.get(10, 4));
    }

    #[test]
    fn too_few_samples_fit_nothing() {
        let s = samples(|l, _, _| l);
        assert!(ToneCorrection::fit(&s[..MIN_SAMPLES - 1], None, AttenuatedView::Right).is_none());
    }
}
