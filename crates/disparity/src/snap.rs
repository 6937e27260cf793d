//! Edge snapping: moves disparity discontinuities onto the nearby intensity edge of the left
//! image, which undoes the "edge fattening" of window costs.
//!
//! A census window straddling a depth edge matches with the foreground's disparity when the
//! foreground has the stronger texture, so the foreground's disparity spreads up to about half a
//! window into the background (worst on the occluded side, where the background pixel has no
//! true match at all). The true depth edge is usually where the image has an intensity edge: on
//! each row (then each column) a disparity jump is moved across the foreground plateau beside it
//! to the strongest intensity step within `radius` pixels, and the pixels passed over take the
//! background's disparity. Fattening only ever spreads the foreground, so the edge moves only
//! into the foreground side.

use rayon::prelude::*;

use crate::{DisparityMap, GrayImage};

/// A disparity step between neighbours larger than this (px) is a depth edge.
pub(crate) const SNAP_JUMP: f32 = 0.6;
/// An intensity step (8-bit grey levels) must exceed this to count as an image edge.
pub(crate) const SNAP_MIN_STEP: f32 = 6.0;
/// ... and be this many times the intensity step at the disparity jump (or at the previous
/// candidate), so weak texture inside the foreground does not move the edge.
pub(crate) const SNAP_RATIO: f32 = 3.0;

/// Snaps the disparity edges of `disparity` onto the intensity edges of `guide` (the left
/// image), first along the rows, then along the columns; see the module documentation.
/// NaN pixels are never sources; a NaN inside a foreground plateau that is passed over takes the
/// background's disparity. `radius` 0 returns the map unchanged.
pub(crate) fn snap_edges(disparity: &DisparityMap, guide: &GrayImage, radius: usize) -> DisparityMap {
    let (w, h) = disparity.size();
    assert_eq!(guide.size(), (w, h), "guide image size");
    if radius == 0 || w == 0 || h == 0 {
        return disparity.clone();
    }
    let mut grey = vec![0f32; w * h];
    grey.par_chunks_mut(w).zip(guide.as_slice().par_chunks(w)).for_each(|(g, v)| {
        for (g, &v) in g.iter_mut().zip(v) {
            *g = f32::from(v) / 257.0;
        }
    });
    let mut rows = disparity.clone();
    rows.as_mut_slice().par_chunks_mut(w).enumerate().for_each(|(y, out)| {
        snap_line(disparity.row(y), &grey[y * w..(y + 1) * w], radius, out);
    });
    // Columns, a block of neighbouring columns at a time: each block is gathered into contiguous
    // columns (one cache line per row read), snapped, and written back row by row.
    const BLOCK: usize = 16;
    let src = rows.as_slice();
    let blocks: Vec<(usize, Vec<f32>)> = (0..w.div_ceil(BLOCK))
        .into_par_iter()
        .map(|b| {
            let (x0, n) = (b * BLOCK, BLOCK.min(w - b * BLOCK));
            let (mut d, mut g) = (vec![0f32; n * h], vec![0f32; n * h]);
            for y in 0..h {
                for j in 0..n {
                    d[j * h + y] = src[y * w + x0 + j];
                    g[j * h + y] = grey[y * w + x0 + j];
                }
            }
            let mut out = d.clone();
            for j in 0..n {
                let col = j * h..(j + 1) * h;
                snap_line(&d[col.clone()], &g[col.clone()], radius, &mut out[col]);
            }
            (x0, out)
        })
        .collect();
    let mut snapped = DisparityMap::new(w, h, 0.0);
    snapped.as_mut_slice().par_chunks_mut(w).enumerate().for_each(|(y, row)| {
        for (x0, out) in &blocks {
            for (j, d) in row[*x0..*x0 + out.len() / h].iter_mut().enumerate() {
                *d = out[j * h + y];
            }
        }
    });
    snapped
}

/// One row or column: `src` the disparities, `grey` the intensities, results into `out`
/// (a copy of `src` on entry).
fn snap_line(src: &[f32], grey: &[f32], radius: usize, out: &mut [f32]) {
    let n = src.len();
    // step(i): the intensity step between pixels i - 1 and i.
    let step = |i: usize| (grey[i] - grey[i - 1]).abs();
    // Whether pixel i still belongs to the plateau of disparity `d` (NaNs do not end it).
    let on_plateau = |i: usize, d: f32| src[i].is_nan() || (src[i] - d).abs() <= SNAP_JUMP;
    for x in 1..n {
        let (a, b) = (src[x - 1], src[x]);
        if a.is_nan() || b.is_nan() || (b - a).abs() <= SNAP_JUMP {
            continue;
        }
        let mut best = x;
        let mut best_step = step(x);
        if b > a {
            // Foreground from x on: look right for a stronger edge inside its plateau.
            for i in x + 1..=(x + radius).min(n - 1) {
                if !on_plateau(i - 1, b) {
                    break;
                }
                let s = step(i);
                if s > SNAP_MIN_STEP && s > SNAP_RATIO * best_step {
                    best = i;
                    best_step = s;
                }
            }
            out[x..best].fill(a);
        } else {
            // Foreground up to x - 1: look left.
            for i in (x.saturating_sub(radius).max(1)..x).rev() {
                if !on_plateau(i, a) {
                    break;
                }
                let s = step(i);
                if s > SNAP_MIN_STEP && s > SNAP_RATIO * best_step {
                    best = i;
                    best_step = s;
                }
            }
            out[best..x].fill(b);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_fattened_edge_moves_onto_the_image_edge() {
        // Image: dark background up to x = 9, bright foreground from x = 10. Disparities: the
        // foreground's 12 has spread three pixels into the background (x = 7..10).
        let w = 20;
        let guide = GrayImage::from_fn(w, 3, |x, _| if x >= 10 { 200 * 257 } else { 40 * 257 });
        let d = DisparityMap::from_fn(w, 3, |x, _| if x >= 7 { 12.0 } else { 5.0 });
        let s = snap_edges(&d, &guide, 5);
        for x in 0..w {
            assert_eq!(s.get(x, 1), if x >= 10 { 12.0 } else { 5.0 }, "x = {x}");
        }
        // Mirrored: foreground on the left, spread to the right.
        let guide = GrayImage::from_fn(w, 3, |x, _| if x < 10 { 200 * 257 } else { 40 * 257 });
        let d = DisparityMap::from_fn(w, 3, |x, _| if x < 13 { 12.0 } else { 5.0 });
        let s = snap_edges(&d, &guide, 5);
        for x in 0..w {
            assert_eq!(s.get(x, 1), if x < 10 { 12.0 } else { 5.0 }, "x = {x}");
        }
    }

    #[test]
    fn edges_beyond_the_radius_or_without_image_edge_stay() {
        let w = 20;
        let flat = GrayImage::new(w, 1, 100 * 257);
        let d = DisparityMap::from_fn(w, 1, |x, _| if x >= 7 { 12.0 } else { 5.0 });
        assert_eq!(snap_edges(&d, &flat, 5), d);
        // The image edge is six pixels inside the foreground: out of reach of radius 5.
        let guide = GrayImage::from_fn(w, 1, |x, _| if x >= 13 { 200 * 257 } else { 40 * 257 });
        assert_eq!(snap_edges(&d, &guide, 5), d);
        assert_eq!(snap_edges(&d, &guide, 0), d);
    }
}
