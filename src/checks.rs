//! Checks of the user's numbers that the matcher cannot make: the `--min-depth`/`--max-depth`
//! cut of the disparity map, and warnings for rig values that look like a unit mistake.

use serde::Serialize;
use stereo_pipeline::{DepthLimits, Rig};

use crate::error::UsageError;

/// `--min-depth` / `--max-depth`, checked: each finite and > 0, min below max; `None` when
/// neither flag is given. The messages name the flags; the pipeline's own check
/// ([`DepthLimits::new`]) then holds by construction.
pub fn depth_limits(min_m: Option<f64>, max_m: Option<f64>) -> Result<Option<DepthLimits>, UsageError> {
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
    DepthLimits::new(min_m, max_m).map_err(|err| UsageError(err.to_string()))
}

/// The flag to name in "needs a rig" messages.
pub fn depth_limits_flag(limits: &DepthLimits) -> &'static str {
    if limits.min_m.is_some() {
        "--min-depth"
    } else {
        "--max-depth"
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

impl DepthLimitsReport {
    pub fn new(limits: &DepthLimits, rig: &Rig, cut_pixels: usize) -> Self {
        let (low, high) = limits.disparity_interval(rig);
        DepthLimitsReport {
            min_m: limits.min_m,
            max_m: limits.max_m,
            disparity_min_px: low,
            disparity_max_px: high,
            cut_pixels,
        }
    }
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
    use stereo_pipeline::DisparityMap;

    use super::*;

    fn rig() -> Rig {
        // B·f = 80 mm · 3000 px: Z = 240 / (d + doffs) m.
        Rig::from_focal_px(80.0, 3000.0).unwrap()
    }

    #[test]
    fn limits_are_validated() {
        assert_eq!(depth_limits(None, None).unwrap(), None);
        assert!(depth_limits(Some(1.0), Some(2.0)).unwrap().is_some());
        for (min, max) in
            [(Some(0.0), None), (None, Some(-1.0)), (Some(f64::NAN), None), (None, Some(f64::INFINITY))]
        {
            let err = depth_limits(min, max).unwrap_err().0;
            assert!(err.contains("must be a finite number > 0 m"), "{err}");
        }
        let err = depth_limits(Some(3.0), Some(3.0)).unwrap_err().0;
        assert_eq!(err, "--min-depth 3 m must be below --max-depth 3 m");
    }

    #[test]
    fn limits_cut_the_disparity_map_by_depth() {
        let limits = depth_limits(Some(4.0), Some(12.0)).unwrap().unwrap();
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
        let limits = depth_limits(None, Some(24.0)).unwrap().unwrap();
        // d + doffs must be >= 240 / 24 = 10: d >= 20. d = 5 has no depth at all (d + doffs < 0).
        assert_eq!(limits.disparity_interval(&rig), (20.0, None));
        let mut d = DisparityMap::from_vec(3, 1, vec![5.0, 10.0, 20.0]).unwrap();
        assert_eq!(limits.apply(&mut d, &rig), 2);
        assert!(d.get(0, 0).is_nan() && d.get(1, 0).is_nan() && d.get(2, 0) == 20.0);
        let report = DepthLimitsReport::new(&limits, &rig, 2);
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
