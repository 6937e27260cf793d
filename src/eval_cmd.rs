//! The eval command: score a disparity map against ground truth, as
//! `stereo_eval.py score --est EST --gt GT --gt-scale S` does.

use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result};
use serde::Serialize;
use stereo_disparity::DisparityMap;
use stereo_eval::Metrics;

use crate::config::EvalConfig;

#[derive(Serialize)]
struct Report<'a> {
    est: String,
    gt: String,
    gt_scale: f32,
    width: usize,
    height: usize,
    metrics: &'a Metrics,
}

pub fn run(config: &EvalConfig, out: &mut impl Write) -> Result<()> {
    let est = read_estimate(&config.est).context("cannot read the estimate")?;
    let gt = read_ground_truth(&config.gt, config.gt_scale).context("cannot read the ground truth")?;
    let metrics = stereo_eval::metrics(&est, &gt)
        .with_context(|| format!("cannot score {} against {}", config.est.display(), config.gt.display()))?;
    // Only on success: a failed run prints its one error line alone.
    if !config.gt_scale_given && is_8bit_image(&config.gt) {
        eprintln!(
            "stereo-depth: warning: {}: 8-bit ground truth scored without --gt-scale (so scale 1): 8-bit \
             disparity images usually store disparity x a scale (Middlebury 2003: --gt-scale 4)",
            config.gt.display()
        );
    }

    if config.json {
        let report = Report {
            est: config.est.display().to_string(),
            gt: config.gt.display().to_string(),
            gt_scale: config.gt_scale,
            width: gt.width(),
            height: gt.height(),
            metrics: &metrics,
        };
        serde_json::to_writer_pretty(&mut *out, &report)?;
        writeln!(out)?;
    } else {
        let opt = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |v| format!("{v:.2}"));
        writeln!(
            out,
            "{} vs {}: {}x{}, {} px with ground truth, {} estimated",
            config.est.display(),
            config.gt.display(),
            gt.width(),
            gt.height(),
            metrics.n_gt,
            metrics.n_est
        )?;
        writeln!(out, "{} {:>8}", Metrics::table_header(), "bad2est")?;
        writeln!(out, "{} {:>8}", metrics.to_table_row(), opt(metrics.bad2_est))?;
    }
    out.flush()?;
    Ok(())
}

/// The estimate, as stored: NaN and infinities mark pixels without an estimate; zero and negative
/// disparities are estimates (as in `stereo_eval.py` without `--est-nonpositive-invalid`).
fn read_estimate(path: &Path) -> Result<DisparityMap> {
    let mut map = stereo_io::read_pfm(path)?;
    for v in map.as_mut_slice() {
        if !v.is_finite() {
            *v = f32::NAN;
        }
    }
    Ok(map)
}

/// Whether `path` is an 8-bit integer image (PNG, PGM, TIFF), from its header (only read once the
/// ground truth has decoded; an unreadable header gives no warning rather than an error).
fn is_8bit_image(path: &Path) -> bool {
    let is_pfm = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("pfm"));
    !is_pfm && stereo_io::probe_image(path).is_ok_and(|header| header.bits_per_channel == 8)
}

/// Ground truth: `stored value / scale`, unknown (0 in PNG/PGM; non-finite or <= 0 in PFM) as
/// NaN. Like `stereo_eval.py`, the scale applies to PFM ground truth too.
fn read_ground_truth(path: &Path, scale: f32) -> Result<DisparityMap> {
    let mut map = stereo_io::read_disparity(path, scale)?;
    let is_pfm = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("pfm"));
    if is_pfm && scale != 1.0 {
        for v in map.as_mut_slice() {
            *v /= scale;
        }
    }
    Ok(map)
}
