//! Metric depth from disparity for a rectified rig: `Z = B·f / ((d + doffs)·p)`.

use stereo_disparity::{DisparityMap, Image};

/// Invalid rig parameters.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("invalid {name}: {value} ({expected})")]
    InvalidParameter { name: &'static str, value: f64, expected: &'static str },
}

/// A rectified stereo rig.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Rig {
    /// Distance between the optical centres, mm.
    pub baseline_mm: f64,
    /// Focal length in pixels (`focal_mm * 1000 / pixel_um`).
    pub focal_px: f64,
    /// Disparity offset between the principal points (Middlebury's `doffs`), pixels.
    pub doffs: f64,
    /// Principal point in pixels; `None` means the image centre.
    pub principal_point: Option<(f64, f64)>,
}

impl Rig {
    /// A rig from datasheet values: baseline and focal length in mm, pixel pitch in µm.
    pub fn from_datasheet(baseline_mm: f64, focal_mm: f64, pixel_um: f64) -> Result<Self, Error> {
        let _ = (baseline_mm, focal_mm, pixel_um);
        todo!()
    }

    /// Depth in metres for disparity `d` pixels; `None` when `d + doffs <= 0` or not finite.
    pub fn depth(&self, d: f64) -> Option<f64> {
        let _ = d;
        todo!()
    }
}

/// The depth map (metres, NaN where invalid) of a disparity map.
pub fn depth_map(disparity: &DisparityMap, rig: &Rig) -> Image<f32> {
    let _ = (disparity, rig);
    todo!()
}
