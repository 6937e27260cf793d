//! Semi-global path aggregation (Hirschmüller 2008, eq. 13):
//!
//! `L_r(p, d) = C(p, d) + min(L_r(p-r, d), L_r(p-r, d±1) + P1, min_k L_r(p-r, k) + P2) - min_k L_r(p-r, k)`
//!
//! summed over the path directions `r`. The directions split into a forward pass (rows top to
//! bottom, pixels left to right: →, ↓, ↘, ↙) and a mirrored backward pass; the two passes run on
//! two threads and add their row sums into the shared volume under a per-row lock, so the
//! aggregated volume is the only `W·H·D` buffer besides the cost volume.

use std::sync::Mutex;

use crate::{GrayImage, PathCount};

/// Penalties of the smoothness term, in cost units.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Penalties {
    pub p1: u16,
    pub p2: u16,
}

/// P2 for each intensity step along a path (8-bit grey levels, 0..=255): disparity jumps are
/// cheaper across image edges, where depth discontinuities usually are.
/// `P2(ΔI) = max(P1 + 1, P2 · s / (s + ΔI))` for edge scale `s`; `s = 0` keeps P2 constant.
pub(crate) struct P2Table([u16; 256]);

impl P2Table {
    pub(crate) fn new(p1: u16, p2: u16, edge_scale: u16) -> Self {
        let mut t = [p2; 256];
        if edge_scale > 0 {
            for (step, v) in t.iter_mut().enumerate() {
                let s = u32::from(edge_scale);
                *v = ((u32::from(p2) * s / (s + step as u32)) as u16).max(p1 + 1);
            }
        }
        P2Table(t)
    }

    #[inline]
    fn penalties(&self, p1: u16, a: u16, b: u16) -> Penalties {
        Penalties { p1, p2: self.0[usize::from(a.abs_diff(b) / 257)] }
    }
}

/// Padding on both ends of each pixel's path-cost vector so the `d±1` neighbours need no
/// bounds checks: large enough never to win, small enough that `+ P1` cannot overflow.
const PAD: u16 = 0x7fff;

/// Largest P2 accepted, so every sum of eight path costs fits in `u16`.
pub(crate) const MAX_P2: u16 = 4000;

/// One step of the recurrence for one pixel: `prev` and `out` are padded (`nd + 2` entries);
/// returns `min_k out`.
#[inline]
fn path_step(cost: &[u8], prev: &[u16], prev_min: u16, pen: Penalties, out: &mut [u16]) -> u16 {
    let nd = cost.len();
    let jump = prev_min + pen.p2;
    let mut min = u16::MAX;
    for k in 0..nd {
        let best = prev[k + 1].min(prev[k] + pen.p1).min(prev[k + 2] + pen.p1).min(jump);
        let v = u16::from(cost[k]) + best - prev_min;
        out[k + 1] = v;
        min = min.min(v);
    }
    min
}

/// The first pixel of a path has no predecessor: its path cost is the matching cost.
#[inline]
fn path_start(cost: &[u8], out: &mut [u16]) -> u16 {
    let mut min = u16::MAX;
    for (o, &c) in out[1..=cost.len()].iter_mut().zip(cost) {
        *o = u16::from(c);
        min = min.min(*o);
    }
    min
}

/// Path costs of one row for one direction, padded per pixel, with each pixel's minimum.
struct RowPaths {
    costs: Vec<u16>,
    mins: Vec<u16>,
}

impl RowPaths {
    fn new(width: usize, nd: usize) -> Self {
        RowPaths { costs: vec![PAD; width * (nd + 2)], mins: vec![0; width] }
    }
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Pass {
    /// Rows top to bottom, pixels left to right.
    Forward,
    /// Rows bottom to top, pixels right to left.
    Backward,
}

/// Adds the aggregated path costs of all directions into `sum` (`[y][x][d]`, zeroed by the
/// caller). `cost` has the same layout.
pub(crate) fn aggregate_paths(
    image: &GrayImage,
    cost: &[u8],
    nd: usize,
    paths: PathCount,
    p1: u16,
    p2: &P2Table,
    sum: &mut [u16],
) {
    let (width, height) = image.size();
    debug_assert_eq!(cost.len(), width * height * nd);
    debug_assert_eq!(sum.len(), cost.len());
    let rows: Vec<Mutex<&mut [u16]>> = sum.chunks_mut(width * nd).map(Mutex::new).collect();
    let diagonals = paths == PathCount::Eight;
    rayon::join(
        || aggregate_pass(image, cost, nd, diagonals, p1, p2, Pass::Forward, &rows),
        || aggregate_pass(image, cost, nd, diagonals, p1, p2, Pass::Backward, &rows),
    );
}

#[allow(clippy::too_many_arguments)]
fn aggregate_pass(
    image: &GrayImage,
    cost: &[u8],
    nd: usize,
    diagonals: bool,
    p1: u16,
    p2: &P2Table,
    pass: Pass,
    rows: &[Mutex<&mut [u16]>],
) {
    let (width, height) = image.size();
    let stride = nd + 2;
    // Previous and current row of the vertical and the two diagonal paths.
    let mut vertical = [RowPaths::new(width, nd), RowPaths::new(width, nd)];
    let mut diag_a = [RowPaths::new(width, nd), RowPaths::new(width, nd)];
    let mut diag_b = [RowPaths::new(width, nd), RowPaths::new(width, nd)];
    let mut horizontal = [vec![PAD; stride], vec![PAD; stride]];
    let mut row_sum = vec![0u16; width * nd];

    // `step` is the x direction of this pass: the horizontal path comes from x - step, the
    // diagonal "a" from (x - step) in the previous row and "b" from (x + step).
    let step: isize = if pass == Pass::Forward { 1 } else { -1 };
    let ys: Vec<usize> = match pass {
        Pass::Forward => (0..height).collect(),
        Pass::Backward => (0..height).rev().collect(),
    };
    let xs: Vec<usize> = match pass {
        Pass::Forward => (0..width).collect(),
        Pass::Backward => (0..width).rev().collect(),
    };

    for (row_index, &y) in ys.iter().enumerate() {
        let first_row = row_index == 0;
        let [v_prev, v_cur] = &mut vertical;
        let [a_prev, a_cur] = &mut diag_a;
        let [b_prev, b_cur] = &mut diag_b;
        let mut h_min = 0u16;
        let row = image.row(y);
        // The previous row of this pass (unused on its first row).
        let prev_row = image.row(if first_row { y } else { ys[row_index - 1] });
        for (col_index, &x) in xs.iter().enumerate() {
            let c = &cost[(y * width + x) * nd..][..nd];
            let here = row[x];

            // Horizontal path, from the previous pixel of this row.
            let [h_prev, h_cur] = &mut horizontal;
            h_min = if col_index == 0 {
                path_start(c, h_cur)
            } else {
                let pen = p2.penalties(p1, here, row[xs[col_index - 1]]);
                path_step(c, h_prev, h_min, pen, h_cur)
            };
            // Vertical path, from the same column of the previous row.
            let from_row = (!first_row).then_some(x);
            row_step(c, v_prev, v_cur, x, from_row, stride, p2.penalties(p1, here, prev_row[x]));

            let out = &mut row_sum[x * nd..(x + 1) * nd];
            let v = &v_cur.costs[x * stride + 1..][..nd];
            for ((o, &hv), &vv) in out.iter_mut().zip(&h_cur[1..=nd]).zip(v) {
                *o = hv + vv;
            }

            if diagonals {
                let neighbour = |offset: isize| {
                    let from = x as isize + offset;
                    (!first_row && from >= 0 && (from as usize) < width).then_some(from as usize)
                };
                let (a_from, b_from) = (neighbour(-step), neighbour(step));
                let pen_a = p2.penalties(p1, here, a_from.map_or(here, |f| prev_row[f]));
                let pen_b = p2.penalties(p1, here, b_from.map_or(here, |f| prev_row[f]));
                row_step(c, a_prev, a_cur, x, a_from, stride, pen_a);
                row_step(c, b_prev, b_cur, x, b_from, stride, pen_b);
                let (a, b) = (&a_cur.costs[x * stride + 1..][..nd], &b_cur.costs[x * stride + 1..][..nd]);
                for ((o, &av), &bv) in out.iter_mut().zip(a).zip(b) {
                    *o += av + bv;
                }
            }
            horizontal.swap(0, 1);
        }
        vertical.swap(0, 1);
        diag_a.swap(0, 1);
        diag_b.swap(0, 1);
        // Each row is locked twice in all (once per pass); the passes only meet mid-image.
        let mut dst = rows[y].lock().unwrap_or_else(|e| e.into_inner());
        for (d, s) in dst.iter_mut().zip(&row_sum) {
            *d += s;
        }
    }
}

/// The path cost at pixel `x` of the current row, continuing from pixel `from` of the previous
/// row, or starting afresh when the path enters the image here (`from` is `None`).
fn row_step(
    c: &[u8],
    prev: &RowPaths,
    cur: &mut RowPaths,
    x: usize,
    from: Option<usize>,
    stride: usize,
    pen: Penalties,
) {
    let out = &mut cur.costs[x * stride..(x + 1) * stride];
    cur.mins[x] = match from {
        None => path_start(c, out),
        Some(f) => path_step(c, &prev.costs[f * stride..(f + 1) * stride], prev.mins[f], pen, out),
    };
}
