//! The original scalar SGM pipeline (stored `u8` cost volume, per-row locked path sums),
//! kept as the readable reference the fused and SIMD pipeline is tested against, bit for bit.

use std::sync::Mutex;

use rayon::prelude::*;

use crate::aggregate::P2Table;
use crate::{CensusWindow, DisparityRange, GrayImage, Image, PathCount};

#[derive(Clone, Copy, Debug)]
struct Penalties {
    p1: u16,
    p2: u16,
}

fn penalties(t: &P2Table, p1: u16, a: u16, b: u16) -> Penalties {
    Penalties { p1, p2: t.p2(a, b) }
}

/// Fills `volume` (`width * height * range.count()` bytes) with Hamming costs.
pub(crate) fn hamming_cost_volume(
    left: &Image<u64>,
    right: &Image<u64>,
    range: DisparityRange,
    census_bits: u32,
    volume: &mut [u8],
) {
    let (width, _) = left.size();
    let nd = range.count();
    let worst = census_bits.min(255) as u8;
    volume.par_chunks_mut(width * nd).enumerate().for_each(|(y, row)| {
        let (l, r) = (left.row(y), right.row(y));
        for (x, costs) in row.chunks_exact_mut(nd).enumerate() {
            for (k, c) in costs.iter_mut().enumerate() {
                let xr = x as i64 - (range.min as i64 + k as i64);
                *c = if xr >= 0 && (xr as usize) < width {
                    (l[x] ^ r[xr as usize]).count_ones() as u8
                } else {
                    worst
                };
            }
        }
    });
}

/// Padding on both ends of each pixel's path-cost vector so the `d±1` neighbours need no
/// bounds checks: large enough never to win, small enough that `+ P1` cannot overflow.
const PAD: u16 = 0x7fff;

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
                let pen = penalties(p2, p1, here, row[xs[col_index - 1]]);
                path_step(c, h_prev, h_min, pen, h_cur)
            };
            // Vertical path, from the same column of the previous row.
            let from_row = (!first_row).then_some(x);
            row_step(c, v_prev, v_cur, x, from_row, stride, penalties(p2, p1, here, prev_row[x]));

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
                let pen_a = penalties(p2, p1, here, a_from.map_or(here, |f| prev_row[f]));
                let pen_b = penalties(p2, p1, here, b_from.map_or(here, |f| prev_row[f]));
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

/// The original census transform (clamped reads per neighbour), where a neighbour must be darker
/// than the centre by more than `tolerance` to set its bit.
pub(crate) fn census_transform(
    image: &GrayImage,
    window: CensusWindow,
    tolerance: u16,
    out: &mut Image<u64>,
) {
    let (width, height) = image.size();
    debug_assert_eq!(out.size(), (width, height));
    let (rx, ry) = ((window.width / 2) as isize, (window.height / 2) as isize);
    out.as_mut_slice().par_chunks_mut(width.max(1)).enumerate().for_each(|(y, row)| {
        let rows: Vec<&[u16]> = (-ry..=ry)
            .map(|dy| image.row((y as isize + dy).clamp(0, height as isize - 1) as usize))
            .collect();
        for (x, bits_out) in row.iter_mut().enumerate() {
            let centre = image.get(x, y);
            let mut bits = 0u64;
            for (dy, r) in (-ry..=ry).zip(&rows) {
                for dx in -rx..=rx {
                    if dx == 0 && dy == 0 {
                        continue;
                    }
                    let v = r[(x as isize + dx).clamp(0, width as isize - 1) as usize];
                    bits = (bits << 1) | u64::from(u32::from(v) + u32::from(tolerance) < u32::from(centre));
                }
            }
            *bits_out = bits;
        }
    });
}

/// The whole original pipeline: census (plus the AD term of [`crate::MatchingCost::AdCensus`]),
/// stored cost volume, aggregation, WTA, median.
pub(crate) fn sgm_reference(
    left: &GrayImage,
    right: &GrayImage,
    params: &crate::SgmParams,
) -> crate::DisparityMap {
    sgm_reference_ad(left, right, params, None)
}

/// Adds an AD-census term to a census cost volume (a prototype to measure the cost kernel
/// change, see docs/accuracy.md): `cost += round(weight · min(BT, truncation))`, with BT the
/// Birchfield–Tomasi sampling-insensitive absolute difference in 8-bit grey levels; infeasible
/// disparities keep their cost; the sum saturates at 255.
pub(crate) fn add_ad_costs(
    left: &GrayImage,
    right: &GrayImage,
    range: DisparityRange,
    weight: f32,
    truncation: f32,
    volume: &mut [u8],
) {
    let (width, _) = left.size();
    let nd = range.count();
    let grey = |row: &[u16], x: usize| f32::from(row[x]) / 257.0;
    // Interval [min, max] of the half-pixel interpolation around x.
    let interval = |row: &[u16], x: usize| {
        let c = grey(row, x);
        let a = 0.5 * (c + grey(row, x.saturating_sub(1)));
        let b = 0.5 * (c + grey(row, (x + 1).min(width - 1)));
        (c.min(a).min(b), c.max(a).max(b))
    };
    volume.par_chunks_mut(width * nd).enumerate().for_each(|(y, row)| {
        let (l, r) = (left.row(y), right.row(y));
        for (x, costs) in row.chunks_exact_mut(nd).enumerate() {
            let (lmin, lmax) = interval(l, x);
            let il = grey(l, x);
            for (k, c) in costs.iter_mut().enumerate() {
                let xr = x as i64 - (range.min as i64 + k as i64);
                if xr < 0 || xr as usize >= width {
                    continue;
                }
                let xr = xr as usize;
                let ir = grey(r, xr);
                let (rmin, rmax) = interval(r, xr);
                let d_lr = (il - rmax).max(rmin - il).max(0.0);
                let d_rl = (ir - lmax).max(lmin - ir).max(0.0);
                let bt = d_lr.min(d_rl).min(truncation);
                *c = (f32::from(*c) + (weight * bt).round()).min(255.0) as u8;
            }
        }
    });
}

/// The production AD-census term, the readable way: adds `min(weight · BT, cap)` to every
/// feasible cost and `cap` to every infeasible one, with BT the Birchfield–Tomasi dissimilarity
/// of `round(I / 257)` against the rounded min/max of the half-pixel interpolations.
pub(crate) fn add_ad_census_costs(
    left: &GrayImage,
    right: &GrayImage,
    range: DisparityRange,
    weight: u8,
    cap: u8,
    volume: &mut [u8],
) {
    let (width, _) = left.size();
    let nd = range.count();
    // (value, min, max) in 8-bit grey levels: twice each sample, rounded from /514.
    let grey = |twice: u32| ((twice + 257) / 514) as i32;
    let levels = |row: &[u16], x: usize| {
        let c = u32::from(row[x]);
        let a = c + u32::from(row[x.saturating_sub(1)]);
        let b = c + u32::from(row[(x + 1).min(width - 1)]);
        (grey(2 * c), grey((2 * c).min(a).min(b)), grey((2 * c).max(a).max(b)))
    };
    volume.par_chunks_mut(width * nd).enumerate().for_each(|(y, row)| {
        let (l, r) = (left.row(y), right.row(y));
        for (x, costs) in row.chunks_exact_mut(nd).enumerate() {
            let (il, lmin, lmax) = levels(l, x);
            for (k, c) in costs.iter_mut().enumerate() {
                let xr = x as i64 - (range.min as i64 + k as i64);
                let term = if xr < 0 || xr as usize >= width {
                    i32::from(cap)
                } else {
                    let (ir, rmin, rmax) = levels(r, xr as usize);
                    let d_lr = (il - rmax).max(rmin - il).max(0);
                    let d_rl = (ir - lmax).max(lmin - ir).max(0);
                    (i32::from(weight) * d_lr.min(d_rl)).min(i32::from(cap))
                };
                *c = (i32::from(*c) + term) as u8;
            }
        }
    });
}

/// [`sgm_reference`] with an optional AD term `(weight, truncation)` ([`add_ad_costs`]).
pub(crate) fn sgm_reference_ad(
    left: &GrayImage,
    right: &GrayImage,
    params: &crate::SgmParams,
    ad: Option<(f32, f32)>,
) -> crate::DisparityMap {
    let (width, height) = left.size();
    let nd = params.range.count();
    let census_bits = (params.census.width * params.census.height - 1) as u32;
    let crate::sgm::Adapted { params: adapted, census_left, census_right, views, .. } =
        crate::sgm::adapt_to_pair(left, right, params, census_transform);
    let params = &adapted;
    let (left, right, edges_left) = views.resolve(left, right);
    let mut cost = vec![0u8; width * height * nd];
    hamming_cost_volume(&census_left, &census_right, params.range, census_bits, &mut cost);
    if let crate::MatchingCost::AdCensus { weight, cap } = params.matching_cost {
        add_ad_census_costs(left, right, params.range, weight, cap, &mut cost);
    }
    if let Some((weight, truncation)) = ad {
        add_ad_costs(left, right, params.range, weight, truncation, &mut cost);
    }
    let mut sum = vec![0u16; width * height * nd];
    let p2 = P2Table::new(params.p1, params.p2, params.p2_edge_scale);
    aggregate_paths(left, &cost, nd, params.paths, params.p1, &p2, &mut sum);
    let mut disparity = crate::DisparityMap::new(width, height, f32::NAN);
    let selection = crate::wta::Selection {
        range: params.range,
        uniqueness_ratio: params.uniqueness_ratio,
        lr_max_diff: params.lr_max_diff,
        lr_left_neighbour: params.lr_left_neighbour,
        subpixel: params.subpixel,
    };
    let mut right_best = vec![0usize; width];
    for (out, costs) in disparity.as_mut_slice().chunks_mut(width).zip(sum.chunks(width * nd)) {
        crate::wta::select_row_reference(costs, width, nd, selection, &mut right_best, out);
    }
    crate::post::reject_range_ends(&mut disparity, params.range);
    if params.median {
        disparity = crate::filter::median_3x3_reference(&disparity);
    }
    crate::post::after_median(disparity, edges_left, params, 1).disparity
}

/// Measurement harness (not a check): runs the reference pipeline with an AD-census cost on
/// the scenes dumped to `/tmp/acc_data` (raw little-endian u16 images and f32 ground truth,
/// `list.txt` of `name width height ndisp`). `STEREO_AD="weight,truncation"` sets the AD term,
/// `STEREO_P="p1,p2"` the penalties. Run with
/// `cargo test -p stereo-disparity --release -- --ignored ad_census_measurement --nocapture`.
#[test]
#[ignore]
fn ad_census_measurement() {
    let Ok(list) = std::fs::read_to_string("/tmp/acc_data/list.txt") else { return };
    let env = |k: &str| std::env::var(k).ok();
    let ad = env("STEREO_AD").map(|v| {
        let (a, b) = v.split_once(',').unwrap();
        (a.parse::<f32>().unwrap(), b.parse::<f32>().unwrap())
    });
    let mut params = crate::SgmParams { matching_cost: crate::MatchingCost::Census, ..Default::default() };
    if let Some(v) = env("STEREO_P") {
        let (a, b) = v.split_once(',').unwrap();
        (params.p1, params.p2) = (a.parse().unwrap(), b.parse().unwrap());
    }
    let mut line = String::new();
    for entry in list.lines() {
        let f: Vec<&str> = entry.split(' ').collect();
        let (w, h, nd): (usize, usize, i32) =
            (f[1].parse().unwrap(), f[2].parse().unwrap(), f[3].parse().unwrap());
        let read = |ext: &str| std::fs::read(format!("/tmp/acc_data/{}.{ext}", f[0])).unwrap();
        let img = |b: Vec<u8>| {
            GrayImage::from_vec(w, h, b.chunks_exact(2).map(|c| u16::from_le_bytes([c[0], c[1]])).collect())
                .unwrap()
        };
        let (l, r) = (img(read("l")), img(read("r")));
        let gt: Vec<f32> =
            read("gt").chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
        let p = crate::SgmParams { range: DisparityRange::new(0, nd).unwrap(), ..params.clone() };
        let d = sgm_reference_ad(&l, &r, &p, ad);
        let (mut n, mut bad) = (0usize, 0usize);
        for (e, g) in d.as_slice().iter().zip(&gt) {
            if g.is_finite() && *g > 0.0 {
                n += 1;
                let err = (f64::from(*e) - f64::from(*g)).abs();
                bad += usize::from(e.is_nan() || err > 2.0);
            }
        }
        line += &format!(" {:.2}", 100.0 * bad as f64 / n as f64);
    }
    println!("AD {ad:?} P1/P2 {}/{} bad2:{line}", params.p1, params.p2);
}
