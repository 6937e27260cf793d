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
    let (src, grey) = (disparity.as_slice(), guide.as_slice());
    let mut rows = disparity.clone();
    rows.as_mut_slice().par_chunks_mut(w).enumerate().for_each_init(Vec::new, |found, (y, out)| {
        let line = Line { src: &src[y * w..(y + 1) * w], grey: &grey[y * w..(y + 1) * w], stride: 1 };
        jumps(&line.src[..w - 1], &line.src[1..], found);
        for &x in found.iter() {
            let (run, value) = snap_jump(&line, 0, w, x as usize + 1, radius);
            out[run].fill(value);
        }
    });
    // Columns: the jumps found row pair by row pair and each followed down or up its own column
    // (in parallel: they only read the rows' result), then the runs written in the order a pass
    // along each column takes its jumps, in place (jumps are rare).
    let line = Line { src: rows.as_slice(), grey, stride: w };
    let runs: Vec<Vec<(u32, std::ops::Range<usize>, f32)>> = (1..h)
        .into_par_iter()
        .map_init(Vec::new, |found, y| {
            jumps(&line.src[(y - 1) * w..y * w], &line.src[y * w..(y + 1) * w], found);
            found
                .iter()
                .map(|&x| {
                    let (run, value) = snap_jump(&line, x as usize, h, y, radius);
                    (x, run, value)
                })
                .collect()
        })
        .collect();
    let out = rows.as_mut_slice();
    for (x, run, value) in runs.into_iter().flatten() {
        for i in run {
            out[x as usize + i * w] = value;
        }
    }
    rows
}

/// The indices `i` where `b[i]` and `a[i]` differ by more than [`SNAP_JUMP`] (a NaN on either
/// side is no jump: the comparison is false), into `out` in increasing order: a block of 16
/// tested at once into a bit mask (a loop the compiler vectorises), then its set bits.
fn jumps(a: &[f32], b: &[f32], out: &mut Vec<u32>) {
    const BLOCK: usize = 16;
    out.clear();
    let mut push_block = |start: usize, a: &[f32], b: &[f32]| {
        let mut mask = 0u32;
        for (j, (&a, &b)) in a.iter().zip(b).enumerate() {
            mask |= u32::from((b - a).abs() > SNAP_JUMP) << j;
        }
        while mask != 0 {
            out.push((start + mask.trailing_zeros() as usize) as u32);
            mask &= mask - 1;
        }
    };
    let (a_blocks, b_blocks) = (a.chunks_exact(BLOCK), b.chunks_exact(BLOCK));
    let tail = a.len() - a_blocks.remainder().len();
    let (a_tail, b_tail) = (a_blocks.remainder(), b_blocks.remainder());
    for (k, (a, b)) in a_blocks.zip(b_blocks).enumerate() {
        let (a, b): (&[f32; BLOCK], &[f32; BLOCK]) = (a.try_into().unwrap(), b.try_into().unwrap());
        push_block(k * BLOCK, a, b);
    }
    push_block(tail, a_tail, b_tail);
}

/// A row (`stride` 1) or all the columns (`stride` = width) of a map and its guide image.
struct Line<'a> {
    src: &'a [f32],
    grey: &'a [u16],
    stride: usize,
}

/// The jump between pixels `i - 1` and `i` (`1 <= i < n`) of the line starting at `start`: moves
/// it across the foreground plateau to the strongest intensity step within `radius`: the run of
/// the line's pixels that takes the background's disparity, and that disparity.
fn snap_jump(
    line: &Line<'_>,
    start: usize,
    n: usize,
    i: usize,
    radius: usize,
) -> (std::ops::Range<usize>, f32) {
    let at = |i: usize| start + i * line.stride;
    let src = |i: usize| line.src[at(i)];
    // The intensity step between pixels i - 1 and i, in 8-bit grey levels.
    let grey = |i: usize| f32::from(line.grey[at(i)]) / 257.0;
    let step = |i: usize| (grey(i) - grey(i - 1)).abs();
    // Whether pixel i still belongs to the plateau of disparity `d` (NaNs do not end it).
    let on_plateau = |i: usize, d: f32| src(i).is_nan() || (src(i) - d).abs() <= SNAP_JUMP;
    let (x, a, b) = (i, src(i - 1), src(i));
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
        (x..best, a)
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
        (best..x, b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The plain version of [`snap_edges`]: each row, then each column, copied out and snapped
    /// pixel by pixel (the implementation before the jumps were found a block at a time).
    fn snap_edges_reference(disparity: &DisparityMap, guide: &GrayImage, radius: usize) -> DisparityMap {
        let (w, h) = disparity.size();
        let grey = |x: usize, y: usize| f32::from(guide.get(x, y)) / 257.0;
        let mut rows = disparity.clone();
        for y in 0..h {
            let g: Vec<f32> = (0..w).map(|x| grey(x, y)).collect();
            snap_line_reference(disparity.row(y), &g, radius, rows.row_mut(y));
        }
        let mut snapped = rows.clone();
        for x in 0..w {
            let d: Vec<f32> = (0..h).map(|y| rows.get(x, y)).collect();
            let g: Vec<f32> = (0..h).map(|y| grey(x, y)).collect();
            let mut out = d.clone();
            snap_line_reference(&d, &g, radius, &mut out);
            for (y, v) in out.into_iter().enumerate() {
                snapped.set(x, y, v);
            }
        }
        snapped
    }

    fn snap_line_reference(src: &[f32], grey: &[f32], radius: usize, out: &mut [f32]) {
        let n = src.len();
        let step = |i: usize| (grey[i] - grey[i - 1]).abs();
        let on_plateau = |i: usize, d: f32| src[i].is_nan() || (src[i] - d).abs() <= SNAP_JUMP;
        for x in 1..n {
            let (a, b) = (src[x - 1], src[x]);
            if a.is_nan() || b.is_nan() || (b - a).abs() <= SNAP_JUMP {
                continue;
            }
            let mut best = x;
            let mut best_step = step(x);
            if b > a {
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

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

        /// Random maps of plateaus with holes over random images with edges: the block-wise
        /// search gives the plain version's map bit for bit.
        #[test]
        fn matches_the_plain_line_by_line_version(w in 1usize..70, h in 1usize..50, radius in 0usize..8, seed in proptest::prelude::any::<u64>()) {
            let mut s = seed | 1;
            let mut next = move || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s };
            let mut map = DisparityMap::new(w, h, 10.0);
            let mut guide = GrayImage::new(w, h, 60 * 257);
            for _ in 0..(w * h / 30).max(2) {
                let (x0, y0) = ((next() % w as u64) as usize, (next() % h as u64) as usize);
                let (rw, rh) = (1 + (next() % 12) as usize, 1 + (next() % 12) as usize);
                let value = match next() % 6 {
                    0 => f32::NAN,
                    k => 5.0 + 3.0 * k as f32 + 0.25 * (next() % 4) as f32,
                };
                let level = (next() % 65536) as u16;
                // Image edges near the region's outline, a pixel or two off at random.
                let (gx, gy) = (x0 + (next() % 3) as usize, y0 + (next() % 3) as usize);
                for y in y0..(y0 + rh).min(h) {
                    for x in x0..(x0 + rw).min(w) {
                        map.set(x, y, value);
                    }
                }
                for y in gy..(gy + rh).min(h) {
                    for x in gx..(gx + rw).min(w) {
                        guide.set(x, y, level);
                    }
                }
            }
            let fast = snap_edges(&map, &guide, radius);
            let slow = snap_edges_reference(&map, &guide, radius);
            for (a, b) in fast.as_slice().iter().zip(slow.as_slice()) {
                proptest::prop_assert!(a.to_bits() == b.to_bits());
            }
        }
    }

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
