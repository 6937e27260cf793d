//! Census transform: each pixel becomes a bit string saying which neighbours in its window are
//! darker than it. Matching costs are then Hamming distances, which are robust to gain and bias
//! differences between the two cameras.

use rayon::prelude::*;

use crate::{CensusWindow, GrayImage, Image};

/// Census transform with a dense `window` (at most 64 comparisons, so one `u64` per pixel).
/// Bit order: window positions row by row, skipping the centre; a bit is 1 when that
/// neighbour is darker than the centre. Outside the image the nearest border pixel is used.
pub(crate) fn census_transform(image: &GrayImage, window: CensusWindow, out: &mut Image<u64>) {
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
                    bits = (bits << 1) | u64::from(v < centre);
                }
            }
            *bits_out = bits;
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn census_marks_darker_neighbours() {
        // 3x3 window around the centre of a 3x3 image: bits in row order, centre skipped.
        let img = GrayImage::from_vec(3, 3, vec![1, 9, 1, 9, 5, 9, 1, 9, 1]).unwrap();
        let mut out = Image::new(3, 3, 0u64);
        census_transform(&img, CensusWindow { width: 3, height: 3 }, &mut out);
        assert_eq!(out.get(1, 1), 0b1010_0101);
    }

    #[test]
    fn census_is_invariant_to_gain_and_bias() {
        let img = GrayImage::from_fn(20, 10, |x, y| ((x * 37 + y * 101) % 200) as u16);
        let brighter = GrayImage::from_fn(20, 10, |x, y| img.get(x, y) * 3 + 500);
        let window = CensusWindow { width: 9, height: 7 };
        let (mut a, mut b) = (Image::new(20, 10, 0u64), Image::new(20, 10, 0u64));
        census_transform(&img, window, &mut a);
        census_transform(&brighter, window, &mut b);
        assert_eq!(a, b);
    }
}
