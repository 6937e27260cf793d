//! The degrade command: write a degraded copy of a stereo pair (camera imperfections for
//! robustness measurements), keeping each image's bit depth and channel count.

use std::io::Write;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;
use stereo_degrade::{degrade, derive_seed, Degradation, Raster};

use crate::config::UsageError;

const AFTER_HELP: &str = "\
SPEC is a comma list of key=value (or `none`):
  gain=G       global gain, clipped (0 < G <= 4)
  gamma=Γ      v^Γ on [0, 1] (0.2 .. 5)
  bias=B       add B grey levels of the 8-bit scale, clipped (-255 .. 255)
  vignette=F   multiply by 1 - F·(r/r_corner)², 1 - F at the corners (0 .. 1)
  noise=S      Gaussian noise, σ in 8-bit grey levels, per pixel and channel (0 .. 64)
  jpeg=Q       JPEG encode + decode at quality Q (1 .. 100)
  blur=S       defocus: Gaussian blur, σ in pixels (0 .. 10)
  vshift=S     vertical shift in pixels, positive moves the content down (-16 .. 16)
  rotate=D     rotation in degrees about the image centre, positive is clockwise (-5 .. 5)
Stages run in camera order: shift/rotation (one bicubic resampling, borders replicated)
→ blur → vignetting → gain → bias → gamma → noise → JPEG. A per-view spec (--left, --right)
overrides the same keys of --both. Each view gets its own noise (seeds derived from --seed),
so noise and JPEG from --both are independent per view. Alpha channels are dropped.

Example:
  stereo-depth degrade im0.png im1.png --out deg --right gain=1.6,vshift=0.5 --both noise=3";

/// `stereo-depth degrade LEFT RIGHT --out DIR [--left SPEC] [--right SPEC] [--both SPEC]`.
#[derive(Debug, Args)]
#[command(after_help = AFTER_HELP)]
pub struct DegradeArgs {
    /// Left image of the pair: PNG, PGM/PPM or JPEG, 8 or 16 bit, grey or RGB.
    #[arg(value_name = "LEFT")]
    pub left: PathBuf,

    /// Right image of the pair.
    #[arg(value_name = "RIGHT")]
    pub right: PathBuf,

    /// Folder to write left.png and right.png to (created if missing).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,

    /// Degradations of the left view.
    #[arg(long = "left", value_name = "SPEC", value_parser = parse_spec)]
    pub left_spec: Option<Degradation>,

    /// Degradations of the right view.
    #[arg(long = "right", value_name = "SPEC", value_parser = parse_spec)]
    pub right_spec: Option<Degradation>,

    /// Degradations of both views (noise and JPEG drawn independently per view).
    #[arg(long = "both", value_name = "SPEC", value_parser = parse_spec)]
    pub both_spec: Option<Degradation>,

    /// Seed of the noise.
    #[arg(long, value_name = "N", default_value_t = 1)]
    pub seed: u64,

    /// Print nothing on stdout.
    #[arg(short, long)]
    pub quiet: bool,
}

fn parse_spec(spec: &str) -> Result<Degradation, String> {
    spec.parse().map_err(|e: stereo_degrade::Error| e.to_string())
}

/// Checked settings of the degrade command.
#[derive(Debug)]
pub struct DegradeConfig {
    pub left: PathBuf,
    pub right: PathBuf,
    pub out: PathBuf,
    pub left_spec: Degradation,
    pub right_spec: Degradation,
    pub seed: u64,
    pub quiet: bool,
}

impl DegradeConfig {
    pub fn from_args(args: DegradeArgs) -> Result<Self, UsageError> {
        if args.out.is_file() {
            return Err(UsageError(format!("--out {}: is a file, want a folder", args.out.display())));
        }
        let both = args.both_spec.unwrap_or_default();
        Ok(DegradeConfig {
            left_spec: args.left_spec.unwrap_or_default().over(&both),
            right_spec: args.right_spec.unwrap_or_default().over(&both),
            left: args.left,
            right: args.right,
            out: args.out,
            seed: args.seed,
            quiet: args.quiet,
        })
    }
}

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
