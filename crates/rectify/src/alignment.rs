//! Residual vertical misalignment of a rectified pair, measured on matched patches.
//!
//! Well-textured patches of the left view are matched in the right view over horizontal
//! disparities and small vertical offsets (coarse at half resolution, then ZNCC at full resolution
//! and a Lucas–Kanade refinement with a gain and bias, so exposure differences do not bias the
//! offset). A robust line `dy = a + b·(x_r − cx)` through the offsets gives the offset at the
//! centre (`a`) and the rotation of the right view (`b = sin θ`).

use rayon::prelude::*;
use stereo_image::{DisparityRange, GrayImage};

/// Below this largest |offset| (px) a pair counts as aligned: matching along rows loses nothing
/// measurable. Published, carefully rectified pairs reach 0.25 px at their edges (Middlebury
/// reindeer: 0.15 px at the centre, confirmed by warping with its ground truth), so a tighter
/// limit would resample pairs that need nothing.
const ALIGNED_PX: f32 = 0.3;
/// Up to this largest |offset| (px) resampling the right view restores matching along rows.
const COMPENSABLE_PX: f32 = 1.5;
/// Fewest reliable patches behind a verdict.
const MIN_PATCHES: usize = 24;
/// Patches tried first, spread over the image: enough for offsets to a few hundredths of a pixel
/// at a bounded cost on large images.
const FIRST_PATCHES: usize = 192;
/// Below this many matches from the first patches, the remaining ones are tried too.
const WANTED_MATCHES: usize = 64;
/// Largest vertical offset searched, px.
const MAX_DY: i32 = 3;
/// Half-size of the full-resolution patch (15×15).
const RADIUS: usize = 7;
/// Half-size of the coarse patch at half resolution (9×9, about 18×18 full-resolution pixels).
const COARSE_RADIUS: usize = 4;
/// Vertical offsets of the coarse search at half resolution: ±2 covers ±3 px with a margin.
const COARSE_DY: i32 = 2;
/// A coarse match must correlate at least this well (ZNCC) ...
const MIN_COARSE_ZNCC: f32 = 0.8;
/// ... and beat every disparity more than [`AMBIGUITY_GAP`] half-resolution px away by this much,
/// so repetitive texture does not vote.
const MIN_COARSE_MARGIN: f32 = 0.05;
const AMBIGUITY_GAP: usize = 2;
/// The refined match must correlate at least this well.
const MIN_FINE_ZNCC: f32 = 0.9;
/// Mean squared gradient (grey levels of 8 bits per pixel, squared) below which a patch is too
/// flat for a vertical offset to be measured: about 2 levels per pixel.
const MIN_STRUCTURE: f64 = (2.0 / 255.0) * (2.0 / 255.0);
/// Full-resolution rows kept clear of the top and bottom: the coarse window with its vertical
/// search, and the refinement's window with its gradient and interpolation margins.
const MARGIN_Y: usize = 16;
const MARGIN_X: usize = 10;

/// How well the rows of a pair line up.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AlignmentVerdict {
    /// Under 0.3 px everywhere: nothing to correct.
    Aligned,
    /// Up to 1.5 px somewhere: resampling the right view ([`compensate`]) restores matching.
    Misaligned,
    /// Beyond 1.5 px somewhere: compensation helps, but the rectification should be redone.
    BadlyMisaligned,
    /// Too few reliable patches (flat or repetitive images, or not a stereo pair).
    Unknown,
}

impl AlignmentVerdict {
    /// The verdict as one lowercase word, as reports print it.
    pub fn as_str(self) -> &'static str {
        match self {
            AlignmentVerdict::Aligned => "aligned",
            AlignmentVerdict::Misaligned => "misaligned",
            AlignmentVerdict::BadlyMisaligned => "badly_misaligned",
            AlignmentVerdict::Unknown => "unknown",
        }
    }
}

/// The measured residual vertical misalignment of the right view against the left view.
///
/// The left pixel `(x, y)` is found in the right view at `(x − d, y + dy)`, with
/// `dy = vertical_offset_px + sin(rotation_deg)·(x − d − cx)` (`cx` the centre column): positive
/// offsets mean the right view shows the scene lower than the left view, and a positive rotation
/// means its right side is lower (clockwise on screen).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Alignment {
    /// Vertical offset at the image centre, px.
    pub vertical_offset_px: f32,
    /// Rotation of the right view about the image centre, degrees.
    pub rotation_deg: f32,
    /// Largest |vertical offset| over the image, px.
    pub max_abs_offset_px: f32,
    /// Reliable patches behind the estimate (the inliers of the fit).
    pub patches_used: usize,
    /// Share of the reliable patches whose best disparity is negative: most of them means the
    /// left and right views look swapped.
    pub negative_disparity_share: f32,
    pub verdict: AlignmentVerdict,
}

impl Alignment {
    /// No measurement: zero offsets, verdict [`AlignmentVerdict::Unknown`].
    fn unknown(patches_used: usize, negative_disparity_share: f32) -> Self {
        Alignment {
            vertical_offset_px: 0.0,
            rotation_deg: 0.0,
            max_abs_offset_px: 0.0,
            patches_used,
            negative_disparity_share,
            verdict: AlignmentVerdict::Unknown,
        }
    }

    /// The vertical offset at right-view column `x` of an image `width` pixels wide.
    fn offset_at(&self, x: f64, width: usize) -> f64 {
        let cx = (width as f64 - 1.0) / 2.0;
        self.vertical_offset_px as f64 + (self.rotation_deg as f64).to_radians().sin() * (x - cx)
    }
}

/// Measures the residual vertical misalignment of `right` against `left` from the images.
///
/// `range` is the disparity range the pair will be matched over; the check searches the
/// symmetric range `−D..=D` (`D` the larger of `|min|` and `|max|`) so it can also tell a pair
/// whose matches want negative disparities (swapped views). Images of different sizes, or too
/// small or flat to measure, give [`AlignmentVerdict::Unknown`].
pub fn estimate_alignment(left: &GrayImage, right: &GrayImage, range: DisparityRange) -> Alignment {
    let (width, height) = left.size();
    if right.size() != left.size() || width < 2 * MARGIN_X + 8 || height < 2 * MARGIN_Y + 8 {
        return Alignment::unknown(0, 0.0);
    }
    // Full resolution is only read around the patches: converting the whole images would cost
    // more than the matches themselves.
    let left_full = Full::new(left);
    let right_full = Full::new(right);
    // The left view's half-resolution plane and its patches beside the right view's plane.
    let ((left_half, (first, rest)), right_half) = rayon::join(
        || {
            let half = Plane::half(left);
            let patches = select_patches(&half);
            (half, patches)
        },
        || Plane::half(right),
    );
    let reach = range.min.unsigned_abs().max(range.max.unsigned_abs()).min(width as u32) as i32;
    let coarse_reach = (reach + 1) / 2 + 1;

    let match_patch = |&(x, y): &(usize, usize)| {
        let coarse = CoarseSearch { left: &left_half, right: &right_half };
        let (d, dy) = coarse.best(x / 2, y / 2, coarse_reach)?;
        let (xr, dy) = fine_search(&left_full, &right_full, x, y, x as i32 - 2 * d, 2 * dy)?;
        refine(&left_full, &right_full, x, y, xr, dy)
    };
    // One patch is a few microseconds of work: rayon's splitting keeps the units large enough.
    let mut matches: Vec<PatchMatch> = first.par_iter().filter_map(match_patch).collect();
    if matches.len() < WANTED_MATCHES && !rest.is_empty() {
        // Too few of the spread subset matched (weak or repetitive texture): try the others.
        matches.par_extend(rest.par_iter().filter_map(match_patch));
    }

    let negative = matches.iter().filter(|m| m.disparity < -0.5).count();
    let negative_disparity_share =
        if matches.is_empty() { 0.0 } else { negative as f32 / matches.len() as f32 };
    if matches.len() < MIN_PATCHES {
        return Alignment::unknown(matches.len(), negative_disparity_share);
    }
    let cx = (width as f64 - 1.0) / 2.0;
    let fit = robust_line(&matches, cx);
    if fit.inliers < MIN_PATCHES {
        return Alignment::unknown(fit.inliers, negative_disparity_share);
    }
    // The model is linear in x: the largest |offset| is at the left or right edge.
    let max_abs_offset_px = (fit.offset.abs() + fit.slope.abs() * cx) as f32;
    let verdict = if max_abs_offset_px < ALIGNED_PX {
        AlignmentVerdict::Aligned
    } else if max_abs_offset_px <= COMPENSABLE_PX {
        AlignmentVerdict::Misaligned
    } else {
        AlignmentVerdict::BadlyMisaligned
    };
    Alignment {
        vertical_offset_px: fit.offset as f32,
        rotation_deg: fit.slope.clamp(-1.0, 1.0).asin().to_degrees() as f32,
        max_abs_offset_px,
        patches_used: fit.inliers,
        negative_disparity_share,
        verdict,
    }
}

/// The right view resampled along columns so that its rows line up with the left view: output
/// pixel `(x, y)` is the right view at `(x, y + dy(x))` (Catmull–Rom cubic along `y`, borders
/// replicated). With a zero offset and rotation the image comes back unchanged.
pub fn compensate(right: &GrayImage, alignment: &Alignment) -> GrayImage {
    let (width, height) = right.size();
    let mut out = GrayImage::new(width, height, 0);
    if width == 0 || height == 0 {
        return out;
    }
    let offsets: Vec<f64> = (0..width).map(|x| alignment.offset_at(x as f64, width)).collect();
    let last = height as i64 - 1;
    let data = right.as_slice();
    out.as_mut_slice().par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        for (x, (value, &dy)) in row.iter_mut().zip(&offsets).enumerate() {
            let source = y as f64 + dy;
            let base = source.floor();
            let t = source - base;
            let weights = catmull_rom(t);
            let mut sum = 0.0;
            for (k, w) in weights.iter().enumerate() {
                let sy = (base as i64 + k as i64 - 1).clamp(0, last) as usize;
                sum += w * data[sy * width + x] as f64;
            }
            *value = sum.round().clamp(0.0, 65535.0) as u16;
        }
    });
    out
}

/// Catmull–Rom weights of the samples at offsets −1, 0, 1, 2 for a point `t ∈ [0, 1)` past 0.
fn catmull_rom(t: f64) -> [f64; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    ]
}

/// A full-resolution grey image read in place.
struct Full<'a> {
    width: usize,
    height: usize,
    data: &'a [u16],
}

impl<'a> Full<'a> {
    fn new(image: &'a GrayImage) -> Self {
        let (width, height) = image.size();
        Full { width, height, data: image.as_slice() }
    }

    #[inline]
    fn row(&self, y: usize) -> &'a [u16] {
        &self.data[y * self.width..(y + 1) * self.width]
    }
}

/// 1/65535: grey levels to `[0, 1]`.
const UNIT: f32 = 1.0 / 65535.0;

/// A half-resolution grey image as f32 in `[0, 1]`.
struct Plane {
    width: usize,
    height: usize,
    data: Vec<f32>,
}

impl Plane {
    /// 2×2 box average of `image` (the odd last row or column is dropped).
    fn half(image: &GrayImage) -> Plane {
        let (full_width, full_height) = image.size();
        let (width, height) = (full_width / 2, full_height / 2);
        let source = image.as_slice();
        let mut data = vec![0f32; width * height];
        if width > 0 {
            data.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
                let top = &source[2 * y * full_width..][..2 * width];
                let bottom = &source[(2 * y + 1) * full_width..][..2 * width];
                for (value, (t, b)) in row.iter_mut().zip(top.chunks_exact(2).zip(bottom.chunks_exact(2))) {
                    *value = (t[0] as u32 + t[1] as u32 + b[0] as u32 + b[1] as u32) as f32 * (0.25 * UNIT);
                }
            });
        }
        Plane { width, height, data }
    }

    #[inline]
    fn row(&self, y: usize) -> &[f32] {
        &self.data[y * self.width..(y + 1) * self.width]
    }
}

/// A patch centre `(x, y)` at full resolution.
type Centre = (usize, usize);

/// Patch centres (even coordinates, so they sit on the half-resolution grid): on a grid of cells,
/// the position of each cell with the strongest two-dimensional structure (Shi–Tomasi: the
/// smaller eigenvalue of the gradient structure tensor), if strong enough. A vertical offset is
/// only observable on structure with a vertical gradient, a disparity only on a horizontal one.
/// The structure is measured at half resolution (`half`), on every other pixel (a patch is
/// 8 half-resolution pixels wide, so that loses nothing that matters and saves most of the work).
///
/// Returns at most [`FIRST_PATCHES`] centres spread evenly over the image, then the others.
fn select_patches(half: &Plane) -> (Vec<Centre>, Vec<Centre>) {
    let (width, height) = (half.width, half.height);
    // Gradient products summed over 2×2 blocks: block (bx, by) holds half-resolution pixels
    // 2bx..2bx+2 × 2by..2by+2 (central differences, none on the border).
    let (bw, bh) = (width / 2, height / 2);
    if bw == 0 || bh == 0 {
        return (Vec::new(), Vec::new());
    }
    let mut blocks = vec![[0f32; 3]; bw * bh];
    let rows_end = (2 * bh).min(height - 1);
    blocks.par_chunks_mut(bw).enumerate().for_each(|(by, block_row)| {
        for y in (2 * by).max(1)..(2 * by + 2).min(rows_end) {
            let (above, row, below) = (half.row(y - 1), half.row(y), half.row(y + 1));
            for x in 1..(2 * bw).min(width - 1) {
                // Half-resolution pixels are two full-resolution ones apart: a quarter of the
                // difference.
                let gx = 0.25 * (row[x + 1] - row[x - 1]);
                let gy = 0.25 * (below[x] - above[x]);
                let b = &mut block_row[x / 2];
                b[0] += gx * gx;
                b[1] += gy * gy;
                b[2] += gx * gy;
            }
        }
    });
    // The full-resolution patch is about 8×8 half-resolution pixels: for an even centre (x, y),
    // half-resolution pixels x−4..x+4 × y−4..y+4, the 4×4 blocks from (x/2 − 2, y/2 − 2).
    const R: usize = RADIUS.div_ceil(2);
    const B: usize = R / 2;
    let mut across = vec![[0f32; 3]; bw * bh];
    across.par_chunks_mut(bw).zip(blocks.par_chunks(bw)).for_each(|(dst, src)| {
        for bx in B..=bw.saturating_sub(B) {
            let mut sum = [0f32; 3];
            for b in &src[bx - B..bx + B] {
                (0..3).for_each(|k| sum[k] += b[k]);
            }
            if bx < bw {
                dst[bx] = sum;
            }
        }
    });
    let n = ((2 * R) * (2 * R)) as f64;
    let structure = |x: usize, y: usize| {
        let (bx, by) = (x / 2, y / 2);
        let mut sum = [0f64; 3];
        for row in by - B..by + B {
            let a = across[row * bw + bx];
            (0..3).for_each(|k| sum[k] += a[k] as f64);
        }
        let (sxx, syy, sxy) = (sum[0] / n, sum[1] / n, sum[2] / n);
        0.5 * (sxx + syy) - (0.25 * (sxx - syy).powi(2) + sxy * sxy).sqrt()
    };

    // A few hundred cells, more on larger images.
    let (x_lo, x_hi) = (MARGIN_X / 2, width - MARGIN_X / 2);
    let (y_lo, y_hi) = (MARGIN_Y / 2, height - MARGIN_Y / 2);
    let area = (4 * (x_hi - x_lo) * (y_hi - y_lo)) as f64;
    let target = (area / 512.0).clamp(64.0, 1024.0);
    let cell = ((area / target).sqrt() / 2.0).round().max((RADIUS + 1) as f64) as usize;
    // Rows of cells in parallel, their results kept in raster order.
    let cell_rows: Vec<usize> = (y_lo..y_hi).step_by(cell).collect();
    let best_by_row: Vec<Vec<(f64, usize, usize)>> = cell_rows
        .par_iter()
        .map(|&cy| {
            let mut best = Vec::new();
            for cx in (x_lo..x_hi).step_by(cell) {
                let mut cell_best: Option<(f64, usize, usize)> = None;
                for y in (cy.next_multiple_of(2)..(cy + cell).min(y_hi)).step_by(2) {
                    for x in (cx.next_multiple_of(2)..(cx + cell).min(x_hi)).step_by(2) {
                        let s = structure(x, y);
                        if cell_best.map_or(true, |(b, _, _)| s > b) {
                            cell_best = Some((s, x, y));
                        }
                    }
                }
                best.extend(cell_best);
            }
            best
        })
        .collect();
    let best: Vec<(f64, usize, usize)> = best_by_row.into_iter().flatten().collect();
    // Strong enough in absolute terms (above noise) and beside the image's best cells (so a
    // barely textured cell does not dilute the fit with noisy offsets).
    let mut scores: Vec<f64> = best.iter().map(|b| b.0).collect();
    scores.sort_by(f64::total_cmp);
    let p90 = scores.get(scores.len() * 9 / 10).copied().unwrap_or(0.0);
    let floor = MIN_STRUCTURE.max(0.1 * p90);
    let centres: Vec<(usize, usize)> =
        best.into_iter().filter(|b| b.0 >= floor).map(|(_, x, y)| (2 * x, 2 * y)).collect();
    // Every k-th centre in raster order (k fractional) covers the image evenly.
    let count = centres.len();
    let first_count = count.min(FIRST_PATCHES);
    let mut chosen = vec![false; count];
    for i in 0..first_count {
        chosen[i * count / first_count] = true;
    }
    let (first, rest): (Vec<_>, Vec<_>) = centres.into_iter().zip(chosen).partition(|(_, c)| *c);
    (first.into_iter().map(|(p, _)| p).collect(), rest.into_iter().map(|(p, _)| p).collect())
}

/// The coarse search at half resolution over disparities and vertical offsets.
struct CoarseSearch<'a> {
    left: &'a Plane,
    right: &'a Plane,
}

impl CoarseSearch<'_> {
    /// The best `(disparity, vertical offset)` in half-resolution pixels of the patch at `(x, y)`
    /// over disparities `−reach..=reach`; `None` when weak or ambiguous.
    fn best(&self, x: usize, y: usize, reach: i32) -> Option<(i32, i32)> {
        const R: usize = COARSE_RADIUS;
        const N: usize = 2 * R + 1;
        let (width, height) = (self.right.width, self.right.height);
        if x < R
            || x + R >= self.left.width
            || y < R + COARSE_DY as usize
            || y + R + COARSE_DY as usize >= height
        {
            return None;
        }
        let mut patch = [0f32; N * N];
        for v in 0..N {
            patch[v * N..(v + 1) * N].copy_from_slice(&self.left.row(y + v - R)[x - R..x + R + 1]);
        }
        let mean = patch.iter().sum::<f32>() / (N * N) as f32;
        patch.iter_mut().for_each(|p| *p -= mean);
        let norm = patch.iter().map(|p| p * p).sum::<f32>().sqrt();
        if norm < 1e-4 {
            return None;
        }
        // Right patch centres xr = x − d, kept inside the image.
        let xr_lo = (x as i32 - reach).max(R as i32) as usize;
        let xr_hi = (x as i32 + reach).min((width - 1 - R) as i32);
        if (xr_hi as usize) < xr_lo {
            return None;
        }
        let count = xr_hi as usize - xr_lo + 1;
        let span = count + 2 * R;
        let mut by_column = vec![f32::NEG_INFINITY; count];
        let mut best = (f32::NEG_INFINITY, 0usize, 0i32);
        let mut acc = vec![0f32; count];
        // Sums and squares of the right view's columns xr_lo − R.. over the window's rows, rolled
        // down one row per vertical offset: only the searched span is summed.
        let mut column_sums = vec![0f32; span];
        let mut column_squares = vec![0f32; span];
        let span_of = |row: usize| &self.right.row(row)[xr_lo - R..xr_lo - R + span];
        let first_row = (y as i32 - COARSE_DY) as usize - R;
        for row in first_row..first_row + N - 1 {
            for ((s, q), &r) in column_sums.iter_mut().zip(&mut column_squares).zip(span_of(row)) {
                *s += r;
                *q += r * r;
            }
        }
        for dy in -COARSE_DY..=COARSE_DY {
            let ry = (y as i32 + dy) as usize;
            for ((s, q), &r) in column_sums.iter_mut().zip(&mut column_squares).zip(span_of(ry + R)) {
                *s += r;
                *q += r * r;
            }
            correlate(&patch, |v| &self.right.row(ry + v - R)[xr_lo - R..], &mut acc);
            // Window sums slide along the columns, in f64 so the running sums do not drift.
            let mut sum: f64 = column_sums[..N].iter().map(|&s| s as f64).sum();
            let mut squares: f64 = column_squares[..N].iter().map(|&q| q as f64).sum();
            for (k, &a) in acc.iter().enumerate() {
                if k > 0 {
                    sum += (column_sums[k + N - 1] - column_sums[k - 1]) as f64;
                    squares += (column_squares[k + N - 1] - column_squares[k - 1]) as f64;
                }
                let variance = squares - sum * sum / (N * N) as f64;
                if variance > 1e-9 {
                    let zncc = a / (norm * (variance as f32).sqrt());
                    if zncc > by_column[k] {
                        by_column[k] = zncc;
                    }
                    if zncc > best.0 {
                        best = (zncc, k, dy);
                    }
                }
            }
            for ((s, q), &r) in column_sums.iter_mut().zip(&mut column_squares).zip(span_of(ry - R)) {
                *s -= r;
                *q -= r * r;
            }
        }
        let (score, k_best, dy) = best;
        let rival = by_column
            .iter()
            .enumerate()
            .filter(|(k, _)| k.abs_diff(k_best) > AMBIGUITY_GAP)
            .map(|(_, &s)| s)
            .fold(f32::NEG_INFINITY, f32::max);
        if score < MIN_COARSE_ZNCC || score - rival < MIN_COARSE_MARGIN {
            return None;
        }
        Some((x as i32 - (xr_lo + k_best) as i32, dy))
    }
}

/// `acc[k] = Σ patch[v][u]·row(v)[k + u]` for the coarse patch: sixteen columns at a time, so
/// the sums stay in registers over all taps instead of going through memory at each one, and each
/// tap's weight is broadcast once for four vectors (8% faster than eight columns, 32 no faster;
/// every sum keeps its order, so the results are the same).
fn correlate<'a>(patch: &[f32], row: impl Fn(usize) -> &'a [f32], acc: &mut [f32]) {
    const N: usize = 2 * COARSE_RADIUS + 1;
    const L: usize = 16;
    let count = acc.len();
    let block = |k0: usize| {
        let mut sums = [0f32; L];
        for v in 0..N {
            let row = &row(v)[k0..k0 + N - 1 + L];
            for (u, &l) in patch[v * N..(v + 1) * N].iter().enumerate() {
                for (s, &r) in sums.iter_mut().zip(&row[u..u + L]) {
                    *s += l * r;
                }
            }
        }
        sums
    };
    if count < L {
        acc.iter_mut().for_each(|a| *a = 0.0);
        for v in 0..N {
            let row = row(v);
            for (u, &l) in patch[v * N..(v + 1) * N].iter().enumerate() {
                for (a, &r) in acc.iter_mut().zip(&row[u..u + count]) {
                    *a += l * r;
                }
            }
        }
        return;
    }
    // The last block is aligned to the end (overlapping the one before) so no read runs past it.
    for k0 in (0..count).step_by(L).map(|k| k.min(count - L)) {
        acc[k0..k0 + L].copy_from_slice(&block(k0));
    }
}

/// The full-resolution left patch, less its mean, for ZNCC against right patches.
struct LeftPatch {
    values: [f32; (2 * RADIUS + 1) * (2 * RADIUS + 1)],
    /// The left patch's mean, subtracted from the right values too: keeps the f32 sums small.
    mean: f32,
    norm_squared: f32,
}

impl LeftPatch {
    fn new(left: &Full, x: usize, y: usize) -> Self {
        const N: usize = 2 * RADIUS + 1;
        let mut values = [0f32; N * N];
        for v in 0..N {
            let row = &left.row(y + v - RADIUS)[x - RADIUS..x + RADIUS + 1];
            for (value, &l) in values[v * N..(v + 1) * N].iter_mut().zip(row) {
                *value = l as f32;
            }
        }
        let mean = values.iter().sum::<f32>() / (N * N) as f32;
        values.iter_mut().for_each(|v| *v -= mean);
        let norm_squared = values.iter().map(|v| v * v).sum();
        LeftPatch { values, mean, norm_squared }
    }

    /// ZNCC with the right patch at `(xr, yr)`.
    fn zncc(&self, right: &Full, xr: usize, yr: usize) -> f32 {
        const N: usize = 2 * RADIUS + 1;
        let (mut sr, mut srr, mut slr) = (0f32, 0f32, 0f32);
        for v in 0..N {
            let row = &right.row(yr + v - RADIUS)[xr - RADIUS..xr + RADIUS + 1];
            for (&l, &r) in self.values[v * N..(v + 1) * N].iter().zip(row) {
                let r = r as f32 - self.mean;
                sr += r;
                srr += r * r;
                slr += l * r;
            }
        }
        // The left values sum to zero, so `slr` is already the covariance.
        let var = self.norm_squared * (srr - sr * sr / (N * N) as f32);
        if var <= 0.0 {
            return f32::NEG_INFINITY;
        }
        slr / var.sqrt()
    }
}

/// The best integer right position `(xr, dy)` at full resolution within ±2 px of the coarse one:
/// a hill climb on ZNCC over 3×3 neighbourhoods, which rarely needs more than 9 to 15 of the 25
/// positions.
fn fine_search(left: &Full, right: &Full, x: usize, y: usize, xr0: i32, dy0: i32) -> Option<(i32, i32)> {
    const W: i32 = 2;
    let limit = MAX_DY + 1;
    let patch = LeftPatch::new(left, x, y);
    let valid = |xr: i32, dy: i32| {
        (xr - xr0).abs() <= W
            && (dy - dy0).abs() <= W
            && dy.abs() <= limit
            && xr >= RADIUS as i32
            && xr + (RADIUS as i32) < right.width as i32
    };
    let mut scores = [[None::<f32>; 5]; 5];
    let mut score_at = |xr: i32, dy: i32| {
        let cell = &mut scores[(dy - dy0 + W) as usize][(xr - xr0 + W) as usize];
        *cell.get_or_insert_with(|| patch.zncc(right, xr as usize, (y as i32 + dy) as usize))
    };
    let (mut cx, mut cy) = (xr0, dy0.clamp(-limit, limit));
    if !valid(cx, cy) {
        return None;
    }
    let mut best = (score_at(cx, cy), cx, cy);
    loop {
        for dy in cy - 1..=cy + 1 {
            for xr in cx - 1..=cx + 1 {
                if valid(xr, dy) {
                    let score = score_at(xr, dy);
                    if score > best.0 {
                        best = (score, xr, dy);
                    }
                }
            }
        }
        if (best.1, best.2) == (cx, cy) {
            break;
        }
        (cx, cy) = (best.1, best.2);
    }
    (best.0 >= MIN_COARSE_ZNCC).then_some((best.1, best.2))
}

/// One matched patch: the left centre's row, the right column it matched, its disparity and
/// vertical offset.
struct PatchMatch {
    x_right: f64,
    disparity: f64,
    dy: f64,
}

/// Sub-pixel match of the left patch at `(x, y)` starting from the right position
/// `(xr, y + dy)`: Gauss–Newton (Lucas–Kanade) on `left ≈ gain·right + bias`, so the offset
/// does not depend on exposure differences between the views.
///
/// Bilinear interpolation smooths what it samples by an amount that depends on the fraction
/// (none at whole pixels), so a fit that interpolates one view only prefers whole pixels on
/// sharp views, half pixels on a noisy one, and is pulled either way by a view blurred against a
/// sharp one (Middlebury pairs: a 0.25 px shift read as 0.16–0.21, a 0.1° rotation as
/// 0.06–0.09°, noise σ 6 in one view added 0.06–0.08 px, blur σ 1.5 up to 0.28 px). Two measures
/// keep that small: both views are first smoothed by a binomial σ 1 px kernel (then the
/// interpolation adds little smoothing of its own), and the sub-pixel part `s` of the shift is
/// split evenly, the left patch sampled at `−s/2` and the right one at `+s/2`, so both are
/// smoothed alike at every shift.
fn refine(left: &Full, right: &Full, x: usize, y: usize, xr: i32, dy: i32) -> Option<PatchMatch> {
    const N: usize = 2 * RADIUS + 1;
    let (u0, v0) = ((xr - x as i32) as f64, dy as f64);
    let left_window = Smoothed::around(left, x as i64, y as i64);
    let right_window = Smoothed::around(right, xr as i64, y as i64 + dy as i64);
    // The sub-pixel part of the shift, and the photometric model.
    let (mut su, mut sv) = (0.0f64, 0.0f64);
    let (mut gain, mut bias) = (1.0, 0.0);
    let mut l = Warped::new();
    let mut r = Warped::new();
    let mut converged = false;
    for iteration in 0..12 {
        let left_origin = (x as f64 - RADIUS as f64 - su / 2.0, y as f64 - RADIUS as f64 - sv / 2.0);
        let right_origin = (left_origin.0 + u0 + su, left_origin.1 + v0 + sv);
        if !l.sample(&left_window, left_origin) || !r.sample(&right_window, right_origin) {
            return None;
        }
        if iteration == 0 {
            // Start the photometric model from the patches' means and spreads.
            let (ml, mr) = mean_pair(&l.value, |k| r.value[k]);
            let (sl, sr) = spread_pair(&l.value, |k| r.value[k], ml, mr);
            if sr <= 1e-9 || sl <= 1e-9 {
                return None;
            }
            gain = sl / sr;
            bias = ml - gain * mr;
        }
        let mut h = [[0f64; 4]; 4];
        let mut g = [0f64; 4];
        for k in 0..N * N {
            let e = l.value[k] - gain * r.value[k] - bias;
            // d e / d s: the left sample moves by −s/2, the right one by +s/2.
            let jac = [
                0.5 * (l.grad_x[k] + gain * r.grad_x[k]),
                0.5 * (l.grad_y[k] + gain * r.grad_y[k]),
                r.value[k],
                1.0,
            ];
            for a in 0..4 {
                g[a] += jac[a] * e;
                for b in a..4 {
                    h[a][b] += jac[a] * jac[b];
                }
            }
        }
        // Only the upper triangle was summed.
        let h = std::array::from_fn(|a| std::array::from_fn(|b| h[a.min(b)][a.max(b)]));
        let step = solve4(h, g)?;
        su += step[0];
        sv += step[1];
        gain += step[2];
        bias += step[3];
        if su.abs() > 1.5 || sv.abs() > 1.5 || (v0 + sv).abs() > MAX_DY as f64 + 0.5 || gain <= 0.0 {
            return None;
        }
        if step[0].abs() < 1e-3 && step[1].abs() < 1e-3 {
            converged = true;
            break;
        }
    }
    if !converged {
        return None;
    }
    let (ml, mr) = mean_pair(&l.value, |k| r.value[k]);
    let (sl, sr) = spread_pair(&l.value, |k| r.value[k], ml, mr);
    let cov: f64 = (0..N * N).map(|k| (l.value[k] - ml) * (r.value[k] - mr)).sum::<f64>() / (N * N) as f64;
    if sl <= 0.0 || sr <= 0.0 || cov / (sl * sr) < MIN_FINE_ZNCC as f64 {
        return None;
    }
    let (u, v) = (u0 + su, v0 + sv);
    Some(PatchMatch { x_right: x as f64 + u, disparity: -u, dy: v })
}

/// Half the side of the smoothed window [`refine`] samples in: the patch, the sub-pixel shift
/// it may take before it is abandoned (1.5 px, half of it on each view) and the bilinear
/// neighbour.
const WINDOW_RADIUS: usize = RADIUS + 2;
const WINDOW: usize = 2 * WINDOW_RADIUS + 1;

/// The square window of an image around a pixel, smoothed by the binomial kernel
/// `[1 4 6 4 1] / 16` along rows and columns (σ 1 px; borders replicated), in `[0, 1]`.
struct Smoothed {
    /// Image coordinates of the window's top-left pixel.
    x0: i64,
    y0: i64,
    value: [f64; WINDOW * WINDOW],
}

impl Smoothed {
    fn around(image: &Full, cx: i64, cy: i64) -> Self {
        const KERNEL: [f64; 5] = [1.0 / 16.0, 4.0 / 16.0, 6.0 / 16.0, 4.0 / 16.0, 1.0 / 16.0];
        const UNIT: f64 = 1.0 / 65535.0;
        const SOURCE: usize = WINDOW + 4;
        let (x0, y0) = (cx - WINDOW_RADIUS as i64, cy - WINDOW_RADIUS as i64);
        let clamp = |v: i64, n: usize| v.clamp(0, n as i64 - 1) as usize;
        // Rows first: SOURCE rows of WINDOW smoothed columns, from the SOURCE columns around the
        // window (the borders replicated).
        let mut rows = [0f64; SOURCE * WINDOW];
        let mut source = [0f64; SOURCE];
        for j in 0..SOURCE {
            let row = image.row(clamp(y0 + j as i64 - 2, image.height));
            for (i, s) in source.iter_mut().enumerate() {
                *s = f64::from(row[clamp(x0 + i as i64 - 2, image.width)]);
            }
            for i in 0..WINDOW {
                rows[j * WINDOW + i] =
                    KERNEL.iter().enumerate().map(|(k, w)| w * source[i + k]).sum::<f64>() * UNIT;
            }
        }
        let mut value = [0f64; WINDOW * WINDOW];
        for j in 0..WINDOW {
            for i in 0..WINDOW {
                value[j * WINDOW + i] =
                    KERNEL.iter().enumerate().map(|(k, w)| w * rows[(j + k) * WINDOW + i]).sum();
            }
        }
        Smoothed { x0, y0, value }
    }
}

/// One `N×N` patch bilinearly sampled at a sub-pixel position, with the exact derivatives of the
/// bilinear interpolant (so Gauss–Newton converges in a few steps).
struct Warped {
    value: [f64; (2 * RADIUS + 1) * (2 * RADIUS + 1)],
    grad_x: [f64; (2 * RADIUS + 1) * (2 * RADIUS + 1)],
    grad_y: [f64; (2 * RADIUS + 1) * (2 * RADIUS + 1)],
}

impl Warped {
    fn new() -> Self {
        const M: usize = (2 * RADIUS + 1) * (2 * RADIUS + 1);
        Warped { value: [0.0; M], grad_x: [0.0; M], grad_y: [0.0; M] }
    }

    /// Samples the patch whose top-left pixel lies at `origin` (image coordinates) from
    /// `window`; `false` if the patch leaves the window or the image.
    fn sample(&mut self, window: &Smoothed, origin: (f64, f64)) -> bool {
        const N: usize = 2 * RADIUS + 1;
        // Every pixel shares the fractional position, so the bilinear weights are computed once.
        let (fx, fy) = (origin.0.floor(), origin.1.floor());
        let (tx, ty) = (origin.0 - fx, origin.1 - fy);
        let (lx, ly) = (fx as i64 - window.x0, fy as i64 - window.y0);
        if lx < 0 || ly < 0 || lx as usize + N >= WINDOW || ly as usize + N >= WINDOW {
            return false;
        }
        let (x0, y0) = (lx as usize, ly as usize);
        for j in 0..N {
            let top = &window.value[(y0 + j) * WINDOW + x0..][..N + 1];
            let bottom = &window.value[(y0 + j + 1) * WINDOW + x0..][..N + 1];
            for i in 0..N {
                let (a, b, c, d) = (top[i], top[i + 1], bottom[i], bottom[i + 1]);
                let upper = a + (b - a) * tx;
                let lower = c + (d - c) * tx;
                self.value[j * N + i] = upper + (lower - upper) * ty;
                self.grad_x[j * N + i] = (b - a) + ((d - c) - (b - a)) * ty;
                self.grad_y[j * N + i] = lower - upper;
            }
        }
        true
    }
}

fn mean_pair(template: &[f64], warped: impl Fn(usize) -> f64) -> (f64, f64) {
    let n = template.len() as f64;
    (template.iter().sum::<f64>() / n, (0..template.len()).map(warped).sum::<f64>() / n)
}

fn spread_pair(template: &[f64], warped: impl Fn(usize) -> f64, ml: f64, mr: f64) -> (f64, f64) {
    let n = template.len() as f64;
    let sl = (template.iter().map(|t| (t - ml).powi(2)).sum::<f64>() / n).sqrt();
    let sr = ((0..template.len()).map(|k| (warped(k) - mr).powi(2)).sum::<f64>() / n).sqrt();
    (sl, sr)
}

/// Solves the 4×4 system `h·x = g` (Gaussian elimination, partial pivoting); `None` if singular.
fn solve4(mut h: [[f64; 4]; 4], mut g: [f64; 4]) -> Option<[f64; 4]> {
    for col in 0..4 {
        let pivot = (col..4).max_by(|&a, &b| h[a][col].abs().total_cmp(&h[b][col].abs()))?;
        if h[pivot][col].abs() < 1e-12 {
            return None;
        }
        h.swap(col, pivot);
        g.swap(col, pivot);
        let pivot_row = h[col];
        for row in col + 1..4 {
            let f = h[row][col] / pivot_row[col];
            for (target, &p) in h[row][col..].iter_mut().zip(&pivot_row[col..]) {
                *target -= f * p;
            }
            g[row] -= f * g[col];
        }
    }
    let mut x = [0f64; 4];
    for row in (0..4).rev() {
        let s: f64 = (row + 1..4).map(|k| h[row][k] * x[k]).sum();
        x[row] = (g[row] - s) / h[row][row];
    }
    Some(x)
}

struct LineFit {
    offset: f64,
    slope: f64,
    inliers: usize,
}

/// `dy = offset + slope·(x_right − cx)` by iteratively reweighted least squares with Tukey's
/// biweight (scale from the median absolute residual), from the median offset and no slope, so
/// mismatches (occlusions, repetitive texture) do not pull the line.
fn robust_line(matches: &[PatchMatch], cx: f64) -> LineFit {
    let median = |mut values: Vec<f64>| {
        values.sort_by(f64::total_cmp);
        values[values.len() / 2]
    };
    let mut offset = median(matches.iter().map(|m| m.dy).collect());
    let mut slope = 0.0;
    let residual = |m: &PatchMatch, offset: f64, slope: f64| m.dy - offset - slope * (m.x_right - cx);
    let mut cutoff = f64::INFINITY;
    for _ in 0..20 {
        let mad = median(matches.iter().map(|m| residual(m, offset, slope).abs()).collect());
        // A floor on the scale: a nearly perfect fit must not reject patches for 0.01 px noise.
        cutoff = 4.685 * (1.4826 * mad).max(0.03);
        let (mut sw, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for m in matches {
            let r = residual(m, offset, slope) / cutoff;
            if r.abs() >= 1.0 {
                continue;
            }
            let w = (1.0 - r * r).powi(2);
            let x = m.x_right - cx;
            sw += w;
            sx += w * x;
            sy += w * m.dy;
            sxx += w * x * x;
            sxy += w * x * m.dy;
        }
        let det = sw * sxx - sx * sx;
        if sw <= 0.0 || det.abs() < 1e-9 {
            break;
        }
        let (new_slope, new_offset) = ((sw * sxy - sx * sy) / det, (sxx * sy - sx * sxy) / det);
        let change = (new_offset - offset).abs() + (new_slope - slope).abs() * cx;
        (offset, slope) = (new_offset, new_slope);
        if change < 1e-5 {
            break;
        }
    }
    let inliers = matches.iter().filter(|m| residual(m, offset, slope).abs() < cutoff).count();
    LineFit { offset, slope, inliers }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `correlate`'s blocks (the last one overlapping the one before) and its short-row path give
    /// the plain sum of each output, term by term in the same order, for every row length.
    #[test]
    fn correlate_matches_the_plain_sum() {
        const N: usize = 2 * COARSE_RADIUS + 1;
        let patch: Vec<f32> = (0..N * N).map(|i| ((i * 37 % 23) as f32 - 11.0) / 7.0).collect();
        for count in 1..70 {
            let rows: Vec<Vec<f32>> = (0..N)
                .map(|v| (0..count + N - 1).map(|x| ((x * 13 + v * 29) % 31) as f32 / 17.0).collect())
                .collect();
            let mut acc = vec![f32::NAN; count];
            correlate(&patch, |v| rows[v].as_slice(), &mut acc);
            for (k, &a) in acc.iter().enumerate() {
                let mut sum = 0f32;
                for v in 0..N {
                    for u in 0..N {
                        sum += patch[v * N + u] * rows[v][k + u];
                    }
                }
                assert_eq!(a.to_bits(), sum.to_bits(), "count {count}, column {k}");
            }
        }
    }
}
