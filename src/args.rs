//! The raw command line, as clap parses it. Nothing here is checked beyond its type; `config`
//! turns it into validated settings, and no clap type leaves the binary.

use std::path::PathBuf;

use clap::{Args, CommandFactory, FromArgMatches, Parser, Subcommand, ValueEnum};
use stereo_disparity::{BmCost, BmParams, PathCount, SgmParams, Subpixel};

const AFTER_HELP: &str = "\
Without a subcommand, stereo-depth matches the rectified pair LEFT RIGHT and writes a metric depth \
map: a 32-bit float OpenEXR file with one channel `Z` holding the depth in metres \
(Z = baseline * focal / ((d + doffs) * pixel)), NaN where no trustworthy disparity was found. \
The path written is always printed on stdout as `depth: PATH`.

Examples:
  stereo-depth left.png right.png --baseline 80 --focal 12 --pixel 4
  stereo-depth left.png right.png --baseline 80 --focal 12 --pixel 4 --max-disparity 64 \\
      -o depth.exr --disparity disp.pfm --stats stats.json
  stereo-depth eval disp.pfm disp0GT.pfm

Exit status: 0 on success, 1 when a file cannot be read or written, 2 for invalid arguments.";

/// Metric depth from a rectified stereo pair: Semi-Global Matching or block matching, EXR depth
/// maps (metres) and point statistics.
#[derive(Debug, Parser)]
#[command(
    name = "stereo-depth",
    version,
    about,
    after_help = AFTER_HELP,
    args_conflicts_with_subcommands = true,
    subcommand_negates_reqs = true
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,

    #[command(flatten)]
    pub pair: PairArgs,
}

impl Cli {
    /// Parses the process arguments. The help shows the matchers' defaults as the library
    /// defines them, so they are never restated here.
    pub fn try_parse_with_defaults() -> Result<Cli, clap::Error> {
        let mut command = with_library_defaults(Cli::command());
        let matches = command.try_get_matches_from_mut(std::env::args_os())?;
        Cli::from_arg_matches(&matches).map_err(|err| err.format(&mut command))
    }
}

fn with_library_defaults(command: clap::Command) -> clap::Command {
    let sgm = SgmParams::default();
    let bm = BmParams::default();
    let subpixel = |s: Subpixel| match s {
        Subpixel::None => "none",
        Subpixel::Parabola => "parabola",
        Subpixel::Equiangular => "equiangular",
    };
    let lr = |diff: Option<f32>| diff.map_or("off".to_string(), |d| d.to_string());
    let defaults = [
        (
            "paths",
            (match sgm.paths {
                PathCount::Four => "4",
                PathCount::Eight => "8",
            })
            .to_string(),
        ),
        ("p1", sgm.p1.to_string()),
        ("p2", sgm.p2.to_string()),
        ("uniqueness", format!("{} (sgm), {} (bm)", sgm.uniqueness_ratio, bm.uniqueness_ratio)),
        ("lr_max_diff", format!("{} (sgm), {} (bm)", lr(sgm.lr_max_diff), lr(bm.lr_max_diff))),
        ("subpixel", format!("{} (sgm), {} (bm)", subpixel(sgm.subpixel), subpixel(bm.subpixel))),
        ("block_size", bm.block_size.to_string()),
        (
            "bm_cost",
            (match bm.cost {
                BmCost::Sad => "sad",
                BmCost::Census => "census",
            })
            .to_string(),
        ),
    ];
    defaults.into_iter().fold(command, |command, (id, default)| {
        command.mut_arg(id, |arg| {
            let help = arg.get_help().map(|h| h.to_string()).unwrap_or_default();
            arg.help(format!("{help} [default: {default}]"))
        })
    })
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Score a disparity map against ground truth (Middlebury-style bad-pixel rates).
    Eval(EvalArgs),
}

/// The pair command: match LEFT against RIGHT and write the depth map.
#[derive(Debug, Args)]
pub struct PairArgs {
    /// Left (reference) image of the rectified pair: PNG, PGM/PPM or JPEG, 8 or 16 bit.
    #[arg(value_name = "LEFT", required = true)]
    pub left: Option<PathBuf>,

    /// Right image of the rectified pair, the same size as LEFT.
    #[arg(value_name = "RIGHT", required = true)]
    pub right: Option<PathBuf>,

    /// Distance between the two optical centres, in millimetres.
    #[arg(long, value_name = "MM", required = true, allow_negative_numbers = true, help_heading = "Rig")]
    pub baseline: Option<f64>,

    /// Lens focal length, in millimetres.
    #[arg(long, value_name = "MM", required = true, allow_negative_numbers = true, help_heading = "Rig")]
    pub focal: Option<f64>,

    /// Sensor pixel pitch, in micrometres.
    #[arg(long, value_name = "UM", required = true, allow_negative_numbers = true, help_heading = "Rig")]
    pub pixel: Option<f64>,

    /// Disparity offset between the two principal points (Middlebury's `doffs`), pixels.
    #[arg(
        long,
        value_name = "PX",
        default_value_t = 0.0,
        allow_negative_numbers = true,
        help_heading = "Rig"
    )]
    pub doffs: f64,

    /// Principal point column, pixels [default: image centre]. Needs --cy.
    #[arg(long, value_name = "PX", requires = "cy", allow_negative_numbers = true, help_heading = "Rig")]
    pub cx: Option<f64>,

    /// Principal point row, pixels [default: image centre]. Needs --cx.
    #[arg(long, value_name = "PX", requires = "cx", allow_negative_numbers = true, help_heading = "Rig")]
    pub cy: Option<f64>,

    /// Smallest disparity searched (pixels).
    #[arg(
        long,
        value_name = "N",
        default_value_t = 0,
        allow_negative_numbers = true,
        help_heading = "Matching"
    )]
    pub min_disparity: i32,

    /// End of the disparity search: disparities min <= d < max are searched, so max - min is
    /// OpenCV's numDisparities [default: a quarter of the image width, rounded up to 16].
    #[arg(long, value_name = "N", allow_negative_numbers = true, help_heading = "Matching")]
    pub max_disparity: Option<i32>,

    /// Matching algorithm: census Semi-Global Matching or window block matching.
    #[arg(long, value_enum, default_value_t = MatcherArg::Sgm, help_heading = "Matching")]
    pub matcher: MatcherArg,

    /// SGM: number of aggregation paths: 4 (horizontal and vertical) or 8 (also diagonals)
    #[arg(long, value_enum, help_heading = "Matching")]
    pub paths: Option<PathsArg>,

    /// SGM: penalty for a one-pixel disparity change along a path, in census bits.
    #[arg(long, value_name = "N", help_heading = "Matching")]
    pub p1: Option<u16>,

    /// SGM: penalty for larger disparity jumps, in census bits.
    #[arg(long, value_name = "N", help_heading = "Matching")]
    pub p2: Option<u16>,

    /// Uniqueness margin in percent: the best cost must beat every other disparity (more than one
    /// pixel away) by this much; 0 disables the check.
    #[arg(long, value_name = "N", help_heading = "Matching")]
    pub uniqueness: Option<u32>,

    /// Left-right consistency: largest allowed disagreement between the left and right
    /// disparity maps, pixels.
    #[arg(long, value_name = "PX", conflicts_with = "no_lr_check", help_heading = "Matching")]
    pub lr_max_diff: Option<f32>,

    /// Disable the left-right consistency check.
    #[arg(long, help_heading = "Matching")]
    pub no_lr_check: bool,

    /// Subpixel refinement of the integer disparity.
    #[arg(long, value_enum, help_heading = "Matching")]
    pub subpixel: Option<SubpixelArg>,

    /// BM: side of the square matching window, odd.
    #[arg(long, value_name = "N", help_heading = "Matching")]
    pub block_size: Option<usize>,

    /// BM: window cost.
    #[arg(long, value_enum, help_heading = "Matching")]
    pub bm_cost: Option<BmCostArg>,

    /// Depth map to write (OpenEXR, channel Z in metres) [default: LEFTSTEM_depth.exr in the
    /// current directory].
    #[arg(short, long, value_name = "PATH.exr", help_heading = "Output")]
    pub output: Option<PathBuf>,

    /// Also write the disparity map of the left view (Middlebury PFM; invalid pixels are NaN).
    #[arg(long, value_name = "PATH.pfm", help_heading = "Output")]
    pub disparity: Option<PathBuf>,

    /// Also write statistics as JSON: width, height, valid_pixels, density_percent, depth_m and
    /// disparity_px (min, max, mean, median, p5, p95), matcher (name and parameters), rig
    /// (baseline_mm, focal_mm, pixel_um, focal_px, doffs, principal_point), timings_ms (load,
    /// match, triangulate, write, total) and mde_per_s (W·H·ndisp per second of matching / 1e6).
    #[arg(long, value_name = "PATH.json", help_heading = "Output")]
    pub stats: Option<PathBuf>,

    /// Print only the paths written, not the summary.
    #[arg(short, long, help_heading = "Output")]
    pub quiet: bool,

    /// Worker threads [default: one per core].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum MatcherArg {
    /// Census Semi-Global Matching (Hirschmüller 2008).
    Sgm,
    /// Window block matching, winner-takes-all.
    Bm,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PathsArg {
    #[value(name = "4")]
    Four,
    #[value(name = "8")]
    Eight,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum SubpixelArg {
    /// Integer disparities only.
    None,
    /// A parabola through the three costs around the minimum.
    Parabola,
    /// Two lines of equal and opposite slope (suits census/L1 costs).
    Equiangular,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BmCostArg {
    /// Sum of absolute differences on an x-Sobel prefiltered image.
    Sad,
    /// Hamming distances of 5x5 census strings; robust to gain and bias changes.
    Census,
}

/// `stereo-depth eval EST GT`.
#[derive(Debug, Args)]
pub struct EvalArgs {
    /// Estimated disparity map (PFM, e.g. from --disparity; NaN or inf = no estimate).
    #[arg(value_name = "EST")]
    pub est: PathBuf,

    /// Ground-truth disparity: PFM, or an 8/16-bit PNG/PGM holding disparity * --gt-scale with 0
    /// unknown.
    #[arg(value_name = "GT")]
    pub gt: PathBuf,

    /// Ground-truth disparity = stored value / S (PNG/PGM: Middlebury 2003 uses 4, KITTI 256;
    /// applied to PFM too, like stereo_eval.py).
    #[arg(long, value_name = "S", default_value_t = 1.0, allow_negative_numbers = true)]
    pub gt_scale: f32,

    /// Print the metrics as JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}
