//! Rig design calculator: what a baseline, a lens and a sensor can measure, before any pair is
//! captured.
//!
//! Units as on a datasheet: baseline `B` and focal length `f` in mm, pixel pitch `p` in µm,
//! disparities in pixels, distances in metres, depth resolutions in mm.
//!
//! - distance `Z = B·f / ((d + doffs)·p)`: [`Rig::depth`], not restated here;
//! - disparity on the sensor `d·p` (mm): [`disparity_mm`];
//! - depth resolution, the change of `Z` for one disparity step `s` of the matcher (1 px for
//!   integer matching, e.g. 0.25 px with subpixel refinement):
//!   `ΔZ ≈ Z²·p·s / (B·f)` ([`Rig::depth_resolution`]). This is the first-order term, what
//!   datasheets and web calculators quote; it is within `s / (d + doffs)` of the exact difference
//!   `Z(d) - Z(d + s)`, so it is close wherever the depth is worth having, and overstates the
//!   exact step near the far end of the range (at `d = s` it says `ΔZ = Z`);
//! - the inverse, the disparity at a distance: [`disparity_at`];
//! - horizontal field of view `2·atan(w / 2f)` for a sensor `w` mm wide: [`horizontal_fov_deg`].
//!
//! [`Design::new`] checks a whole set of inputs and computes all of it, including the working
//! range (the nearest and farthest measurable distances) and an optional table; the result
//! serializes to JSON.
//!
//! ```
//! use stereo_triangulation::design::{Design, DesignInput};
//!
//! // 200 mm baseline, 6 mm lens, 2.5 µm pixels: 150 px of disparity is 3.2 m away.
//! let design =
//!     Design::new(&DesignInput { disparity_px: Some(150.0), ..DesignInput::new(200.0, 6.0, 2.5) })?;
//! let at = design.disparity.unwrap();
//! assert_eq!(design.focal_px, 2400.0);
//! assert_eq!(at.distance_m, 3.2);
//! assert_eq!(at.disparity_mm, 0.375);
//! // 3.2² m² · 2.5 µm · 1 px / (200 mm · 6 mm) = 21.33 mm per pixel of disparity.
//! assert!((at.depth_resolution_mm - 21.333).abs() < 1e-3);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::fmt;

use serde::Serialize;
use stereo_image::DisparityRange;

use crate::{Error, Rig};

/// The maximum disparity (exclusive, as the matchers take it) of the working range when neither
/// `max_disparity_px` nor the image width is given.
pub const DEFAULT_MAX_DISPARITY_PX: u32 = 128;

/// The most rows a table may have.
pub const MAX_TABLE_ROWS: usize = 10_000;

/// The chart's far end: where the depth resolution reaches this fraction of the distance
/// (`ΔZ / Z = s / (d + doffs)`, so at 10 steps of disparity), see [`Design::chart_range`].
pub const CHART_FAR_RELATIVE_RESOLUTION: f64 = 0.1;

/// Horizontal field of view in degrees of a sensor `sensor_width_mm` wide behind a lens of
/// `focal_mm`: `2·atan(w / 2f)`.
pub fn horizontal_fov_deg(sensor_width_mm: f64, focal_mm: f64) -> f64 {
    2.0 * (sensor_width_mm / (2.0 * focal_mm)).atan().to_degrees()
}

/// A disparity of `disparity_px` pixels measured on the sensor, mm: `d·p / 1000`.
pub fn disparity_mm(disparity_px: f64, pixel_um: f64) -> f64 {
    disparity_px * pixel_um / 1000.0
}

/// The disparity in pixels at which `rig` sees a point `distance_m` metres away, the inverse of
/// [`Rig::depth`]: `d = B·f_px / Z - doffs` (`B` in metres).
pub fn disparity_at(rig: &Rig, distance_m: f64) -> f64 {
    rig.baseline_mm * rig.focal_px / (distance_m * 1000.0) - rig.doffs
}

/// A parameter of [`DesignInput`], as named in [`DesignError`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Param {
    Baseline,
    Focal,
    Pixel,
    Doffs,
    SubpixelStep,
    SensorWidth,
    WidthPx,
    MaxDisparity,
    Disparity,
    Distance,
    TableMin,
    TableMax,
    TableStep,
}

impl Param {
    /// The parameter in words, e.g. `"pixel size"`.
    pub fn name(self) -> &'static str {
        match self {
            Param::Baseline => "baseline",
            Param::Focal => "focal length",
            Param::Pixel => "pixel size",
            Param::Doffs => "disparity offset",
            Param::SubpixelStep => "disparity step",
            Param::SensorWidth => "sensor width",
            Param::WidthPx => "image width",
            Param::MaxDisparity => "maximum disparity",
            Param::Disparity => "disparity",
            Param::Distance => "distance",
            Param::TableMin => "table minimum disparity",
            Param::TableMax => "table maximum disparity",
            Param::TableStep => "table disparity step",
        }
    }
}

/// An invalid design input: the parameter, its value and what it must be.
///
/// Displays as e.g. `invalid pixel size: 4000 µm (must be at most 1500 µm: …)`.
#[derive(Clone, Debug, PartialEq)]
pub struct DesignError {
    pub param: Param,
    /// The rejected value.
    pub value: f64,
    /// The unit of `value`, e.g. `"µm"`.
    pub unit: &'static str,
    /// The accepted range, e.g. `"a finite number > 0 mm"`.
    pub expected: String,
}

impl fmt::Display for DesignError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "invalid {}: {} {} (must be {})", self.param.name(), self.value, self.unit, self.expected)
    }
}

impl std::error::Error for DesignError {}

impl From<Error> for DesignError {
    fn from(err: Error) -> Self {
        let Error::InvalidParameter { name, value, unit, expected } = err;
        let param = match name {
            "baseline" => Param::Baseline,
            "pixel size" => Param::Pixel,
            "disparity offset" => Param::Doffs,
            // `from_datasheet` checks the focal length in mm, `from_focal_px` in px; both are
            // the lens.
            _ => Param::Focal,
        };
        DesignError { param, value, unit, expected: expected.to_string() }
    }
}

fn invalid(param: Param, value: f64, unit: &'static str, expected: impl Into<String>) -> DesignError {
    DesignError { param, value, unit, expected: expected.into() }
}

/// How wide the image is: the sensor width in mm or the image width in pixels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SensorWidth {
    /// Sensor width in mm; the image is `⌊w·1000 / p⌋` pixels wide.
    Mm(f64),
    /// Image width in pixels (a whole number >= 2); the sensor is `n·p / 1000` mm wide.
    Px(f64),
}

/// The disparities of a table; `None` fields take their defaults, see [`table_disparities`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TableSpec {
    pub min_px: Option<f64>,
    pub max_px: Option<f64>,
    pub step_px: Option<f64>,
}

/// Everything [`Design::new`] takes, unchecked.
#[derive(Clone, Debug, PartialEq)]
pub struct DesignInput {
    pub baseline_mm: f64,
    pub focal_mm: f64,
    pub pixel_um: f64,
    /// Disparity offset between the principal points, px (0 for most rigs).
    pub doffs_px: f64,
    /// The matcher's disparity step, in (0, 1] px: 1 for integer matching.
    pub subpixel_step_px: f64,
    pub sensor: Option<SensorWidth>,
    /// End of the disparity search (exclusive, like the matchers' `--max-disparity`), a whole
    /// number of pixels. `None`: the matchers' default for the image width when it is known
    /// (a quarter of it, rounded up to 16), else [`DEFAULT_MAX_DISPARITY_PX`].
    pub max_disparity_px: Option<f64>,
    /// Distance, disparity in mm and depth resolution at this disparity (px).
    pub disparity_px: Option<f64>,
    /// Disparity and depth resolution at this distance (m).
    pub distance_m: Option<f64>,
    pub table: Option<TableSpec>,
}

impl DesignInput {
    /// The rig alone: no doffs, 1 px steps, nothing else known or asked.
    pub fn new(baseline_mm: f64, focal_mm: f64, pixel_um: f64) -> Self {
        DesignInput {
            baseline_mm,
            focal_mm,
            pixel_um,
            doffs_px: 0.0,
            subpixel_step_px: 1.0,
            sensor: None,
            max_disparity_px: None,
            disparity_px: None,
            distance_m: None,
            table: None,
        }
    }
}

/// One disparity of the rig and what it means.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Point {
    /// Disparity, px.
    pub disparity_px: f64,
    /// The same disparity on the sensor, mm.
    pub disparity_mm: f64,
    /// Distance, m.
    pub distance_m: f64,
    /// Depth change for one disparity step at this distance, mm (`≈ Z²·p·s / (B·f)`).
    pub depth_resolution_mm: f64,
}

/// Where did the maximum disparity come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum MaxDisparitySource {
    /// Given.
    Given,
    /// The matchers' default for the image width.
    ImageWidth,
    /// [`DEFAULT_MAX_DISPARITY_PX`]: no width known.
    Default,
}

/// The distances the rig can measure: the disparity search covers `0 <= d < max_disparity_px`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct WorkingRange {
    /// End of the disparity search (exclusive), px.
    pub max_disparity_px: u32,
    pub max_disparity_source: MaxDisparitySource,
    /// At the largest searched disparity, `max_disparity_px - 1`.
    pub near: Point,
    /// At the smallest usable disparity: one disparity step (or, with a negative doffs, the
    /// first multiple of the step that still has a depth).
    pub far: Point,
}

/// The checked inputs and everything computed from them.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Design {
    pub baseline_mm: f64,
    pub focal_mm: f64,
    pub pixel_um: f64,
    /// `f·1000 / p`.
    pub focal_px: f64,
    pub doffs_px: f64,
    /// The disparity step `s` of every depth resolution.
    pub subpixel_step_px: f64,
    /// Given, or the image width × the pixel size.
    pub sensor_width_mm: Option<f64>,
    /// Given, or the whole pixels on the sensor width.
    pub image_width_px: Option<u64>,
    /// `2·atan(w / 2f)` when the sensor width is known.
    pub horizontal_fov_deg: Option<f64>,
    pub working_range: WorkingRange,
    /// At the asked disparity.
    pub disparity: Option<Point>,
    /// At the asked distance.
    pub distance: Option<Point>,
    pub table: Option<Vec<Point>>,
    #[serde(skip)]
    pub rig: Rig,
}

fn positive(param: Param, value: f64, unit: &'static str) -> Result<f64, DesignError> {
    if value.is_finite() && value > 0.0 {
        Ok(value)
    } else {
        Err(invalid(param, value, unit, format!("a finite number > 0 {unit}")))
    }
}

/// A whole number of pixels in `lo..=hi`, `hi` being e.g. `"the image width"` or, when `None`,
/// the largest `u32`.
fn whole(param: Param, value: f64, lo: f64, hi: Option<(f64, &str)>) -> Result<f64, DesignError> {
    let (hi, what) = hi.unwrap_or((f64::from(u32::MAX), ""));
    if value.is_finite() && value.fract() == 0.0 && value >= lo && value <= hi {
        return Ok(value);
    }
    let expected = if !what.is_empty() {
        format!("a whole number from {lo} px to {what} {hi} px")
    } else if value > hi {
        format!("a whole number from {lo} px to {hi} px")
    } else {
        format!("a whole number >= {lo} px")
    };
    Err(invalid(param, value, "px", expected))
}

/// `"> 0 px"` or, with a disparity offset, `"> -doffs px (d + doffs > 0)"`.
fn above_offset(doffs: f64) -> String {
    if doffs == 0.0 {
        "> 0 px".to_string()
    } else {
        format!("> {} px (d + doffs > 0)", -doffs)
    }
}

impl Design {
    /// Checks `input` and computes the design. Every rejected value names its parameter and the
    /// accepted range: zero, negative or non-finite values; a pixel so large that the sensor is
    /// less than 2 px wide; disparities at or beyond the image width; a disparity step outside
    /// (0, 1] px; a table of more than [`MAX_TABLE_ROWS`] rows.
    pub fn new(input: &DesignInput) -> Result<Design, DesignError> {
        let rig = Rig::from_datasheet(input.baseline_mm, input.focal_mm, input.pixel_um)?
            .with_doffs(input.doffs_px)?;
        let (focal_mm, pixel_um, doffs) = (input.focal_mm, input.pixel_um, rig.doffs);

        let step = input.subpixel_step_px;
        if !(step.is_finite() && step > 0.0 && step <= 1.0) {
            return Err(invalid(
                Param::SubpixelStep,
                step,
                "px",
                "a number in (0, 1] px: 1 for integer matching, e.g. 0.25 with subpixel refinement",
            ));
        }

        let (sensor_width_mm, image_width_px) = match input.sensor {
            None => (None, None),
            Some(SensorWidth::Mm(w)) => {
                let w = positive(Param::SensorWidth, w, "mm")?;
                // A hair of tolerance so that 6.4 mm / 4 µm is 1600 px, not 1599.
                let px = (w * 1000.0 / pixel_um * (1.0 + 1e-12)).floor();
                if px < 2.0 {
                    return Err(invalid(
                        Param::Pixel,
                        pixel_um,
                        "µm",
                        format!("at most {} µm: the {w} mm sensor must be at least 2 pixels wide", w * 500.0),
                    ));
                }
                (Some(w), Some(px as u64))
            }
            Some(SensorWidth::Px(n)) => {
                let n = whole(Param::WidthPx, n, 2.0, None)?;
                (Some(n * pixel_um / 1000.0), Some(n as u64))
            }
        };
        let width = image_width_px.map(|w| w as f64);

        // The smallest disparity with a depth: one step, or with a negative doffs the first
        // multiple of the step beyond -doffs.
        let smallest = if step + doffs > 0.0 { step } else { ((-doffs / step).floor() + 1.0) * step };

        let (max_disparity, source) = match (input.max_disparity_px, image_width_px) {
            (Some(max), _) => {
                let lo = (smallest.ceil() + 1.0).max(2.0);
                let max = whole(Param::MaxDisparity, max, lo, width.map(|w| (w, "the image width")))?;
                (max as u32, MaxDisparitySource::Given)
            }
            (None, Some(w)) => {
                let w = usize::try_from(w).unwrap_or(usize::MAX);
                (DisparityRange::default_for_width(w).max as u32, MaxDisparitySource::ImageWidth)
            }
            (None, None) => (DEFAULT_MAX_DISPARITY_PX, MaxDisparitySource::Default),
        };
        let largest = f64::from(max_disparity) - 1.0;
        if largest < smallest {
            return Err(invalid(
                Param::MaxDisparity,
                f64::from(max_disparity),
                "px",
                format!(
                    "a whole number >= {} px: no smaller disparity has a depth",
                    (smallest.ceil() + 1.0).max(2.0)
                ),
            ));
        }

        let mut design = Design {
            baseline_mm: rig.baseline_mm,
            focal_mm,
            pixel_um,
            focal_px: rig.focal_px,
            doffs_px: doffs,
            subpixel_step_px: step,
            sensor_width_mm,
            image_width_px,
            horizontal_fov_deg: sensor_width_mm.map(|w| horizontal_fov_deg(w, focal_mm)),
            working_range: WorkingRange {
                max_disparity_px: max_disparity,
                max_disparity_source: source,
                near: Point {
                    disparity_px: 0.0,
                    disparity_mm: 0.0,
                    distance_m: 0.0,
                    depth_resolution_mm: 0.0,
                },
                far: Point {
                    disparity_px: 0.0,
                    disparity_mm: 0.0,
                    distance_m: 0.0,
                    depth_resolution_mm: 0.0,
                },
            },
            disparity: None,
            distance: None,
            table: None,
            rig,
        };
        let max_error = |d: f64| {
            invalid(
                Param::MaxDisparity,
                f64::from(max_disparity),
                "px",
                format!("small enough that {d} px has a depth"),
            )
        };
        design.working_range.near = design.at_disparity(largest).ok_or_else(|| max_error(largest))?;
        design.working_range.far = design.at_disparity(smallest).ok_or_else(|| max_error(smallest))?;

        let below_width =
            |w: Option<f64>| w.map_or(String::new(), |w| format!(" and < the image width {w} px"));
        if let Some(d) = input.disparity_px {
            let ok = d.is_finite() && d + doffs > 0.0 && width.map_or(true, |w| d < w);
            let point = design.at_disparity(d).filter(|_| ok).ok_or_else(|| {
                invalid(
                    Param::Disparity,
                    d,
                    "px",
                    format!("a finite number {}{}", above_offset(doffs), below_width(width)),
                )
            })?;
            design.disparity = Some(point);
        }

        if let Some(z) = input.distance_m {
            let z = positive(Param::Distance, z, "m")?;
            let point = design.at_distance(z).ok_or_else(|| {
                invalid(Param::Distance, z, "m", "a finite number > 0 m with a finite disparity")
            })?;
            if let Some(w) = width {
                if point.disparity_px >= w {
                    // The nearest distance whose disparity is still inside the image.
                    let nearest = design.rig.depth(w).unwrap_or(0.0);
                    return Err(invalid(
                        Param::Distance,
                        z,
                        "m",
                        format!(
                            "> {} m: closer, the disparity {} px is not smaller than the image width {w} px",
                            sig(nearest, 4),
                            sig(point.disparity_px, 4)
                        ),
                    ));
                }
            }
            design.distance = Some(point);
        }

        if let Some(spec) = input.table {
            let disparities = table_disparities(&spec, smallest, largest, width)?;
            let rows: Vec<Point> = disparities.iter().filter_map(|&d| design.at_disparity(d)).collect();
            if rows.is_empty() {
                let min = disparities.first().copied().unwrap_or(smallest);
                return Err(invalid(
                    Param::TableMin,
                    min,
                    "px",
                    format!("a finite number {}: no row has a depth", above_offset(doffs)),
                ));
            }
            design.table = Some(rows);
        }
        Ok(design)
    }

    /// The rig's numbers at disparity `d` px; `None` where [`Rig::depth`] has no depth.
    pub fn at_disparity(&self, d: f64) -> Option<Point> {
        let z = self.rig.depth(d)?;
        Some(self.point(d, z))
    }

    /// The rig's numbers at distance `z` m (finite and > 0); `None` when the disparity would not
    /// be finite.
    pub fn at_distance(&self, z: f64) -> Option<Point> {
        let d = disparity_at(&self.rig, z);
        (z.is_finite() && z > 0.0 && d.is_finite()).then(|| self.point(d, z))
    }

    fn point(&self, d: f64, z: f64) -> Point {
        Point {
            disparity_px: d,
            disparity_mm: disparity_mm(d, self.pixel_um),
            distance_m: z,
            depth_resolution_mm: self.rig.depth_resolution(z, self.subpixel_step_px) * 1000.0,
        }
    }

    /// The distances a chart of the working range spans, m: from the nearest measurable
    /// distance to where the depth resolution reaches [`CHART_FAR_RELATIVE_RESOLUTION`] of the
    /// distance (10 disparity steps), or to the farthest measurable distance when the search
    /// range is shorter than that.
    pub fn chart_range(&self) -> (f64, f64) {
        let near = self.working_range.near;
        let far = self.working_range.far;
        let d = self.subpixel_step_px / CHART_FAR_RELATIVE_RESOLUTION - self.doffs_px;
        let far_m = match self.rig.depth(d) {
            Some(z) if d > far.disparity_px && d < near.disparity_px => z,
            _ => far.distance_m,
        };
        (near.distance_m, far_m)
    }

    /// `n >= 2` points from `from_m` to `to_m` (both > 0), spaced geometrically in distance so
    /// that the steep near end of the disparity curve gets as many as the flat far end.
    pub fn curve(&self, from_m: f64, to_m: f64, n: usize) -> Vec<Point> {
        let n = n.max(2);
        (0..n)
            .filter_map(|i| {
                let z = from_m * (to_m / from_m).powf(i as f64 / (n - 1) as f64);
                self.at_distance(z)
            })
            .collect()
    }
}

/// The disparities of a table, ascending. `spec`'s minimum defaults to `smallest` (one disparity
/// step) and its maximum to `largest` (the largest searched disparity). With a step, the rows are
/// `min, min + step, …` up to the maximum; without, a geometric series of `1` and `1.5` times the
/// powers of two between the two (…, 1, 1.5, 2, 3, 4, 6, 8, 12, …) and both ends. At most
/// [`MAX_TABLE_ROWS`] rows; the maximum must be below the image width when it is known.
pub fn table_disparities(
    spec: &TableSpec,
    smallest: f64,
    largest: f64,
    width: Option<f64>,
) -> Result<Vec<f64>, DesignError> {
    let min = match spec.min_px {
        Some(v) => positive(Param::TableMin, v, "px")?,
        None => smallest,
    };
    let max = match spec.max_px {
        Some(v) => {
            let v = positive(Param::TableMax, v, "px")?;
            if let Some(w) = width.filter(|&w| v >= w) {
                return Err(invalid(
                    Param::TableMax,
                    v,
                    "px",
                    format!("a number > 0 px and < the image width {w} px"),
                ));
            }
            v
        }
        None => largest,
    };
    if min > max {
        return Err(if spec.max_px.is_some() {
            invalid(Param::TableMax, max, "px", format!("a number >= the table minimum {min} px"))
        } else {
            invalid(
                Param::TableMin,
                min,
                "px",
                format!("a number > 0 px and <= the largest searched disparity {max} px"),
            )
        });
    }
    let mut rows = Vec::new();
    match spec.step_px {
        Some(step) => {
            let step = positive(Param::TableStep, step, "px")?;
            let count = ((max - min) / step * (1.0 + 1e-12)).floor() + 1.0;
            if count > MAX_TABLE_ROWS as f64 {
                let least = (max - min) / (MAX_TABLE_ROWS - 1) as f64;
                return Err(invalid(
                    Param::TableStep,
                    step,
                    "px",
                    format!("at least {} px for {MAX_TABLE_ROWS} rows at most", sig(least, 6)),
                ));
            }
            rows.extend((0..count as usize).map(|i| min + i as f64 * step));
        }
        None => {
            rows.push(min);
            let mut power = 2f64.powi(min.log2().floor() as i32 - 1);
            while power <= max {
                for v in [power, 1.5 * power] {
                    if v > min && v < max {
                        rows.push(v);
                    }
                }
                power *= 2.0;
            }
            if max > min {
                rows.push(max);
            }
        }
    }
    Ok(rows)
}

/// `x` with `digits` significant digits and no trailing zeros: `sig(1.8898, 4)` is `"1.89"`,
/// `sig(240.0, 4)` is `"240"`, `sig(0.000375, 3)` is `"0.000375"`.
pub fn sig(x: f64, digits: usize) -> String {
    if !x.is_finite() || x == 0.0 {
        return format!("{x}");
    }
    let digits = digits.max(1) as i32;
    let magnitude = x.abs().log10().floor() as i32;
    let decimals = (digits - 1 - magnitude).max(0) as usize;
    let text = format!("{x:.decimals$}");
    // Rounding may carry into a new digit (9.9996 -> 10.000): one decimal too many, trimmed below.
    let text =
        if text.contains('.') { text.trim_end_matches('0').trim_end_matches('.').to_string() } else { text };
    if text == "-0" {
        "0".to_string()
    } else {
        text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol
    }

    fn with(f: impl FnOnce(&mut DesignInput), base: DesignInput) -> DesignInput {
        let mut input = base;
        f(&mut input);
        input
    }

    #[test]
    fn worked_example_200mm_6mm() {
        // B = 200 mm, f = 6 mm, p = 2.5 µm: f = 2400 px; d = 150 px -> Z = 200·6/(150·2.5) = 3.2 m.
        let design =
            Design::new(&with(|i| i.disparity_px = Some(150.0), DesignInput::new(200.0, 6.0, 2.5))).unwrap();
        assert_eq!(design.focal_px, 2400.0);
        let p = design.disparity.unwrap();
        assert_eq!(p.distance_m, 3.2);
        assert_eq!(p.disparity_mm, 0.375);
        // ΔZ = 3.2² · 2.5e-6 / (0.2 · 0.006) = 10.24 · 2.5e-6 / 1.2e-3 = 0.021333 m.
        assert!(close(p.depth_resolution_mm, 64.0 / 3.0, 1e-9), "{}", p.depth_resolution_mm);
    }

    #[test]
    fn worked_example_80mm_12mm() {
        // B = 80 mm, f = 12 mm, p = 4 µm: f = 3000 px; d = 400 px -> Z = 80·12/(400·4) = 0.6 m.
        let design =
            Design::new(&with(|i| i.disparity_px = Some(400.0), DesignInput::new(80.0, 12.0, 4.0))).unwrap();
        assert_eq!(design.focal_px, 3000.0);
        let p = design.disparity.unwrap();
        assert_eq!(p.distance_m, 0.6);
        assert_eq!(p.disparity_mm, 1.6);
        // 0.36 m² · 4e-6 / (0.08 · 0.012) = 1.5 mm; a quarter step: 0.375 mm.
        assert!(close(p.depth_resolution_mm, 1.5, 1e-12));
        let quarter = Design::new(&with(
            |i| {
                i.disparity_px = Some(400.0);
                i.subpixel_step_px = 0.25;
            },
            DesignInput::new(80.0, 12.0, 4.0),
        ))
        .unwrap();
        assert!(close(quarter.disparity.unwrap().depth_resolution_mm, 0.375, 1e-12));
        let json = serde_json::to_value(&design).unwrap();
        assert_eq!(json["disparity"]["distance_m"], 0.6);
        assert_eq!(json["disparity"]["disparity_mm"], 1.6);
        assert_eq!(json["focal_px"], 3000.0);
        assert!(json.get("rig").is_none());
    }

    #[test]
    fn field_of_view_by_hand() {
        // 2·atan(3.2 / 12) = 2 · 14.9314° = 29.8628°.
        assert!(close(horizontal_fov_deg(6.4, 12.0), 29.8628, 1e-4));
        assert_eq!(sig(horizontal_fov_deg(6.4, 12.0), 4), "29.86");
        // A sensor as wide as twice the focal length sees 90°.
        assert!(close(horizontal_fov_deg(24.0, 12.0), 90.0, 1e-12));
        // From the image width: 1600 px · 4 µm = 6.4 mm.
        let d = Design::new(&with(
            |i| i.sensor = Some(SensorWidth::Px(1600.0)),
            DesignInput::new(80.0, 12.0, 4.0),
        ))
        .unwrap();
        assert!(close(d.sensor_width_mm.unwrap(), 6.4, 1e-12));
        assert!(close(d.horizontal_fov_deg.unwrap(), 29.8628, 1e-4));
        let d =
            Design::new(&with(|i| i.sensor = Some(SensorWidth::Mm(6.4)), DesignInput::new(80.0, 12.0, 4.0)))
                .unwrap();
        assert_eq!(d.image_width_px, Some(1600));
        // The matchers' default search for 1600 px: a quarter, 400.
        assert_eq!(d.working_range.max_disparity_px, 400);
        assert_eq!(d.working_range.max_disparity_source, MaxDisparitySource::ImageWidth);
    }

    #[test]
    fn inverse_by_hand() {
        // 80 mm · 3000 px / 5 m = 48 px = 0.192 mm; ΔZ = 25 · 1 / (0.08 · 3000) m = 104.17 mm.
        let d = Design::new(&with(|i| i.distance_m = Some(5.0), DesignInput::new(80.0, 12.0, 4.0))).unwrap();
        let p = d.distance.unwrap();
        assert!(close(p.disparity_px, 48.0, 1e-12));
        assert!(close(p.disparity_mm, 0.192, 1e-12));
        assert_eq!(p.distance_m, 5.0);
        assert!(close(p.depth_resolution_mm, 2500.0 / 24.0, 1e-9));
        // The round trip through Rig::depth.
        let rig = Rig::from_datasheet(200.0, 6.0, 2.5).unwrap().with_doffs(12.5).unwrap();
        for z in [0.3, 3.2, 17.0] {
            assert!(close(rig.depth(disparity_at(&rig, z)).unwrap(), z, 1e-12));
        }
        // doffs counts: Z = 0.2 · 2400 / (137.5 + 12.5) = 3.2.
        assert!(close(disparity_at(&rig, 3.2), 137.5, 1e-9));
    }

    #[test]
    fn depth_resolution_is_the_first_order_step() {
        let d = Design::new(&DesignInput::new(80.0, 12.0, 4.0)).unwrap();
        for disparity in [20.0, 100.0, 127.0] {
            let p = d.at_disparity(disparity).unwrap();
            let exact = (d.rig.depth(disparity).unwrap() - d.rig.depth(disparity + 1.0).unwrap()) * 1000.0;
            // Within s / d of the exact difference.
            assert!(p.depth_resolution_mm >= exact);
            assert!(close(p.depth_resolution_mm, exact, p.depth_resolution_mm / disparity * 1.0001));
        }
    }

    #[test]
    fn working_range_by_hand() {
        // Default search 0..128: nearest at 127 px, farthest at 1 px.
        let d = Design::new(&DesignInput::new(80.0, 12.0, 4.0)).unwrap();
        let r = d.working_range;
        assert_eq!((r.max_disparity_px, r.max_disparity_source), (128, MaxDisparitySource::Default));
        assert_eq!(r.near.disparity_px, 127.0);
        assert!(close(r.near.distance_m, 240.0 / 127.0, 1e-12));
        assert_eq!((r.far.disparity_px, r.far.distance_m), (1.0, 240.0));
        assert!(close(r.far.depth_resolution_mm, 240_000.0, 1e-6));
        // Quarter-pixel steps reach 4× farther.
        let d = Design::new(&with(
            |i| {
                i.subpixel_step_px = 0.25;
                i.max_disparity_px = Some(64.0);
            },
            DesignInput::new(80.0, 12.0, 4.0),
        ))
        .unwrap();
        assert_eq!(d.working_range.far.distance_m, 960.0);
        assert_eq!(d.working_range.near.disparity_px, 63.0);
        assert_eq!(d.working_range.max_disparity_source, MaxDisparitySource::Given);
        // A negative doffs: the smallest disparity with a depth is the first step beyond 2.5.
        let d = Design::new(&with(|i| i.doffs_px = -2.5, DesignInput::new(80.0, 12.0, 4.0))).unwrap();
        assert_eq!(d.working_range.far.disparity_px, 3.0);
        assert_eq!(d.working_range.far.distance_m, 480.0);
    }

    #[test]
    fn chart_range_ends_at_ten_steps() {
        let d = Design::new(&DesignInput::new(80.0, 12.0, 4.0)).unwrap();
        let (near, far) = d.chart_range();
        assert!(close(near, 240.0 / 127.0, 1e-12));
        assert!(close(far, 24.0, 1e-12));
        let curve = d.curve(near, far, 50);
        assert_eq!(curve.len(), 50);
        assert!(close(curve[0].disparity_px, 127.0, 1e-9) && close(curve[49].disparity_px, 10.0, 1e-9));
        // A search shorter than 10 steps: the chart ends at the farthest distance.
        let d = Design::new(&with(|i| i.max_disparity_px = Some(8.0), DesignInput::new(80.0, 12.0, 4.0)))
            .unwrap();
        assert_eq!(d.chart_range().1, 240.0);
    }

    #[test]
    fn default_table_is_geometric() {
        let d =
            Design::new(&with(|i| i.table = Some(TableSpec::default()), DesignInput::new(80.0, 12.0, 4.0)))
                .unwrap();
        let ds: Vec<f64> = d.table.as_ref().unwrap().iter().map(|p| p.disparity_px).collect();
        assert_eq!(ds, [1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0, 32.0, 48.0, 64.0, 96.0, 127.0]);
        let rows = d.table.unwrap();
        assert_eq!(rows[0].distance_m, 240.0);
        assert_eq!(rows[4].distance_m, 60.0);
        // From the subpixel step.
        let spec = TableSpec { min_px: Some(0.25), max_px: Some(1.0), step_px: None };
        assert_eq!(table_disparities(&spec, 1.0, 127.0, None).unwrap(), [0.25, 0.375, 0.5, 0.75, 1.0]);
        let spec = TableSpec { min_px: Some(5.0), max_px: Some(5.0), step_px: None };
        assert_eq!(table_disparities(&spec, 1.0, 127.0, None).unwrap(), [5.0]);
    }

    #[test]
    fn table_with_step() {
        let spec = TableSpec { min_px: Some(100.0), max_px: Some(400.0), step_px: Some(100.0) };
        assert_eq!(table_disparities(&spec, 1.0, 127.0, None).unwrap(), [100.0, 200.0, 300.0, 400.0]);
        let spec = TableSpec { min_px: Some(0.1), max_px: Some(0.5), step_px: Some(0.1) };
        assert_eq!(table_disparities(&spec, 1.0, 127.0, None).unwrap().len(), 5);
        let d = Design::new(&with(
            |i| i.table = Some(TableSpec { min_px: Some(100.0), max_px: Some(400.0), step_px: Some(100.0) }),
            DesignInput::new(80.0, 12.0, 4.0),
        ))
        .unwrap();
        let z: Vec<f64> = d.table.unwrap().iter().map(|p| p.distance_m).collect();
        assert_eq!(z, [2.4, 1.2, 0.8, 0.6]);
    }

    fn err(input: DesignInput) -> DesignError {
        Design::new(&input).unwrap_err()
    }

    #[test]
    fn bad_rig_names_the_parameter() {
        let base = DesignInput::new(80.0, 12.0, 4.0);
        let e = err(with(|i| i.baseline_mm = 0.0, base.clone()));
        assert_eq!(e.param, Param::Baseline);
        assert_eq!(e.to_string(), "invalid baseline: 0 mm (must be a finite number > 0 mm)");
        assert_eq!(err(with(|i| i.focal_mm = -12.0, base.clone())).param, Param::Focal);
        assert_eq!(err(with(|i| i.pixel_um = f64::NAN, base.clone())).param, Param::Pixel);
        assert_eq!(err(with(|i| i.doffs_px = f64::INFINITY, base.clone())).param, Param::Doffs);
        for step in [0.0, -0.5, 1.5, f64::NAN] {
            assert_eq!(err(with(|i| i.subpixel_step_px = step, base.clone())).param, Param::SubpixelStep);
        }
    }

    #[test]
    fn absurd_sizes_are_rejected() {
        let base = DesignInput::new(80.0, 12.0, 4.0);
        // A 4000 µm pixel on a 3 mm sensor.
        let e = err(with(
            |i| {
                i.pixel_um = 4000.0;
                i.sensor = Some(SensorWidth::Mm(3.0));
            },
            base.clone(),
        ));
        assert_eq!(e.param, Param::Pixel);
        assert_eq!(
            e.to_string(),
            "invalid pixel size: 4000 µm (must be at most 1500 µm: the 3 mm sensor must be at least 2 pixels wide)"
        );
        assert_eq!(
            err(with(|i| i.sensor = Some(SensorWidth::Mm(0.0)), base.clone())).param,
            Param::SensorWidth
        );
        for n in [0.0, 1.0, 1600.5, -5.0, f64::NAN] {
            assert_eq!(
                err(with(|i| i.sensor = Some(SensorWidth::Px(n)), base.clone())).param,
                Param::WidthPx
            );
        }
        // A disparity as wide as the image.
        let e = err(with(
            |i| {
                i.sensor = Some(SensorWidth::Px(1600.0));
                i.disparity_px = Some(1600.0);
            },
            base.clone(),
        ));
        assert_eq!(
            e.to_string(),
            "invalid disparity: 1600 px (must be a finite number > 0 px and < the image width 1600 px)"
        );
        for d in [0.0, -3.0, f64::NAN, f64::INFINITY] {
            assert_eq!(err(with(|i| i.disparity_px = Some(d), base.clone())).param, Param::Disparity);
        }
        let e = err(with(
            |i| {
                i.doffs_px = 10.0;
                i.disparity_px = Some(-10.0);
            },
            base.clone(),
        ));
        assert!(e.expected.contains("> -10 px (d + doffs > 0)"), "{e}");
        for z in [0.0, -1.0, f64::NAN] {
            assert_eq!(err(with(|i| i.distance_m = Some(z), base.clone())).param, Param::Distance);
        }
        // 0.1 m needs 2400 px of disparity, more than the 1600 px image: nearest 0.15 m.
        let e = err(with(
            |i| {
                i.sensor = Some(SensorWidth::Px(1600.0));
                i.distance_m = Some(0.1);
            },
            base.clone(),
        ));
        assert_eq!(
            e.to_string(),
            "invalid distance: 0.1 m (must be > 0.15 m: closer, the disparity 2400 px is not smaller than \
             the image width 1600 px)"
        );
        for max in [1.0, 0.0, 64.5, 2000.0, f64::NAN] {
            let e = err(with(
                |i| {
                    i.sensor = Some(SensorWidth::Px(1600.0));
                    i.max_disparity_px = Some(max);
                },
                base.clone(),
            ));
            assert_eq!(e.param, Param::MaxDisparity);
            assert_eq!(e.expected, "a whole number from 2 px to the image width 1600 px");
        }
    }

    #[test]
    fn bad_tables_are_rejected() {
        let base = DesignInput::new(80.0, 12.0, 4.0);
        let table = |min, max, step| {
            with(|i| i.table = Some(TableSpec { min_px: min, max_px: max, step_px: step }), base.clone())
        };
        assert_eq!(err(table(Some(0.0), None, None)).param, Param::TableMin);
        assert_eq!(err(table(None, Some(-1.0), None)).param, Param::TableMax);
        assert_eq!(err(table(None, None, Some(f64::NAN))).param, Param::TableStep);
        assert_eq!(err(table(Some(10.0), Some(5.0), None)).param, Param::TableMax);
        assert_eq!(err(table(Some(200.0), None, None)).param, Param::TableMin);
        let e = err(table(Some(1.0), Some(100.0), Some(0.001)));
        assert_eq!(e.param, Param::TableStep);
        assert_eq!(e.expected, "at least 0.00990099 px for 10000 rows at most");
        assert!(Design::new(&table(Some(1.0), Some(100.0), Some(0.0099011))).is_ok());
        assert!(Design::new(&table(Some(1.0), Some(100.0), Some(0.0099))).is_err());
        let e = err(with(|i| i.sensor = Some(SensorWidth::Px(640.0)), table(None, Some(640.0), None)));
        assert_eq!(e.param, Param::TableMax);
    }

    #[test]
    fn significant_digits() {
        assert_eq!(sig(3.2, 4), "3.2");
        assert_eq!(sig(0.6, 4), "0.6");
        assert_eq!(sig(240.0 / 127.0, 4), "1.89");
        assert_eq!(sig(64.0 / 3.0, 4), "21.33");
        assert_eq!(sig(240_000.0, 4), "240000");
        assert_eq!(sig(0.000375, 3), "0.000375");
        assert_eq!(sig(9.9996, 4), "10");
        assert_eq!(sig(-0.00001, 2), "-0.00001");
        assert_eq!(sig(0.0, 4), "0");
    }
}
