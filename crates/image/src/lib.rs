//! The images every stereo-depth crate shares: owned row-major [`Image`]s, borrowed strided
//! [`ImageRef`] views over a caller's buffer (a numpy array, a camera frame), their conversion
//! to the matchers' working 16-bit grey, and the [`DisparityRange`] convention.
//!
//! Conventions: left pixel `(x, y)` matches right pixel `(x - d, y)`; a [`DisparityMap`] holds
//! NaN where no disparity is known.
//!
//! # Example
//!
//! ```
//! use stereo_image::{ImageRef, GrayImage};
//!
//! // An 8-bit RGB camera frame with one pixel of padding per row, viewed in place.
//! let (width, height, stride) = (4, 2, 5 * 3);
//! let frame: Vec<u8> = (0..stride * height).map(|i| i as u8).collect();
//! let view = ImageRef::<[u8; 3]>::from_interleaved(&frame, width, height, stride)?;
//! assert_eq!(view.get(1, 1), [18, 19, 20]);
//! let grey: GrayImage = view.to_gray16();
//! assert_eq!(grey.size(), (4, 2));
//! Ok::<(), stereo_image::Error>(())
//! ```

mod grey;
mod image;
mod range;
mod view;

pub use grey::{expand8, luma16, ToGray16};
pub use image::{DisparityMap, GrayImage, Image};
pub use range::DisparityRange;
pub use view::ImageRef;

/// Buffers and ranges that do not describe an image.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Error {
    /// A buffer's length does not match the image size it was given with.
    #[error("buffer of {len} samples does not hold a {width}x{height} image")]
    BufferSize { width: usize, height: usize, len: usize },
    /// A strided buffer ends before the last pixel of the last row.
    #[error("buffer of {len} pixels does not hold a {width}x{height} image with rows {stride} pixels apart")]
    StridedBufferSize { width: usize, height: usize, stride: usize, len: usize },
    /// Rows would overlap.
    #[error("row stride {stride} is smaller than the width {width}")]
    Stride { width: usize, stride: usize },
    /// An interleaved row stride that is not a whole number of pixels.
    #[error("row stride of {stride} samples is not a whole number of {channels}-sample pixels")]
    Interleave { channels: usize, stride: usize },
    /// The disparity range `min..max` contains no disparity.
    #[error("disparity range is empty: min {min} must be below max {max}")]
    EmptyRange { min: i32, max: i32 },
}

#[cfg(test)]
mod tests;
