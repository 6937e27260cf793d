//! Window block matching with winner-takes-all.

use crate::{BmParams, DisparityMap, Error, GrayImage};

/// Block matching of a rectified pair: window costs (SAD on a prefiltered image or census),
/// winner-takes-all, optional subpixel refinement, uniqueness and left-right checks.
pub fn block_match(left: &GrayImage, right: &GrayImage, params: &BmParams) -> Result<DisparityMap, Error> {
    let _ = (left, right, params);
    todo!("block matching")
}
