//! Rectification of stereo pairs.
//!
//! Raw pairs from a calibrated rig: [`read_calibration`] reads OpenCV (YAML, XML, JSON), ROS
//! `camera_info` and Middlebury calibrations; a [`Rectifier`] (Bouguet's construction as in
//! OpenCV's `stereoRectify`, plumb-bob distortion) holds the undistort-rectify maps of one
//! calibration at one image size and the rectified rig, and [`RectifyMap::remap`] applies them.
//!
//! Already rectified pairs:
//!
//! A rectified pair puts every scene point on the same row of both views. Real rigs drift: the
//! right view ends up a fraction of a pixel higher or lower, or slightly rotated, and matching
//! along rows then degrades. [`estimate_alignment`] measures that residual vertical misalignment
//! from the images themselves (and whether the pair looks swapped), and [`compensate`] resamples
//! the right view so its rows line up with the left view again.
//!
//! # Example
//!
//! ```
//! use stereo_image::{DisparityRange, GrayImage};
//! use stereo_rectify::{compensate, estimate_alignment, AlignmentVerdict};
//!
//! // A smooth random texture; the right view sees it 6 px to the left and 0.8 px lower.
//! let texture = |x: f64, y: f64| {
//!     let v = (0.31 * x + 0.17 * y).sin() + (0.23 * x - 0.29 * y).sin() + (0.11 * x + 0.41 * y).cos()
//!         + (0.07 * x * 0.5 - 0.13 * y).sin() + (0.37 * x + 0.05 * y).cos();
//!     (32768.0 + 6000.0 * v) as u16
//! };
//! let left = GrayImage::from_fn(200, 150, |x, y| texture(x as f64, y as f64));
//! let right = GrayImage::from_fn(200, 150, |x, y| texture(x as f64 + 6.0, y as f64 - 0.8));
//! let range = DisparityRange::new(0, 16)?;
//!
//! let alignment = estimate_alignment(&left, &right, range);
//! assert_eq!(alignment.verdict, AlignmentVerdict::Misaligned);
//! assert!((alignment.vertical_offset_px - 0.8).abs() < 0.1);
//!
//! // After compensation the rows line up again.
//! let aligned = compensate(&right, &alignment);
//! let residual = estimate_alignment(&left, &aligned, range);
//! assert!(residual.max_abs_offset_px < 0.15);
//! Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod alignment;
mod cache;
mod calib_file;
mod camera;
mod remap;
mod stereo;
mod tree;

pub use alignment::{compensate, estimate_alignment, Alignment, AlignmentVerdict};
pub use cache::RectifierCache;
pub use calib_file::{
    read_calibration, CalibError, CalibFormat, CalibrationFile, GivenRectification, StereoCalibration,
};
pub use camera::{rodrigues, rotation_vector, Camera, LensModel};
pub use remap::{RectifyMap, Sample};
pub use stereo::{
    fisheye_stereo_rectify, stereo_rectify, undistort_rectify_map, RectifiedRig, Rectifier,
    StereoRectification,
};
