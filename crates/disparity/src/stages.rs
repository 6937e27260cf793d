//! The SGM stages one at a time, for the `matchers` benchmark (not a stable API).
//!
//! [`sgm`](crate::sgm) runs them fused; these entry points run each over a whole image so its
//! throughput can be measured alone.

use crate::cost::{infeasible_cost, AdRows, BtRow};
use crate::kernels::layout::{padded_lanes, padded_lanes_u8};
use crate::kernels::{self, features};
use crate::{DisparityMap, GrayImage, Image, MatchingCost, SgmParams};

/// Census transform of one image with the window of `params`.
pub fn census(image: &GrayImage, params: &SgmParams) -> Image<u64> {
    let mut out = Image::new(image.width(), image.height(), 0u64);
    crate::census::census_transform(image, params.census, &mut out);
    out
}

/// The matching costs of every row as the aggregation computes them (census Hamming distance,
/// plus the intensity term for AD-census as `params.matching_cost` says): in 8 bits where the
/// aggregation runs 8-bit path costs (AVX-512 or NEON, costs and penalties within the 8-bit
/// bound), else in 16; returns a checksum.
pub fn matching_costs(
    left: &GrayImage,
    right: &GrayImage,
    census_left: &Image<u64>,
    census_right: &Image<u64>,
    params: &SgmParams,
) -> u64 {
    let nd = params.range.count();
    let census_bits = (params.census.width * params.census.height - 1) as u32;
    let worst = infeasible_cost(census_bits, params.matching_cost);
    let narrow = crate::aggregate::u8_passes(worst, params.p1, params.p2);
    let mut row = vec![0u16; census_left.width() * padded_lanes(nd)];
    let mut row_u8 = vec![0u8; census_left.width() * padded_lanes_u8(nd)];
    let (mut bt_left, mut bt_right) = (BtRow::default(), BtRow::default());
    let mut check = 0u64;
    for y in 0..census_left.height() {
        let ad = match params.matching_cost {
            MatchingCost::AdCensus { weight, cap } => {
                bt_left.fill(left.row(y), false);
                bt_right.fill(right.row(y), true);
                Some(AdRows {
                    left: &bt_left,
                    right: &bt_right,
                    weight: u16::from(weight),
                    cap: u16::from(cap),
                })
            }
            MatchingCost::Census => None,
        };
        let (l, r, min) = (census_left.row(y), census_right.row(y), params.range.min);
        if narrow {
            kernels::cost_row_u8(features(), l, r, min, nd, worst, ad, &mut row_u8);
            check = check.wrapping_add(u64::from(row_u8[y % row_u8.len()]));
        } else {
            kernels::cost_row(features(), l, r, min, nd, worst, ad, &mut row);
            check = check.wrapping_add(u64::from(row[y % row.len()]));
        }
    }
    check
}

/// Path aggregation (with the costs computed on the fly) and winner-takes-all with the checks,
/// without the median: `sgm` minus census and post-filter (census cost only: no right image).
pub fn aggregate_and_select_disparities(
    left: &GrayImage,
    census_left: &Image<u64>,
    census_right: &Image<u64>,
    params: &SgmParams,
) -> DisparityMap {
    crate::sgm::aggregate_census(left, None, census_left, census_right, params)
}

/// The post-processing of a selected map, as [`sgm`](crate::sgm) runs it with `params`: range
/// ends, the median, border ramps, far islands, speckles, the status image, the fill (with
/// [`SgmParams::fill`]), edge snapping and the weighted median.
pub fn post_process(disparity: &DisparityMap, left: &GrayImage, params: &SgmParams) -> DisparityMap {
    crate::post::finish(disparity.clone(), left, params, 1).disparity
}

/// The 3×3 median post-filter.
pub fn median(disparity: &DisparityMap) -> DisparityMap {
    crate::filter::median_3x3(disparity)
}

/// The instruction set the kernels run with on this machine (`STEREO_DISPARITY_SIMD` caps it).
pub fn simd_level() -> &'static str {
    features().level.name()
}
