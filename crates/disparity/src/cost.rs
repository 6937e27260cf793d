//! Matching costs: Hamming distances between left and right census strings. They are computed
//! row by row inside the aggregation passes ([`crate::simd::cost_row`]), never stored as a
//! `W·H·D` volume.

/// Cost of a disparity that points outside the right image: as bad as the worst census match,
/// so path aggregation can cross the border but winner-takes-all never picks it.
pub(crate) fn infeasible_cost(census_bits: u32) -> u16 {
    census_bits.min(255) as u16
}
