//! Writing one pair's outputs: depth EXR, disparity PFM/PNG, depth PNG, point cloud, preview.
//! Every file is written atomically; a failed run removes what it had written.

use std::path::Path;

use anyhow::{bail, Context, Result};
use stereo_pipeline::{DepthResult, Image};

use crate::config::{PairConfig, PreviewOf};

/// What the writers counted, for the statistics.
#[derive(Default)]
pub struct WriteCounts {
    pub points_written: Option<usize>,
    pub depth_png_too_deep: Option<usize>,
}

/// Writes every output of `config` but the statistics, in a fixed order, into `written`;
/// `colour` (the left view's) colours the point cloud.
pub fn write_outputs<'a>(
    config: &'a PairConfig,
    result: &DepthResult,
    colour: Option<&Image<[u8; 3]>>,
    written: &mut Written<'a>,
) -> Result<WriteCounts> {
    let disparity = &result.disparity;
    let (width, height) = disparity.size();
    let mut counts = WriteCounts::default();
    if let (Some(path), Some(depth)) = (&config.output, &result.depth) {
        let mut channels = vec![("Z", depth)];
        if let (true, Some(confidence)) = (config.extras.confidence_channel, &result.confidence) {
            channels.push(("confidence", confidence));
        }
        if config.extras.disparity_channel {
            channels.push(("disparity", disparity));
        }
        stereo_io::write_exr(path, &channels).context("cannot write the depth map")?;
        written.0.push(path);
    }
    if let Some(path) = &config.disparity {
        stereo_io::write_pfm(path, disparity).context("cannot write the disparity map")?;
        written.0.push(path);
    }
    if let Some(path) = &config.disparity_png {
        stereo_io::write_png16(path, &stereo_io::disparity_to_kitti(disparity))
            .context("cannot write the disparity PNG")?;
        written.0.push(path);
    }
    if let (Some(path), Some(depth)) = (&config.depth_png, &result.depth) {
        let (mm, too_deep) = stereo_io::depth_to_mm(depth);
        stereo_io::write_png16(path, &mm).context("cannot write the depth PNG")?;
        written.0.push(path);
        if too_deep > 0 {
            eprintln!(
                "stereo-depth: warning: {}: {too_deep} pixels deeper than 65.535 m written as 0 (invalid)",
                path.display()
            );
        }
        counts.depth_png_too_deep = Some(too_deep);
    }
    if let (Some(path), Some(setup)) = (&config.points, &config.rig) {
        // The colours of the left view as decoded with it, rectified like it for a raw pair.
        let colour = match (colour, &config.rectify) {
            (Some(colour), Some(rectifier)) => Some(rectifier.left.remap(colour)),
            (colour, _) => colour.cloned(),
        };
        let Some(colour) = colour.filter(|c| c.size() == disparity.size()) else {
            bail!("{}: no colours of the left view's size for the point cloud", config.left.display());
        };
        let vertices: Vec<stereo_io::PlyVertex> =
            stereo_triangulation::points(disparity, &setup.rig, config.points_step)
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
        counts.points_written = Some(vertices.len());
    }
    if let Some(path) = &config.preview {
        let preview = match (config.preview_of, &result.depth) {
            (PreviewOf::Depth, Some(depth)) => {
                stereo_io::render_preview(depth, "m", stereo_io::ColourScale::SmallIsWarm)
            }
            _ => stereo_io::render_preview(disparity, "px", stereo_io::ColourScale::LargeIsWarm),
        };
        stereo_io::write_png_rgb8(path, &preview.image).context("cannot write the preview")?;
        written.0.push(path);
    }
    Ok(counts)
}

/// Fails early (before matching) when an output's folder does not exist, rather than after
/// the work is done.
pub fn check_output_folders(config: &PairConfig) -> Result<()> {
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
pub struct Written<'a>(pub Vec<&'a Path>);

impl Written<'_> {
    pub fn commit(mut self) {
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
