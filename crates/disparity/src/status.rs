//! Why a pixel has no matched disparity, and which pixels a dense fill invented.
//!
//! Inside the pipeline the reason travels in the payload of the NaN that marks the pixel (so
//! the fused aggregation and the post-filters need no extra buffer); [`crate::sgm_detailed`]
//! turns it into a [`PixelStatus`] image and leaves plain NaNs in the map.

use rayon::prelude::*;

use crate::{DisparityMap, Image};

/// What happened to a pixel of the left disparity map (the values of [`crate::SgmOutput::status`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum PixelStatus {
    /// A matched disparity that passed every check.
    Matched = 0,
    /// No disparity of the range fits inside the right image (the left border), or unknown.
    NoMatch = 1,
    /// Rejected by the uniqueness test.
    Ambiguous = 2,
    /// Rejected by the left-right check, and the right view's disparity at the matched pixel is
    /// larger: the pixel is hidden behind a nearer surface in the right view.
    Occluded = 3,
    /// Rejected by the left-right check otherwise: a wrong match.
    Mismatch = 4,
    /// Removed by the speckle filter (part of a small isolated region).
    Speckle = 5,
    /// The best match lies at an end of the disparities searched for the pixel (the range's
    /// ends, or the last disparity that stays inside the right image): the true minimum may lie
    /// outside, so the match is not trusted (these are the "flying points" of a depth map).
    /// Also a winner near the left border whose right census window leaves the image and that
    /// lies behind the surface beside it (more than 1 px with [`crate::SgmParams::fill`], more
    /// than a third farther without).
    RangeEnd = 6,
    /// Part of a small island (fewer than [`crate::DENSE_SPECKLE_SIZE`] pixels of similar
    /// depth) at least half of whose disparities are below half the median disparity around it:
    /// more than twice as far as the scene there, which the matcher cannot tell from a wrong match
    /// (mostly near the left border, where the true match has left the right image).
    FarIsland = 7,
}

impl PixelStatus {
    /// The status stored as `code` (unknown codes are [`PixelStatus::NoMatch`]).
    pub fn from_code(code: u8) -> Self {
        match code {
            0 => PixelStatus::Matched,
            2 => PixelStatus::Ambiguous,
            3 => PixelStatus::Occluded,
            4 => PixelStatus::Mismatch,
            5 => PixelStatus::Speckle,
            6 => PixelStatus::RangeEnd,
            7 => PixelStatus::FarIsland,
            _ => PixelStatus::NoMatch,
        }
    }
}

/// The quiet NaN whose payload says why the pixel is invalid.
#[inline]
pub(crate) fn tagged_nan(status: PixelStatus) -> f32 {
    f32::from_bits(0x7fc0_0000 | status as u32)
}

/// The status of a pixel of a map whose NaNs are tagged ([`tagged_nan`]); a plain NaN is
/// [`PixelStatus::NoMatch`].
#[inline]
pub(crate) fn status_of(value: f32) -> PixelStatus {
    if value.is_nan() {
        match (value.to_bits() & 0xff) as u8 {
            0 => PixelStatus::NoMatch,
            code => PixelStatus::from_code(code),
        }
    } else {
        PixelStatus::Matched
    }
}

/// Splits a tagged map into its status image and a map with plain NaNs.
pub(crate) fn untag(disparity: &mut DisparityMap) -> Image<u8> {
    let (w, h) = disparity.size();
    let mut status = Image::new(w, h, 0u8);
    status
        .as_mut_slice()
        .par_chunks_mut(w.max(1))
        .zip(disparity.as_mut_slice().par_chunks_mut(w.max(1)))
        .for_each(|(status, disparity)| {
            for (s, d) in status.iter_mut().zip(disparity) {
                *s = status_of(*d) as u8;
                if d.is_nan() {
                    *d = f32::NAN;
                }
            }
        });
    status
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tags_survive_the_round_trip() {
        for s in [
            PixelStatus::NoMatch,
            PixelStatus::Ambiguous,
            PixelStatus::Occluded,
            PixelStatus::Mismatch,
            PixelStatus::Speckle,
            PixelStatus::RangeEnd,
            PixelStatus::FarIsland,
        ] {
            let v = tagged_nan(s);
            assert!(v.is_nan());
            assert_eq!(status_of(v), s);
        }
        assert_eq!(status_of(f32::NAN), PixelStatus::NoMatch);
        assert_eq!(status_of(3.5), PixelStatus::Matched);
        let mut d =
            DisparityMap::from_vec(3, 1, vec![1.0, tagged_nan(PixelStatus::Occluded), f32::NAN]).unwrap();
        let s = untag(&mut d);
        assert_eq!(s.as_slice(), &[0, 3, 1]);
        assert_eq!(d.get(1, 0).to_bits(), f32::NAN.to_bits());
    }

    /// Every payload byte of positive and negative NaNs, beside values: `untag` gives
    /// `status_of`'s status and plain NaNs.
    #[test]
    fn untag_reads_every_payload_as_status_of_does() {
        let values: Vec<f32> = (0..256u32)
            .flat_map(|code| [f32::from_bits(0x7fc0_0000 | code), f32::from_bits(0xffc0_0000 | code)])
            .chain([0.0, -0.0, 1.5, f32::INFINITY, f32::from_bits(0x7f80_0001)])
            .collect();
        let mut d = DisparityMap::from_vec(values.len(), 1, values.clone()).unwrap();
        let s = untag(&mut d);
        for ((&v, &s), &out) in values.iter().zip(s.as_slice()).zip(d.as_slice()) {
            assert_eq!(s, status_of(v) as u8, "{:#x}", v.to_bits());
            assert_eq!(out.to_bits(), if v.is_nan() { f32::NAN.to_bits() } else { v.to_bits() });
        }
    }
}
