//! A depth interval: pixels nearer or farther are invalidated in every output.

use stereo_image::DisparityMap;
use stereo_triangulation::Rig;

use crate::Error;

/// Depths outside `[min_m, max_m]` (metres; either end open) are invalidated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthLimits {
    pub min_m: Option<f64>,
    pub max_m: Option<f64>,
}

impl DepthLimits {
    /// Checks each end is finite and > 0 and `min < max`; `None` when both ends are open.
    pub fn new(min_m: Option<f64>, max_m: Option<f64>) -> Result<Option<Self>, Error> {
        for (name, value) in [("min_depth", min_m), ("max_depth", max_m)] {
            if let Some(v) = value {
                if !(v.is_finite() && v > 0.0) {
                    return Err(Error::InvalidParameter {
                        name,
                        message: format!("{v} m (must be finite and > 0)"),
                    });
                }
            }
        }
        if let (Some(min), Some(max)) = (min_m, max_m) {
            if min >= max {
                return Err(Error::InvalidParameter {
                    name: "min_depth",
                    message: format!("{min} m must be below max_depth {max} m"),
                });
            }
        }
        Ok((min_m.is_some() || max_m.is_some()).then_some(DepthLimits { min_m, max_m }))
    }

    /// The disparities whose depth is within the limits: `d + doffs` in `[B·f / max, B·f / min]`
    /// (`Z = B·f / (d + doffs)`, so the far limit bounds the disparity from below). Without
    /// a far limit the lower bound is exclusive: `d + doffs` must stay > 0 to have a depth.
    pub fn disparity_interval(&self, rig: &Rig) -> (f64, Option<f64>) {
        let bf_m = rig.baseline_mm * rig.focal_px / 1000.0;
        let low = self.max_m.map_or(0.0, |max| bf_m / max) - rig.doffs;
        let high = self.min_m.map(|min| bf_m / min - rig.doffs);
        (low, high)
    }

    /// Invalidates (NaN) every disparity whose depth is outside the limits or that has no depth
    /// at all (`d + doffs <= 0`); returns how many were cut. The decision uses [`Rig::depth`],
    /// the function that triangulates, so a pixel on the edge of the interval never yields a
    /// depth a rounding step outside the limits.
    pub fn apply(&self, disparity: &mut DisparityMap, rig: &Rig) -> usize {
        let (min, max) = (self.min_m.unwrap_or(0.0), self.max_m.unwrap_or(f64::INFINITY));
        let mut cut = 0;
        for d in disparity.as_mut_slice() {
            if !d.is_finite() {
                continue;
            }
            let inside = rig.depth(f64::from(*d)).is_some_and(|z| z >= min && z <= max);
            if !inside {
                *d = f32::NAN;
                cut += 1;
            }
        }
        cut
    }
}
