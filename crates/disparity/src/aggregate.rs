//! Semi-global path aggregation (Hirschmüller 2008, eq. 13):
//!
//! `L_r(p, d) = C(p, d) + min(L_r(p-r, d), L_r(p-r, d±1) + P1, min_k L_r(p-r, k) + P2) - min_k L_r(p-r, k)`
//!
//! summed over the path directions `r`. The directions split into a forward pass (rows top to
//! bottom, pixels left to right: →, ↓, ↘, ↙) and a mirrored backward pass, run on two threads.
//!
//! Each pass computes the census Hamming costs of a row on the fly (no stored cost volume) and
//! runs the four path steps of a pixel in one fused SIMD kernel ([`crate::simd::path_step`]),
//! which adds the path costs straight into the shared `u16` sum volume. Rows are handed over
//! through a per-row lock: the first pass to reach a row stores its sums, the second adds its own
//! and, the row now being final, selects the row's disparities while it is still in cache. So
//! the aggregated volume (`2·W·H·D` bytes) is the only `W·H·D` buffer; each pass holds
//! `O(W·D)` of path state, allocated once.

use std::sync::Mutex;

use crate::simd::{self, padded_lanes, Level, PathIn, PAD};
use crate::wta::{select_row, Selection, WtaScratch};
use crate::{DisparityRange, GrayImage, Image, PathCount};

/// P2 for each intensity step along a path (8-bit grey levels, 0..=255): disparity jumps are
/// cheaper across image edges, where depth discontinuities usually are.
/// `P2(ΔI) = max(P1 + 1, P2 · s / (s + ΔI))` for edge scale `s`; `s = 0` keeps P2 constant.
pub(crate) struct P2Table {
    table: [u16; 256],
    /// `Some(P2)` when P2 does not depend on the intensity step (edge scale 0).
    constant: Option<u16>,
}

impl P2Table {
    pub(crate) fn new(p1: u16, p2: u16, edge_scale: u16) -> Self {
        let mut t = [p2; 256];
        if edge_scale > 0 {
            for (step, v) in t.iter_mut().enumerate() {
                let s = u32::from(edge_scale);
                *v = ((u32::from(p2) * s / (s + step as u32)) as u16).max(p1 + 1);
            }
        }
        P2Table { table: t, constant: (edge_scale == 0).then_some(p2) }
    }

    /// P2 between neighbouring pixels of intensities `a` and `b`.
    #[inline]
    pub(crate) fn p2(&self, a: u16, b: u16) -> u16 {
        match self.constant {
            Some(p2) => p2,
            None => self.table[usize::from(a.abs_diff(b) / 257)],
        }
    }
}

/// Largest P2 accepted, so every sum of eight path costs fits in `u16`.
pub(crate) const MAX_P2: u16 = 4000;

/// What the aggregation reads.
pub(crate) struct Inputs<'a> {
    /// The left image (for the edge-adaptive P2).
    pub image: &'a GrayImage,
    pub census_left: &'a Image<u64>,
    pub census_right: &'a Image<u64>,
    pub range: DisparityRange,
    /// Matching cost of a disparity that points outside the right image.
    pub worst: u16,
    pub paths: PathCount,
    pub p1: u16,
    pub p2: &'a P2Table,
    pub selection: Selection,
}

/// Bytes of path state one pass holds (for the memory plan).
pub(crate) fn pass_state_bytes(width: usize, nd: usize, paths: PathCount) -> usize {
    let lanes = padded_lanes(nd);
    let stride = lanes + 2;
    let row_paths = if paths == PathCount::Eight { 3 } else { 1 };
    // cost row + two rows per row path (+ minima) + horizontal + zero vector + WTA scratch
    2 * (width * lanes + row_paths * 2 * width * (stride + 1) + 3 * stride) + WtaScratch::bytes(width)
}

/// One row of the shared output: the path sums and the disparities, and whether one pass has
/// already stored its sums.
struct RowSlot<'a> {
    sum: &'a mut [u16],
    disparity: &'a mut [f32],
    visited: bool,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Pass {
    /// Rows top to bottom, pixels left to right.
    Forward,
    /// Rows bottom to top, pixels right to left.
    Backward,
}

/// Aggregates all path directions into `sum` (`[y][x][d]`, any initial contents) and selects
/// every row's disparities into `disparity`.
pub(crate) fn aggregate_and_select(inputs: &Inputs<'_>, sum: &mut [u16], disparity: &mut [f32]) {
    let (width, height) = inputs.image.size();
    let nd = inputs.range.count();
    debug_assert_eq!(sum.len(), width * height * nd);
    debug_assert_eq!(disparity.len(), width * height);
    let rows: Vec<Mutex<RowSlot<'_>>> = sum
        .chunks_mut(width * nd)
        .zip(disparity.chunks_mut(width))
        .map(|(sum, disparity)| Mutex::new(RowSlot { sum, disparity, visited: false }))
        .collect();
    rayon::join(
        || aggregate_pass(inputs, Pass::Forward, &rows),
        || aggregate_pass(inputs, Pass::Backward, &rows),
    );
}

/// How many pixels ahead the second pass prefetches the sums it will add to: by then the first
/// pass's sums of that row have long left the cache.
const PREFETCH_PIXELS: usize = 6;

/// Asks for the stored sums of the pixel `PREFETCH_PIXELS` ahead in this pass's direction.
#[inline(always)]
fn prefetch_ahead(sum: &[u16], x: usize, nd: usize, forward: bool) {
    #[cfg(target_arch = "x86_64")]
    {
        let width = sum.len() / nd;
        let ahead = if forward { x + PREFETCH_PIXELS } else { x.wrapping_sub(PREFETCH_PIXELS) };
        if ahead < width {
            let bytes = &sum[ahead * nd..(ahead + 1) * nd];
            let (start, end) = (bytes.as_ptr() as usize, bytes.as_ptr() as usize + 2 * nd);
            let mut line = start & !63;
            while line < end {
                // SAFETY: a prefetch is only a hint; it never faults, and the address lies inside
                // `sum` (rounded down to its cache line).
                unsafe {
                    std::arch::x86_64::_mm_prefetch::<{ std::arch::x86_64::_MM_HINT_T0 }>(line as *const i8)
                };
                line += 64;
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (sum, x, nd, forward);
}

/// Path costs of one row for one direction (padded per pixel) and each pixel's minimum.
struct RowPaths {
    costs: Vec<u16>,
    mins: Vec<u16>,
}

impl RowPaths {
    fn pair(width: usize, stride: usize) -> [RowPaths; 2] {
        std::array::from_fn(|_| RowPaths { costs: vec![PAD; width * stride], mins: vec![0; width] })
    }
}

fn aggregate_pass(inputs: &Inputs<'_>, pass: Pass, rows: &[Mutex<RowSlot<'_>>]) {
    match simd::features().level {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: the level was detected on this CPU.
        Level::Avx512 => unsafe { aggregate_pass_avx512(inputs, pass, rows) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above.
        Level::Avx2 => unsafe { aggregate_pass_avx2(inputs, pass, rows) },
        _ => aggregate_pass_generic(inputs, pass, rows, Level::Scalar),
    }
}

/// The pass compiled for AVX-512BW, so the path-step kernel inlines into the pixel loop.
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2")]
unsafe fn aggregate_pass_avx512(inputs: &Inputs<'_>, pass: Pass, rows: &[Mutex<RowSlot<'_>>]) {
    aggregate_pass_generic(inputs, pass, rows, Level::Avx512)
}

/// The pass compiled for AVX2.
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn aggregate_pass_avx2(inputs: &Inputs<'_>, pass: Pass, rows: &[Mutex<RowSlot<'_>>]) {
    aggregate_pass_generic(inputs, pass, rows, Level::Avx2)
}

#[inline(always)]
fn aggregate_pass_generic(inputs: &Inputs<'_>, pass: Pass, rows: &[Mutex<RowSlot<'_>>], level: Level) {
    let (width, height) = inputs.image.size();
    let nd = inputs.range.count();
    let features = simd::features();
    let lanes = padded_lanes(nd);
    let stride = lanes + 2;
    let diagonals = inputs.paths == PathCount::Eight;
    let (p1, p2) = (inputs.p1, inputs.p2);

    let mut cost = vec![0u16; width * lanes];
    // Previous and current row of the vertical and the two diagonal paths.
    let mut vertical = RowPaths::pair(width, stride);
    let (mut diag_a, mut diag_b) = if diagonals {
        (RowPaths::pair(width, stride), RowPaths::pair(width, stride))
    } else {
        (RowPaths::pair(0, stride), RowPaths::pair(0, stride))
    };
    let mut horizontal = [vec![PAD; stride], vec![PAD; stride]];
    // A path entering the image: stepping from all-zero costs yields the matching cost.
    let zero = vec![0u16; stride];
    let start = PathIn { prev: &zero, prev_min: 0, p2: 0 };
    let mut scratch = WtaScratch::new(width);

    // The diagonal "a" comes from x - step in the previous row of the pass, "b" from x + step.
    let forward = pass == Pass::Forward;
    for row_index in 0..height {
        let y = if forward { row_index } else { height - 1 - row_index };
        let first_row = row_index == 0;
        let prev_y = if first_row {
            y
        } else if forward {
            y - 1
        } else {
            y + 1
        };
        let row = inputs.image.row(y);
        let prev_row = inputs.image.row(prev_y);
        simd::cost_row(
            features,
            inputs.census_left.row(y),
            inputs.census_right.row(y),
            inputs.range.min,
            nd,
            inputs.worst,
            &mut cost,
        );

        let mut slot = rows[y].lock().unwrap_or_else(|e| e.into_inner());
        let accumulate = slot.visited;
        let [v_prev, v_cur] = &mut vertical;
        let [a_prev, a_cur] = &mut diag_a;
        let [b_prev, b_cur] = &mut diag_b;
        let mut h_min = 0u16;
        // The input of a path continuing from pixel `from` of the previous row.
        fn at<'a>(paths: &'a RowPaths, from: usize, stride: usize, p2: u16) -> PathIn<'a> {
            PathIn { prev: &paths.costs[from * stride..(from + 1) * stride], prev_min: paths.mins[from], p2 }
        }
        for col_index in 0..width {
            let x = if forward { col_index } else { width - 1 - col_index };
            let c = &cost[x * lanes..(x + 1) * lanes];
            let here = row[x];
            if accumulate {
                prefetch_ahead(slot.sum, x, nd, forward);
            }
            let sum = &mut slot.sum[x * nd..(x + 1) * nd];
            let [h_prev, h_cur] = &mut horizontal;
            let h_in = if col_index == 0 {
                start
            } else {
                let from = if forward { x - 1 } else { x + 1 };
                PathIn { prev: h_prev, prev_min: h_min, p2: p2.p2(here, row[from]) }
            };
            let v_in = if first_row { start } else { at(v_prev, x, stride, p2.p2(here, prev_row[x])) };
            let v_out = &mut v_cur.costs[x * stride..(x + 1) * stride];
            if diagonals {
                let (left, right) = (x.checked_sub(1), (x + 1 < width).then_some(x + 1));
                let (a_from, b_from) = if forward { (left, right) } else { (right, left) };
                let a_in = match a_from {
                    Some(f) if !first_row => at(a_prev, f, stride, p2.p2(here, prev_row[f])),
                    _ => start,
                };
                let b_in = match b_from {
                    Some(f) if !first_row => at(b_prev, f, stride, p2.p2(here, prev_row[f])),
                    _ => start,
                };
                let a_out = &mut a_cur.costs[x * stride..(x + 1) * stride];
                let b_out = &mut b_cur.costs[x * stride..(x + 1) * stride];
                let [mh, mv, ma, mb] = simd::path_step(
                    level,
                    c,
                    p1,
                    [h_in, v_in, a_in, b_in],
                    [h_cur, v_out, a_out, b_out],
                    sum,
                    accumulate,
                );
                h_min = mh;
                v_cur.mins[x] = mv;
                a_cur.mins[x] = ma;
                b_cur.mins[x] = mb;
            } else {
                let [mh, mv] = simd::path_step(level, c, p1, [h_in, v_in], [h_cur, v_out], sum, accumulate);
                h_min = mh;
                v_cur.mins[x] = mv;
            }
            horizontal.swap(0, 1);
        }
        vertical.swap(0, 1);
        diag_a.swap(0, 1);
        diag_b.swap(0, 1);
        if accumulate {
            // Both passes are in: the row's sums are final.
            let RowSlot { sum, disparity, .. } = &mut *slot;
            select_row(sum, width, nd, inputs.selection, &mut scratch, disparity);
        } else {
            slot.visited = true;
        }
    }
}
