//! What the pair command reports: the statistics JSON (`--stats`) and the human summary.

use std::io::{self, Write};
use std::path::Path;
use std::time::Duration;

use serde::Serialize;
use stereo_pipeline::{Adaptation, Named, PathCount, SearchReport};
use stereo_triangulation::{DepthStats, DisparityStats};

use crate::checks::DepthLimitsReport;
use stereo_pipeline::{DepthResult, Plan};

use crate::config::{Matcher, PairConfig, RigSetup};
use crate::writers::WriteCounts;

/// The `--stats` document. Depths are in metres, disparities in pixels, times in milliseconds;
/// statistics of an empty set (no valid pixel) are `null`, and so are the depth fields and `rig`
/// in disparity-only mode (no rig given).
#[derive(Debug, Serialize)]
pub struct Stats {
    pub left: String,
    pub right: String,
    pub outputs: Outputs,
    pub width: usize,
    pub height: usize,
    /// Pixels with a finite depth (disparity-only mode: a finite disparity).
    pub valid_pixels: usize,
    /// `valid_pixels` as a percentage of all pixels.
    pub density_percent: f64,
    pub depth_m: Option<Summary>,
    /// The depth step of one pixel of disparity (`ΔZ ≈ Z²·1 px / (B·f_px)`) at the median and
    /// 95th-percentile depths, millimetres.
    pub depth_resolution_mm: Option<DepthResolution>,
    pub disparity_px: Option<Summary>,
    pub matcher: MatcherReport,
    pub rig: Option<RigReport>,
    /// Points in the --points cloud.
    pub points_written: Option<usize>,
    /// Valid depths beyond 65.535 m written as 0 in the --depth-png.
    pub depth_png_too_deep: Option<usize>,
    /// --min-depth/--max-depth, their disparity interval and the pixels they cut.
    pub depth_limits: Option<DepthLimitsReport>,
    /// The check of the pair's rectification (residual vertical misalignment) before matching.
    pub rectification: RectificationReport,
    pub timings_ms: Timings,
    /// Million disparity evaluations per second of the matching stage: W·H·ndisp / seconds / 1e6.
    pub mde_per_s: f64,
    /// The instruction set the matcher's kernels ran with (`scalar`, `avx2`, `avx512`, `neon`).
    pub simd: &'static str,
    /// Peak working memory the matcher planned (aggregation buffers, per-thread rows), bytes.
    pub planned_matcher_bytes: u64,
}

/// Times the command measured around the pipeline.
pub struct StageTimes {
    pub load: Duration,
    /// Undistorting and rectifying a raw pair (a raw --calib), `None` otherwise.
    pub remap: Option<Duration>,
    pub write: Duration,
    pub total: Duration,
}

impl Stats {
    /// The statistics of one pair from its config, plan and pipeline result.
    pub fn new(
        config: &PairConfig,
        plan: &Plan,
        result: &DepthResult,
        counts: WriteCounts,
        times: StageTimes,
    ) -> Self {
        let (width, height) = plan.size();
        let disparity_stats = DisparityStats::from_disparity(&result.disparity);
        let (valid_pixels, density_percent, depth_m) = match &result.depth {
            Some(depth) => {
                let stats = DepthStats::from_depth(depth);
                (stats.valid_pixels, stats.density_percent, Summary::of_depth(&stats))
            }
            None => (disparity_stats.valid_pixels, disparity_stats.density_percent, None),
        };
        let match_seconds = result.timings.matching.as_secs_f64();
        let depth_limits = match (&config.depth_limits, &config.rig, result.depth_limits_cut) {
            (Some(limits), Some(setup), Some(cut)) => Some(DepthLimitsReport::new(limits, &setup.rig, cut)),
            _ => None,
        };
        Stats {
            left: display(&config.left),
            right: display(&config.right),
            outputs: Outputs {
                depth: config.output.as_deref().map(display),
                disparity: config.disparity.as_deref().map(display),
                stats: config.stats.as_deref().map(display),
                points: config.points.as_deref().map(display),
                preview: config.preview.as_deref().map(display),
                depth_png: config.depth_png.as_deref().map(display),
                disparity_png: config.disparity_png.as_deref().map(display),
            },
            width,
            height,
            valid_pixels,
            density_percent,
            depth_resolution_mm: config
                .rig
                .as_ref()
                .and_then(|s| DepthResolution::new(&s.rig, depth_m.as_ref())),
            depth_m,
            disparity_px: Summary::of_disparity(&disparity_stats),
            matcher: MatcherReport::new(plan.matcher(), result.adaptation.as_ref(), result.search.as_ref()),
            rig: config.rig.as_ref().map(|setup| RigReport::new(setup, width, height)),
            points_written: counts.points_written,
            depth_png_too_deep: counts.depth_png_too_deep,
            depth_limits,
            rectification: RectificationReport::new(
                &result.rectification.alignment,
                result.rectification.compensated,
            ),
            timings_ms: Timings {
                load: ms(times.load),
                remap: times.remap.map(ms),
                rectification: ms(result.timings.rectification),
                match_: ms(result.timings.matching),
                triangulate: ms(result.timings.triangulation),
                write: ms(times.write),
                total: ms(times.total),
            },
            planned_matcher_bytes: plan.planned_matcher_bytes(),
            mde_per_s: if match_seconds > 0.0 {
                (width * height * plan.range().count()) as f64 / match_seconds / 1e6
            } else {
                0.0
            },
            simd: stereo_pipeline::simd_level(),
        }
    }
}

#[derive(Debug, Serialize)]
pub struct Outputs {
    pub depth: Option<String>,
    pub disparity: Option<String>,
    pub stats: Option<String>,
    pub points: Option<String>,
    pub preview: Option<String>,
    pub depth_png: Option<String>,
    pub disparity_png: Option<String>,
}

#[derive(Debug, Serialize, PartialEq)]
pub struct DepthResolution {
    /// The disparity step, pixels.
    pub step_px: f64,
    pub at_median: f64,
    pub at_p95: f64,
}

impl DepthResolution {
    pub fn new(rig: &stereo_triangulation::Rig, depth: Option<&Summary>) -> Option<Self> {
        let depth = depth?;
        let step_px = 1.0;
        Some(DepthResolution {
            step_px,
            at_median: rig.depth_resolution(depth.median, step_px) * 1000.0,
            at_p95: rig.depth_resolution(depth.p95, step_px) * 1000.0,
        })
    }
}

/// Statistics of the valid pixels of a map (percentiles interpolate linearly, like NumPy's).
#[derive(Debug, Serialize, PartialEq)]
pub struct Summary {
    pub min: f64,
    pub max: f64,
    pub mean: f64,
    pub median: f64,
    pub p5: f64,
    pub p95: f64,
}

#[derive(Debug, Serialize)]
#[serde(tag = "name", rename_all = "lowercase")]
pub enum MatcherReport {
    Sgm {
        min_disparity: i32,
        max_disparity: i32,
        num_disparities: usize,
        census_window: [usize; 2],
        /// Path directions aggregated: 8 or 4 in two passes, 5 or 3 in a single pass.
        paths: u8,
        single_pass: bool,
        p1: u16,
        p2: u16,
        uniqueness: u32,
        lr_max_diff: Option<f32>,
        /// Whether a would-be occlusion passes against the right view's left neighbour
        /// (default yes, `--fill` no; docs/accuracy.md).
        lr_left_neighbour: bool,
        subpixel: &'static str,
        median: bool,
        speckle_size: usize,
        /// Speckle regions at the image border kept from this many pixels (0 = none kept).
        speckle_keep_border: usize,
        /// Holes up to this many px wide do not split a speckle region (0 = 4-connected only).
        speckle_bridge: usize,
        weighted_median_radius: usize,
        /// Edge snapping radius (px, 0 = off) and passes.
        edge_snap_radius: usize,
        edge_snap_passes: usize,
        fill: bool,
        /// What the matcher measured of the pair and adapted to (`null` when not measured).
        adaptation: Option<AdaptationReport>,
        /// Which search ran: `full`, or `hierarchical` (coarse to fine, `--search`).
        search: &'static str,
        /// Half-resolution levels matched below the full one (0 for the full search).
        search_levels: u32,
        /// The mean number of disparities a pixel searched (`num_disparities` for the full search),
        /// on the matched pair.
        mean_disparities_searched: f32,
        /// The factor the pair was reduced by before matching (`--downscale`; 1: full resolution).
        downscale: usize,
        /// Whether the rows were halved once more than the columns before matching
        /// (`--downscale coarse` on a range too short to halve).
        rows_halved: bool,
    },
    Bm {
        min_disparity: i32,
        max_disparity: i32,
        num_disparities: usize,
        block_size: usize,
        cost: &'static str,
        uniqueness: u32,
        lr_max_diff: Option<f32>,
        subpixel: &'static str,
    },
}

/// [`stereo_disparity::Adaptation`] as reported.
#[derive(Debug, Serialize)]
pub struct AdaptationReport {
    /// How differently the two views render the same surfaces (8-bit grey levels); above 9 the
    /// intensity term is dropped.
    pub radiometric_difference_grey: Option<f32>,
    /// What remains of it after mapping the right view's tones onto the left's (measured only
    /// above 9); at 3 or less the intensity term compares the left view with the mapped right view.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tone_corrected_difference_grey: Option<f32>,
    /// Whether one view's shadows or highlights were clipped and the other was clipped alike.
    pub clipped_alike: bool,
    /// Whether the AD-census intensity term was used (false: census alone).
    pub intensity_term: bool,
    /// Median census Hamming distance at the true match (bits); above 8 P1/P2 are raised.
    pub census_residual_bits: Option<f32>,
    /// JPEG block artefacts (steps across the 8×8 grid over steps between; ~1 without JPEG).
    pub blockiness: Option<f32>,
    /// Whether census compared smoothed views (Gaussian σ 1 px): residual above 8 or blockiness
    /// above 1.05.
    pub census_smoothing: bool,
    /// A one-sided defocus: the softer view ("left" or "right") and the Gaussian σ (px) that
    /// brings the other to its sharpness; a softer left view is sharpened before matching.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub defocused_view: Option<&'static str>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub defocus_sigma_px: Option<f32>,
    /// How much darker than the centre a neighbour had to be to set its census bit (8-bit grey
    /// levels): 1 where both views were smoothed for noise or JPEG, else 0.
    pub census_tolerance_grey: f32,
    /// The penalties used, after raising them for a noisy cost.
    pub p1_used: u16,
    pub p2_used: u16,
    /// P2 lowered across image edges as `P2 · s / (s + ΔI)` with this `s` (0: constant P2); set
    /// on noisy and JPEG pairs.
    pub p2_edge_scale_used: u16,
}

#[derive(Debug, Serialize)]
pub struct RigReport {
    pub baseline_mm: f64,
    /// `null` when the focal length came in pixels from a Middlebury calib.txt (batch).
    pub focal_mm: Option<f64>,
    pub pixel_um: Option<f64>,
    pub focal_px: f64,
    pub doffs: f64,
    /// `[cx, cy]` in pixels.
    pub principal_point: [f64; 2],
    /// Whether the principal point is the image centre (no --cx/--cy).
    pub principal_point_default: bool,
    pub sensor_width_mm: Option<f64>,
    /// Horizontal field of view `2·atan(w / 2f)` (with --sensor-width), degrees.
    pub horizontal_fov_deg: Option<f64>,
}

/// The measured vertical misalignment of the right view (see [`stereo_rectify::Alignment`]):
/// positive offsets mean the right view is lower, a positive rotation that its right side is.
#[derive(Debug, Serialize)]
pub struct RectificationReport {
    /// At the image centre, px.
    pub vertical_offset_px: f32,
    pub rotation_deg: f32,
    /// Largest |offset| over the image, px.
    pub max_abs_offset_px: f32,
    /// aligned, misaligned, badly_misaligned or unknown.
    pub verdict: &'static str,
    /// Whether the right view was resampled to line up with the left view before matching.
    pub compensated: bool,
}

impl RectificationReport {
    pub fn new(alignment: &stereo_rectify::Alignment, compensated: bool) -> Self {
        RectificationReport {
            vertical_offset_px: alignment.vertical_offset_px,
            rotation_deg: alignment.rotation_deg,
            max_abs_offset_px: alignment.max_abs_offset_px,
            verdict: alignment.verdict.as_str(),
            compensated,
        }
    }
}

#[derive(Debug, Default, Serialize)]
pub struct Timings {
    pub load: f64,
    /// Undistorting and rectifying a raw pair through its calibration's maps (a raw --calib).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub remap: Option<f64>,
    /// Measuring (and compensating) the pair's vertical misalignment.
    pub rectification: f64,
    #[serde(rename = "match")]
    pub match_: f64,
    pub triangulate: f64,
    /// Writing the depth map and the disparity map (the stats file itself is written after).
    pub write: f64,
    pub total: f64,
}

pub fn ms(duration: Duration) -> f64 {
    duration.as_secs_f64() * 1e3
}

impl MatcherReport {
    pub fn new(matcher: &Matcher, adaptation: Option<&Adaptation>, search: Option<&SearchReport>) -> Self {
        match matcher {
            Matcher::Sgm(p) => MatcherReport::Sgm {
                min_disparity: p.range.min,
                max_disparity: p.range.max,
                num_disparities: p.range.count(),
                census_window: [p.census.width, p.census.height],
                paths: match (p.paths, p.single_pass) {
                    (PathCount::Four, false) => 4,
                    (PathCount::Eight, false) => 8,
                    (PathCount::Four, true) => 3,
                    (PathCount::Eight, true) => 5,
                },
                single_pass: p.single_pass,
                p1: p.p1,
                p2: p.p2,
                uniqueness: p.uniqueness_ratio,
                lr_max_diff: p.lr_max_diff,
                lr_left_neighbour: p.lr_left_neighbour,
                subpixel: p.subpixel.name(),
                median: p.median,
                speckle_size: p.speckle_size,
                speckle_keep_border: p.speckle_keep_border,
                speckle_bridge: p.speckle_bridge,
                weighted_median_radius: p.wmf_radius,
                edge_snap_radius: p.edge_snap_radius,
                edge_snap_passes: p.edge_snap_passes,
                fill: p.fill,
                adaptation: adaptation.map(|a| AdaptationReport {
                    radiometric_difference_grey: a.radiometric_difference,
                    tone_corrected_difference_grey: a.corrected_radiometric_difference,
                    clipped_alike: a.clipped_alike,
                    intensity_term: a.intensity_term,
                    census_residual_bits: a.census_residual,
                    blockiness: a.blockiness,
                    census_smoothing: a.census_smoothing,
                    defocused_view: a.defocused_view().map(|(view, _)| view),
                    defocus_sigma_px: a.defocused_view().map(|(_, sigma)| sigma),
                    census_tolerance_grey: a.census_tolerance_grey(),
                    p1_used: a.p1,
                    p2_used: a.p2,
                    p2_edge_scale_used: a.p2_edge_scale,
                }),
                search: if search.is_some_and(|s| s.hierarchical) { "hierarchical" } else { "full" },
                search_levels: search.map_or(0, |s| s.levels),
                mean_disparities_searched: search.map_or(p.range.count() as f32, |s| s.mean_range),
                downscale: search.map_or(1, |s| s.downscale),
                rows_halved: search.is_some_and(|s| s.rows_halved),
            },
            Matcher::Bm(p) => MatcherReport::Bm {
                min_disparity: p.range.min,
                max_disparity: p.range.max,
                num_disparities: p.range.count(),
                block_size: p.block_size,
                cost: p.cost.name(),
                uniqueness: p.uniqueness_ratio,
                lr_max_diff: p.lr_max_diff,
                subpixel: p.subpixel.name(),
            },
        }
    }
}

impl RigReport {
    pub fn new(setup: &RigSetup, width: usize, height: usize) -> Self {
        let rig = &setup.rig;
        let (cx, cy) = rig.principal_point_for(width, height);
        RigReport {
            baseline_mm: setup.input.baseline_mm,
            focal_mm: setup.input.focal_mm,
            pixel_um: setup.input.pixel_um,
            focal_px: rig.focal_px,
            doffs: rig.doffs,
            principal_point: [cx, cy],
            principal_point_default: rig.principal_point.is_none(),
            sensor_width_mm: setup.input.sensor_width_mm,
            horizontal_fov_deg: setup.input.horizontal_fov_deg,
        }
    }
}

impl Summary {
    /// `None` when there was no valid pixel.
    fn new(
        min: Option<f64>,
        max: Option<f64>,
        mean: Option<f64>,
        median: Option<f64>,
        p5: Option<f64>,
        p95: Option<f64>,
    ) -> Option<Self> {
        Some(Summary { min: min?, max: max?, mean: mean?, median: median?, p5: p5?, p95: p95? })
    }

    pub fn of_depth(stats: &DepthStats) -> Option<Self> {
        Summary::new(stats.min, stats.max, stats.mean, stats.median, stats.p5, stats.p95)
    }

    pub fn of_disparity(stats: &DisparityStats) -> Option<Self> {
        Summary::new(stats.min, stats.max, stats.mean, stats.median, stats.p5, stats.p95)
    }
}

pub fn display(path: &Path) -> String {
    path.display().to_string()
}

/// The human summary printed after a pair run (unless --quiet).
pub fn write_summary(out: &mut impl Write, stats: &Stats) -> io::Result<()> {
    let (range, matcher) = match &stats.matcher {
        MatcherReport::Sgm { min_disparity, max_disparity, paths, .. } => {
            ((*min_disparity, *max_disparity), format!("sgm, {paths} paths"))
        }
        MatcherReport::Bm { min_disparity, max_disparity, block_size, cost, .. } => {
            ((*min_disparity, *max_disparity), format!("bm, {block_size}x{block_size} {cost}"))
        }
    };
    let rig = match &stats.rig {
        Some(rig) => format!("focal {:.1} px", rig.focal_px),
        None => "no rig: disparity only".to_string(),
    };
    writeln!(
        out,
        "{}x{} px, {matcher}, disparities {}..{}, {rig}",
        stats.width, stats.height, range.0, range.1
    )?;
    writeln!(out, "valid         {} px ({:.1} %)", stats.valid_pixels, stats.density_percent)?;
    if let Some(d) = &stats.depth_m {
        writeln!(
            out,
            "depth m       min {:.4}  p5 {:.4}  median {:.4}  mean {:.4}  p95 {:.4}  max {:.4}",
            d.min, d.p5, d.median, d.mean, d.p95, d.max
        )?;
    }
    if let (Some(r), Some(d)) = (&stats.depth_resolution_mm, &stats.depth_m) {
        writeln!(
            out,
            "resolution    {:.3} mm at the median {:.3} m, {:.3} mm at p95 {:.3} m (per {} px of disparity)",
            r.at_median, d.median, r.at_p95, d.p95, r.step_px
        )?;
    }
    if let Some(rig) = &stats.rig {
        if let (Some(fov), Some(w)) = (rig.horizontal_fov_deg, rig.sensor_width_mm) {
            writeln!(out, "field of view {fov:.2}° horizontal ({w} mm sensor)")?;
        }
    }
    if let Some(d) = &stats.disparity_px {
        writeln!(out, "disparity px  min {:.2}  median {:.2}  max {:.2}", d.min, d.median, d.max)?;
    }
    if let Some(l) = &stats.depth_limits {
        let m = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |v| format!("{v}"));
        writeln!(out, "depth limits  {} .. {} m: {} px cut", m(l.min_m), m(l.max_m), l.cut_pixels)?;
    }
    let r = &stats.rectification;
    writeln!(
        out,
        "rectification {}: offset {:+.2} px at the centre, rotation {:+.3}°, max {:.2} px{}",
        r.verdict,
        r.vertical_offset_px,
        r.rotation_deg,
        r.max_abs_offset_px,
        if r.compensated { ", compensated" } else { "" }
    )?;
    if let MatcherReport::Sgm { adaptation: Some(a), p1, p2, .. } = &stats.matcher {
        // The CLI always asks for AD-census: without its intensity term, the pair made it drop.
        let cost = match (a.intensity_term, a.radiometric_difference_grey) {
            (true, Some(d)) if a.tone_corrected_difference_grey.is_some() => {
                format!("AD-census on the right view's tones mapped to the left's (they differed by {d:.0})")
            }
            (true, _) => "AD-census".to_string(),
            (false, Some(d)) if a.clipped_alike => {
                format!(
                    "census alone (the views' grey levels differ by {d:.0}; clipping matched in both views)"
                )
            }
            (false, Some(d)) => format!("census alone (the views' grey levels differ by {d:.0})"),
            (false, None) => "census".to_string(),
        };
        let penalties = if (a.p1_used, a.p2_used) == (*p1, *p2) {
            format!("P1 {p1} P2 {p2}")
        } else {
            format!("P1 {} P2 {} (raised for a noisy cost)", a.p1_used, a.p2_used)
        };
        let penalties = if a.p2_edge_scale_used > 0 {
            format!("{penalties}, P2 lowered across image edges")
        } else {
            penalties
        };
        let penalties = match (a.census_smoothing, a.census_tolerance_grey, a.defocused_view) {
            (true, t, None) if t > 0.0 => {
                format!("{penalties}, census on smoothed views (tolerance {t} grey level)")
            }
            (true, _, None) => format!("{penalties}, census on smoothed views"),
            (true, _, Some(_)) => format!("{penalties}, census with the sharper view blurred to match"),
            (false, _, _) => penalties,
        };
        let penalties = match (a.defocused_view, a.defocus_sigma_px) {
            (Some("left"), Some(s)) => {
                format!("{penalties}, left view defocused (σ {s:.1} px) and sharpened")
            }
            (Some(view), Some(s)) => format!("{penalties}, {view} view defocused (σ {s:.1} px)"),
            _ => penalties,
        };
        writeln!(out, "cost          {cost}, {penalties}")?;
    }
    if let MatcherReport::Sgm { downscale, rows_halved, .. } = &stats.matcher {
        if *downscale > 1 && *rows_halved {
            writeln!(
                out,
                "downscale     matched at 1/{downscale} of the width and 1/{} of the height, disparities \
                 {downscale} times coarser",
                2 * downscale
            )?;
        } else if *downscale > 1 {
            writeln!(
                out,
                "downscale     matched at 1/{downscale} of the size, disparities {downscale} times coarser"
            )?;
        } else if *rows_halved {
            writeln!(out, "downscale     matched with the rows halved, disparities at full resolution")?;
        }
    }
    if let MatcherReport::Sgm {
        search: "hierarchical",
        search_levels,
        mean_disparities_searched,
        num_disparities,
        ..
    } = &stats.matcher
    {
        writeln!(
            out,
            "search        coarse to fine ({search_levels} half-resolution level{}), {mean_disparities_searched:.0} of {num_disparities} disparities per pixel",
            if *search_levels == 1 { "" } else { "s" }
        )?;
    }
    let t = &stats.timings_ms;
    writeln!(
        out,
        "time ms       load {:.1}{}  match {:.1} ({:.0} MDE/s, {})  triangulate {:.1}  write {:.1}  total {:.1}",
        t.load,
        t.remap.map(|r| format!("  rectify {r:.1}")).unwrap_or_default(),
        t.match_,
        stats.mde_per_s,
        stats.simd,
        t.triangulate,
        t.write,
        t.total
    )
}
