//! Coarse-to-fine search (tSGM, Rothermel et al. 2012): match a half-resolution pair over the
//! whole range, then search each full-resolution pixel only in a band of disparities around the
//! upsampled coarse result, with the path aggregation running on those per-pixel bands. Time
//! and memory then scale with the bands' widths, not with the range.
//!
//! A pixel's band is `offset .. offset + lanes` (`lanes` a multiple of 16, so the path step runs
//! whole registers): the span of the coarse disparities of its two nearest coarse pixels in each
//! direction (a 2×2 block), doubled, plus [`MARGIN`] on each side; where none is valid, a 7×7
//! neighbourhood with twice the margin; where that has none either, the whole range. A path entering a pixel from a neighbour whose
//! band differs sees the neighbour's costs where the bands overlap and [`PAD`] (never the
//! minimum) elsewhere, and the neighbour's minimum over its own band: outside its band a path
//! can only arrive with the large-jump penalty.
//!
//! With every band covering the whole range this is exactly the full search (tested), so the
//! bands are the only approximation.

use std::ops::Range;
use std::sync::Mutex;

use rayon::prelude::*;

use crate::aggregate::Inputs;
use crate::cost::{AdRows, BtRow};
use crate::kernels::layout::{padded_lanes, BandRow, PathIn, PAD};
use crate::kernels::{self, Features, Level};
use crate::status::{tagged_nan, PixelStatus};
use crate::winner::{ambiguous, left_right_check, refined_offset, Ties};
use crate::{DisparityMap, DisparityRange, PathCount};

/// Fine-level disparities added on each side of the coarse neighbourhood's span: a coarse
/// disparity `c` means `2c ± 1` at the fine level, and the coarse winner may be off by one.
pub(crate) const MARGIN: i32 = 4;

/// Per-pixel disparity bands of a `width × height` image. Every band starts inside the range and
/// lies within the whole range's padded lanes (`offset - min + lanes <= padded_lanes(count)`).
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Bands {
    pub width: usize,
    pub height: usize,
    /// The first disparity of each pixel's band.
    offset: Vec<i32>,
    /// The band's width in disparities (a multiple of 16; lanes past the range's end are padding
    /// that never wins).
    lanes: Vec<u16>,
}

impl Bands {
    /// Every pixel searches the whole range (the full search).
    #[cfg(test)]
    pub(crate) fn full(width: usize, height: usize, range: DisparityRange) -> Self {
        let lanes = padded_lanes(range.count()) as u16;
        Bands { width, height, offset: vec![range.min; width * height], lanes: vec![lanes; width * height] }
    }

    /// Bands around `coarse`, a disparity map of the pair at half resolution (NaN where invalid).
    pub(crate) fn from_coarse(
        coarse: &DisparityMap,
        width: usize,
        height: usize,
        range: DisparityRange,
    ) -> Self {
        let (cw, ch) = coarse.size();
        let full = padded_lanes(range.count());
        if cw == 0 || ch == 0 {
            return Bands {
                width,
                height,
                offset: vec![range.min; width * height],
                lanes: vec![full as u16; width * height],
            };
        }
        // Span of the valid coarse disparities in columns xs and rows ys.
        let span = |xs: (usize, usize), ys: (usize, usize)| -> Option<(f32, f32)> {
            let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
            for y in ys.0..=ys.1 {
                for &d in &coarse.row(y)[xs.0..=xs.1] {
                    if d.is_finite() {
                        lo = lo.min(d);
                        hi = hi.max(d);
                    }
                }
            }
            (lo <= hi).then_some((lo, hi))
        };
        // A fine pixel's band spans its two nearest coarse pixels in each direction: fine `v`
        // lies between coarse `(v - 1) / 2` and `(v + 1) / 2`, so each 2×2 block of coarse pixels
        // (`block[j][i]`: coarse columns `i - 1, i` and rows `j - 1, j`, clamped) serves the fine
        // pixels `2i - 1 ..= 2i`.
        let pair = |i: usize, n: usize| (i.saturating_sub(1).min(n - 1), i.min(n - 1));
        let wide = |i: usize, n: usize| (i.saturating_sub(3).min(n - 1), (i + 2).min(n - 1));
        let blocks: Vec<Vec<(i32, u16)>> = (0..=ch)
            .into_par_iter()
            .map(|j| {
                (0..=cw)
                    .map(|i| {
                        let wanted = match span(pair(i, cw), pair(j, ch)) {
                            Some((lo, hi)) => Some((floor2(lo) - MARGIN, ceil2(hi) + MARGIN)),
                            // No valid coarse pixel: a wider neighbourhood and margin.
                            None => span(wide(i, cw), wide(j, ch))
                                .map(|(lo, hi)| (floor2(lo) - 2 * MARGIN, ceil2(hi) + 2 * MARGIN)),
                        };
                        let (o, n) = match wanted {
                            Some((lo, hi)) => band(lo, hi, range, full),
                            None => (range.min, full),
                        };
                        (o, n as u16)
                    })
                    .collect()
            })
            .collect();
        let block = |v: usize| v.div_ceil(2);
        let mut offset = Vec::with_capacity(width * height);
        let mut lanes = Vec::with_capacity(width * height);
        for y in 0..height {
            let row = &blocks[block(y).min(ch)];
            for x in 0..width {
                let (o, n) = row[block(x).min(cw)];
                offset.push(o);
                lanes.push(n);
            }
        }
        Bands { width, height, offset, lanes }
    }

    /// Entries of a volume over the bands (the sum of the band widths).
    pub(crate) fn entries(&self) -> usize {
        self.lanes.iter().map(|&n| usize::from(n)).sum()
    }

    /// The mean number of disparities of the range a pixel searches.
    pub(crate) fn mean_searched(&self, range: DisparityRange) -> f32 {
        let n = self.offset.len().max(1);
        let total: u64 = self
            .offset
            .iter()
            .zip(&self.lanes)
            .map(|(&o, &l)| (o + i32::from(l)).min(range.max).saturating_sub(o.max(range.min)).max(0) as u64)
            .sum();
        total as f32 / n as f32
    }

    fn row(&self, y: usize) -> (&[i32], &[u16]) {
        let r = y * self.width..(y + 1) * self.width;
        (&self.offset[r.clone()], &self.lanes[r])
    }
}

/// `2v` rounded down and up to whole disparities (coarse disparities are halved fine ones).
fn floor2(v: f32) -> i32 {
    let t = (2.0 * v) as i32;
    t - i32::from((t as f32) > 2.0 * v)
}

fn ceil2(v: f32) -> i32 {
    let t = (2.0 * v) as i32;
    t + i32::from((t as f32) < 2.0 * v)
}

/// The band `(offset, lanes)` covering `lo..=hi` (clipped to the range), `lanes` rounded up to
/// whole [`LANES`] blocks with the extra split around the span, at most the whole range.
fn band(lo: i32, hi: i32, range: DisparityRange, full: usize) -> (i32, usize) {
    let lo = lo.clamp(range.min, range.max - 1);
    let hi = hi.clamp(lo, range.max - 1);
    let needed = (hi - lo + 1) as usize;
    let lanes = padded_lanes(needed).min(full);
    if lanes == full {
        return (range.min, full);
    }
    let o = lo - (lanes - needed) as i32 / 2;
    (o.clamp(range.min, (range.max - lanes as i32).max(range.min)), lanes)
}

/// Where each pixel's entries start in a row laid out band after band (`pad` extra entries per
/// pixel), plus the row's total at the end.
fn starts(lanes: &[u16], pad: usize, out: &mut Vec<usize>) {
    out.clear();
    let mut s = 0;
    for &n in lanes {
        out.push(s);
        s += usize::from(n) + pad;
    }
    out.push(s);
}

/// Aggregates the paths over `bands` and selects each pixel's disparity (tagged NaNs where
/// rejected): the forward pass (→, ↓, ↘, ↙) and the backward pass (←, ↑, ↖, ↗; four paths: →,
/// ↓ and ←, ↑) run on two threads; the second to finish a row adds the first's sums and selects
/// the row.
pub(crate) fn aggregate_bands(inputs: &Inputs<'_>, bands: &Bands, level: Level) -> DisparityMap {
    let (width, height) = (bands.width, bands.height);
    let mut disparity = DisparityMap::new(width, height, f32::NAN);
    let shared = Shared {
        slots: (0..height).map(|_| Mutex::new(None)).collect(),
        rows: disparity.as_mut_slice().chunks_exact_mut(width.max(1)).map(Mutex::new).collect(),
        spare: Mutex::new(Vec::new()),
    };
    rayon::join(
        || run_pass(inputs, bands, true, level, &shared),
        || run_pass(inputs, bands, false, level, &shared),
    );
    drop(shared);
    disparity
}

/// The single-pass variant ([`crate::SgmParams::single_pass`], as
/// [`crate::aggregate::stream_and_select`]): only the forward directions plus a ← sweep over
/// each row, so every row is final when done and nothing is stored. The image is cut into
/// `strips` strips, each on its own thread and warming its paths up over `overlap` rows above.
pub(crate) fn stream_bands(
    inputs: &Inputs<'_>,
    bands: &Bands,
    level: Level,
    strips: usize,
    overlap: usize,
) -> DisparityMap {
    let (width, height) = (bands.width, bands.height);
    let mut disparity = DisparityMap::new(width, height, f32::NAN);
    let strip_rows = height.div_ceil(strips.clamp(1, height.max(1))).max(1);
    rayon::scope(|scope| {
        for (strip, rows) in disparity.as_mut_slice().chunks_mut(strip_rows * width.max(1)).enumerate() {
            scope.spawn(move |_| stream_strip(inputs, bands, level, strip * strip_rows, overlap, rows));
        }
    });
    disparity
}

kernels::multiversion! {
    /// One strip of [`stream_bands`]: rows from `y0` (warm-up above it) into `rows`.
    fn stream_strip(inputs: &Inputs<'_>, bands: &Bands, level: Level, y0: usize, overlap: usize, rows: &mut [f32]) => stream_strip_generic;
}

#[inline(always)]
fn stream_strip_generic(
    inputs: &Inputs<'_>,
    bands: &Bands,
    level: Level,
    y0: usize,
    overlap: usize,
    rows: &mut [f32],
    _compiled_for: Level,
) {
    let width = bands.width.max(1);
    let mut pass = Pass::new(inputs, bands, true, level);
    let mut sel = SelectScratch::default();
    let mut sum = Vec::new();
    for y in y0.saturating_sub(overlap)..y0 + rows.len() / width {
        pass.row(y, &mut sum);
        if y >= y0 {
            pass.leftward(y, &mut sum);
            select_row(inputs, bands, y, &sum, level, &mut sel, &mut rows[(y - y0) * width..][..width]);
        }
    }
}

/// The lock's contents, also after a panic elsewhere (the data stays consistent per row).
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// What the two passes share: per row, the first pass's sums until the second takes them, and
/// the output row; the sum buffers the second pass is done with, for the first to reuse.
struct Shared<'d> {
    slots: Vec<Mutex<Option<Vec<u16>>>>,
    rows: Vec<Mutex<&'d mut [f32]>>,
    spare: Mutex<Vec<Vec<u16>>>,
}

kernels::multiversion! {
    /// One pass over every row, handing each row's sums over to (or taking them from) the other.
    fn run_pass(inputs: &Inputs<'_>, bands: &Bands, forward: bool, level: Level, shared: &Shared<'_>) => run_pass_generic;
}

#[inline(always)]
fn run_pass_generic(
    inputs: &Inputs<'_>,
    bands: &Bands,
    forward: bool,
    level: Level,
    shared: &Shared<'_>,
    _compiled_for: Level,
) {
    let height = bands.height;
    let mut pass = Pass::new(inputs, bands, forward, level);
    let mut sel = SelectScratch::default();
    let mut sum = Vec::new();
    for i in 0..height {
        let y = if forward { i } else { height - 1 - i };
        pass.row(y, &mut sum);
        let other = {
            let mut slot = lock(&shared.slots[y]);
            match slot.take() {
                Some(other) => Some(other),
                None => {
                    *slot = Some(std::mem::take(&mut sum));
                    sum = lock(&shared.spare).pop().unwrap_or_default();
                    None
                }
            }
        };
        if let Some(other) = other {
            for (s, o) in sum.iter_mut().zip(&other) {
                *s = s.wrapping_add(*o);
            }
            lock(&shared.spare).push(other);
            let mut out = lock(&shared.rows[y]);
            select_row(inputs, bands, y, &sum, level, &mut sel, &mut out);
        }
    }
}

/// One aggregation pass's state.
struct Pass<'a, 'i> {
    inputs: &'a Inputs<'i>,
    bands: &'a Bands,
    forward: bool,
    level: Level,
    /// Paths crossing rows: ↓ (and the two diagonals with eight paths), previous and current row,
    /// each pixel's band padded by one entry at both ends.
    prev: Vec<Vec<u16>>,
    cur: Vec<Vec<u16>>,
    prev_min: Vec<Vec<u16>>,
    cur_min: Vec<Vec<u16>>,
    prev_starts: Vec<usize>,
    cur_starts: Vec<usize>,
    /// The previous row of the pass, if any.
    prev_y: Option<usize>,
    sum_starts: Vec<usize>,
    cost: Vec<u16>,
    /// The horizontal path at the previous and the current pixel.
    h_prev: Vec<u16>,
    h_cur: Vec<u16>,
    /// Previous pixels' vectors re-aligned to the current pixel's band.
    aligned: [Vec<u16>; 4],
    zero: Vec<u16>,
    bt_left: BtRow,
    bt_right: BtRow,
}

impl<'a, 'i> Pass<'a, 'i> {
    fn new(inputs: &'a Inputs<'i>, bands: &'a Bands, forward: bool, level: Level) -> Self {
        let row_paths = if inputs.paths == PathCount::Eight { 3 } else { 1 };
        let max = padded_lanes(inputs.range.count()) + 2;
        Pass {
            inputs,
            bands,
            forward,
            level,
            prev: vec![Vec::new(); row_paths],
            cur: vec![Vec::new(); row_paths],
            prev_min: vec![Vec::new(); row_paths],
            cur_min: vec![Vec::new(); row_paths],
            prev_starts: Vec::new(),
            cur_starts: Vec::new(),
            prev_y: None,
            sum_starts: Vec::new(),
            cost: Vec::new(),
            h_prev: vec![PAD; max],
            h_cur: vec![PAD; max],
            aligned: std::array::from_fn(|_| vec![PAD; max]),
            zero: vec![0; max],
            bt_left: BtRow::default(),
            bt_right: BtRow::default(),
        }
    }

    /// Aggregates row `y` (the next row of the pass) into `sum`: its path sums, band after band.
    #[inline(always)]
    fn row(&mut self, y: usize, sum: &mut Vec<u16>) {
        let inputs = self.inputs;
        let width = self.bands.width;
        let (offsets, lanes) = self.bands.row(y);
        starts(lanes, 0, &mut self.sum_starts);
        starts(lanes, 2, &mut self.cur_starts);
        let total = self.sum_starts[width];
        self.cost.resize(total, 0);
        let ad = ad_rows(inputs, y, &mut self.bt_left, &mut self.bt_right);
        let (cl, cr) = (inputs.census_left.row(y), inputs.census_right.row(y));
        let band_row = BandRow { offsets, lanes, starts: &self.sum_starts };
        let features = Features::capped(self.level);
        kernels::cost_bands(features, cl, cr, band_row, inputs.range.max, inputs.worst, ad, &mut self.cost);

        let padded = self.cur_starts[width];
        for (row, mins) in self.cur.iter_mut().zip(&mut self.cur_min) {
            // The steps write every entry but the pads, which are set pixel by pixel.
            row.resize(padded, PAD);
            mins.resize(width, 0);
        }
        // Every entry is written by the first path step of its pixel.
        sum.resize(total, 0);
        let image = inputs.image.row(y);
        let prev_image = self.prev_y.map(|py| inputs.image.row(py));
        let prev_bands = self.prev_y.map(|py| self.bands.row(py));
        let step: isize = if self.forward { 1 } else { -1 };
        let mut h_min = 0u16;
        let mut h_src: Option<usize> = None;
        for i in 0..width {
            let x = if self.forward { i } else { width - 1 - i };
            let (o, n) = (offsets[x], usize::from(lanes[x]));
            let cost = &self.cost[self.sum_starts[x]..self.sum_starts[x] + n];
            let s = &mut sum[self.sum_starts[x]..self.sum_starts[x] + n];
            let [a0, a1, a2, a3] = &mut self.aligned;
            // The horizontal path from the previous pixel of the row.
            let h_in = match h_src {
                Some(px) => {
                    let src =
                        Source { costs: &self.h_prev, offset: offsets[px], lanes: usize::from(lanes[px]) };
                    let prev = align(src, o, n, a0);
                    PathIn { prev, prev_min: h_min, p2: inputs.p2.p2(image[x], image[px]) }
                }
                None => PathIn { prev: &self.zero[..n + 2], prev_min: 0, p2: 0 },
            };
            // Paths from the previous row: from x, x − step and x + step.
            let start = PathIn { prev: &self.zero[..n + 2], prev_min: 0, p2: 0 };
            let mut row_ins: [PathIn<'_>; 3] = [start; 3];
            if let (Some(pb), Some(pi)) = (prev_bands, prev_image) {
                let back = x.checked_add_signed(-step).filter(|&v| v < width);
                let ahead = x.checked_add_signed(step).filter(|&v| v < width);
                let paths = self.cur.len();
                for (k, (scratch, src_x)) in
                    [a1, a2, a3].into_iter().zip([Some(x), back, ahead]).enumerate().take(paths)
                {
                    if let Some(sx) = src_x {
                        let st = self.prev_starts[sx];
                        let sn = usize::from(pb.1[sx]);
                        let src =
                            Source { costs: &self.prev[k][st..st + sn + 2], offset: pb.0[sx], lanes: sn };
                        let prev = align(src, o, n, scratch);
                        row_ins[k] = PathIn {
                            prev,
                            prev_min: self.prev_min[k][sx],
                            p2: inputs.p2.p2(image[x], pi[sx]),
                        };
                    }
                }
            }
            let st = self.cur_starts[x];
            let h_out = &mut self.h_cur[..n + 2];
            let mins = if self.cur.len() == 3 {
                let [c0, c1, c2] = &mut self.cur[..] else { unreachable!() };
                let (c0, c1, c2) = (
                    with_pads(&mut c0[st..st + n + 2]),
                    with_pads(&mut c1[st..st + n + 2]),
                    with_pads(&mut c2[st..st + n + 2]),
                );
                let outs = [h_out, c0, c1, c2];
                let ins = [h_in, row_ins[0], row_ins[1], row_ins[2]];
                let m = kernels::path_step::<4>(self.level, cost, inputs.p1, ins, outs, s, false);
                for k in 0..3 {
                    self.cur_min[k][x] = m[k + 1];
                }
                m[0]
            } else {
                let outs = [h_out, with_pads(&mut self.cur[0][st..st + n + 2])];
                let m =
                    kernels::path_step::<2>(self.level, cost, inputs.p1, [h_in, row_ins[0]], outs, s, false);
                self.cur_min[0][x] = m[1];
                m[0]
            };
            // The buffer held wider bands before: its end pad must be a pad again.
            self.h_cur[n + 1] = PAD;
            h_min = mins;
            h_src = Some(x);
            std::mem::swap(&mut self.h_prev, &mut self.h_cur);
        }
        std::mem::swap(&mut self.prev, &mut self.cur);
        std::mem::swap(&mut self.prev_min, &mut self.cur_min);
        std::mem::swap(&mut self.prev_starts, &mut self.cur_starts);
        self.prev_y = Some(y);
    }

    /// Adds the ← path of row `y` into `sum`, right after [`Pass::row`] of the same row (whose
    /// costs it reuses).
    #[inline(always)]
    fn leftward(&mut self, y: usize, sum: &mut [u16]) {
        let inputs = self.inputs;
        let width = self.bands.width;
        let (offsets, lanes) = self.bands.row(y);
        let image = inputs.image.row(y);
        let mut h_min = 0u16;
        for x in (0..width).rev() {
            let (o, n) = (offsets[x], usize::from(lanes[x]));
            let range = self.sum_starts[x]..self.sum_starts[x] + n;
            let h_in = if x + 1 < width {
                let px = x + 1;
                let src = Source { costs: &self.h_prev, offset: offsets[px], lanes: usize::from(lanes[px]) };
                let prev = align(src, o, n, &mut self.aligned[0]);
                PathIn { prev, prev_min: h_min, p2: inputs.p2.p2(image[x], image[px]) }
            } else {
                PathIn { prev: &self.zero[..n + 2], prev_min: 0, p2: 0 }
            };
            let outs = [&mut self.h_cur[..n + 2]];
            let [m] = kernels::path_step::<1>(
                self.level,
                &self.cost[range.clone()],
                inputs.p1,
                [h_in],
                outs,
                &mut sum[range],
                true,
            );
            self.h_cur[n + 1] = PAD;
            h_min = m;
            std::mem::swap(&mut self.h_prev, &mut self.h_cur);
        }
    }
}

/// Row `y`'s AD-census intensity-term inputs (if the cost has the term), filled into `left` and
/// `right`.
fn ad_rows<'b>(
    inputs: &Inputs<'_>,
    y: usize,
    left: &'b mut BtRow,
    right: &'b mut BtRow,
) -> Option<AdRows<'b>> {
    let (l, r, weight, cap) = inputs.ad?;
    left.fill(l.row(y), false);
    right.fill(r.row(y), true);
    Some(AdRows { left, right, weight, cap })
}

/// `v` with [`PAD`] at both ends (a pixel's path-cost vector before its step fills the rest).
#[inline(always)]
fn with_pads(v: &mut [u16]) -> &mut [u16] {
    let n = v.len();
    v[0] = PAD;
    v[n - 1] = PAD;
    v
}

/// A neighbour's padded path-cost vector and its band.
#[derive(Clone, Copy)]
struct Source<'s> {
    costs: &'s [u16],
    offset: i32,
    lanes: usize,
}

/// `src` as a padded vector over the band `offset .. offset + lanes` (the pads standing for
/// `offset - 1` and `offset + lanes`): itself where the bands agree, else re-aligned into
/// `scratch` with [`PAD`] where the neighbour has no entry.
#[inline]
fn align<'s>(src: Source<'s>, offset: i32, lanes: usize, scratch: &'s mut [u16]) -> &'s [u16] {
    if src.offset == offset && src.lanes == lanes {
        return &src.costs[..lanes + 2];
    }
    let out = &mut scratch[..lanes + 2];
    out.fill(PAD);
    // The pads stand for the disparities just outside the band, which the neighbour may have.
    let lo = (offset - 1).max(src.offset);
    let hi = (offset + lanes as i32 + 1).min(src.offset + src.lanes as i32);
    if lo < hi {
        let (a, b, len) = ((lo - offset + 1) as usize, (lo - src.offset) as usize + 1, (hi - lo) as usize);
        out[a..a + len].copy_from_slice(&src.costs[b..b + len]);
    }
    out
}

#[derive(Default)]
struct SelectScratch {
    starts: Vec<usize>,
    right_cost: Vec<u16>,
    right_index: Vec<u16>,
}

/// The lanes of a band at `offset` whose disparity is in the range and whose right pixel is in
/// the image.
fn feasible_lanes(x: usize, width: usize, range: DisparityRange, offset: i32, lanes: usize) -> Range<usize> {
    let lo = i64::from(range.min).max(x as i64 - (width as i64 - 1)).max(i64::from(offset));
    let hi = i64::from(range.max).min(x as i64 + 1).min(i64::from(offset) + lanes as i64);
    let (lo, hi) = (lo - i64::from(offset), hi - i64::from(offset));
    if lo >= hi {
        0..0
    } else {
        lo as usize..hi as usize
    }
}

/// Winner-takes-all over a row of band sums, as [`crate::wta::select_row`] over the full range:
/// the uniqueness test, the left-right check against the right view's winners from the same
/// sums, the subpixel fit. A winner at an end of its band where the band (not the range or the
/// image) stopped the search is rejected as [`PixelStatus::RangeEnd`].
#[allow(clippy::too_many_arguments)]
fn select_row(
    inputs: &Inputs<'_>,
    bands: &Bands,
    y: usize,
    sum: &[u16],
    level: Level,
    scratch: &mut SelectScratch,
    out: &mut [f32],
) {
    let sel = inputs.selection;
    let width = bands.width;
    let (offsets, lanes) = bands.row(y);
    starts(lanes, 0, &mut scratch.starts);
    let costs = |x: usize| &sum[scratch.starts[x]..scratch.starts[x] + usize::from(lanes[x])];
    // The right view's winners (as `winner::right_view_winners`): indexed by `width - 1 - xr`, a
    // left pixel's candidates are contiguous; disparity indices from the range's start.
    const NONE: u16 = u16::MAX;
    if sel.lr_max_diff.is_some() {
        scratch.right_cost.clear();
        scratch.right_cost.resize(width, u16::MAX);
        scratch.right_index.clear();
        scratch.right_index.resize(width, NONE);
        for (x, &o) in offsets.iter().enumerate() {
            let c = costs(x);
            let ks = feasible_lanes(x, width, sel.range, o, c.len());
            if ks.is_empty() {
                continue;
            }
            let q0 = (width as i64 - 1 - x as i64 + i64::from(o) + ks.start as i64) as usize;
            let span = q0..q0 + ks.len();
            let first = (o - sel.range.min) as usize + ks.start;
            kernels::keep_smaller(
                level,
                &c[ks],
                first as u16,
                &mut scratch.right_cost[span.clone()],
                &mut scratch.right_index[span],
            );
        }
    }
    for (x, o) in out.iter_mut().enumerate() {
        *o = tagged_nan(PixelStatus::NoMatch);
        let offset = offsets[x];
        let c = costs(x);
        let ks = feasible_lanes(x, width, sel.range, offset, c.len());
        if ks.is_empty() {
            continue;
        }
        let best = ks.start + kernels::argmin(level, &c[ks.clone()]).1;
        let d_int = offset + best as i32;
        // Where the band, not the range or the image, ended the search.
        let all = feasible_lanes(x, width, sel.range, sel.range.min, sel.range.count());
        let (first, last) = (sel.range.min + all.start as i32, sel.range.min + all.end as i32 - 1);
        if (best == ks.start && d_int > first) || (best + 1 == ks.end && d_int < last) {
            *o = tagged_nan(PixelStatus::RangeEnd);
            continue;
        }
        if ambiguous(c, ks.clone(), best, sel.uniqueness_ratio, Ties::Unique) {
            *o = tagged_nan(PixelStatus::Ambiguous);
            continue;
        }
        if let Some(max_diff) = sel.lr_max_diff {
            let xr = x as i64 - i64::from(d_int);
            let check = left_right_check(
                &scratch.right_index,
                xr,
                d_int as f32,
                i64::from(sel.range.min),
                max_diff,
                sel.lr_left_neighbour,
            );
            if let Err(occluded) = check {
                *o = tagged_nan(if occluded { PixelStatus::Occluded } else { PixelStatus::Mismatch });
                continue;
            }
        }
        *o = d_int as f32 + refined_offset(c, ks, best, sel.subpixel);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bands_cover_the_coarse_span_with_a_margin() {
        let range = DisparityRange::new(0, 128).unwrap();
        let mut coarse = DisparityMap::new(10, 10, 20.0);
        coarse.row_mut(5)[5] = 25.0;
        for y in 0..10 {
            coarse.row_mut(y)[0] = f32::NAN;
        }
        let bands = Bands::from_coarse(&coarse, 20, 20, range);
        // Fine (10, 10) → coarse (5, 5): span 40..=50 plus the margin, in one 16-lane block.
        let i = 10 * 20 + 10;
        let (o, n) = (bands.offset[i], i32::from(bands.lanes[i]));
        assert!(o <= 40 - MARGIN && o + n > 50 + MARGIN, "{o} + {n}");
        // Far from the odd pixel: 40 ± margin in 16 lanes.
        let j = 18 * 20 + 18;
        assert_eq!(bands.lanes[j], 16);
        assert!(bands.offset[j] <= 36 && bands.offset[j] + 16 > 44);
        // Nothing valid anywhere: the whole range.
        let empty = Bands::from_coarse(&DisparityMap::new(10, 10, f32::NAN), 20, 20, range);
        assert_eq!(empty, Bands::full(20, 20, range));
    }

    #[test]
    fn bands_stay_inside_the_range() {
        let range = DisparityRange::new(-8, 40).unwrap();
        for d in [-4.0f32, 0.0, 10.0, 19.5] {
            let bands = Bands::from_coarse(&DisparityMap::new(8, 8, d), 16, 16, range);
            for (&o, &n) in bands.offset.iter().zip(&bands.lanes) {
                assert!(o >= range.min && (o + i32::from(n) <= range.max || o == range.min), "{d}: {o} {n}");
            }
        }
    }

    use crate::aggregate::P2Table;
    use crate::{GrayImage, Image, MatchingCost, SgmParams, Subpixel};

    fn pair(w: usize, h: usize, shift: i64, seed: u64) -> (GrayImage, GrayImage) {
        let mut s = seed | 1;
        let tex: Vec<u16> = (0..(w + 64) * h)
            .map(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                // Blocks of 3 px: smooth enough for ties and plateaus, textured enough to match.
                (s % 8) as u16 * 8000
            })
            .collect();
        let at = |x: i64, y: usize| tex[y * (w + 64) + (x + 32) as usize];
        let left = GrayImage::from_fn(w, h, |x, y| at(x as i64 / 3 * 3, y));
        let right = GrayImage::from_fn(w, h, |x, y| at((x as i64 + shift + y as i64 % 3) / 3 * 3, y));
        (left, right)
    }

    /// Random bands: offsets anywhere in (or a little past) the range, 1–3 blocks of lanes.
    fn random_bands(w: usize, h: usize, range: DisparityRange, seed: u64) -> Bands {
        let mut s = seed | 1;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let full = padded_lanes(range.count());
        let mut bands = Bands::full(w, h, range);
        for (o, n) in bands.offset.iter_mut().zip(&mut bands.lanes) {
            let lanes = (16 * (1 + next() % 3) as usize).min(full);
            let lo = (range.min as i64 + (next() % range.count() as u64) as i64 - 4) as i32;
            let (bo, bn) = band(lo, lo + (next() % 8) as i32, range, full);
            (*o, *n) = if next() % 4 == 0 { (range.min, full as u16) } else { (bo, bn.max(lanes) as u16) };
            // The invariant of `Bands`: inside the padded lanes of the whole range.
            *o = (*o).min(range.min + (full - usize::from(*n)) as i32);
        }
        bands
    }

    /// The path sums of every row over `bands`, straight from the recurrence: per direction,
    /// `L(p, d) = C(p, d) + min(L(q, d), L(q, d ± 1) + P1, min L(q) + P2) - min L(q)` with `L(q, d)`
    /// infinite outside `q`'s band.
    fn reference_sums(inputs: &Inputs<'_>, bands: &Bands) -> Vec<Vec<u16>> {
        let (w, h) = (bands.width, bands.height);
        let costs: Vec<Vec<u16>> = (0..h)
            .map(|y| {
                let mut p = Pass::new(inputs, bands, true, Level::Scalar);
                let (offsets, lanes) = bands.row(y);
                starts(lanes, 0, &mut p.sum_starts);
                let mut c = vec![0u16; p.sum_starts[w]];
                let ad = ad_rows(inputs, y, &mut p.bt_left, &mut p.bt_right);
                let (cl, cr) = (inputs.census_left.row(y), inputs.census_right.row(y));
                let row = BandRow { offsets, lanes, starts: &p.sum_starts };
                crate::kernels::scalar::cost_bands_scalar(
                    cl,
                    cr,
                    row,
                    inputs.range.max,
                    inputs.worst,
                    ad,
                    &mut c,
                );
                c
            })
            .collect();
        let mut sums: Vec<Vec<u32>> = costs.iter().map(|c| vec![0; c.len()]).collect();
        let dirs: &[(isize, isize)] = if inputs.paths == PathCount::Eight {
            &[(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, 1), (1, -1), (-1, -1)]
        } else {
            &[(1, 0), (-1, 0), (0, 1), (0, -1)]
        };
        let at = |x: usize, y: usize| (bands.offset[y * w + x], usize::from(bands.lanes[y * w + x]));
        let start =
            |x: usize, y: usize| bands.lanes[y * w..y * w + x].iter().map(|&n| usize::from(n)).sum::<usize>();
        for &(dx, dy) in dirs {
            let mut l: Vec<Vec<u32>> = costs.iter().map(|c| vec![0; c.len()]).collect();
            let ys: Vec<usize> = if dy >= 0 { (0..h).collect() } else { (0..h).rev().collect() };
            let xs: Vec<usize> =
                if dx > 0 || (dx == 0 && dy > 0) { (0..w).collect() } else { (0..w).rev().collect() };
            for &y in &ys {
                for &x in &xs {
                    let (o, n) = at(x, y);
                    let s = start(x, y);
                    let (qx, qy) = (x as isize - dx, y as isize - dy);
                    let prev = ((0..w as isize).contains(&qx) && (0..h as isize).contains(&qy)).then(|| {
                        let (qx, qy) = (qx as usize, qy as usize);
                        let (qo, qn) = at(qx, qy);
                        let qs = start(qx, qy);
                        let v: Vec<u32> = l[qy][qs..qs + qn].to_vec();
                        let p2 = u32::from(inputs.p2.p2(inputs.image.get(x, y), inputs.image.get(qx, qy)));
                        (qo, v, p2)
                    });
                    for k in 0..n {
                        let c = u32::from(costs[y][s + k]);
                        l[y][s + k] = match &prev {
                            None => c,
                            Some((qo, v, p2)) => {
                                let min = *v.iter().min().unwrap();
                                let get = |d: i32| {
                                    let i = d - qo;
                                    if (0..v.len() as i32).contains(&i) {
                                        v[i as usize]
                                    } else {
                                        u32::MAX / 4
                                    }
                                };
                                let d = o + k as i32;
                                let p1 = u32::from(inputs.p1);
                                let best = get(d).min(get(d - 1) + p1).min(get(d + 1) + p1).min(min + p2);
                                c + best - min
                            }
                        };
                        sums[y][s + k] += l[y][s + k];
                    }
                }
            }
        }
        sums.into_iter().map(|r| r.into_iter().map(|v| v as u16).collect()).collect()
    }

    /// The sums [`aggregate_bands`] selects from: both passes, added.
    fn band_sums(inputs: &Inputs<'_>, bands: &Bands, level: Level) -> Vec<Vec<u16>> {
        let mut forward = Pass::new(inputs, bands, true, level);
        let mut sums: Vec<Vec<u16>> = (0..bands.height)
            .map(|y| {
                let mut s = Vec::new();
                forward.row(y, &mut s);
                s
            })
            .collect();
        let mut backward = Pass::new(inputs, bands, false, level);
        let mut b = Vec::new();
        for y in (0..bands.height).rev() {
            backward.row(y, &mut b);
            for (s, b) in sums[y].iter_mut().zip(&b) {
                *s = s.wrapping_add(*b);
            }
        }
        sums
    }

    fn census(image: &GrayImage, params: &SgmParams) -> Image<u64> {
        let mut out = Image::new(image.width(), image.height(), 0u64);
        crate::census::census_transform(image, params.census, &mut out);
        out
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]

        /// Bands covering the whole range give the full search's winners bit for bit (tags too),
        /// two-pass and single-pass, at every SIMD level.
        #[test]
        fn full_bands_are_the_full_search(
            w in 10usize..70, h in 8usize..24, nd in 1i32..40, min in -6i32..6, four in proptest::prelude::any::<bool>(),
            p1 in 1u16..40, p2_extra in 1u16..200, edge in 0u16..40, uniq in 0u32..15, lr in proptest::prelude::any::<Option<u8>>(),
            sub in 0u8..3, ad in proptest::prelude::any::<Option<(u8, u8)>>(), seed in proptest::prelude::any::<u64>(),
            strips in 1usize..4, overlap in 0usize..12,
        ) {
            let nd = nd.min(w as i32 - 2);
            let params = SgmParams {
                range: DisparityRange::new(min, min + nd).unwrap(),
                paths: if four { PathCount::Four } else { PathCount::Eight },
                p1, p2: p1 + p2_extra, p2_edge_scale: edge, uniqueness_ratio: uniq,
                lr_max_diff: lr.map(|v| f32::from(v % 4) * 0.75),
                subpixel: [Subpixel::None, Subpixel::Parabola, Subpixel::Equiangular][sub as usize],
                matching_cost: match ad {
                    None => MatchingCost::Census,
                    Some((weight, cap)) => MatchingCost::AdCensus { weight: weight % 9, cap: cap % 100 },
                },
                ..SgmParams::default()
            };
            let (left, right) = pair(w, h, (seed % 7) as i64 + i64::from(min), seed);
            let (cl, cr) = (census(&left, &params), census(&right, &params));
            let full = crate::sgm::aggregate_census(&left, Some(&right), &cl, &cr, &params);
            let p2 = P2Table::new(params.p1, params.p2, params.p2_edge_scale);
            let inputs = crate::sgm::aggregation_inputs(&left, Some(&right), &cl, &cr, &params, &p2);
            let mut streamed = DisparityMap::new(w, h, 0.0);
            crate::aggregate::stream_and_select(&inputs, strips, overlap, streamed.as_mut_slice());
            for level in crate::kernels::supported_levels() {
                let bands = Bands::full(w, h, params.range);
                let banded = aggregate_bands(&inputs, &bands, level);
                for (i, (a, b)) in banded.as_slice().iter().zip(full.as_slice()).enumerate() {
                    proptest::prop_assert_eq!(a.to_bits(), b.to_bits(), "{:?} pixel {}: {} vs {}", level, i, a, b);
                }
                // Single pass, in strips with warm-up rows.
                let banded = stream_bands(&inputs, &bands, level, strips, overlap);
                for (i, (a, b)) in banded.as_slice().iter().zip(streamed.as_slice()).enumerate() {
                    proptest::prop_assert_eq!(a.to_bits(), b.to_bits(), "single pass {:?} pixel {}: {} vs {}", level, i, a, b);
                }
            }
        }

        /// Any bands: the passes' sums equal the recurrence computed directly, at every SIMD level,
        /// and the two threads' handover gives the same map as the sums selected row by row.
        #[test]
        fn band_sums_follow_the_recurrence(
            w in 10usize..60, h in 6usize..20, nd in 8i32..60, min in -6i32..6, four in proptest::prelude::any::<bool>(),
            p1 in 1u16..40, p2_extra in 1u16..200, edge in 0u16..40, seed in proptest::prelude::any::<u64>(),
        ) {
            let nd = nd.min(w as i32 - 2);
            let params = SgmParams {
                range: DisparityRange::new(min, min + nd).unwrap(),
                paths: if four { PathCount::Four } else { PathCount::Eight },
                p1, p2: p1 + p2_extra, p2_edge_scale: edge,
                ..SgmParams::default()
            };
            let (left, right) = pair(w, h, (seed % 5) as i64, seed);
            let (cl, cr) = (census(&left, &params), census(&right, &params));
            let p2 = P2Table::new(params.p1, params.p2, params.p2_edge_scale);
            let inputs = crate::sgm::aggregation_inputs(&left, Some(&right), &cl, &cr, &params, &p2);
            let bands = random_bands(w, h, params.range, seed);
            let reference = reference_sums(&inputs, &bands);
            for level in crate::kernels::supported_levels() {
                let sums = band_sums(&inputs, &bands, level);
                for y in 0..h {
                    if let Some(i) = (0..sums[y].len()).find(|&i| sums[y][i] != reference[y][i]) {
                        let (o, l) = bands.row(y);
                        proptest::prop_assert!(false, "{:?} row {} entry {}: {} vs {}; offsets {:?} lanes {:?}", level, y, i, sums[y][i], reference[y][i], o, l);
                    }
                }
                let map = aggregate_bands(&inputs, &bands, level);
                let mut scratch = SelectScratch::default();
                for (y, s) in sums.iter().enumerate() {
                    let mut row = vec![0f32; w];
                    select_row(&inputs, &bands, y, s, level, &mut scratch, &mut row);
                    for (a, b) in row.iter().zip(map.row(y)) {
                        proptest::prop_assert_eq!(a.to_bits(), b.to_bits());
                    }
                }
            }
        }
    }
}
