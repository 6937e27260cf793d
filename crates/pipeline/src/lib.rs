//! Pair in, depth out: the stereo-depth pipeline that the command line, batch processing and
//! the Python package all call.
//!
//! A [`Plan`] is made once from the views' sizes and the [`PipelineParams`] (sizes and range
//! checked, memory planned), before any pixel is read; [`Plan::run`] then checks the pair's
//! rectification, matches, cuts by confidence and depth limits and triangulates, returning one
//! [`DepthResult`]. Writing files is the caller's business (`stereo-io`).
//!
//! # Example
//!
//! A caller's 8-bit buffers (a camera frame, a numpy array) are viewed in place, not copied:
//!
//! ```
//! use stereo_pipeline::{DisparityRange, ImageRef, Matcher, PipelineParams, Plan, Rig, SgmParams};
//!
//! // A textured plane 6 px away in disparity: the right view is the left one shifted.
//! let (width, height) = (96, 48);
//! let texture = |x: usize, y: usize| ((x * 7919 + y * 104_729) % 251) as u8;
//! let left: Vec<u8> = (0..width * height).map(|i| texture(i % width, i / width)).collect();
//! let right: Vec<u8> = (0..width * height).map(|i| texture(i % width + 6, i / width)).collect();
//!
//! let mut params = PipelineParams::new(Matcher::Sgm(SgmParams {
//!     range: DisparityRange::new(0, 16)?,
//!     ..SgmParams::default()
//! }));
//! params.rig = Some(Rig::from_focal_px(120.0, 600.0)?); // baseline 120 mm, focal 600 px
//! let plan = Plan::new(&params, (width, height), (width, height))?;
//! let result = plan.run(ImageRef::new(&left, width, height)?, ImageRef::new(&right, width, height)?)?;
//!
//! assert!((result.disparity.get(60, 24) - 6.0).abs() < 0.25);
//! let z = result.depth.as_ref().unwrap().get(60, 24); // Z = B·f / d = 0.12 m · 600 / 6
//! assert!((z - 12.0).abs() < 0.5);
//! Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod depth_limits;
mod matcher;
mod options;
mod plan;
mod run;
mod sizes;

pub use depth_limits::DepthLimits;
pub use matcher::{Matcher, MatcherKind};
pub use options::{MatcherOptions, OptionError};
pub use plan::{MemoryLimit, PipelineParams, Plan};
pub use run::{DepthResult, Rectification, StageTimings};
pub use sizes::parse_scaled;

/// The instruction set the matcher's kernels run with here (`scalar`, `avx2`, `avx512`, `neon`;
/// `STEREO_DISPARITY_SIMD` caps it). The maps are the same on every one.
pub use stereo_disparity::stages::simd_level;
pub use stereo_disparity::{
    parse_named, Adaptation, BmCost, BmParams, DisparityRange, Downscale, Named, PathCount, Preset, Search,
    SearchReport, SgmParams, Subpixel,
};
pub use stereo_image::{DisparityMap, GrayImage, Image, ImageRef};
pub use stereo_rectify::{Alignment, AlignmentVerdict};
pub use stereo_triangulation::Rig;

/// Why a pair cannot be processed.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// The matcher refused the pair or its parameters (sizes, range, window).
    #[error(transparent)]
    Matcher(#[from] stereo_disparity::Error),
    /// A pipeline parameter is outside its accepted range.
    #[error("invalid parameter {name}: {message}")]
    InvalidParameter { name: &'static str, message: String },
    /// An image without pixels.
    #[error("image is {width}x{height}")]
    EmptyImage { width: usize, height: usize },
    /// A view of another size than the plan was made for.
    #[error("the plan is for {}x{} views, not {}x{}", planned.0, planned.1, given.0, given.1)]
    PlannedFor { planned: (usize, usize), given: (usize, usize) },
    /// The pair needs more memory than the limit, even with the matcher at its leanest.
    #[error("the pair needs about {needed} bytes, more than the limit of {limit}")]
    TooLarge { needed: u64, limit: u64 },
}

#[cfg(test)]
mod tests;
