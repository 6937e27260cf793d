//! The pair command: load, match, triangulate, write, report.
//!
//! Everything that can fail on the inputs (rig, disparity range, image sizes, output folders) is
//! checked before the first output is written; every output is written atomically.

use std::io::Write;
use std::path::Path;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use stereo_disparity::{block_match, sgm_detailed, Adaptation, DisparityMap, GrayImage, Image};

use crate::config::{Matcher, PairConfig, PreviewOf, UsageError};
use crate::limits;
use crate::report::{
    self, DepthResolution, MatcherReport, Outputs, RectificationReport, RigReport, Stats, Summary, Timings,
};
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

    // Headers first: sizes and memory are checked before any pixel is decoded.
    let t = Instant::now();
    let limits = &config.limits;
    let left_header = limits::probe(&config.left, limits).context("cannot read the left image")?;
    let right_header = limits::probe(&config.right, limits).context("cannot read the right image")?;
    let size = (left_header.width, left_header.height);
    let right_size = (right_header.width, right_header.height);
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
    let mut matcher = config.matcher.clone();
    matcher.set_range(range);
    let other = limits::other_bytes(&left_header, &right_header, config.points.is_some());
    limits::fit_memory(&mut matcher, &config.left, size, other, limits)?;
    let planned_matcher_bytes = limits::matcher_bytes(&matcher, width, height);

    // Both views decode at once: PNG decoding is single-threaded, and it is most of the load.
    let (left, right) = rayon::join(
        || stereo_io::load_gray_limited(&config.left, limits.max_pixels),
        || stereo_io::load_gray_limited(&config.right, limits.max_pixels),
    );
    let left = left.context("cannot read the left image")?;
    let right = right.context("cannot read the right image")?;
    let load = t.elapsed();
    // The headers were read a moment ago; a file replaced since is caught here.
    for (path, image) in [(&config.left, &left), (&config.right, &right)] {
        if image.size() != size {
            bail!("{} changed while it was being read", path.display());
        }
    }

    let t = Instant::now();
    let (right, rectification) = check_rectification(config, &left, right, range);
    let rectification_time = t.elapsed();

    let t = Instant::now();
    let Matched { mut disparity, confidence, adaptation } =
        run_matcher(&matcher, &left, &right, &config.left, config.extras.min_confidence)?;
    let match_time = t.elapsed();
    drop((left, right));
    // Cut once here, so every output below (depth, disparity, PNGs, points, preview, stats)
    // agrees on which pixels are valid.
    let depth_limits = match (&config.depth_limits, &config.rig) {
        (Some(limits), Some(setup)) => {
            Some(limits.report(&setup.rig, limits.apply(&mut disparity, &setup.rig)))
        }
        _ => None,
    };

    let t = Instant::now();
    let depth = config.rig.as_ref().map(|setup| stereo_triangulation::depth_map(&disparity, &setup.rig));
    let triangulate = t.elapsed();

    let t = Instant::now();
    let mut written = Written::default();
    let mut depth_png_too_deep = None;
    let mut points_written = None;
    if let (Some(path), Some(depth)) = (&config.output, &depth) {
        let mut channels = vec![("Z", depth)];
        if let (true, Some(confidence)) = (config.extras.confidence_channel, &confidence) {
            channels.push(("confidence", confidence));
        }
        if config.extras.disparity_channel {
            channels.push(("disparity", &disparity));
        }
        stereo_io::write_exr(path, &channels).context("cannot write the depth map")?;
        written.0.push(path);
    }
    if let Some(path) = &config.disparity {
        stereo_io::write_pfm(path, &disparity).context("cannot write the disparity map")?;
        written.0.push(path);
    }
    if let Some(path) = &config.disparity_png {
        stereo_io::write_png16(path, &stereo_io::disparity_to_kitti(&disparity))
            .context("cannot write the disparity PNG")?;
        written.0.push(path);
    }
    if let (Some(path), Some(depth)) = (&config.depth_png, &depth) {
        let (mm, too_deep) = stereo_io::depth_to_mm(depth);
        stereo_io::write_png16(path, &mm).context("cannot write the depth PNG")?;
        written.0.push(path);
        if too_deep > 0 {
            eprintln!(
                "stereo-depth: warning: {}: {too_deep} pixels deeper than 65.535 m written as 0 (invalid)",
                path.display()
            );
        }
        depth_png_too_deep = Some(too_deep);
    }
    if let (Some(path), Some(setup)) = (&config.points, &config.rig) {
        let colour = stereo_io::load_rgb8_limited(&config.left, limits.max_pixels)
            .context("cannot read the left image's colours")?;
        if colour.size() != disparity.size() {
            bail!("{} changed while it was being processed", config.left.display());
        }
        let vertices: Vec<stereo_io::PlyVertex> =
            stereo_triangulation::points(&disparity, &setup.rig, config.points_step)
                .into_iter()
                .map(|p| stereo_io::PlyVertex {
                    position: [p.position.x as f32, p.position.y as f32, p.position.z as f32],
                    colour: colour.get(p.x, p.y),
                })
                .filter(|v| v.position.iter().all(|c| c.is_finite()))
                .collect();
        let rig = &setup.rig;
        let (cx, cy) = rig.principal_point_for(width, height);
        let comments = [
            "stereo-depth point cloud: x y z in metres, camera frame of the left view: x right, y down, \
             z forward (optical axis); colour from the left image"
                .to_string(),
            format!(
                "rig: baseline_mm {} focal_px {} doffs {} cx {cx} cy {cy}; image {width}x{height}; step {}",
                rig.baseline_mm, rig.focal_px, rig.doffs, config.points_step
            ),
            format!("left {}", config.left.display()),
        ];
        let comments: Vec<&str> = comments.iter().map(String::as_str).collect();
        stereo_io::write_ply(path, &vertices, &comments).context("cannot write the point cloud")?;
        written.0.push(path);
        points_written = Some(vertices.len());
    }
    if let Some(path) = &config.preview {
        let preview = match (config.preview_of, &depth) {
            (PreviewOf::Depth, Some(depth)) => {
                stereo_io::render_preview(depth, "m", stereo_io::ColourScale::SmallIsWarm)
            }
            _ => stereo_io::render_preview(&disparity, "px", stereo_io::ColourScale::LargeIsWarm),
        };
        stereo_io::write_png_rgb8(path, &preview.image).context("cannot write the preview")?;
        written.0.push(path);
    }
    let write = t.elapsed();
    let total = start.elapsed();

    let disparity_stats = DisparityStats::from_disparity(&disparity);
    let (valid_pixels, density_percent, depth_m) = match &depth {
        Some(depth) => {
            let stats = DepthStats::from_depth(depth);
            (stats.valid_pixels, stats.density_percent, Summary::of_depth(&stats))
        }
        None => (disparity_stats.valid_pixels, disparity_stats.density_percent, None),
    };
    let pixels = width * height;
    let match_seconds = match_time.as_secs_f64();
    let stats = Stats {
        left: report::display(&config.left),
        right: report::display(&config.right),
        outputs: Outputs {
            depth: config.output.as_deref().map(report::display),
            disparity: config.disparity.as_deref().map(report::display),
            stats: config.stats.as_deref().map(report::display),
            points: config.points.as_deref().map(report::display),
            preview: config.preview.as_deref().map(report::display),
            depth_png: config.depth_png.as_deref().map(report::display),
            disparity_png: config.disparity_png.as_deref().map(report::display),
        },
        width,
        height,
        valid_pixels,
        density_percent,
        depth_resolution_mm: config.rig.as_ref().and_then(|s| DepthResolution::new(&s.rig, depth_m.as_ref())),
        depth_m,
        disparity_px: Summary::of_disparity(&disparity_stats),
        matcher: MatcherReport::new(&matcher, adaptation.as_ref()),
        rig: config.rig.as_ref().map(|setup| RigReport::new(setup, width, height)),
        points_written,
        depth_png_too_deep,
        depth_limits,
        rectification,
        timings_ms: Timings {
            load: report::ms(load),
            rectification: report::ms(rectification_time),
            match_: report::ms(match_time),
            triangulate: report::ms(triangulate),
            write: report::ms(write),
            total: report::ms(total),
        },
        planned_matcher_bytes,
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

/// Measures how well the rows of the pair line up; resamples the right view when they do not
/// (unless `--no-align`), so clean pairs are matched exactly as loaded. Warns (one line each)
/// about an offset above half a pixel and about a pair that looks swapped.
fn check_rectification(
    config: &PairConfig,
    left: &GrayImage,
    right: GrayImage,
    range: stereo_disparity::DisparityRange,
) -> (GrayImage, RectificationReport) {
    use stereo_rectify::AlignmentVerdict;
    let alignment = stereo_rectify::estimate_alignment(left, &right, range);
    let misaligned =
        matches!(alignment.verdict, AlignmentVerdict::Misaligned | AlignmentVerdict::BadlyMisaligned);
    let compensated = misaligned && config.align;
    let (left_name, right_name) = (config.left.display(), config.right.display());
    if misaligned && alignment.max_abs_offset_px > 0.5 {
        let offset = alignment.vertical_offset_px;
        eprintln!(
            "stereo-depth: warning: {right_name} is {:.2} px {} than {left_name} at the centre, rotated {:.2}° \
             (up to {:.2} px off); {} (check the rectification)",
            offset.abs(),
            if offset >= 0.0 { "lower" } else { "higher" },
            alignment.rotation_deg,
            alignment.max_abs_offset_px,
            if compensated { "compensated" } else { "not compensated (--no-align)" }
        );
    }
    if alignment.verdict != AlignmentVerdict::Unknown && alignment.negative_disparity_share > 0.5 {
        eprintln!(
            "stereo-depth: warning: {left_name}, {right_name}: {:.0} % of the matches want negative \
             disparity: are LEFT and RIGHT swapped?",
            alignment.negative_disparity_share * 100.0
        );
    }
    let right = if compensated { stereo_rectify::compensate(&right, &alignment) } else { right };
    (right, RectificationReport::new(&alignment, compensated))
}

/// What [`run_matcher`] returns: the disparity map, SGM's confidence when asked for, and what SGM
/// measured of the pair and adapted to.
pub(crate) struct Matched {
    pub disparity: DisparityMap,
    pub confidence: Option<Image<f32>>,
    pub adaptation: Option<Adaptation>,
}

/// Runs the matcher; with SGM's confidence asked for, also returns it, and invalidates the
/// pixels under `min_confidence`.
pub(crate) fn run_matcher(
    matcher: &Matcher,
    left: &GrayImage,
    right: &GrayImage,
    path: &Path,
    min_confidence: Option<f32>,
) -> Result<Matched> {
    let result = match matcher {
        Matcher::Sgm(params) => sgm_detailed(left, right, params).map(|out| {
            let (mut disparity, confidence) = (out.disparity, out.confidence);
            if let (Some(t), Some(c)) = (min_confidence, &confidence) {
                for (d, &c) in disparity.as_mut_slice().iter_mut().zip(c.as_slice()) {
                    if c < t {
                        *d = f32::NAN;
                    }
                }
            }
            Matched { disparity, confidence, adaptation: Some(out.adaptation) }
        }),
        Matcher::Bm(params) => block_match(left, right, params).map(|disparity| Matched {
            disparity,
            confidence: None,
            adaptation: None,
        }),
    };
    result.map_err(|err| {
        use stereo_disparity::Error;
        match err {
            // Argument problems the config could not see before the images were loaded.
            Error::EmptyRange { .. } | Error::RangeWiderThanImage { .. } | Error::InvalidParameter { .. } => {
                UsageError(err.to_string()).into()
            }
            _ => anyhow::Error::new(err).context(format!(
                "{}: {} matching failed",
                path.display(),
                matcher.name()
            )),
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
