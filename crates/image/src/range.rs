//! The disparity convention every crate shares.

use crate::Error;

/// The disparities searched: `min <= d < max` (so `max - min` is OpenCV's `numDisparities`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct DisparityRange {
    pub min: i32,
    pub max: i32,
}

impl DisparityRange {
    /// Checks that the range holds at least one disparity.
    pub fn new(min: i32, max: i32) -> Result<Self, Error> {
        if max <= min {
            return Err(Error::EmptyRange { min, max });
        }
        Ok(DisparityRange { min, max })
    }

    /// How many disparities are searched.
    pub fn count(&self) -> usize {
        (self.max as i64 - self.min as i64).max(0) as usize
    }

    /// The default search range for an image `width` pixels wide: `0..` a quarter of the width,
    /// rounded up to a multiple of 16 (at least 16, at most the width).
    pub fn default_for_width(width: usize) -> Self {
        let quarter = width.div_ceil(4).div_ceil(16) * 16;
        let max = quarter.clamp(16.min(width), width.max(1));
        DisparityRange { min: 0, max: max as i32 }
    }
}

impl Default for DisparityRange {
    fn default() -> Self {
        DisparityRange { min: 0, max: 64 }
    }
}
