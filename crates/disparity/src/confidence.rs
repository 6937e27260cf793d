//! A per-pixel confidence in `[0, 1]` for a matched disparity map.
//!
//! Two cues, multiplied: how well the two census strings at the match agree
//! (`1 − min(1, 2·H / bits)` for Hamming distance `H`: identical strings give 1, a random pair,
//! about `bits / 2` differing bits, gives 0), and how many of the 8 neighbours agree with the
//! pixel's disparity within 1 px (isolated values are rarely right). Invalid pixels have 0.

use rayon::prelude::*;

use crate::{DisparityMap, Image};

/// The confidence of every pixel of `disparity` (before the median and the fill: the disparity
/// winner-takes-all chose), from the census images it was matched with.
pub(crate) fn census_confidence(
    disparity: &DisparityMap,
    census_left: &Image<u64>,
    census_right: &Image<u64>,
    census_bits: u32,
) -> Image<f32> {
    let (width, height) = disparity.size();
    let mut out = Image::new(width, height, 0f32);
    out.as_mut_slice().par_chunks_mut(width.max(1)).enumerate().for_each(|(y, row)| {
        for (x, c) in row.iter_mut().enumerate() {
            let d = disparity.get(x, y);
            if !d.is_finite() {
                continue;
            }
            let xr = (x as f32 - d).round();
            if xr < 0.0 || xr >= width as f32 {
                continue;
            }
            let hamming = (census_left.get(x, y) ^ census_right.get(xr as usize, y)).count_ones();
            let agreement = 1.0 - (2.0 * hamming as f32 / census_bits as f32).min(1.0);
            let (mut neighbours, mut agreeing) = (0u32, 0u32);
            for yy in y.saturating_sub(1)..(y + 2).min(height) {
                for xx in x.saturating_sub(1)..(x + 2).min(width) {
                    if (xx, yy) == (x, y) {
                        continue;
                    }
                    neighbours += 1;
                    agreeing += u32::from((disparity.get(xx, yy) - d).abs() <= 1.0);
                }
            }
            let consistency = if neighbours == 0 { 1.0 } else { agreeing as f32 / neighbours as f32 };
            *c = agreement * consistency;
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn perfect_matches_are_confident_and_invalid_pixels_are_not() {
        let census = Image::from_fn(8, 4, |x, y| (x as u64 * 0x9E37_79B9) ^ (y as u64) << 40);
        // The right census is the left one shifted by 2: disparity 2 matches exactly.
        let right = Image::from_fn(8, 4, |x, y| census.get((x + 2).min(7), y));
        let mut d = DisparityMap::new(8, 4, 2.0);
        d.set(2, 0, f32::NAN);
        let c = census_confidence(&d, &census, &right, 63);
        assert_eq!(c.get(4, 2), 1.0);
        assert_eq!(c.get(2, 0), 0.0);
        // Left of x = 2 the match would be outside the right image.
        assert_eq!(c.get(1, 3), 0.0);
        // (3, 0) sees one invalid neighbour out of five.
        assert!((c.get(3, 0) - 0.8).abs() < 1e-6, "{}", c.get(3, 0));
        // An outlier disparity disagrees with all its neighbours.
        d.set(5, 2, 6.0);
        assert_eq!(census_confidence(&d, &census, &right, 63).get(5, 2), 0.0);
    }
}
