//! The pair command: config → pipeline → writers → report.
//!
//! Everything that can fail on the inputs (rig, disparity range, image sizes, memory, output
//! folders) is checked before the first output is written; every output is written atomically.

use std::io::Write;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use stereo_pipeline::{Plan, Rectification};

use crate::config::PairConfig;
use crate::error::UsageError;
use crate::limits;
use crate::report::{self, StageTimes, Stats};
use crate::writers::{self, Written};

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

/// The work on one pair, shared by the pair and batch commands: plan, load, run the pipeline,
/// write every output of `config` (the statistics last). On failure no output of this call is
/// left behind.
pub fn process(config: &PairConfig) -> Result<Stats> {
    let start = Instant::now();
    writers::check_output_folders(config)?;

    // Headers first: sizes and memory are planned before any pixel is decoded.
    let t = Instant::now();
    let plan = plan(config)?;
    // Both views decode at once: PNG decoding is single-threaded, and it is most of the load.
    let max_pixels = config.limits.max_pixels;
    // A coloured point cloud takes its colours from the same decode of the left view.
    let wants_colour = config.points.is_some() && config.rig.is_some();
    let (left, right) = rayon::join(
        || match wants_colour {
            true => {
                stereo_io::load_gray_and_rgb8_limited(&config.left, max_pixels).map(|(g, c)| (g, Some(c)))
            }
            false => stereo_io::load_gray_limited(&config.left, max_pixels).map(|g| (g, None)),
        },
        || stereo_io::load_gray_limited(&config.right, max_pixels),
    );
    let (left, colour) = left.context("cannot read the left image")?;
    let right = right.context("cannot read the right image")?;
    let load = t.elapsed();
    // The headers were read a moment ago; a file replaced since is caught here.
    for (path, image) in [(&config.left, &left), (&config.right, &right)] {
        if image.size() != plan.size() {
            bail!("{} changed while it was being read", path.display());
        }
    }

    // A raw pair (--calib with an OpenCV/ROS calibration) is rectified before matching.
    let t = Instant::now();
    let (left, right) = match &config.rectify {
        Some(rectifier) => crate::rectify_cmd::rectify_gray(rectifier, &left, &right),
        None => (left, right),
    };
    let remap = config.rectify.as_ref().map(|_| t.elapsed());
    let result = plan.run_gray(&left, right).map_err(|err| matching_error(config, &plan, err))?;
    drop(left);
    warn_about_rectification(config, &result.rectification);

    let t = Instant::now();
    let mut written = Written::default();
    let counts = writers::write_outputs(config, &result, colour.as_ref(), &mut written)?;
    let write = t.elapsed();
    let stats =
        Stats::new(config, &plan, &result, counts, StageTimes { load, remap, write, total: start.elapsed() });
    if let Some(path) = &config.stats {
        let mut json = serde_json::to_vec_pretty(&stats).context("cannot serialise the statistics")?;
        json.push(b'\n');
        stereo_io::write_atomic(path, &json).context("cannot write the statistics")?;
    }
    written.commit();
    Ok(stats)
}

/// The pair's plan, from the image headers: sizes checked against each other and the
/// calibration, the range resolved for the width, memory planned against the limit.
pub fn plan(config: &PairConfig) -> Result<Plan> {
    let limits = &config.limits;
    let left = limits::probe(&config.left, limits).context("cannot read the left image")?;
    let right = limits::probe(&config.right, limits).context("cannot read the right image")?;
    let (size, right_size) = ((left.width, left.height), (right.width, right.height));
    if size != right_size {
        bail!(
            "{} is {}x{} but {} is {}x{}; a rectified pair has equal sizes",
            config.left.display(),
            size.0,
            size.1,
            config.right.display(),
            right_size.0,
            right_size.1
        );
    }
    let (width, height) = size;
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
    let params = config.pipeline_params(range);
    let other = limits::other_bytes(&left, &right, config.points.is_some());
    let (limit, source) = limits::memory_limit(limits, other);
    Plan::with_memory_limit(&params, size, right_size, limit)
        .map_err(|err| limits::explain(err, &config.left, &params.matcher, size, source))
}

/// Warns (one line each) about an offset above half a pixel and about a pair that looks swapped.
fn warn_about_rectification(config: &PairConfig, rectification: &Rectification) {
    use stereo_pipeline::AlignmentVerdict;
    let alignment = &rectification.alignment;
    let (left_name, right_name) = (config.left.display(), config.right.display());
    if rectification.misaligned() && alignment.max_abs_offset_px > 0.5 {
        let offset = alignment.vertical_offset_px;
        eprintln!(
            "stereo-depth: warning: {right_name} is {:.2} px {} than {left_name} at the centre, rotated {:.2}° \
             (up to {:.2} px off); {} (check the rectification)",
            offset.abs(),
            if offset >= 0.0 { "lower" } else { "higher" },
            alignment.rotation_deg,
            alignment.max_abs_offset_px,
            if rectification.compensated { "compensated" } else { "not compensated (--no-align)" }
        );
    }
    if alignment.verdict != AlignmentVerdict::Unknown && alignment.negative_disparity_share > 0.5 {
        eprintln!(
            "stereo-depth: warning: {left_name}, {right_name}: {:.0} % of the matches want negative \
             disparity: are LEFT and RIGHT swapped?",
            alignment.negative_disparity_share * 100.0
        );
    }
}

/// A matcher error as the user should read it: argument problems the config could not see
/// before the images were loaded are usage errors, the rest name the file.
pub fn matching_error(config: &PairConfig, plan: &Plan, err: stereo_pipeline::Error) -> anyhow::Error {
    use stereo_disparity::Error as Matcher;
    use stereo_pipeline::Error;
    match err {
        Error::Matcher(
            Matcher::EmptyRange { .. }
            | Matcher::RangeWiderThanImage { .. }
            | Matcher::InvalidParameter { .. },
        )
        | Error::InvalidParameter { .. } => UsageError(err.to_string()).into(),
        _ => anyhow::Error::new(err).context(format!(
            "{}: {} matching failed",
            config.left.display(),
            plan.matcher().name()
        )),
    }
}
