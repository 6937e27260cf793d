//! What the pair command reports: the statistics JSON (`--stats`) and the human summary.

use std::io::{self, Write};
use std::path::Path;
use std::time::Duration;

use serde::Serialize;
use stereo_disparity::{BmCost, PathCount, Subpixel};
use stereo_triangulation::{DepthStats, DisparityStats};

use crate::config::{Matcher, PairConfig};

/// The `--stats` document. Depths are in metres, disparities in pixels, times in milliseconds;
/// statistics of an empty set (no valid pixel) are `null`.
#[derive(Debug, Serialize)]
pub struct Stats {
    pub left: String,
    pub right: String,
    pub outputs: Outputs,
    pub width: usize,
    pub height: usize,
    /// Pixels with a finite depth.
    pub valid_pixels: usize,
    /// `valid_pixels` as a percentage of all pixels.
    pub density_percent: f64,
    pub depth_m: Option<Summary>,
    pub disparity_px: Option<Summary>,
    pub matcher: MatcherReport,
    pub rig: RigReport,
    pub timings_ms: Timings,
    /// Million disparity evaluations per second of the matching stage: W·H·ndisp / seconds / 1e6.
    pub mde_per_s: f64,
}

#[derive(Debug, Serialize)]
pub struct Outputs {
    pub depth: String,
    pub disparity: Option<String>,
    pub stats: Option<String>,
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
        paths: u8,
        p1: u16,
        p2: u16,
        uniqueness: u32,
        lr_max_diff: Option<f32>,
        subpixel: &'static str,
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
}

#[derive(Debug, Default, Serialize)]
pub struct Timings {
    pub load: f64,
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

fn subpixel_name(subpixel: Subpixel) -> &'static str {
    match subpixel {
        Subpixel::None => "none",
        Subpixel::Parabola => "parabola",
        Subpixel::Equiangular => "equiangular",
    }
}

impl MatcherReport {
    pub fn new(matcher: &Matcher) -> Self {
        match matcher {
            Matcher::Sgm(p) => MatcherReport::Sgm {
                min_disparity: p.range.min,
                max_disparity: p.range.max,
                num_disparities: p.range.count(),
                census_window: [p.census.width, p.census.height],
                paths: match p.paths {
                    PathCount::Four => 4,
                    PathCount::Eight => 8,
                },
                p1: p.p1,
                p2: p.p2,
                uniqueness: p.uniqueness_ratio,
                lr_max_diff: p.lr_max_diff,
                subpixel: subpixel_name(p.subpixel),
            },
            Matcher::Bm(p) => MatcherReport::Bm {
                min_disparity: p.range.min,
                max_disparity: p.range.max,
                num_disparities: p.range.count(),
                block_size: p.block_size,
                cost: match p.cost {
                    BmCost::Sad => "sad",
                    BmCost::Census => "census",
                },
                uniqueness: p.uniqueness_ratio,
                lr_max_diff: p.lr_max_diff,
                subpixel: subpixel_name(p.subpixel),
            },
        }
    }
}

impl RigReport {
    pub fn new(config: &PairConfig, width: usize, height: usize) -> Self {
        let rig = &config.rig;
        let (cx, cy) = rig.principal_point_for(width, height);
        RigReport {
            baseline_mm: config.rig_input.baseline_mm,
            focal_mm: config.rig_input.focal_mm,
            pixel_um: config.rig_input.pixel_um,
            focal_px: rig.focal_px,
            doffs: rig.doffs,
            principal_point: [cx, cy],
            principal_point_default: rig.principal_point.is_none(),
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
    writeln!(
        out,
        "{}x{} px, {matcher}, disparities {}..{}, focal {:.1} px",
        stats.width, stats.height, range.0, range.1, stats.rig.focal_px
    )?;
    writeln!(out, "valid         {} px ({:.1} %)", stats.valid_pixels, stats.density_percent)?;
    if let Some(d) = &stats.depth_m {
        writeln!(
            out,
            "depth m       min {:.4}  p5 {:.4}  median {:.4}  mean {:.4}  p95 {:.4}  max {:.4}",
            d.min, d.p5, d.median, d.mean, d.p95, d.max
        )?;
    }
    if let Some(d) = &stats.disparity_px {
        writeln!(out, "disparity px  min {:.2}  median {:.2}  max {:.2}", d.min, d.median, d.max)?;
    }
    let t = &stats.timings_ms;
    writeln!(
        out,
        "time ms       load {:.1}  match {:.1} ({:.0} MDE/s)  triangulate {:.1}  write {:.1}  total {:.1}",
        t.load, t.match_, stats.mde_per_s, t.triangulate, t.write, t.total
    )
}
