//! The degrade command: write a degraded copy of a stereo pair (camera imperfections for
//! robustness measurements), keeping each image's bit depth and channel count.

use std::io::Write;
use std::path::Path;

use anyhow::{Context, Result};
use stereo_degrade::{degrade, derive_seed, Raster};

use crate::config::DegradeConfig;

pub fn run(config: &DegradeConfig, out: &mut impl Write) -> Result<()> {
    // Both inputs are read before anything is written, so a bad RIGHT leaves no half-done pair.
    let left = load(&config.left)?;
    let right = load(&config.right)?;
    std::fs::create_dir_all(&config.out)
        .with_context(|| format!("{}: cannot create the folder", config.out.display()))?;
    let views = [("left", left, &config.left_spec, 0), ("right", right, &config.right_spec, 1)];
    for (name, image, spec, stream) in views {
        let degraded = degrade(&image, spec, derive_seed(config.seed, stream))
            .with_context(|| format!("cannot degrade the {name} view ({spec})"))?;
        let path = config.out.join(format!("{name}.png"));
        let bytes =
            degraded.encode_png().with_context(|| format!("{}: cannot encode PNG", path.display()))?;
        stereo_io::write_atomic(&path, &bytes)?;
        if !config.quiet {
            writeln!(out, "{name}: {}", path.display())?;
        }
    }
    out.flush()?;
    Ok(())
}

/// Reads an image at its own depth and channel count. The header is probed first so a corrupt
/// or oversized file gets the same messages as the matcher's inputs.
fn load(path: &Path) -> Result<Raster> {
    let header = stereo_io::probe_image(path)?;
    if header.pixels() > stereo_io::DEFAULT_MAX_PIXELS {
        anyhow::bail!(
            "{}: {}x{} image too large (more than {} pixels)",
            path.display(),
            header.width,
            header.height,
            stereo_io::DEFAULT_MAX_PIXELS
        );
    }
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
    Raster::decode(&bytes)
        .with_context(|| format!("{}: cannot decode {} image", path.display(), header.format))
}
