//! The raw command line, as clap parses it. Nothing here is checked beyond its type; `config`
//! turns it into validated settings, and no clap type leaves the binary.

use std::path::PathBuf;

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use clap::{Args, CommandFactory, FromArgMatches, Parser, Subcommand, ValueEnum};
use stereo_degrade::Degradation;
use stereo_pipeline::{
    parse_named, BmCost, BmParams, Downscale, MatcherKind, Named, PathCount, Preset, Search, SgmParams,
    Subpixel,
};

const AFTER_HELP: &str = "\
Without a subcommand, stereo-depth matches the rectified pair LEFT RIGHT and writes a metric depth \
map: a 32-bit float OpenEXR file with one channel `Z` holding the depth in metres \
(Z = baseline * focal / ((d + doffs) * pixel)), NaN where no trustworthy disparity was found. \
Every path written is printed on stdout as `WHAT: PATH` (depth, disparity, disparity-png, \
depth-png, points, preview, stats). The rig is --baseline with --focal and --pixel, or with \
--focal-px, or a --calib file: a Middlebury calib.txt (rectified pair) or an OpenCV/ROS stereo \
calibration (raw pair, rectified first). Without any rig flag only disparity outputs can be written \
(--disparity, --disparity-png, --preview-of disparity, --stats with null depth fields).

Examples:
  stereo-depth left.png right.png --baseline 80 --focal 12 --pixel 4
  stereo-depth im0.png im1.png --calib calib.txt --points cloud.ply --preview depth.png
  stereo-depth raw_left.png raw_right.png --calib stereo.yaml
  stereo-depth left.png right.png --max-disparity 64 --disparity disp.pfm
  stereo-depth info cloud.ply
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
        Cli::try_parse_from_with_defaults(std::env::args_os())
    }

    /// [`Cli::try_parse_with_defaults`] on the given arguments (the first is the program name).
    pub fn try_parse_from_with_defaults<I, T>(args: I) -> Result<Cli, clap::Error>
    where
        I: IntoIterator<Item = T>,
        T: Into<std::ffi::OsString> + Clone,
    {
        let mut command = Cli::command_with_defaults();
        let matches = command.try_get_matches_from_mut(args)?;
        Cli::from_arg_matches(&matches).map_err(|err| err.format(&mut command))
    }

    /// The clap command with the library defaults in the help of the pair and batch commands.
    /// No rig flag is required by clap: `config` checks that the rig is complete (or absent, for
    /// the pair command's disparity-only mode) and names what is missing.
    pub fn command_with_defaults() -> clap::Command {
        with_library_defaults(Cli::command()).mut_subcommand("batch", with_library_defaults)
    }
}

fn with_library_defaults(command: clap::Command) -> clap::Command {
    let sgm = SgmParams::default();
    let bm = BmParams::default();
    let lr = |diff: Option<f32>| diff.map_or("off".to_string(), |d| d.to_string());
    let defaults = [
        ("paths", sgm.paths.to_string()),
        ("search", sgm.search.to_string()),
        ("p1", sgm.p1.to_string()),
        ("p2", sgm.p2.to_string()),
        ("uniqueness", format!("{} (sgm), {} (bm)", sgm.uniqueness_ratio, bm.uniqueness_ratio)),
        ("lr_max_diff", format!("{} (sgm), {} (bm)", lr(sgm.lr_max_diff), lr(bm.lr_max_diff))),
        ("subpixel", format!("{} (sgm), {} (bm)", sgm.subpixel, bm.subpixel)),
        ("block_size", bm.block_size.to_string()),
        ("bm_cost", bm.cost.to_string()),
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
    /// Process every stereo pair found in a folder (see `batch --help` for the layouts).
    Batch(Box<BatchArgs>),
    /// Join the per-shard summaries of `batch --shard K/N` runs into summary.json and summary.csv.
    BatchMerge(BatchMergeArgs),
    /// Run the matcher on every scene of a folder with ground truth and score it (per scene and
    /// on average): a folder with scenes.tsv, or Middlebury SCENE/im0.png, im1.png, disp0GT.pfm
    /// (and calib.txt for ndisp) folders.
    EvalFolder(Box<EvalFolderArgs>),
    /// Rig design calculator: distance, disparity in mm, depth resolution, field of view, table, chart.
    Calc(CalcArgs),
    /// Print what a file stereo-depth writes contains: EXR, PFM, PNG, PLY or stats JSON.
    Info(InfoArgs),
    /// Write a degraded copy of a pair (gain, gamma, bias, vignetting, noise, JPEG, blur, vertical
    /// shift, rotation) for robustness measurements.
    Degrade(DegradeArgs),
    /// Rectify a raw pair with its calibration (OpenCV YAML/XML/JSON or ROS camera_info): writes
    /// the rectified pair and the rectified rig's calib.txt.
    Rectify(RectifyArgs),
}

/// `stereo-depth info FILE`.
#[derive(Debug, Args)]
pub struct InfoArgs {
    /// A depth EXR, disparity PFM, 16-bit depth/disparity PNG, preview PNG, point cloud PLY or
    /// stats/summary JSON.
    #[arg(value_name = "FILE")]
    pub file: PathBuf,
}

/// What `--preview` shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PreviewOfArg {
    /// Depth in metres (near is red).
    Depth,
    /// Disparity in pixels (near is red).
    Disparity,
}

/// The pair command: match LEFT against RIGHT and write the depth map.
#[derive(Debug, Args)]
pub struct PairArgs {
    /// Left (reference) image of the rectified pair: PNG, PGM/PPM, TIFF or JPEG, 8 or 16 bit.
    #[arg(value_name = "LEFT", required = true)]
    pub left: Option<PathBuf>,

    /// Right image of the rectified pair, the same size as LEFT.
    #[arg(value_name = "RIGHT", required = true)]
    pub right: Option<PathBuf>,

    #[command(flatten)]
    pub rig: RigArgs,

    #[command(flatten)]
    pub matching: MatchArgs,

    #[command(flatten)]
    pub depth_limits: DepthLimitArgs,

    /// Depth map to write (OpenEXR, channel Z in metres) [default: LEFTSTEM_depth.exr in the
    /// current directory].
    #[arg(short, long, value_name = "PATH.exr", help_heading = "Output")]
    pub output: Option<PathBuf>,

    /// Also write the disparity map of the left view (Middlebury PFM; invalid pixels are NaN).
    #[arg(long, value_name = "PATH.pfm", help_heading = "Output")]
    pub disparity: Option<PathBuf>,

    /// Also write statistics as JSON: width, height, valid_pixels, density_percent, depth_m and
    /// disparity_px (min, max, mean, median, p5, p95), matcher (name and parameters), rig
    /// (baseline_mm, focal_mm, pixel_um, focal_px, doffs, principal_point), rectification
    /// (vertical_offset_px, rotation_deg, max_abs_offset_px, verdict, compensated), timings_ms
    /// (load, rectification, match, triangulate, write, total) and mde_per_s (W·H·ndisp per
    /// second of matching / 1e6).
    #[arg(long, value_name = "PATH.json", help_heading = "Output")]
    pub stats: Option<PathBuf>,

    /// Also write the valid 3-D points as a binary little-endian PLY point cloud: float x y z in
    /// metres (camera frame of the left view: x right, y down, z forward) and uchar red green
    /// blue from the left image.
    #[arg(long, value_name = "PATH.ply", help_heading = "Output")]
    pub points: Option<PathBuf>,

    /// Write every N-th pixel's point in both directions (N = 2 keeps a quarter).
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..),
          help_heading = "Output")]
    pub points_step: u32,

    /// Also write a colour preview PNG (Turbo colour map, near is red, invalid pixels black) with
    /// a colour bar labelled with the range of the map.
    #[arg(long, value_name = "PATH.png", help_heading = "Output")]
    pub preview: Option<PathBuf>,

    /// What --preview shows [default: depth].
    #[arg(long, value_enum, value_name = "MAP", requires = "preview", help_heading = "Output")]
    pub preview_of: Option<PreviewOfArg>,

    /// Also write the depth as a 16-bit grey PNG in millimetres: round(Z * 1000); 0 = invalid or
    /// deeper than 65.535 m (counted and warned about).
    #[arg(long, value_name = "PATH.png", help_heading = "Output")]
    pub depth_png: Option<PathBuf>,

    /// Also write the disparity as a 16-bit grey PNG in the KITTI convention:
    /// round(disparity * 256); 0 = invalid (and disparities <= 0).
    #[arg(long, value_name = "PATH.png", help_heading = "Output")]
    pub disparity_png: Option<PathBuf>,

    /// Print only the paths written, not the summary.
    #[arg(short, long, help_heading = "Output")]
    pub quiet: bool,

    /// Do not resample the right view when its rows are measured off the left view's (a
    /// vertical offset or rotation left by the rectification); the check is still reported.
    #[arg(long, help_heading = "Matching")]
    pub no_align: bool,

    /// Worker threads [default: one per core].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
}

/// The rig flags, shared by the pair and batch commands. The rig is the baseline and the focal
/// length in pixels: --focal with --pixel, or --focal-px, or a --calib file.
#[derive(Debug, Args)]
pub struct RigArgs {
    /// Distance between the two optical centres, in millimetres.
    #[arg(long, value_name = "MM", allow_negative_numbers = true, help_heading = "Rig")]
    pub baseline: Option<f64>,

    /// Lens focal length, in millimetres (with --pixel).
    #[arg(long, value_name = "MM", allow_negative_numbers = true, help_heading = "Rig")]
    pub focal: Option<f64>,

    /// Sensor pixel pitch, in micrometres.
    #[arg(long, value_name = "UM", allow_negative_numbers = true, help_heading = "Rig")]
    pub pixel: Option<f64>,

    /// Focal length in pixels, instead of --focal and --pixel.
    #[arg(long, value_name = "PX", allow_negative_numbers = true, help_heading = "Rig")]
    pub focal_px: Option<f64>,

    /// Calibration file, detected from its content. A Middlebury calib.txt (cam0=[f 0 cx; 0 f cy;
    /// 0 0 1], doffs, baseline in mm, width, height, ndisp) describes an already rectified pair. An
    /// OpenCV stereo calibration (FileStorage YAML/XML or JSON: K1 D1 K2 D2 R T) or ROS
    /// camera_info files (left.yaml with right.yaml beside it, or their folder) describe raw
    /// cameras: the pair is rectified first (see docs/calibration.md). Either gives the focal
    /// length in pixels, the principal point, doffs and the baseline; --baseline, --doffs,
    /// --cx/--cy and --max-disparity given too take precedence.
    #[arg(long, value_name = "FILE", help_heading = "Rig")]
    pub calib: Option<PathBuf>,

    /// Rectification scaling for a raw --calib (OpenCV's stereoRectify alpha): 0 keeps only
    /// valid pixels, 1 keeps every source pixel.
    #[arg(long, value_name = "0..1", default_value_t = 0.0, help_heading = "Rig")]
    pub alpha: f64,

    /// Sensor width in millimetres: reports the horizontal field of view 2*atan(w / 2f) (needs
    /// the focal length in mm: --focal, or --pixel with --focal-px or --calib).
    #[arg(long, value_name = "MM", allow_negative_numbers = true, help_heading = "Rig")]
    pub sensor_width: Option<f64>,

    /// Disparity offset between the two principal points (Middlebury's `doffs`), pixels
    /// [default: 0].
    #[arg(long, value_name = "PX", allow_negative_numbers = true, help_heading = "Rig")]
    pub doffs: Option<f64>,

    /// Principal point column, pixels [default: image centre]. Needs --cy.
    #[arg(long, value_name = "PX", requires = "cy", allow_negative_numbers = true, help_heading = "Rig")]
    pub cx: Option<f64>,

    /// Principal point row, pixels [default: image centre]. Needs --cx.
    #[arg(long, value_name = "PX", requires = "cx", allow_negative_numbers = true, help_heading = "Rig")]
    pub cy: Option<f64>,
}

/// The depth limits, shared by the pair and batch commands (they need a rig).
#[derive(Debug, Args)]
pub struct DepthLimitArgs {
    /// Invalidate pixels nearer than M metres, in every output (depth, disparity, PNGs, points,
    /// preview, stats); the stats count the pixels cut.
    #[arg(long, value_name = "M", allow_negative_numbers = true, help_heading = "Depth limits")]
    pub min_depth: Option<f64>,

    /// Invalidate pixels farther than M metres (and those without a finite depth), in every
    /// output, like --min-depth.
    #[arg(long, value_name = "M", allow_negative_numbers = true, help_heading = "Depth limits")]
    pub max_depth: Option<f64>,
}

/// The matcher flags, shared by the pair and batch commands.
#[derive(Debug, Args)]
pub struct MatchArgs {
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
    #[arg(long, value_parser = named::<MatcherKind>(), default_value_t = MatcherKind::Sgm, help_heading = "Matching")]
    pub matcher: MatcherKind,

    /// SGM preset; the options below override single parameters of it.
    #[arg(long, value_parser = named::<Preset>(), default_value_t = Preset::Balanced, help_heading = "Matching")]
    pub preset: Preset,

    /// SGM: a dense map: small speckles removed, then every invalid pixel filled (occlusions from
    /// the background side, mismatches by interpolation).
    #[arg(long, help_heading = "Matching")]
    pub fill: bool,

    /// SGM: invalidate connected regions of similar disparity (within 1 px) smaller than N
    /// pixels; 0 disables [default: 0, or 400 with --fill].
    #[arg(long, value_name = "N", help_heading = "Matching")]
    pub speckle_size: Option<usize>,

    /// SGM: move disparity edges onto the intensity edges of the left image within PX pixels
    /// (undoes the edge fattening of window costs); 0 disables [default: 5].
    #[arg(long, value_name = "PX", help_heading = "Matching")]
    pub edge_snap: Option<usize>,

    /// SGM: add a `confidence` channel to the depth EXR: per pixel in [0, 1], the census
    /// agreement at the match times the share of neighbours within 1 px; 0 where the disparity
    /// is invalid or was filled.
    #[arg(long, help_heading = "Matching")]
    pub confidence: bool,

    /// SGM: invalidate pixels whose confidence (see --confidence) is below T, in [0, 1].
    #[arg(long, value_name = "T", allow_negative_numbers = true, help_heading = "Matching")]
    pub min_confidence: Option<f32>,

    /// Add a `disparity` channel (pixels, NaN invalid) to the depth EXR beside `Z`.
    #[arg(long, help_heading = "Matching")]
    pub exr_disparity: bool,

    /// SGM: aggregate in one top-down pass (3 directions with --paths 4, 5 with --paths 8):
    /// faster and O(width x disparities) memory, somewhat less accurate.
    #[arg(long, help_heading = "Matching")]
    pub single_pass: bool,

    /// SGM: number of aggregation paths: 4 (horizontal and vertical) or 8 (also diagonals)
    #[arg(long, value_parser = named::<PathCount>(), help_heading = "Matching")]
    pub paths: Option<PathCount>,

    /// SGM: search every pixel over the whole range (full), or coarse to fine around a
    /// half-resolution match (hierarchical); auto: hierarchical for large ranges.
    #[arg(long, value_parser = named::<Search>(), help_heading = "Matching")]
    pub search: Option<Search>,

    /// SGM: match the pair reduced N times on each side (box filter), then bring the disparities
    /// back to full size: about N³ times less work, for disparities N times coarser and no detail
    /// below N pixels. auto (default): halve, repeatedly, while both views hold no detail finer than
    /// 2 px (enlarged images, soft optics; sensor noise discounted) and at least 100 000 pixels
    /// remain, reducing by 3 where it would halve twice (6 for three times); coarse (the fast
    /// preset's default): as auto, but sharp pairs are halved too where at least 16 disparities and
    /// 25 000 pixels remain, and where the range is too short to halve (again) the rows once more
    /// (the rows alone, or by 4 after a halving); 1: full resolution
    /// (docs/performance.md)
    #[arg(long, value_name = "auto|coarse|N", help_heading = "Matching")]
    pub downscale: Option<Downscale>,

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
    #[arg(
        long,
        value_name = "PX",
        conflicts_with = "no_lr_check",
        allow_negative_numbers = true,
        help_heading = "Matching"
    )]
    pub lr_max_diff: Option<f32>,

    /// Disable the left-right consistency check.
    #[arg(long, help_heading = "Matching")]
    pub no_lr_check: bool,

    /// Subpixel refinement of the integer disparity.
    #[arg(long, value_parser = named::<Subpixel>(), help_heading = "Matching")]
    pub subpixel: Option<Subpixel>,

    /// BM: side of the square matching window, odd.
    #[arg(long, value_name = "N", help_heading = "Matching")]
    pub block_size: Option<usize>,

    /// BM: window cost.
    #[arg(long, value_parser = named::<BmCost>(), help_heading = "Matching")]
    pub bm_cost: Option<BmCost>,

    /// Largest image accepted, in pixels; suffixes K, M, G are 10^3, 10^6, 10^9 (e.g. 250M). An
    /// image is checked from its header, before it is decoded [default: 100M].
    #[arg(long, value_name = "PIXELS", value_parser = parse_pixels, allow_negative_numbers = true,
          help_heading = "Limits")]
    pub max_pixels: Option<u64>,

    /// Working memory one pair may use, bytes; suffixes K, M, G, T are powers of 1024 (e.g. 4G,
    /// 512M). SGM then aggregates in strips that fit; a pair that cannot fit is refused before
    /// its images are decoded [default: the memory available (MemAvailable)].
    #[arg(long, value_name = "SIZE", value_parser = parse_size, allow_negative_numbers = true,
          help_heading = "Limits")]
    pub max_memory: Option<u64>,
}

/// `--max-pixels`: decimal suffixes (megapixels).
pub fn parse_pixels(text: &str) -> Result<u64, String> {
    stereo_pipeline::parse_scaled(text, 1000, "pixels")
}

/// `--max-memory`: binary suffixes (`4G` = 4 GiB).
pub fn parse_size(text: &str) -> Result<u64, String> {
    stereo_pipeline::parse_scaled(text, 1024, "bytes")
}

/// A clap parser for a library choice: its names, each with its help line, as possible values.
fn named<T: Named + Clone + Send + Sync>() -> impl TypedValueParser<Value = T> {
    PossibleValuesParser::new(T::ALL.iter().map(|v| PossibleValue::new(v.name()).help(v.help())))
        .map(|name| parse_named::<T>(&name).expect("clap accepts only the listed names"))
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
    /// applied to PFM too, like stereo_eval.py) [default: 1; an 8-bit image ground truth without
    /// it is warned about].
    #[arg(long, value_name = "S", allow_negative_numbers = true)]
    pub gt_scale: Option<f32>,

    /// Print the metrics as JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// `stereo-depth eval-folder DIR`.
#[derive(Debug, Args)]
pub struct EvalFolderArgs {
    /// Folder of scenes with ground truth.
    #[arg(value_name = "DIR")]
    pub dir: PathBuf,

    /// The matcher and its options, as for the pair command (the disparity range defaults to each
    /// scene's ndisp).
    #[command(flatten)]
    pub matching: MatchArgs,

    /// Print the per-scene metrics and their average as JSON.
    #[arg(long)]
    pub json: bool,
}

const BATCH_AFTER_HELP: &str = "\
Pairs are found by walking INPUT_DIR (hidden files and OUT_DIR are skipped; images are .png, .pgm, \
.ppm, .pnm, .tif, .tiff, .jpg, .jpeg) in these layouts, all at once and at any depth:
  DIR/left/NAME    + DIR/right/NAME        -> OUT_DIR/DIR/STEM.*   (also image_0/image_1)
  DIR/image_2/NAME + DIR/image_3/NAME      -> OUT_DIR/DIR/STEM.*   (KITTI, e.g. 000000_10.png)
  DIR/NAME_left.EXT + DIR/NAME_right.EXT   -> OUT_DIR/DIR/NAME.*   (also _L/_R)
  SCENE/im0.EXT    + SCENE/im1.EXT         -> OUT_DIR/SCENE/im0.*  (Middlebury)
A Middlebury SCENE/calib.txt gives the focal length (px), baseline, doffs and principal point, and \
ndisp as --max-disparity; rig flags given on the command line take precedence. Other pairs need \
--baseline and --focal with --pixel (or --focal-px); --calib FILE gives one calibration for every \
pair, in place of the calib.txt files. --pattern 'LEFT:RIGHT' replaces the layouts: each side is a file \
name (matched in every folder) or a path from INPUT_DIR (when it has a '/') with one {name}, e.g. \
--pattern '{name}_a.png:{name}_b.png' -> OUT_DIR/DIR/{name}.*. Images that pair with nothing are \
reported on stderr and in --list.

Outputs per pair: STEM.depth.exr, with --disparity STEM.disparity.pfm, with --stats STEM.stats.json, \
with --points STEM.points.ply, with --preview STEM.preview.png, with --depth-png STEM.depth.png, with \
--disparity-png STEM.disparity.png; and OUT_DIR/summary.json and summary.csv (one row per pair: status ok/skipped/failed, error, \
density, median depth, timings). A pair whose requested outputs all exist is skipped unless \
--overwrite; outputs are written atomically, so an interrupted run resumes where it stopped.

--shard K/N processes the pairs whose index in the sorted list is K modulo N (K in 0..N) and writes \
summary.shard-K-of-N.json/.csv; `stereo-depth batch-merge OUT_DIR` joins them.

Exit status: 0 when every pair succeeded (or was skipped), 1 when any failed or on a runtime error, \
2 for invalid arguments.

Examples:
  stereo-depth batch drive/ --out depth/ --baseline 80 --focal 12 --pixel 4 --stats
  stereo-depth batch middlebury/ --out depth/ --list
  stereo-depth batch drive/ --out depth/ --baseline 80 --focal 12 --pixel 4 \\
      --shard $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT
  stereo-depth batch-merge depth/";

/// `stereo-depth batch INPUT_DIR --out OUT_DIR`.
#[derive(Debug, Args)]
#[command(after_help = BATCH_AFTER_HELP)]
pub struct BatchArgs {
    /// Folder searched (recursively) for stereo pairs.
    #[arg(value_name = "INPUT_DIR")]
    pub input: PathBuf,

    /// Folder the outputs are written to, mirroring the layout of INPUT_DIR (created if needed).
    #[arg(short, long, value_name = "OUT_DIR")]
    pub out: PathBuf,

    #[command(flatten)]
    pub rig: RigArgs,

    #[command(flatten)]
    pub matching: MatchArgs,

    #[command(flatten)]
    pub depth_limits: DepthLimitArgs,

    /// Also write each pair's disparity map as STEM.disparity.pfm.
    #[arg(long, help_heading = "Output")]
    pub disparity: bool,

    /// Also write each pair's statistics as STEM.stats.json (the pair command's --stats).
    #[arg(long, help_heading = "Output")]
    pub stats: bool,

    /// Also write each pair's point cloud as STEM.points.ply (the pair command's --points).
    #[arg(long, help_heading = "Output")]
    pub points: bool,

    /// Every N-th pixel's point in both directions (with --points).
    #[arg(long, value_name = "N", default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..),
          requires = "points", help_heading = "Output")]
    pub points_step: u32,

    /// Also write each pair's colour preview as STEM.preview.png.
    #[arg(long, help_heading = "Output")]
    pub preview: bool,

    /// What --preview shows [default: depth].
    #[arg(long, value_enum, value_name = "MAP", requires = "preview", help_heading = "Output")]
    pub preview_of: Option<PreviewOfArg>,

    /// Also write each pair's depth in millimetres as STEM.depth.png (16-bit, 0 = invalid).
    #[arg(long, help_heading = "Output")]
    pub depth_png: bool,

    /// Also write each pair's KITTI-convention disparity (x 256, 16-bit) as STEM.disparity.png.
    #[arg(long, help_heading = "Output")]
    pub disparity_png: bool,

    /// Redo pairs whose outputs already exist (default: skip them).
    #[arg(long, help_heading = "Output")]
    pub overwrite: bool,

    /// No progress bar or per-pair lines; only warnings and the failure count on stderr.
    #[arg(short, long, help_heading = "Output")]
    pub quiet: bool,

    /// Pair files by 'LEFT:RIGHT' templates with one {name} each instead of the known layouts,
    /// e.g. '{name}_a.png:{name}_b.png'.
    #[arg(long, value_name = "LEFT:RIGHT", help_heading = "Pairs")]
    pub pattern: Option<String>,

    /// Dry run: print the pairs found, what would be written or skipped, and the unpaired
    /// images; write nothing.
    #[arg(long, help_heading = "Pairs")]
    pub list: bool,

    /// Process only the K-th of N slices of the sorted pair list (pairs whose index is K mod N),
    /// e.g. --shard $SLURM_ARRAY_TASK_ID/$SLURM_ARRAY_TASK_COUNT.
    #[arg(long, value_name = "K/N", help_heading = "Pairs")]
    pub shard: Option<String>,

    /// Pairs processed at the same time (each holds its images and cost volume in memory)
    /// [default: 2, at most the number of cores].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub jobs: Option<u16>,

    /// Matcher worker threads, shared by the pairs in flight [default: one per core].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
}

/// `stereo-depth batch-merge OUT_DIR`.
#[derive(Debug, Args)]
pub struct BatchMergeArgs {
    /// The OUT_DIR of the `batch --shard K/N` runs, holding summary.shard-K-of-N.json files.
    #[arg(value_name = "OUT_DIR")]
    pub out: PathBuf,
}

const CALC_AFTER_HELP: &str = "\
Distance Z = baseline * focal / ((d + doffs) * pixel). Depth resolution is the first-order change of \
Z for one disparity step: dZ ~ Z^2 * pixel * step / (baseline * focal), per 1 px by default, per \
--subpixel STEP for a subpixel matcher. The working range runs from the largest searched disparity \
(--max-disparity - 1; the default is the matcher's default for the image width when it is known, \
else 128) to one disparity step.

Examples:
  stereo-depth calc --baseline 200 --focal 6 --pixel 2.5 --disparity 150
  stereo-depth calc --baseline 80 --focal 12 --pixel 4 --width-px 1600 --distance 5 --subpixel 0.25
  stereo-depth calc --baseline 80 --focal 12 --pixel 4 --table --json
  stereo-depth calc --baseline 80 --focal 12 --pixel 4 --chart depth-range.png

Exit status: 0 on success, 1 when the chart cannot be written, 2 for invalid arguments.";

/// `stereo-depth calc`: distance, disparity in mm, depth resolution, field of view, working range,
/// a table and a chart for a stereo rig, before capturing anything.
#[derive(Debug, Args)]
#[command(after_help = CALC_AFTER_HELP)]
pub struct CalcArgs {
    /// Distance between the two optical centres, in millimetres.
    #[arg(long, value_name = "MM", allow_negative_numbers = true, help_heading = "Rig")]
    pub baseline: f64,

    /// Lens focal length, in millimetres.
    #[arg(long, value_name = "MM", allow_negative_numbers = true, help_heading = "Rig")]
    pub focal: f64,

    /// Sensor pixel pitch, in micrometres.
    #[arg(long, value_name = "UM", allow_negative_numbers = true, help_heading = "Rig")]
    pub pixel: f64,

    /// Sensor width, in millimetres: gives the horizontal field of view and the image width.
    #[arg(
        long,
        value_name = "MM",
        allow_negative_numbers = true,
        conflicts_with = "width_px",
        help_heading = "Rig"
    )]
    pub sensor_width: Option<f64>,

    /// Image width in pixels (instead of --sensor-width: the sensor is N x pixel wide).
    #[arg(long, value_name = "N", allow_negative_numbers = true, help_heading = "Rig")]
    pub width_px: Option<f64>,

    /// Disparity offset between the two principal points (Middlebury's `doffs`), pixels.
    #[arg(
        long,
        value_name = "PX",
        default_value_t = 0.0,
        allow_negative_numbers = true,
        help_heading = "Rig"
    )]
    pub doffs: f64,

    /// The matcher's disparity step in (0, 1] pixels: 1 for integer matching, e.g. 0.25 for
    /// quarter-pixel subpixel refinement. Every depth resolution is per this step.
    #[arg(
        long,
        value_name = "STEP",
        default_value_t = 1.0,
        allow_negative_numbers = true,
        help_heading = "Matching"
    )]
    pub subpixel: f64,

    /// End of the disparity search, as for matching (disparities 0 <= d < max are searched)
    /// [default: a quarter of the image width rounded up to 16 when the width is known, else 128].
    #[arg(long, value_name = "PX", allow_negative_numbers = true, help_heading = "Matching")]
    pub max_disparity: Option<f64>,

    /// Distance, disparity in mm and depth resolution at this disparity (pixels).
    #[arg(long, value_name = "PX", allow_negative_numbers = true, help_heading = "Questions")]
    pub disparity: Option<f64>,

    /// Disparity and depth resolution at this distance (metres).
    #[arg(long, value_name = "M", allow_negative_numbers = true, help_heading = "Questions")]
    pub distance: Option<f64>,

    /// Print a table of disparity -> distance -> depth resolution: by default from one disparity
    /// step to the largest searched disparity in steps of x1.5 and x1.33 (1, 1.5, 2, 3, 4, 6, ...).
    #[arg(long, help_heading = "Table")]
    pub table: bool,

    /// First disparity of the table, pixels (implies --table) [default: the disparity step].
    #[arg(long, value_name = "PX", allow_negative_numbers = true, help_heading = "Table")]
    pub table_min: Option<f64>,

    /// Last disparity of the table, pixels (implies --table) [default: --max-disparity - 1].
    #[arg(long, value_name = "PX", allow_negative_numbers = true, help_heading = "Table")]
    pub table_max: Option<f64>,

    /// Evenly spaced table rows this many pixels apart (implies --table) [default: geometric].
    #[arg(long, value_name = "PX", allow_negative_numbers = true, help_heading = "Table")]
    pub table_step: Option<f64>,

    /// Print everything as JSON instead of text.
    #[arg(long, help_heading = "Output")]
    pub json: bool,

    /// Write a chart of disparity and depth resolution against distance: PNG or SVG, by the
    /// extension.
    #[arg(long, value_name = "PATH.png|PATH.svg", help_heading = "Output")]
    pub chart: Option<PathBuf>,
}

const DEGRADE_AFTER_HELP: &str = "\
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
#[command(after_help = DEGRADE_AFTER_HELP)]
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

/// `stereo-depth rectify LEFT RIGHT --calib FILE -o DIR`.
#[derive(Debug, Args)]
pub struct RectifyArgs {
    /// The raw left image.
    #[arg(value_name = "LEFT")]
    pub left: PathBuf,
    /// The raw right image.
    #[arg(value_name = "RIGHT")]
    pub right: PathBuf,
    /// The calibration: OpenCV stereo calibration (FileStorage YAML/XML or JSON: K1 D1 K2 D2 R T),
    /// or ROS camera_info (left.yaml with right.yaml beside it, or their folder).
    #[arg(long, value_name = "FILE")]
    pub calib: PathBuf,
    /// Output folder: im0.png, im1.png (the rectified pair), calib.txt (the rectified rig,
    /// Middlebury format) and rectification.yaml (R1 R2 P1 P2, OpenCV format).
    #[arg(short = 'o', long = "out", value_name = "DIR")]
    pub out: PathBuf,
    /// Free scaling (OpenCV's stereoRectify alpha): 0 keeps only valid pixels, 1 every source pixel.
    #[arg(long, value_name = "0..1", default_value_t = 0.0)]
    pub alpha: f64,
    /// Also write the undistort-rectify maps as PFM images (left_map_x.pfm, left_map_y.pfm,
    /// right_map_x.pfm, right_map_y.pfm: the source position of every rectified pixel).
    #[arg(long)]
    pub maps: bool,
    /// Print nothing but errors.
    #[arg(long, short = 'q')]
    pub quiet: bool,
}
