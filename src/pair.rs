//! The pair command: load, match, triangulate, write, report.
//!
//! Everything that can fail on the inputs (rig, disparity range, image sizes, output folders) is
//! checked before the first output is written; every output is written atomically.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use stereo_disparity::{block_match, sgm, DisparityMap, GrayImage};

use crate::config::{Matcher, PairConfig, UsageError};
use crate::report::{self, MatcherReport, Outputs, RigReport, Stats, Summary, Timings};
use stereo_triangulation::{DepthStats, DisparityStats};

pub fn run(config: &PairConfig, out: &mut impl Write) -> Result<()> {
    let stats = process(config)?;
    if !config.quiet {
        report::write_summary(out, &stats)?;
    }
    for (what, path) in config.outputs() {
        writeln!(out, "{what}: {}", path.display())?;
    }
    out.flush()?;
    Ok(())
}

/// The work on one pair, shared by the pair and batch commands: load, match, triangulate, write
/// every output of `config` (depth map, then the disparity map and statistics when asked for).
/// On failure no output of this call is left behind.
pub fn process(config: &PairConfig) -> Result<Stats> {
    let start = Instant::now();
    check_output_folders(config)?;

    let t = Instant::now();
    let left = stereo_io::load_gray(&config.left).context("cannot read the left image")?;
    let right = stereo_io::load_gray(&config.right).context("cannot read the right image")?;
    let load = t.elapsed();
    if left.size() != right.size() {
        bail!(
            "{} is {}x{} but {} is {}x{}; a rectified pair has equal sizes",
            config.left.display(),
            left.width(),
            left.height(),
            config.right.display(),
            right.width(),
            right.height()
        );
    }
    let (width, height) = left.size();
    if let Some((w, h)) = config.expected_size {
        if (w, h) != (width, height) {
            bail!(
                "{} is {width}x{height} but its calib.txt is for {w}x{h}; the focal length and \
                 principal point would not apply",
                config.left.display()
            );
        }
    }
    let range = config.resolve_range(width)?;
    let mut matcher = config.matcher.clone();
    matcher.set_range(range);

    let t = Instant::now();
    let disparity = run_matcher(&matcher, &left, &right)?;
    let match_time = t.elapsed();
    drop((left, right));

    let t = Instant::now();
    let depth = stereo_triangulation::depth_map(&disparity, &config.rig);
    let triangulate = t.elapsed();

    let t = Instant::now();
    let mut written = Written::default();
    stereo_io::write_exr(&config.output, &[("Z", &depth)]).context("cannot write the depth map")?;
    written.0.push(&config.output);
    if let Some(path) = &config.disparity {
        stereo_io::write_pfm(path, &disparity).context("cannot write the disparity map")?;
        written.0.push(path);
    }
    let write = t.elapsed();
    let total = start.elapsed();

    let depth_stats = DepthStats::from_depth(&depth);
    let pixels = width * height;
    let match_seconds = match_time.as_secs_f64();
    let stats = Stats {
        left: report::display(&config.left),
        right: report::display(&config.right),
        outputs: Outputs {
            depth: report::display(&config.output),
            disparity: config.disparity.as_deref().map(report::display),
            stats: config.stats.as_deref().map(report::display),
        },
        width,
        height,
        valid_pixels: depth_stats.valid_pixels,
        density_percent: depth_stats.density_percent,
        depth_m: Summary::of_depth(&depth_stats),
        disparity_px: Summary::of_disparity(&DisparityStats::from_disparity(&disparity)),
        matcher: MatcherReport::new(&matcher),
        rig: RigReport::new(config, width, height),
        timings_ms: Timings {
            load: report::ms(load),
            match_: report::ms(match_time),
            triangulate: report::ms(triangulate),
            write: report::ms(write),
            total: report::ms(total),
        },
        mde_per_s: if match_seconds > 0.0 {
            (pixels * range.count()) as f64 / match_seconds / 1e6
        } else {
            0.0
        },
    };
    if let Some(path) = &config.stats {
        let mut json = serde_json::to_vec_pretty(&stats).context("cannot serialise the statistics")?;
        json.push(b'\n');
        stereo_io::write_atomic(path, &json).context("cannot write the statistics")?;
    }
    written.commit();
    Ok(stats)
}

fn run_matcher(matcher: &Matcher, left: &GrayImage, right: &GrayImage) -> Result<DisparityMap> {
    let result = match matcher {
        Matcher::Sgm(params) => sgm(left, right, params),
        Matcher::Bm(params) => block_match(left, right, params),
    };
    result.map_err(|err| {
        use stereo_disparity::Error;
        match err {
            // Argument problems the config could not see before the images were loaded.
            Error::EmptyRange { .. } | Error::RangeWiderThanImage { .. } | Error::InvalidParameter { .. } => {
                UsageError(err.to_string()).into()
            }
            _ => anyhow::Error::new(err).context(format!("{} matching failed", matcher.name())),
        }
    })
}

/// Fails early (before matching) when an output's folder does not exist, rather than after
/// the work is done.
fn check_output_folders(config: &PairConfig) -> Result<()> {
    for (what, path) in config.outputs() {
        let folder = match path.parent() {
            Some(parent) if !parent.as_os_str().is_empty() => parent,
            _ => Path::new("."),
        };
        if !folder.is_dir() {
            bail!(
                "cannot write the {what} output {}: folder {} does not exist",
                path.display(),
                folder.display()
            );
        }
        if path.is_dir() {
            bail!("cannot write the {what} output {}: it is a folder", path.display());
        }
    }
    Ok(())
}

/// The outputs written so far. Dropped without [`Written::commit`] (a later write failed), it
/// removes them, so a failed run leaves no partial set of outputs.
#[derive(Default)]
struct Written<'a>(Vec<&'a Path>);

impl Written<'_> {
    fn commit(mut self) {
        self.0.clear();
    }
}

impl Drop for Written<'_> {
    fn drop(&mut self) {
        for path in &self.0 {
            let _ = std::fs::remove_file(path);
        }
    }
}
