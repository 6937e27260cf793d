//! Checks of the user's numbers that the matcher cannot make: the `--min-depth`/`--max-depth`
//! cut of the disparity map, and warnings for rig values that look like a unit mistake.

use serde::Serialize;
use stereo_disparity::DisparityMap;
use stereo_triangulation::Rig;

use crate::config::UsageError;

/// `--min-depth` / `--max-depth`, checked: each finite and > 0, min below max.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DepthLimits {
    pub min_m: Option<f64>,
    pub max_m: Option<f64>,
}

impl DepthLimits {
    /// `None` when neither flag is given.
    pub fn new(min_m: Option<f64>, max_m: Option<f64>) -> Result<Option<Self>, UsageError> {
        for (flag, value) in [("--min-depth", min_m), ("--max-depth", max_m)] {
            if let Some(v) = value {
                if !(v.is_finite() && v > 0.0) {
                    return Err(UsageError(format!("invalid {flag} {v} m (must be a finite number > 0 m)")));
                }
            }
        }
        if let (Some(min), Some(max)) = (min_m, max_m) {
            if min >= max {
                return Err(UsageError(format!("--min-depth {min} m must be below --max-depth {max} m")));
            }
        }
        Ok((min_m.is_some() || max_m.is_some()).then_some(DepthLimits { min_m, max_m }))
    }

    /// The flag to name in "needs a rig" messages.
    pub fn flag(&self) -> &'static str {
        if self.min_m.is_some() {
            "--min-depth"
        } else {
            "--max-depth"
        }
    }

    /// The disparities whose depth is within the limits: `d + doffs` in `[B·f / max, B·f / min]`
    /// (`Z = B·f / (d + doffs)`, so the far limit bounds the disparity from below). Without
    /// --max-depth the lower bound is exclusive: `d + doffs` must stay > 0 to have a depth.
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

    pub fn report(&self, rig: &Rig, cut_pixels: usize) -> DepthLimitsReport {
        let (low, high) = self.disparity_interval(rig);
        DepthLimitsReport {
            min_m: self.min_m,
            max_m: self.max_m,
            disparity_min_px: low,
            disparity_max_px: high,
            cut_pixels,
        }
    }
}

/// The `depth_limits` object of the stats.
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct DepthLimitsReport {
    pub min_m: Option<f64>,
    pub max_m: Option<f64>,
    /// The disparity interval the limits amount to with this rig, pixels (`null`: unbounded).
    pub disparity_min_px: f64,
    pub disparity_max_px: Option<f64>,
    /// Pixels with a disparity that the limits invalidated.
    pub cut_pixels: usize,
}

/// Where a baseline came from, for the warning: a flag or a calibration file.
pub enum BaselineSource<'a> {
    Flag,
    Calib(&'a std::path::Path),
}

/// Warnings for rig values no real camera has, most likely given in the wrong unit. They never
/// change the result: a lab rig may really be that odd.
pub fn rig_warnings(baseline: Option<(f64, BaselineSource)>, pixel_um: Option<f64>) -> Vec<String> {
    let mut warnings = Vec::new();
    if let Some((mm, source)) = baseline {
        if mm < 1.0 {
            warnings.push(match source {
                BaselineSource::Flag => format!(
                    "--baseline {mm} mm is below 1 mm: --baseline is in millimetres (were these metres? \
                     {mm} m is --baseline {})",
                    // Rounded to the micrometre: 0.12 · 1000 is not exactly 120 in binary.
                    (mm * 1e6).round() / 1e3
                ),
                BaselineSource::Calib(path) => format!(
                    "{}: baseline {mm} mm is below 1 mm: calib.txt gives it in millimetres (were these \
                     metres?)",
                    path.display()
                ),
            });
        }
    }
    if let Some(um) = pixel_um {
        if um > 100.0 {
            warnings.push(format!(
                "--pixel {um} µm is above 100 µm, far larger than camera pixels (about 1 to 20 µm): \
                 --pixel is in micrometres (were these another unit?)"
            ));
        }
    }
    warnings
}

/// Prints each warning as one `stereo-depth: warning: ` line on stderr.
pub fn print_warnings(warnings: &[String]) {
    for warning in warnings {
        eprintln!("stereo-depth: warning: {warning}");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rig() -> Rig {
        // B·f = 80 mm · 3000 px: Z = 240 / (d + doffs) m.
        Rig::from_focal_px(80.0, 3000.0).unwrap()
    }

    #[test]
    fn limits_are_validated() {
        assert_eq!(DepthLimits::new(None, None).unwrap(), None);
        assert!(DepthLimits::new(Some(1.0), Some(2.0)).unwrap().is_some());
        for (min, max) in
            [(Some(0.0), None), (None, Some(-1.0)), (Some(f64::NAN), None), (None, Some(f64::INFINITY))]
        {
            let err = DepthLimits::new(min, max).unwrap_err().0;
            assert!(err.contains("must be a finite number > 0 m"), "{err}");
        }
        let err = DepthLimits::new(Some(3.0), Some(3.0)).unwrap_err().0;
        assert_eq!(err, "--min-depth 3 m must be below --max-depth 3 m");
    }

    #[test]
    fn limits_cut_the_disparity_map_by_depth() {
        let limits = DepthLimits::new(Some(4.0), Some(12.0)).unwrap().unwrap();
        // 240 / 12 = 20 px and 240 / 4 = 60 px are the edges, and are kept.
        assert_eq!(limits.disparity_interval(&rig()), (20.0, Some(60.0)));
        let mut d = DisparityMap::from_vec(7, 1, vec![19.9, 20.0, 40.0, 60.0, 60.1, f32::NAN, -2.0]).unwrap();
        // NaN was not valid, so not cut: 19.9, 60.1 and -2 (no depth) are.
        assert_eq!(limits.apply(&mut d, &rig()), 3);
        let kept: Vec<bool> = d.as_slice().iter().map(|v| v.is_finite()).collect();
        assert_eq!(kept, [false, true, true, true, false, false, false]);
    }

    #[test]
    fn a_far_limit_alone_cuts_disparities_without_depth() {
        let rig = rig().with_doffs(-10.0).unwrap();
        let limits = DepthLimits::new(None, Some(24.0)).unwrap().unwrap();
        // d + doffs must be >= 240 / 24 = 10: d >= 20. d = 5 has no depth at all (d + doffs < 0).
        assert_eq!(limits.disparity_interval(&rig), (20.0, None));
        let mut d = DisparityMap::from_vec(3, 1, vec![5.0, 10.0, 20.0]).unwrap();
        assert_eq!(limits.apply(&mut d, &rig), 2);
        assert!(d.get(0, 0).is_nan() && d.get(1, 0).is_nan() && d.get(2, 0) == 20.0);
        let report = limits.report(&rig, 2);
        assert_eq!((report.disparity_min_px, report.disparity_max_px, report.cut_pixels), (20.0, None, 2));
    }

    #[test]
    fn unit_mistakes_are_warned_about() {
        assert!(rig_warnings(Some((80.0, BaselineSource::Flag)), Some(4.0)).is_empty());
        assert!(rig_warnings(Some((1.0, BaselineSource::Flag)), Some(100.0)).is_empty());
        let w = rig_warnings(Some((0.08, BaselineSource::Flag)), Some(3450.0));
        assert_eq!(w.len(), 2);
        assert!(
            w[0].contains("--baseline 0.08 mm is below 1 mm") && w[0].contains("--baseline 80"),
            "{}",
            w[0]
        );
        assert!(w[1].contains("--pixel 3450 µm is above 100 µm"), "{}", w[1]);
        let path = std::path::Path::new("scene/calib.txt");
        let w = rig_warnings(Some((0.193, BaselineSource::Calib(path))), None);
        assert!(w[0].starts_with("scene/calib.txt: baseline 0.193 mm"), "{}", w[0]);
    }
}
