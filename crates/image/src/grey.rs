//! Conversion of any supported pixel to the matchers' working grey: 16 bits, so 16-bit cameras
//! keep their precision; 8-bit values are scaled by 257 to use the full range, colour is
//! Rec. 601 luma. File loading (`stereo-io`) and in-memory views use these same functions, so
//! a PNG and the numpy array decoded from it match identically.

use crate::{GrayImage, ImageRef};

/// Rec. 601 luma (0.299, 0.587, 0.114) of 16-bit samples, rounded.
#[inline]
pub fn luma16(r: u16, g: u16, b: u16) -> u16 {
    let y = (299 * r as u32 + 587 * g as u32 + 114 * b as u32 + 500) / 1000;
    y as u16
}

/// An 8-bit sample on the 16-bit scale (0 → 0, 255 → 65535).
#[inline]
pub fn expand8(v: u8) -> u16 {
    v as u16 * 257
}

/// A pixel the matchers can take: its working 16-bit grey value (alpha ignored). (`Sync`, so two
/// views convert on two threads.)
pub trait ToGray16: Copy + Sync {
    fn to_gray16(self) -> u16;
}

impl ToGray16 for u8 {
    #[inline]
    fn to_gray16(self) -> u16 {
        expand8(self)
    }
}

impl ToGray16 for u16 {
    #[inline]
    fn to_gray16(self) -> u16 {
        self
    }
}

impl ToGray16 for [u8; 3] {
    #[inline]
    fn to_gray16(self) -> u16 {
        luma16(expand8(self[0]), expand8(self[1]), expand8(self[2]))
    }
}

impl ToGray16 for [u8; 4] {
    #[inline]
    fn to_gray16(self) -> u16 {
        luma16(expand8(self[0]), expand8(self[1]), expand8(self[2]))
    }
}

impl ToGray16 for [u16; 3] {
    #[inline]
    fn to_gray16(self) -> u16 {
        luma16(self[0], self[1], self[2])
    }
}

impl ToGray16 for [u16; 4] {
    #[inline]
    fn to_gray16(self) -> u16 {
        luma16(self[0], self[1], self[2])
    }
}

impl<T: ToGray16> ImageRef<'_, T> {
    /// The matchers' working grey image of this view.
    pub fn to_gray16(&self) -> GrayImage {
        self.map(ToGray16::to_gray16)
    }
}
