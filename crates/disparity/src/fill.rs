//! Dense output: invalid pixels filled as in Hirschmüller's SGM paper (2008, section 4.3) —
//! occlusions from the background side, wrong matches by interpolation.

use crate::status::PixelStatus;
use crate::{DisparityMap, Image};

/// The eight scan directions `(dx, dy)` the mismatch interpolation looks along.
const DIRECTIONS: [(isize, isize); 8] =
    [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, -1), (1, -1), (-1, 1)];

/// Fills every NaN pixel of `disparity` whose `status` ([`PixelStatus`] codes) is not
/// [`PixelStatus::Matched`]; the valid pixels are not changed, and only they are used as sources:
///
/// * [`PixelStatus::Occluded`]: the lower (background) of the nearest valid disparities to the
///   left and to the right along the row;
/// * everything else (mismatches, speckles, ambiguous and border pixels): the median of the
///   nearest valid disparities along the eight horizontal, vertical and diagonal directions.
///
/// Returns the number of pixels filled. Every NaN is filled unless the map has no valid pixel.
/// A map without status information can be filled with `status` all [`PixelStatus::Mismatch`].
pub fn fill_invalid(disparity: &mut DisparityMap, status: &Image<u8>) -> usize {
    assert_eq!(status.size(), disparity.size(), "status image size");
    let mut count = fill_pass(disparity, Some(status));
    // Holes that see no valid pixel along any of the eight directions: fill again from the
    // filled map, until nothing changes.
    loop {
        let more = fill_pass(disparity, None);
        if more == 0 {
            return count;
        }
        count += more;
    }
}

/// One fill from the current valid pixels; `status` `None` treats every hole as a mismatch.
fn fill_pass(disparity: &mut DisparityMap, status: Option<&Image<u8>>) -> usize {
    let (w, h) = disparity.size();
    let holes: Vec<usize> = (0..w * h).filter(|&i| disparity.as_slice()[i].is_nan()).collect();
    if holes.is_empty() || holes.len() == w * h {
        return 0;
    }
    let src = disparity.as_slice();
    // Per hole: the nearest valid value along each direction (NaN if none).
    let mut nearest = vec![[f32::NAN; 8]; holes.len()];
    let mut hole_index = vec![u32::MAX; w * h];
    for (n, &i) in holes.iter().enumerate() {
        hole_index[i] = n as u32;
    }
    let mut carry = vec![f32::NAN; w * h];
    for (k, &(dx, dy)) in DIRECTIONS.iter().enumerate() {
        // Visit pixels so that (x - dx, y - dy) comes before (x, y): carry[p] is the nearest
        // valid value at or behind p along the direction.
        let ys: Vec<usize> = if dy >= 0 { (0..h).collect() } else { (0..h).rev().collect() };
        let xs: Vec<usize> = if dx >= 0 { (0..w).collect() } else { (0..w).rev().collect() };
        for &y in &ys {
            for &x in &xs {
                let p = y * w + x;
                let (px, py) = (x as isize - dx, y as isize - dy);
                let behind = if px >= 0 && py >= 0 && (px as usize) < w && (py as usize) < h {
                    carry[py as usize * w + px as usize]
                } else {
                    f32::NAN
                };
                let v = src[p];
                carry[p] = if v.is_nan() { behind } else { v };
                if v.is_nan() {
                    nearest[hole_index[p] as usize][k] = behind;
                }
            }
        }
    }
    let occluded =
        |i: usize| status.is_some_and(|s| PixelStatus::from_code(s.as_slice()[i]) == PixelStatus::Occluded);
    let values: Vec<f32> = holes
        .iter()
        .zip(&nearest)
        .map(|(&i, near)| {
            // Directions 0 and 1 look along the row; an occlusion whose row has no valid pixel
            // falls back to the median.
            let v = if occluded(i) { min_valid(near[0], near[1]) } else { f32::NAN };
            if v.is_nan() {
                median_valid(near)
            } else {
                v
            }
        })
        .collect();
    let d = disparity.as_mut_slice();
    let mut count = 0;
    for (&i, v) in holes.iter().zip(values) {
        if !v.is_nan() {
            d[i] = v;
            count += 1;
        }
    }
    count
}

fn min_valid(a: f32, b: f32) -> f32 {
    match (a.is_nan(), b.is_nan()) {
        (false, false) => a.min(b),
        (false, true) => a,
        (true, false) => b,
        (true, true) => f32::NAN,
    }
}

/// The median of the non-NaN values (mean of the middle two for an even count); NaN if none.
fn median_valid(values: &[f32; 8]) -> f32 {
    // On the stack: this runs for every filled pixel.
    let mut valid = [0f32; 8];
    let mut n = 0;
    for &d in values.iter().filter(|d| !d.is_nan()) {
        valid[n] = d;
        n += 1;
    }
    if n == 0 {
        return f32::NAN;
    }
    let v = &mut valid[..n];
    v.sort_unstable_by(f32::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The pixels [`fill_invalid`] filled: 255 where `status` is not matched and the filled map has
/// a value, 0 elsewhere (e.g. for a confidence channel).
pub fn filled_mask(disparity: &DisparityMap, status: &Image<u8>) -> Image<u8> {
    let (w, h) = disparity.size();
    Image::from_fn(w, h, |x, y| {
        if status.get(x, y) != PixelStatus::Matched as u8 && !disparity.get(x, y).is_nan() {
            255
        } else {
            0
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn occlusions_take_the_background_mismatches_the_median() {
        // Row: background 10 on the left, foreground 30 on the right, a 2-pixel occlusion gap.
        let nan = f32::NAN;
        let mut d = DisparityMap::from_vec(6, 1, vec![10.0, 10.0, nan, nan, 30.0, 30.0]).unwrap();
        let status = Image::from_vec(6, 1, vec![0, 0, 3, 3, 0, 0]).unwrap();
        assert_eq!(fill_invalid(&mut d, &status), 2);
        assert_eq!(d.as_slice(), &[10.0, 10.0, 10.0, 10.0, 30.0, 30.0]);

        // A mismatch in the middle of a 3x3 block: the median of its eight neighbours.
        let mut m = DisparityMap::from_vec(3, 3, vec![1.0, 2.0, 3.0, 4.0, nan, 6.0, 7.0, 8.0, 9.0]).unwrap();
        let status = Image::from_vec(3, 3, vec![0, 0, 0, 0, 4, 0, 0, 0, 0]).unwrap();
        assert_eq!(fill_invalid(&mut m, &status), 1);
        assert_eq!(m.get(1, 1), 5.0);
        let mask = filled_mask(&m, &status);
        assert_eq!(mask.as_slice(), &[0, 0, 0, 0, 255, 0, 0, 0, 0]);
    }

    #[test]
    fn every_hole_is_filled_when_anything_is_valid() {
        let mut d = DisparityMap::new(7, 5, f32::NAN);
        d.set(6, 4, 3.0);
        let status = Image::new(7, 5, PixelStatus::Occluded as u8);
        assert_eq!(fill_invalid(&mut d, &status), 34);
        assert!(d.as_slice().iter().all(|&v| v == 3.0));
        let mut none = DisparityMap::new(3, 3, f32::NAN);
        assert_eq!(fill_invalid(&mut none, &Image::new(3, 3, 4)), 0);
    }
}
