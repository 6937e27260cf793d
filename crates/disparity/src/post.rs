//! Post-processing after winner-takes-all: median, speckle removal, the status image and the
//! optional dense fill.

use crate::fill::fill_invalid;
use crate::filter::{median_3x3, weighted_median, weighted_median_at_edges};
use crate::snap::snap_edges;
use crate::speckle::remove_speckles;
use crate::status::untag;
use crate::{DisparityMap, Error, GrayImage, Image, SgmParams};

/// The full result of [`crate::sgm_detailed`].
#[derive(Clone, Debug, PartialEq)]
pub struct SgmOutput {
    /// The left view's disparity map (dense when [`SgmParams::fill`] is set and anything matched).
    pub disparity: DisparityMap,
    /// Per pixel, why it has no matched disparity: a [`crate::PixelStatus`] code (0 = matched).
    /// With [`SgmParams::fill`], every pixel whose status is not 0 but whose disparity is finite
    /// was filled.
    pub status: Image<u8>,
    /// With [`SgmParams::confidence`]: per pixel, a confidence in `[0, 1]` (census agreement at
    /// the match times the share of neighbours within 1 px); 0 for invalid and filled pixels.
    pub confidence: Option<Image<f32>>,
}

impl SgmOutput {
    /// 255 where the disparity was filled rather than matched, 0 elsewhere.
    pub fn filled_mask(&self) -> Image<u8> {
        crate::fill::filled_mask(&self.disparity, &self.status)
    }
}

/// Checks the post-processing parameters.
pub(crate) fn check(params: &SgmParams) -> Result<(), Error> {
    if params.speckle_max_diff.is_nan() || params.speckle_max_diff < 0.0 {
        return Err(Error::InvalidParameter {
            name: "speckle max difference",
            message: format!("{} must be a number >= 0", params.speckle_max_diff),
        });
    }
    Ok(())
}

/// [`SgmParams::wmf_edges_only`]: the weighted median runs where its window spans more than
/// this many pixels of disparity (measured: 1 px keeps its full effect on the seven Middlebury
/// scenes, docs/accuracy.md).
const WMF_EDGE_JUMP: f32 = 1.0;

/// Median (if enabled), then [`after_median`].
pub(crate) fn finish(mut disparity: DisparityMap, left: &GrayImage, params: &SgmParams) -> SgmOutput {
    if params.median {
        disparity = median_3x3(&disparity);
    }
    after_median(disparity, left, params)
}

/// Speckle removal, the status image (plain NaNs from here on), the fill, edge snapping and the
/// weighted median.
pub(crate) fn after_median(mut disparity: DisparityMap, left: &GrayImage, params: &SgmParams) -> SgmOutput {
    remove_speckles(&mut disparity, params.speckle_size, params.speckle_max_diff);
    let status = untag(&mut disparity);
    if params.fill {
        fill_invalid(&mut disparity, &status);
    }
    for _ in 0..params.edge_snap_passes {
        disparity = snap_edges(&disparity, left, params.edge_snap_radius);
    }
    if params.wmf_radius > 0 {
        disparity = if params.wmf_edges_only {
            weighted_median_at_edges(
                &disparity,
                left,
                params.wmf_radius,
                params.wmf_sigma_color,
                WMF_EDGE_JUMP,
            )
        } else {
            weighted_median(&disparity, left, params.wmf_radius, params.wmf_sigma_color, false)
        };
    }
    SgmOutput { disparity, status, confidence: None }
}
