//! Window block matching with winner-takes-all.
//!
//! Per-pixel costs (SAD of x-Sobel responses, or Hamming distance of 5×5 census strings) are
//! summed over a square window with running sums: each strip of rows keeps per-column sums of
//! the window's rows for every disparity and slides them down one row at a time, and each row's
//! window sums come from a running horizontal sum of those. That makes the work O(W·H·D)
//! independent of the window size. Strips run in parallel; each row is finished (WTA,
//! uniqueness, left-right check, subpixel) as soon as its window costs are known.

use rayon::prelude::*;

use crate::winner::{
    ambiguous, keep_smaller, left_right_check, refined_offset, right_view_winners, winner, RangeEnds, Ties,
};
use crate::{check_pair, BmCost, BmParams, DisparityMap, Error, GrayImage};

/// The largest accepted window side; keeps every window sum well inside `u32`.
pub(crate) const MAX_BLOCK_SIZE: usize = 255;

/// OpenCV's default `preFilterCap` (31 in 8-bit units), in our 16-bit units (8-bit × 257).
const SOBEL_CAP: i32 = 31 * 257;

/// Block matching of a rectified pair: window costs (SAD on a prefiltered image or census),
/// winner-takes-all, optional subpixel refinement, uniqueness and left-right checks.
///
/// A pixel gets a disparity only where the whole window fits in the left image and, for each
/// disparity considered, in the right image: near the left border only the disparities whose
/// window stays inside the right image are searched. Pixels are NaN where the window does not
/// fit, no disparity is feasible, the best cost is not unique enough
/// (`second · 100 <= best · (100 + uniqueness_ratio)`, with `second` the best cost more than one
/// disparity away; ties are rejected), or the left-right check fails: the right view's integer
/// WTA disparity from the same costs at `x - round(d)` differs from `d` by more than
/// `lr_max_diff`. Subpixel refinement needs both neighbouring disparities to be searched.
/// Small islands more than twice as far as the scene around them are then invalidated, as in SGM
/// (`PixelStatus::FarIsland`, docs/robustness.md).
pub fn block_match(left: &GrayImage, right: &GrayImage, params: &BmParams) -> Result<DisparityMap, Error> {
    crate::on_pool_thread(|| block_match_on_pool_thread(left, right, params))
}

fn block_match_on_pool_thread(
    left: &GrayImage,
    right: &GrayImage,
    params: &BmParams,
) -> Result<DisparityMap, Error> {
    check_pair(left, right)?;
    let (width, height) = left.size();
    crate::check_range(&params.range, width)?;
    params.validate()?;
    let block = params.block_size;
    if width < block || height < block {
        return Err(Error::ImageTooSmall { width, height, window_width: block, window_height: block });
    }

    let features = match params.cost {
        BmCost::Sad => Features::Sad { left: x_sobel(left), right: x_sobel(right) },
        BmCost::Census => Features::Census { left: census_5x5(left), right: census_5x5(right) },
    };
    let matcher = Matcher {
        features,
        width,
        radius: block / 2,
        min: params.range.min as i64,
        count: params.range.count(),
        params,
    };

    let mut disparity = DisparityMap::new(width, height, f32::NAN);
    let r = matcher.radius;
    let rows = height - 2 * r;
    let threads = rayon::current_num_threads().max(1);
    // A few strips per thread for balance, but tall enough that re-summing the first window
    // (`block` rows) of each strip stays a small overhead.
    let strip = rows.div_ceil(4 * threads).max(4 * block).min(rows);
    disparity.as_mut_slice()[r * width..(height - r) * width]
        .par_chunks_mut(strip * width)
        .enumerate()
        .for_each(|(i, out)| matcher.strip(r + i * strip, out));
    crate::far_islands::reject_far_islands(&mut disparity, params.range, f32::NAN);
    Ok(disparity)
}

/// Per-pixel matching features of both views.
enum Features {
    /// Clamped x-Sobel responses.
    Sad { left: Vec<i16>, right: Vec<i16> },
    /// 24-bit census strings.
    Census { left: Vec<u32>, right: Vec<u32> },
}

struct Matcher<'a> {
    features: Features,
    width: usize,
    radius: usize,
    /// Smallest disparity searched; disparity index `k` is disparity `min + k`.
    min: i64,
    /// Number of disparities searched.
    count: usize,
    params: &'a BmParams,
}

impl Matcher<'_> {
    /// Fills `out[x * count + k]` with the pixel cost of left `(x, y)` against right
    /// `(x - min - k, y)`, the right column clamped into the image (clamped costs only ever
    /// enter windows of infeasible disparities, which are never selected).
    fn pixel_costs(&self, y: usize, out: &mut [u32]) {
        let (w, n) = (self.width, self.count);
        let right_x = |x: usize, k: usize| (x as i64 - self.min - k as i64).clamp(0, w as i64 - 1) as usize;
        match &self.features {
            Features::Sad { left, right } => {
                let (l, r) = (&left[y * w..(y + 1) * w], &right[y * w..(y + 1) * w]);
                for (x, costs) in out.chunks_exact_mut(n).enumerate() {
                    for (k, c) in costs.iter_mut().enumerate() {
                        *c = (l[x] as i32 - r[right_x(x, k)] as i32).unsigned_abs();
                    }
                }
            }
            Features::Census { left, right } => {
                let (l, r) = (&left[y * w..(y + 1) * w], &right[y * w..(y + 1) * w]);
                for (x, costs) in out.chunks_exact_mut(n).enumerate() {
                    for (k, c) in costs.iter_mut().enumerate() {
                        *c = (l[x] ^ r[right_x(x, k)]).count_ones();
                    }
                }
            }
        }
    }

    /// Computes the disparities of rows `y0 .. y0 + out.len() / width` into `out`.
    fn strip(&self, y0: usize, out: &mut [f32]) {
        let (w, n, r) = (self.width, self.count, self.radius);
        let mut column_sums = vec![0u32; w * n];
        let mut pixel = vec![0u32; w * n];
        let mut window = vec![0u32; w * n];
        let mut right = RightView { cost: vec![0; w], index: vec![0; w] };
        for yy in y0 - r..=y0 + r {
            self.pixel_costs(yy, &mut pixel);
            column_sums.iter_mut().zip(&pixel).for_each(|(s, &c)| *s += c);
        }
        for (i, out_row) in out.chunks_exact_mut(w).enumerate() {
            let y = y0 + i;
            if i > 0 {
                self.pixel_costs(y + r, &mut pixel);
                column_sums.iter_mut().zip(&pixel).for_each(|(s, &c)| *s += c);
                self.pixel_costs(y - r - 1, &mut pixel);
                column_sums.iter_mut().zip(&pixel).for_each(|(s, &c)| *s -= c);
            }
            self.window_sums(&column_sums, &mut window);
            self.select_row(&window, &mut right, out_row);
        }
    }

    /// Horizontal running sums of `2r + 1` column sums: `window[x]` for `r <= x < width - r`.
    fn window_sums(&self, column_sums: &[u32], window: &mut [u32]) {
        let (w, n, r) = (self.width, self.count, self.radius);
        let column = |x: usize| &column_sums[x * n..(x + 1) * n];
        let mut running = vec![0u32; n];
        for x in 0..2 * r + 1 {
            running.iter_mut().zip(column(x)).for_each(|(s, &c)| *s += c);
        }
        window[r * n..(r + 1) * n].copy_from_slice(&running);
        for x in r + 1..w - r {
            let (add, sub) = (column(x + r), column(x - r - 1));
            for ((s, &a), &b) in running.iter_mut().zip(add).zip(sub) {
                *s = *s + a - b;
            }
            window[x * n..(x + 1) * n].copy_from_slice(&running);
        }
    }

    /// The disparity indices `k` whose windows fit both images for left column `x`.
    fn feasible(&self, x: usize) -> Option<(usize, usize)> {
        let (w, r) = (self.width as i64, self.radius as i64);
        let x = x as i64;
        // r <= x - min - k <= w - 1 - r
        let lo = (x - (w - 1 - r) - self.min).max(0);
        let hi = (x - r - self.min).min(self.count as i64 - 1);
        (lo <= hi).then_some((lo as usize, hi as usize))
    }

    /// WTA, uniqueness, left-right check and subpixel refinement for one row of window costs
    /// (the shared [`crate::winner`] functions with BM's choices: ties with the uniqueness bound
    /// are ambiguous, the range ends are rejected here, the left-right check compares the refined
    /// disparity).
    fn select_row(&self, window: &[u32], right: &mut RightView, out: &mut [f32]) {
        let (w, n, r) = (self.width, self.count, self.radius);
        let costs = |x: usize| &window[x * n..(x + 1) * n];
        // The disparity indices searched for left pixel `x` (none outside the window columns).
        let searched = |x: usize| match self.feasible(x) {
            Some((lo, hi)) if x >= r && x < w - r => lo..hi + 1,
            _ => 0..0,
        };

        if self.params.lr_max_diff.is_some() {
            right_view_winners(
                self.min,
                costs,
                searched,
                keep_smaller,
                u32::MAX,
                &mut right.cost,
                &mut right.index,
            );
        }

        let ends = RangeEnds::indices(self.count);
        for (x, out) in out.iter_mut().enumerate().take(w - r).skip(r) {
            *out = f32::NAN;
            let Some((lo, hi)) = self.feasible(x) else { continue };
            let (c, ks) = (costs(x), lo..hi + 1);
            let best = winner(c, ks.clone());
            // At an end of the searched disparities the true minimum may lie beyond: rejected as
            // in SGM (`post::reject_range_ends`), the image edge only in the lowest quarter.
            if ends.at_end(best, lo, hi) {
                continue;
            }
            if ambiguous(c, ks.clone(), best, self.params.uniqueness_ratio, Ties::Ambiguous) {
                continue;
            }
            let d = (self.min + best as i64) as f32 + refined_offset(c, ks, best, self.params.subpixel);
            if let Some(max_diff) = self.params.lr_max_diff {
                let xr = x as i64 - d.round() as i64;
                if left_right_check(&right.index, xr, d, self.min, max_diff, false).is_err() {
                    continue;
                }
            }
            *out = d;
        }
    }
}

/// The right view's winners of one row (indexed by `width - 1 - xr`, see
/// [`right_view_winners`]).
struct RightView {
    cost: Vec<u32>,
    index: Vec<u32>,
}

/// Horizontal Sobel response (`[-1 0 1; -2 0 2; -1 0 1]`, replicated borders) clamped to
/// `±SOBEL_CAP`, as OpenCV's StereoBM x-Sobel prefilter.
fn x_sobel(image: &GrayImage) -> Vec<i16> {
    let (w, h) = image.size();
    let mut out = vec![0i16; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let rows = [image.row(y.saturating_sub(1)), image.row(y), image.row((y + 1).min(h - 1))];
        for (x, o) in out.iter_mut().enumerate() {
            let (xl, xr) = (x.saturating_sub(1), (x + 1).min(w - 1));
            let diff = |row: &[u16]| row[xr] as i32 - row[xl] as i32;
            let g = diff(rows[0]) + 2 * diff(rows[1]) + diff(rows[2]);
            *o = g.clamp(-SOBEL_CAP, SOBEL_CAP) as i16;
        }
    });
    out
}

/// 5×5 census strings: bit set where the neighbour is darker than the centre (24 bits, replicated
/// borders).
fn census_5x5(image: &GrayImage) -> Vec<u32> {
    let (w, h) = image.size();
    let mut out = vec![0u32; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        let rows: [&[u16]; 5] = std::array::from_fn(|j| image.row((y + j).saturating_sub(2).min(h - 1)));
        for (x, o) in out.iter_mut().enumerate() {
            let centre = rows[2][x];
            let mut bits = 0u32;
            for row in rows {
                for dx in 0..5 {
                    let xx = (x + dx).saturating_sub(2).min(w - 1);
                    bits = (bits << 1) | u32::from(row[xx] < centre);
                }
            }
            // The centre compared with itself is always 0; drop its bit.
            *o = ((bits >> 13) << 12) | (bits & 0xFFF);
        }
    });
    out
}

#[cfg(test)]
mod tests;
