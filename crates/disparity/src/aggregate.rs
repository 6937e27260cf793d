//! Semi-global path aggregation (Hirschmüller 2008, eq. 13):
//!
//! `L_r(p, d) = C(p, d) + min(L_r(p-r, d), L_r(p-r, d±1) + P1, min_k L_r(p-r, k) + P2) - min_k L_r(p-r, k)`
//!
//! summed over the path directions `r`.
//!
//! **Two passes, by strips** (the default): the directions split into a forward pass (rows top
//! to bottom, pixels left to right: →, ↓, ↘, ↙) and a mirrored backward pass, run on two
//! threads. The image is cut into horizontal strips of [`StripPlan::rows`] rows, processed one
//! after the other with one strip-sized `u16` sum volume reused by every strip. The forward pass
//! runs straight through (its path state carries over from strip to strip, so its paths are
//! exact); the backward pass of a strip starts [`StripPlan::overlap`] rows below the strip and
//! warms its vertical and diagonal paths up over those rows without storing anything. With one
//! strip (or an overlap reaching the bottom of the image) the result is exact SGM.
//!
//! The matching costs of a row are computed when a pass reaches it (no cost volume of the whole
//! image); the path steps of a pixel run in one fused SIMD kernel ([`crate::kernels::path_step`]),
//! which adds the path costs straight into the sum volume. Rows are handed over through a
//! per-row lock: the first pass to reach a row stores its sums (and, where the plan allows,
//! [`StripPlan::shared_costs`], its cost row for the other pass), the second adds its own and,
//! the row now being final, selects the row's disparities while it is still in cache.
//!
//! **Single pass** ([`stream_and_select`]): only the directions coming from above or from the
//! left (→, ↓, ↘, ↙, plus ← by a second sweep over each row, as OpenCV's default `MODE_SGBM`),
//! so every row is final as soon as it is done: `O(W·D)` memory, one cost row per image row.
//! The image is cut into strips by its height ([`crate::memory::stream_strips`], not by the
//! threads, so the map is the same on any machine), each warming its paths up over the rows
//! above it, run in parallel.

use std::sync::Mutex;

use crate::buffer::ScratchBuffer;
use crate::cost::{AdRows, AlignedRow, BtRow};
use crate::kernels::layout::{
    fits, padded_lanes, padded_lanes_u8, FromRow, PathIn, Trailing, MAX_PATH_COST, PAD, PAD_U8,
};
use crate::kernels::{self, features, Level};
use crate::wta::{select_row, Selection, WtaScratch};
use crate::{DisparityRange, GrayImage, Image, PathCount};

/// P2 for each intensity step along a path (8-bit grey levels, 0..=255): disparity jumps are
/// cheaper across image edges, where depth discontinuities usually are.
/// `P2(ΔI) = max(P1 + 1, P2 · s / (s + ΔI))` for edge scale `s`; `s = 0` keeps P2 constant.
pub(crate) struct P2Table {
    table: [u16; 256],
    /// The table in 8 bits, where every entry fits (the 8-bit passes).
    table_u8: Option<[u8; 256]>,
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
        let table_u8 = t.iter().all(|&v| v <= 255).then(|| t.map(|v| v as u8));
        P2Table { table: t, table_u8, constant: (edge_scale == 0).then_some(p2) }
    }

    /// [`P2Table::p2`] of each pair `a[i]`, `b[i]` into `out[i]`, narrowed to `T`.
    fn narrowed_row<T: PathCost>(&self, a: &[u16], b: &[u16], out: &mut [T]) {
        for ((o, &a), &b) in out.iter_mut().zip(a).zip(b) {
            *o = T::narrow(self.p2(a, b));
        }
    }

    /// The largest P2 of the table.
    pub(crate) fn max(&self) -> u16 {
        self.table.iter().copied().max().unwrap_or(0)
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

/// The type a pass keeps its path costs in: `u16` for any costs and penalties, `u8` (twice the
/// disparities per instruction, half the memory traffic) when every path cost fits in it
/// ([`fits`]); the sums are `u16` either way and the results identical.
trait PathCost: Copy + Default + Send + Sync + 'static {
    /// Pad at both ends of a path-cost vector.
    const PAD: Self;
    /// Path-cost vector length (before the two pads) for `nd` disparities.
    fn lanes(nd: usize) -> usize;
    /// A value known to fit (a penalty or a path minimum).
    fn narrow(v: u16) -> Self;
    /// Makes row `y`'s matching costs: [`kernels::cost_row`] into `wide` for `u16`,
    /// [`kernels::cost_row_u8`] straight into `narrow` for `u8` (no `u16` row in between).
    fn make_costs(
        inputs: &Inputs<'_>,
        y: usize,
        ad: Option<AdRows<'_>>,
        wide: &mut [u16],
        narrow: &mut [Self],
    );
    /// This pass's cost row made by [`PathCost::make_costs`]: `wide` for `u16`, `narrow` for `u8`.
    fn costs<'a>(level: Level, wide: &'a [u16], nd: usize, narrow: &'a mut [Self]) -> &'a [Self];
    /// The rows [`PathCost::make_costs`] writes when the row's costs live in `shared` (a row of
    /// the strip's shared cost rows) instead of this pass's own rows `wide` and `narrow`.
    fn shared_rows<'a>(
        shared: &'a mut [Self],
        wide: &'a mut [u16],
        narrow: &'a mut [Self],
    ) -> (&'a mut [u16], &'a mut [Self]);
    /// [`kernels::path_step`] in this type.
    fn step<const N: usize>(
        level: Level,
        cost: &[Self],
        p1: Self,
        ins: [PathIn<'_, Self>; N],
        outs: [&mut [Self]; N],
        sum: &mut [u16],
        accumulate: bool,
    ) -> [Self; N];
    /// Whether [`PathCost::row`] has a kernel for this level and lane count.
    fn has_row(level: Level, lanes: usize) -> bool;
    /// `out[i]` = the P2 of a step between pixels of intensities `a[i]` and `b[i]`.
    fn p2_row(_level: Level, p2: &P2Table, a: &[u16], b: &[u16], out: &mut [Self]) {
        p2.narrowed_row(a, b, out);
    }
    /// [`crate::kernels::row_u8`] in this type: a row of a pass with the horizontal path in
    /// registers; `false` (nothing done) where there is no such kernel.
    #[allow(clippy::too_many_arguments)]
    fn row<const K: usize>(
        level: Level,
        cost: &[Self],
        lanes: usize,
        nd: usize,
        p1: Self,
        p2: &[Self],
        from_row: [FromRow<'_, Self>; K],
        sum: &mut [u16],
        reverse: bool,
        accumulate: bool,
        trailing: Option<Trailing<'_, Self>>,
    ) -> bool;
}

impl PathCost for u16 {
    const PAD: u16 = PAD;
    fn lanes(nd: usize) -> usize {
        padded_lanes(nd)
    }
    fn narrow(v: u16) -> u16 {
        v
    }
    #[inline(always)]
    fn make_costs(inputs: &Inputs<'_>, y: usize, ad: Option<AdRows<'_>>, wide: &mut [u16], _: &mut [u16]) {
        let (census_left, census_right) = (inputs.census_left.row(y), inputs.census_right.row(y));
        let (min, nd) = (inputs.range.min, inputs.range.count());
        kernels::cost_row(features(), census_left, census_right, min, nd, inputs.worst, ad, wide);
    }
    fn costs<'a>(_: Level, wide: &'a [u16], _: usize, _: &'a mut [u16]) -> &'a [u16] {
        wide
    }
    fn shared_rows<'a>(
        shared: &'a mut [u16],
        _: &'a mut [u16],
        narrow: &'a mut [u16],
    ) -> (&'a mut [u16], &'a mut [u16]) {
        (shared, narrow)
    }
    #[inline(always)]
    fn step<const N: usize>(
        level: Level,
        cost: &[u16],
        p1: u16,
        ins: [PathIn<'_>; N],
        outs: [&mut [u16]; N],
        sum: &mut [u16],
        accumulate: bool,
    ) -> [u16; N] {
        // Only from the multiversioned loops below (`run_rows`, `stream_rows`).
        kernels::path_step_inlined(level, cost, p1, ins, outs, sum, accumulate)
    }
    fn has_row(_: Level, _: usize) -> bool {
        false
    }
    #[allow(clippy::too_many_arguments)]
    fn row<const K: usize>(
        _: Level,
        _: &[u16],
        _: usize,
        _: usize,
        _: u16,
        _: &[u16],
        _: [FromRow<'_, u16>; K],
        _: &mut [u16],
        _: bool,
        _: bool,
        _: Option<Trailing<'_, u16>>,
    ) -> bool {
        false
    }
}

impl PathCost for u8 {
    const PAD: u8 = PAD_U8;
    fn lanes(nd: usize) -> usize {
        padded_lanes_u8(nd)
    }
    fn narrow(v: u16) -> u8 {
        debug_assert!(v <= MAX_PATH_COST);
        v as u8
    }
    #[inline(always)]
    fn make_costs(inputs: &Inputs<'_>, y: usize, ad: Option<AdRows<'_>>, _: &mut [u16], narrow: &mut [u8]) {
        let (census_left, census_right) = (inputs.census_left.row(y), inputs.census_right.row(y));
        let (min, nd) = (inputs.range.min, inputs.range.count());
        kernels::cost_row_u8(features(), census_left, census_right, min, nd, inputs.worst, ad, narrow);
    }
    fn costs<'a>(_: Level, _: &'a [u16], _: usize, narrow: &'a mut [u8]) -> &'a [u8] {
        narrow
    }
    fn shared_rows<'a>(
        shared: &'a mut [u8],
        wide: &'a mut [u16],
        _: &'a mut [u8],
    ) -> (&'a mut [u16], &'a mut [u8]) {
        (wide, shared)
    }
    #[inline(always)]
    fn step<const N: usize>(
        level: Level,
        cost: &[u8],
        p1: u8,
        ins: [PathIn<'_, u8>; N],
        outs: [&mut [u8]; N],
        sum: &mut [u16],
        accumulate: bool,
    ) -> [u8; N] {
        kernels::path_step_u8(level, cost, p1, ins, outs, sum, accumulate)
    }
    fn has_row(level: Level, lanes: usize) -> bool {
        crate::kernels::row_u8_available(level, lanes)
    }
    fn p2_row(level: Level, p2: &P2Table, a: &[u16], b: &[u16], out: &mut [u8]) {
        match (p2.constant, &p2.table_u8) {
            (Some(c), _) => out.fill(Self::narrow(c)),
            (None, Some(table)) => kernels::p2_row_u8(level, table, a, b, out),
            (None, None) => p2.narrowed_row(a, b, out),
        }
    }
    #[inline(always)]
    fn row<const K: usize>(
        level: Level,
        cost: &[u8],
        lanes: usize,
        nd: usize,
        p1: u8,
        p2: &[u8],
        from_row: [FromRow<'_, u8>; K],
        sum: &mut [u16],
        reverse: bool,
        accumulate: bool,
        trailing: Option<Trailing<'_, u8>>,
    ) -> bool {
        crate::kernels::row_u8(level, cost, lanes, nd, p1, p2, from_row, sum, reverse, accumulate, trailing)
    }
}

/// Whether the passes run on 8-bit path costs: only where the 8-bit kernel pays off
/// ([`Level::u8_passes`]: every SIMD level) and every path cost fits.
fn use_u8(inputs: &Inputs<'_>) -> bool {
    u8_passes(inputs.worst, inputs.p1, inputs.p2.max())
}

/// [`use_u8`] from the matching cost's largest value and the penalties.
pub(crate) fn u8_passes(worst: u16, p1: u16, max_p2: u16) -> bool {
    features().level.u8_passes() && fits(worst, p1, max_p2)
}

/// What the aggregation reads.
pub(crate) struct Inputs<'a> {
    /// The left image (for the edge-adaptive P2).
    pub image: &'a GrayImage,
    pub census_left: &'a Image<u64>,
    pub census_right: &'a Image<u64>,
    /// The left and right images of the AD-census intensity term and its `(weight, cap)`, if the
    /// cost has one.
    pub ad: Option<(&'a GrayImage, &'a GrayImage, u16, u16)>,
    pub range: DisparityRange,
    /// Matching cost of a disparity that points outside the right image.
    pub worst: u16,
    pub paths: PathCount,
    pub p1: u16,
    pub p2: &'a P2Table,
    pub selection: Selection,
}

/// How the two-pass aggregation cuts the image into strips.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct StripPlan {
    /// Rows per strip (the sum volume holds this many rows).
    pub rows: usize,
    /// Rows below a strip over which the backward pass warms up its paths.
    pub overlap: usize,
    /// Whether the passes keep each strip row's matching costs for the other pass (a strip of
    /// `W × lanes` entries per row in the passes' type, beside the sums), so every cost row is
    /// computed once instead of once per pass.
    pub shared_costs: bool,
}

/// Bytes of one row of matching costs as the passes hold it (`u8` or `u16`), the row
/// [`aggregate_strips`] keeps per strip row with [`StripPlan::shared_costs`].
pub(crate) fn cost_row_bytes(width: usize, nd: usize, u8_passes: bool) -> usize {
    fn bytes<T: PathCost>(width: usize, nd: usize) -> usize {
        width.saturating_mul(T::lanes(nd)).saturating_mul(std::mem::size_of::<T>())
    }
    if u8_passes {
        bytes::<u8>(width, nd)
    } else {
        bytes::<u16>(width, nd)
    }
}

/// Bytes of path state one pass holds (for the memory plan).
pub(crate) fn pass_state_bytes(width: usize, nd: usize, paths: PathCount) -> usize {
    let lanes = padded_lanes(nd);
    let stride = lanes + 2;
    let row_paths = if paths == PathCount::Eight { 3 } else { 1 };
    // cost row + two rows per row path (+ minima) + 2×2 horizontal + zero vector + the P2 rows
    // of the whole-row kernel + WTA scratch (16-bit path costs: the 8-bit passes need less),
    // saturating for absurd sizes.
    let cost_row = width.saturating_mul(lanes);
    let row_path_rows = width.saturating_mul(stride + 1).saturating_mul(2 * row_paths);
    cost_row
        .saturating_add(row_path_rows)
        .saturating_add(5 * stride)
        .saturating_add(width.saturating_mul(4))
        .saturating_mul(2)
        .saturating_add(WtaScratch::bytes(width))
}

/// One row of the shared output: the path sums and the disparities, and whether one pass has
/// already stored its sums (and, with shared costs, the row's matching costs).
struct RowSlot<'a, T> {
    sum: &'a mut [u16],
    /// The row's matching costs (in the passes' type), made by the first pass to reach the row.
    cost: Option<&'a mut [T]>,
    disparity: &'a mut [f32],
    visited: bool,
}

#[derive(Clone, Copy, PartialEq, Eq, Debug)]
enum Pass {
    /// Rows top to bottom, pixels left to right.
    Forward,
    /// Rows bottom to top, pixels right to left.
    Backward,
}

/// Aggregates all path directions strip by strip (see the module documentation) and selects
/// every row's disparities into `disparity`. `volume` holds at least `plan.rows` rows of sums
/// (`[y][x][d]`, any initial contents). With [`StripPlan::shared_costs`] a strip's rows of
/// matching costs (in the passes' type) are kept for the second pass.
pub(crate) fn aggregate_and_select(
    inputs: &Inputs<'_>,
    plan: StripPlan,
    volume: &mut [u16],
    disparity: &mut [f32],
) {
    let height = inputs.image.height();
    let strip_rows = plan.rows.clamp(1, height.max(1));
    debug_assert!(volume.len() >= strip_rows.min(height) * inputs.image.width() * inputs.range.count());
    debug_assert_eq!(disparity.len(), inputs.image.width() * height);
    if use_u8(inputs) {
        aggregate_strips::<u8>(inputs, strip_rows, plan.overlap, plan.shared_costs, volume, disparity);
    } else {
        aggregate_strips::<u16>(inputs, strip_rows, plan.overlap, plan.shared_costs, volume, disparity);
    }
}

/// [`aggregate_and_select`] with path costs of type `T`. With `shared_costs` each strip row's
/// matching costs are kept for the second pass (every entry is written before it is read).
fn aggregate_strips<T: PathCost>(
    inputs: &Inputs<'_>,
    strip_rows: usize,
    overlap: usize,
    shared_costs: bool,
    volume: &mut [u16],
    disparity: &mut [f32],
) {
    let (width, height) = inputs.image.size();
    let nd = inputs.range.count();
    let cost_row = width * T::lanes(nd);
    let mut costs = ScratchBuffer::<T>::new(if shared_costs { strip_rows.min(height) * cost_row } else { 0 });
    let costs = costs.as_mut_slice();
    let mut forward = PassState::<T>::new(inputs, Pass::Forward);
    let mut backward = PassState::<T>::new(inputs, Pass::Backward);
    for (strip, disparity) in disparity.chunks_mut(strip_rows * width).enumerate() {
        let y0 = strip * strip_rows;
        let y1 = y0 + disparity.len() / width.max(1);
        let mut cost_rows = costs.chunks_mut(cost_row.max(1));
        let rows: Vec<Mutex<RowSlot<'_, T>>> = volume[..(y1 - y0) * width * nd]
            .chunks_mut(width * nd)
            .zip(disparity.chunks_mut(width))
            .map(|(sum, disparity)| {
                let cost = cost_rows.next();
                Mutex::new(RowSlot { sum, cost, disparity, visited: false })
            })
            .collect();
        let warm_end = y1.saturating_add(overlap).min(height);
        let rows = &rows;
        let (forward, backward) = (&mut forward, &mut backward);
        rayon::join(
            || run_rows(forward, inputs, y0, y1, rows),
            || {
                backward.restart();
                run_rows(backward, inputs, y1, warm_end, &[]);
                run_rows(backward, inputs, y0, y1, rows);
            },
        );
    }
}

/// The single-pass ("streaming") aggregation over the directions from above and the left
/// (→, ↓, ↘, ↙ and ← for 8 paths; →, ↓ and ← for 4), in `strips` strips run in parallel, each warming up
/// over `overlap` rows above it; selects every row's disparities into `disparity`.
pub(crate) fn stream_and_select(inputs: &Inputs<'_>, strips: usize, overlap: usize, disparity: &mut [f32]) {
    let (width, height) = inputs.image.size();
    let strip_rows = height.div_ceil(strips.clamp(1, height.max(1))).max(1);
    rayon::scope(|scope| {
        for (strip, disparity) in disparity.chunks_mut(strip_rows * width).enumerate() {
            scope.spawn(move |_| {
                let y0 = strip * strip_rows;
                let y1 = y0 + disparity.len() / width.max(1);
                // Two rows: one being aggregated, one waiting for its ← path.
                let mut sum = vec![0u16; 2 * width * inputs.range.count()];
                let warm = y0.saturating_sub(overlap);
                if use_u8(inputs) {
                    let mut state = PassState::<u8>::new(inputs, Pass::Forward);
                    stream_rows(&mut state, inputs, warm, y0, y1, &mut sum, disparity);
                } else {
                    let mut state = PassState::<u16>::new(inputs, Pass::Forward);
                    stream_rows(&mut state, inputs, warm, y0, y1, &mut sum, disparity);
                }
            });
        }
    });
}

/// How many pixels ahead the second pass prefetches the sums it will add to: by then the first
/// pass's sums of that row have long left the cache.
#[cfg(target_arch = "x86_64")]
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
struct RowPaths<T> {
    costs: Vec<T>,
    mins: Vec<T>,
}

impl<T: PathCost> RowPaths<T> {
    fn pair(width: usize, stride: usize) -> [RowPaths<T>; 2] {
        std::array::from_fn(|_| RowPaths {
            costs: vec![T::PAD; width * stride],
            mins: vec![T::default(); width],
        })
    }
}

/// The `O(W·D)` state of one pass: the current cost row, the path costs of the previous and the
/// current row, and the WTA scratch. Allocated once per call.
struct PassState<T> {
    pass: Pass,
    /// The previous row of this pass, or `None` when the next row starts the paths.
    prev_y: Option<usize>,
    /// The `u16` cost row (empty for `u8`, which uses `cost_narrow`).
    cost: Vec<u16>,
    /// The cost row in `T`, 64-byte aligned (empty for `u16`, which uses `cost`).
    cost_narrow: AlignedRow<T>,
    vertical: [RowPaths<T>; 2],
    diag_a: [RowPaths<T>; 2],
    diag_b: [RowPaths<T>; 2],
    horizontal: [Vec<T>; 2],
    zero: Vec<T>,
    /// The current row's Birchfield–Tomasi inputs (AD-census only).
    bt_left: BtRow,
    bt_right: BtRow,
    scratch: WtaScratch,
    /// P2 entering each pixel of the current row along the horizontal, vertical and the two
    /// diagonal paths (for the whole-row kernel).
    p2_rows: [Vec<T>; 4],
}

impl<T: PathCost> PassState<T> {
    fn new(inputs: &Inputs<'_>, pass: Pass) -> Self {
        let width = inputs.image.width();
        let nd = inputs.range.count();
        let lanes = T::lanes(nd);
        let stride = lanes + 2;
        let diagonal_width = if inputs.paths == PathCount::Eight { width } else { 0 };
        // Each pass has one cost row: the `u16` passes `cost`, the `u8` passes `cost_narrow`.
        let (wide, narrow) =
            if std::mem::size_of::<T>() == 2 { (width * lanes, 0) } else { (0, width * lanes) };
        PassState {
            pass,
            prev_y: None,
            cost: vec![0; wide],
            cost_narrow: AlignedRow::new(narrow),
            vertical: RowPaths::pair(width, stride),
            diag_a: RowPaths::pair(diagonal_width, stride),
            diag_b: RowPaths::pair(diagonal_width, stride),
            horizontal: [vec![T::PAD; stride], vec![T::PAD; stride]],
            zero: vec![T::default(); stride],
            bt_left: BtRow::default(),
            bt_right: BtRow::default(),
            scratch: WtaScratch::new(width),
            p2_rows: std::array::from_fn(|_| vec![T::default(); width]),
        }
    }

    /// The next row starts every path afresh (as at the image border).
    fn restart(&mut self) {
        self.prev_y = None;
    }
}

kernels::multiversion! {
    /// Runs `state`'s pass over rows `y0..y1` (in the pass's direction). With `rows` (one slot per
    /// row from `y0`) it stores or adds the sums and selects the finished rows; with no slots it
    /// only advances the paths (warm-up).
    fn run_rows<T: PathCost>(
        state: &mut PassState<T>,
        inputs: &Inputs<'_>,
        y0: usize,
        y1: usize,
        rows: &[Mutex<RowSlot<'_, T>>],
    ) => run_rows_generic;
}

#[inline(always)]
fn run_rows_generic<T: PathCost>(
    state: &mut PassState<T>,
    inputs: &Inputs<'_>,
    y0: usize,
    y1: usize,
    rows: &[Mutex<RowSlot<'_, T>>],
    level: Level,
) {
    let (width, nd) = (inputs.image.width(), inputs.range.count());
    for i in 0..y1.saturating_sub(y0) {
        let y = if state.pass == Pass::Forward { y0 + i } else { y1 - 1 - i };
        if rows.is_empty() {
            step_row(state, inputs, y, level, &mut [], false);
            continue;
        }
        let mut slot = rows[y - y0].lock().unwrap_or_else(|e| e.into_inner());
        let accumulate = slot.visited;
        let RowSlot { sum, cost, .. } = &mut *slot;
        // The second pass at a row with shared costs reads them; the first makes them.
        let shared = cost.as_deref_mut().map(|c| (c, accumulate));
        step_row_with(state, inputs, y, level, sum, accumulate, None, shared);
        if accumulate {
            // Both passes are in: the row's sums are final.
            let RowSlot { sum, disparity, .. } = &mut *slot;
            select_row(sum, width, nd, inputs.selection, &mut state.scratch, disparity);
        } else {
            slot.visited = true;
        }
    }
}

kernels::multiversion! {
    /// The single pass over rows `warm..y1`, see [`stream_rows_generic`].
    fn stream_rows<T: PathCost>(
        state: &mut PassState<T>,
        inputs: &Inputs<'_>,
        warm: usize,
        y0: usize,
        y1: usize,
        sum: &mut [u16],
        disparity: &mut [f32],
    ) => stream_rows_generic;
}

/// The ← path's P2 of row `y`: `p2[x]` for stepping into `x` from `x + 1` (the last entry is not
/// read).
fn left_path_p2<T: PathCost>(inputs: &Inputs<'_>, y: usize, level: Level, p2: &mut [T]) {
    let row = inputs.image.row(y);
    let n = row.len().saturating_sub(1);
    T::p2_row(level, inputs.p2, &row[..n], &row[1.min(row.len())..], &mut p2[..n]);
}

/// The single pass over rows `warm..y1`: warm-up only above `y0`, then per row the forward
/// directions (stored into the row's `sum`), the ← sweep (added) and the selection into the
/// row's `disparity` (`disparity` starts at row `y0`).
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn stream_rows_generic<T: PathCost>(
    state: &mut PassState<T>,
    inputs: &Inputs<'_>,
    warm: usize,
    y0: usize,
    y1: usize,
    sum: &mut [u16],
    disparity: &mut [f32],
    level: Level,
) {
    let (width, nd) = (inputs.image.width(), inputs.range.count());
    let lanes = T::lanes(nd);
    let (sum, held_sum) = sum.split_at_mut(width * nd);
    // The ← path's P2 per pixel (stepping into `x` from `x + 1`), made once per row.
    let mut p2_row = vec![T::default(); width];
    if width > 0 && T::has_row(level, lanes) {
        // The ← path of each row runs beside the →, ↓ paths of the next, so the two dependency
        // chains overlap; the row waiting for its ← path keeps its cost row and sums here.
        let mut held_cost = AlignedRow::<T>::new(width * lanes);
        let (mut sum, mut held_sum) = (sum, held_sum);
        let mut held: Option<usize> = None;
        for y in warm..y1 {
            if y < y0 {
                step_row(state, inputs, y, level, &mut [], false);
                continue;
            }
            let trailing =
                held.map(|_| Trailing { cost: &held_cost[..], p2: &p2_row[..], sum: &mut *held_sum });
            step_row_with(state, inputs, y, level, sum, false, trailing, None);
            if let Some(held_y) = held {
                let out = &mut disparity[(held_y - y0) * width..(held_y - y0 + 1) * width];
                select_row(held_sum, width, nd, inputs.selection, &mut state.scratch, out);
            }
            std::mem::swap(&mut state.cost_narrow, &mut held_cost);
            std::mem::swap(&mut sum, &mut held_sum);
            left_path_p2(inputs, y, level, &mut p2_row);
            held = Some(y);
        }
        if let Some(held_y) = held {
            let p1 = T::narrow(inputs.p1);
            let ran = T::row(level, &held_cost, lanes, nd, p1, &p2_row, [], held_sum, true, true, None);
            debug_assert!(ran);
            let out = &mut disparity[(held_y - y0) * width..(held_y - y0 + 1) * width];
            select_row(held_sum, width, nd, inputs.selection, &mut state.scratch, out);
        }
        return;
    }
    for y in warm..y1 {
        if y < y0 {
            step_row(state, inputs, y, level, &mut [], false);
            continue;
        }
        step_row(state, inputs, y, level, sum, false);
        // ←: right to left over the same cost row (already in `T`), added to the row's sums (pixel
        // by pixel: this loop runs where there is no whole-row kernel).
        let cost: &[T] = if state.cost_narrow.is_empty() {
            T::costs(level, &state.cost, nd, &mut [])
        } else {
            &state.cost_narrow
        };
        left_path_p2(inputs, y, level, &mut p2_row);
        let start = PathIn { prev: &state.zero[..], prev_min: T::default(), p2: T::default() };
        let mut h_min = T::default();
        for x in (0..width).rev() {
            let [h_prev, h_cur] = &mut state.horizontal;
            let h_in = if x + 1 == width {
                start
            } else {
                PathIn { prev: &h_prev[..], prev_min: h_min, p2: p2_row[x] }
            };
            let [m] = T::step(
                level,
                &cost[x * lanes..(x + 1) * lanes],
                T::narrow(inputs.p1),
                [h_in],
                [&mut h_cur[..]],
                &mut sum[x * nd..(x + 1) * nd],
                true,
            );
            h_min = m;
            state.horizontal.swap(0, 1);
        }
        let out = &mut disparity[(y - y0) * width..(y - y0 + 1) * width];
        select_row(sum, width, nd, inputs.selection, &mut state.scratch, out);
    }
}

/// One row of `state`'s pass: the row's cost row, then every pixel's path steps (horizontal,
/// vertical and, for 8 paths, both diagonals) in the pass's direction, storing (or, with
/// `accumulate`, adding) the path costs into `sum` (`[x][d]`; empty for warm-up).
#[inline(always)]
fn step_row<T: PathCost>(
    state: &mut PassState<T>,
    inputs: &Inputs<'_>,
    y: usize,
    level: Level,
    sum: &mut [u16],
    accumulate: bool,
) {
    step_row_with(state, inputs, y, level, sum, accumulate, None, None);
}

/// [`step_row`], with the ← path of an earlier row (`trailing`) run in the same loop: only for
/// stored rows through the whole-row kernel ([`PathCost::has_row`]). With `shared = Some((row,
/// ready))` (`u16` passes) the row's `u16` matching costs live in `row`: already made by the
/// other pass when `ready`, made there now otherwise.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn step_row_with<T: PathCost>(
    state: &mut PassState<T>,
    inputs: &Inputs<'_>,
    y: usize,
    level: Level,
    sum: &mut [u16],
    accumulate: bool,
    trailing: Option<Trailing<'_, T>>,
    shared: Option<(&mut [T], bool)>,
) {
    let width = inputs.image.width();
    let nd = inputs.range.count();
    let lanes = T::lanes(nd);
    let stride = lanes + 2;
    let diagonals = inputs.paths == PathCount::Eight;
    let (p1, p2) = (T::narrow(inputs.p1), inputs.p2);
    let p2_between = |a: u16, b: u16| T::narrow(p2.p2(a, b));
    let forward = state.pass == Pass::Forward;
    let first_row = state.prev_y.is_none();
    let prev_y = state.prev_y.unwrap_or(y);
    state.prev_y = Some(y);
    let row = inputs.image.row(y);
    let prev_row = inputs.image.row(prev_y);
    let PassState {
        cost,
        cost_narrow,
        bt_left,
        bt_right,
        vertical,
        diag_a,
        diag_b,
        horizontal,
        zero,
        p2_rows,
        ..
    } = state;
    let (wide, narrow, ready) = match shared {
        Some((row, ready)) => {
            let (wide, narrow) = T::shared_rows(row, cost, cost_narrow);
            (wide, narrow, ready)
        }
        None => (&mut cost[..], &mut cost_narrow[..], false),
    };
    if !ready {
        let ad = inputs.ad.map(|(left, right, weight, cap)| {
            bt_left.fill(left.row(y), false);
            bt_right.fill(right.row(y), true);
            AdRows { left: &*bt_left, right: &*bt_right, weight, cap }
        });
        T::make_costs(inputs, y, ad, wide, narrow);
    }
    let store = !sum.is_empty();
    let has_trailing = trailing.is_some();
    let cost = T::costs(level, wide, nd, narrow);
    if store
        && row_kernel(
            level,
            inputs,
            cost,
            row,
            prev_row,
            first_row,
            forward,
            p2_rows,
            [vertical, diag_a, diag_b],
            sum,
            accumulate,
            trailing,
        )
    {
        vertical.swap(0, 1);
        diag_a.swap(0, 1);
        diag_b.swap(0, 1);
        return;
    }
    assert!(!has_trailing, "a trailing row needs the whole-row kernel");
    // A path entering the image: stepping from all-zero costs yields the matching cost.
    let start = PathIn { prev: &zero[..], prev_min: T::default(), p2: T::default() };
    let [v_prev, v_cur] = vertical;
    let [a_prev, a_cur] = diag_a;
    let [b_prev, b_cur] = diag_b;
    let mut h_min = T::default();
    // The input of a path continuing from pixel `from` of the previous row.
    fn at<T: PathCost>(paths: &RowPaths<T>, from: usize, stride: usize, p2: T) -> PathIn<'_, T> {
        PathIn { prev: &paths.costs[from * stride..(from + 1) * stride], prev_min: paths.mins[from], p2 }
    }
    // The diagonal "a" comes from x - step in the previous row of the pass, "b" from x + step.
    for col_index in 0..width {
        let x = if forward { col_index } else { width - 1 - col_index };
        let c = &cost[x * lanes..(x + 1) * lanes];
        let here = row[x];
        if accumulate {
            prefetch_ahead(sum, x, nd, forward);
        }
        let sum = if store { &mut sum[x * nd..(x + 1) * nd] } else { &mut [][..] };
        let [h_prev, h_cur] = &mut *horizontal;
        let h_in = if col_index == 0 {
            start
        } else {
            let from = if forward { x - 1 } else { x + 1 };
            PathIn { prev: &h_prev[..], prev_min: h_min, p2: p2_between(here, row[from]) }
        };
        let v_in = if first_row { start } else { at(v_prev, x, stride, p2_between(here, prev_row[x])) };
        let v_out = &mut v_cur.costs[x * stride..(x + 1) * stride];
        if diagonals {
            let (left, right) = (x.checked_sub(1), (x + 1 < width).then_some(x + 1));
            let (a_from, b_from) = if forward { (left, right) } else { (right, left) };
            let a_in = match a_from {
                Some(f) if !first_row => at(a_prev, f, stride, p2_between(here, prev_row[f])),
                _ => start,
            };
            let b_in = match b_from {
                Some(f) if !first_row => at(b_prev, f, stride, p2_between(here, prev_row[f])),
                _ => start,
            };
            let a_out = &mut a_cur.costs[x * stride..(x + 1) * stride];
            let b_out = &mut b_cur.costs[x * stride..(x + 1) * stride];
            if !store {
                // Warm-up: the horizontal path starts afresh on every row, so only the paths
                // that carry into the next row are needed.
                let [mv, ma, mb] =
                    T::step(level, c, p1, [v_in, a_in, b_in], [v_out, a_out, b_out], sum, false);
                v_cur.mins[x] = mv;
                a_cur.mins[x] = ma;
                b_cur.mins[x] = mb;
                continue;
            }
            let [mh, mv, ma, mb] = T::step(
                level,
                c,
                p1,
                [h_in, v_in, a_in, b_in],
                [&mut h_cur[..], v_out, a_out, b_out],
                sum,
                accumulate,
            );
            h_min = mh;
            v_cur.mins[x] = mv;
            a_cur.mins[x] = ma;
            b_cur.mins[x] = mb;
        } else if !store {
            let [mv] = T::step(level, c, p1, [v_in], [v_out], sum, false);
            v_cur.mins[x] = mv;
        } else {
            let [mh, mv] = T::step(level, c, p1, [h_in, v_in], [&mut h_cur[..], v_out], sum, accumulate);
            h_min = mh;
            v_cur.mins[x] = mv;
        }
        horizontal.swap(0, 1);
    }
    vertical.swap(0, 1);
    diag_a.swap(0, 1);
    diag_b.swap(0, 1);
}

/// The stored rows of [`step_row`] through the whole-row kernel ([`PathCost::row`]), when
/// there is one for this type and CPU: fills the P2 of every path for the row, then runs it.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn row_kernel<T: PathCost>(
    level: Level,
    inputs: &Inputs<'_>,
    cost: &[T],
    row: &[u16],
    prev_row: &[u16],
    first_row: bool,
    forward: bool,
    p2_rows: &mut [Vec<T>; 4],
    [vertical, diag_a, diag_b]: [&mut [RowPaths<T>; 2]; 3],
    sum: &mut [u16],
    accumulate: bool,
    trailing: Option<Trailing<'_, T>>,
) -> bool {
    // Only where the kernel exists (the `u16` passes and other CPUs step pixel by pixel).
    let width = row.len();
    let nd = inputs.range.count();
    let lanes = T::lanes(nd);
    if width == 0 || !T::has_row(level, lanes) {
        return false;
    }
    let [p2_h, p2_v, p2_a, p2_b] = p2_rows;
    let p2_of = |a: &[u16], b: &[u16], out: &mut [T]| T::p2_row(level, inputs.p2, a, b, out);
    // Pixel x is entered from x - step along the row and from x + dx of the previous row:
    // pixels 1.. from their left neighbours, pixels ..width - 1 from their right ones (entries
    // without a source are not read).
    let step: isize = if forward { 1 } else { -1 };
    let (from_left, from_right) = (1..width, 0..width - 1);
    let diagonals = inputs.paths == PathCount::Eight;
    if forward {
        p2_of(&row[from_left.clone()], &row[from_right.clone()], &mut p2_h[from_left.clone()]);
    } else {
        p2_of(&row[from_right.clone()], &row[from_left.clone()], &mut p2_h[from_right.clone()]);
    }
    p2_of(row, prev_row, p2_v);
    if diagonals {
        // The diagonal "a" comes from x - step in the previous row, "b" from x + step.
        let (left, right) = if forward { (&mut *p2_a, &mut *p2_b) } else { (&mut *p2_b, &mut *p2_a) };
        p2_of(&row[from_left.clone()], &prev_row[from_right.clone()], &mut left[from_left]);
        p2_of(&row[from_right.clone()], &prev_row[1..], &mut right[from_right]);
    }
    fn from<'a, T>(
        paths: &'a mut [RowPaths<T>; 2],
        dx: isize,
        p2: &'a [T],
        first_row: bool,
    ) -> FromRow<'a, T> {
        let [prev, cur] = paths;
        FromRow {
            prev: if first_row { &[] } else { &prev.costs[..] },
            prev_mins: if first_row { &[] } else { &prev.mins[..] },
            dx,
            p2,
            out: &mut cur.costs[..],
            out_mins: &mut cur.mins[..],
        }
    }
    let (cost, p1) = (&cost[..width * lanes], T::narrow(inputs.p1));
    if diagonals {
        let paths = [
            from(vertical, 0, p2_v, first_row),
            from(diag_a, -step, p2_a, first_row),
            from(diag_b, step, p2_b, first_row),
        ];
        T::row(level, cost, lanes, nd, p1, p2_h, paths, sum, !forward, accumulate, trailing)
    } else {
        T::row(
            level,
            cost,
            lanes,
            nd,
            p1,
            p2_h,
            [from(vertical, 0, p2_v, first_row)],
            sum,
            !forward,
            accumulate,
            trailing,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::reference::{census_transform, hamming_cost_volume};
    use crate::wta::select_row_reference;
    use crate::{CensusWindow, Subpixel};

    /// The single-pass sums by the textbook recurrence: every direction `(dx, dy)` from above or
    /// the left, paths starting where the previous pixel is outside the image.
    fn stream_sums_reference(
        image: &GrayImage,
        cost: &[u8],
        nd: usize,
        paths: PathCount,
        p1: u16,
        p2: &P2Table,
    ) -> Vec<u16> {
        let (w, h) = image.size();
        let dirs: &[(i64, i64)] = if paths == PathCount::Eight {
            &[(1, 0), (0, 1), (1, 1), (-1, 1), (-1, 0)]
        } else {
            &[(1, 0), (0, 1), (-1, 0)]
        };
        let mut sum = vec![0u16; w * h * nd];
        for &(dx, dy) in dirs {
            let mut l = vec![0u16; w * h * nd];
            let ys: Vec<usize> = (0..h).collect();
            let xs: Vec<usize> = if dx < 0 { (0..w).rev().collect() } else { (0..w).collect() };
            for &y in &ys {
                for &x in &xs {
                    let (px, py) = (x as i64 - dx, y as i64 - dy);
                    let c = &cost[(y * w + x) * nd..][..nd];
                    let at = (y * w + x) * nd;
                    if px < 0 || py < 0 || px >= w as i64 {
                        for d in 0..nd {
                            l[at + d] = u16::from(c[d]);
                        }
                        continue;
                    }
                    let from = (py as usize * w + px as usize) * nd;
                    let prev = l[from..from + nd].to_vec();
                    let pmin = *prev.iter().min().unwrap();
                    let jump =
                        pmin.saturating_add(p2.p2(image.get(x, y), image.get(px as usize, py as usize)));
                    for d in 0..nd {
                        let mut best = prev[d].min(jump);
                        if d > 0 {
                            best = best.min(prev[d - 1].saturating_add(p1));
                        }
                        if d + 1 < nd {
                            best = best.min(prev[d + 1].saturating_add(p1));
                        }
                        l[at + d] = u16::from(c[d]).saturating_add(best).wrapping_sub(pmin);
                    }
                }
            }
            for (s, v) in sum.iter_mut().zip(&l) {
                *s = s.wrapping_add(*v);
            }
        }
        sum
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(48))]

        /// The single pass gives the textbook recurrence's winners bit for bit, on one strip and on
        /// several strips whose warm-up reaches the top of the image.
        #[test]
        fn single_pass_matches_the_recurrence(
            w in 9usize..70, h in 7usize..30, nd_frac in 0.0f64..1.0, min in -6i32..6, four in proptest::prelude::any::<bool>(),
            p1 in 1u16..40, p2_extra in 1u16..200, edge in 0u16..40, strips in 1usize..5, seed in proptest::prelude::any::<u64>(),
        ) {
            let nd = ((w as f64 * nd_frac.min(0.8)) as usize).max(1);
            let range = DisparityRange::new(min, min + nd as i32).unwrap();
            let mut s = seed | 1;
            let left = GrayImage::from_fn(w, h, |_, _| { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s as u16 });
            let right = GrayImage::from_fn(w, h, |x, y| left.get((x + 2) % w, y) ^ ((x * y) as u16 & 0x0300));
            let window = CensusWindow { width: 5, height: 5 };
            let (mut cl, mut cr) = (Image::new(w, h, 0u64), Image::new(w, h, 0u64));
            census_transform(&left, window, 0, &mut cl);
            census_transform(&right, window, 0, &mut cr);
            let mut cost = vec![0u8; w * h * nd];
            hamming_cost_volume(&cl, &cr, range, 24, &mut cost);
            let paths = if four { PathCount::Four } else { PathCount::Eight };
            let p2 = P2Table::new(p1, (p1 + p2_extra).min(MAX_P2), edge);
            let selection = Selection { range, uniqueness_ratio: 5, lr_max_diff: Some(1.0), lr_left_neighbour: true, subpixel: Subpixel::Equiangular };
            let sums = stream_sums_reference(&left, &cost, nd, paths, p1, &p2);
            let mut expected = vec![f32::NAN; w * h];
            let mut right_best = vec![0usize; w];
            for (out, costs) in expected.chunks_mut(w).zip(sums.chunks(w * nd)) {
                select_row_reference(costs, w, nd, selection, &mut right_best, out);
            }
            let inputs = Inputs {
                image: &left, census_left: &cl, census_right: &cr, ad: None, range,
                worst: crate::cost::infeasible_cost(24, crate::MatchingCost::Census),
                paths, p1, p2: &p2, selection,
            };
            for (threads, overlap) in [(1, 0), (strips, h)] {
                let mut got = vec![f32::NAN; w * h];
                stream_and_select(&inputs, threads, overlap, &mut got);
                for (i, (a, b)) in got.iter().zip(&expected).enumerate() {
                    proptest::prop_assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()), "{threads} strips, pixel {i}: {a} vs {b}");
                }
            }
        }
    }
}
