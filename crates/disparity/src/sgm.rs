//! Semi-Global Matching: census cost volume, path aggregation, winner-takes-all, checks.

use crate::{DisparityMap, Error, GrayImage, SgmParams};

/// Semi-Global Matching of a rectified pair.
pub fn sgm(left: &GrayImage, right: &GrayImage, params: &SgmParams) -> Result<DisparityMap, Error> {
    let _ = (left, right, params);
    todo!("sgm")
}
