//! Matching cost volume: Hamming distance between left and right census strings for every pixel
//! and disparity, stored `[y][x][d]` with the disparities of a pixel contiguous.

use rayon::prelude::*;

use crate::{DisparityRange, Image};

/// Cost of a disparity that points outside the right image: as bad as the worst census match,
/// so path aggregation can cross the border but winner-takes-all never picks it.
pub(crate) fn infeasible_cost(census_bits: u32) -> u8 {
    census_bits.min(255) as u8
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
    let worst = infeasible_cost(census_bits);
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
