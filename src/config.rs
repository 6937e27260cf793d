//! Checked, resolved settings built from the raw command line. Everything that can be checked
//! without reading the images is checked here, so a bad argument fails before any work is done.

use std::path::{Path, PathBuf};

use stereo_chart::Format as ChartFormat;
use stereo_degrade::Degradation;
use stereo_pipeline::{DisparityRange, MatcherOptions, OptionError};
use stereo_triangulation::design::{Design, DesignError, DesignInput, Param, SensorWidth, TableSpec};
use stereo_triangulation::Rig;

use stereo_io::Calib;

use crate::args::{
    BatchArgs, BatchMergeArgs, CalcArgs, DegradeArgs, DepthLimitArgs, EvalArgs, EvalFolderArgs, MatchArgs,
    PairArgs, PreviewOfArg, RigArgs,
};
use crate::checks::{self, BaselineSource};
use crate::discover::{Pattern, Shard};
use crate::error::UsageError;

/// The rig as the user gave it (datasheet units), kept for the report. The focal length and
/// pixel pitch are `None` when the focal length came in pixels (--focal-px or a Middlebury
/// `calib.txt`) without them.
#[derive(Clone, Debug)]
pub struct RigInput {
    pub baseline_mm: f64,
    pub focal_mm: Option<f64>,
    pub pixel_um: Option<f64>,
    pub sensor_width_mm: Option<f64>,
    /// Horizontal field of view `2·atan(w / 2f)`, with --sensor-width.
    pub horizontal_fov_deg: Option<f64>,
}

/// A resolved rig: what triangulates, and what the user gave.
#[derive(Clone, Debug)]
pub struct RigSetup {
    pub rig: Rig,
    pub input: RigInput,
}

/// How to give the focal length, for error messages.
const FOCAL_SOURCES: &str = "--focal and --pixel, --focal-px, or --calib";

/// The rig flags, each checked on its own; [`RigFlags::resolve`] completes them from a
/// Middlebury `calib.txt` (the flags take precedence) and builds the [`Rig`].
#[derive(Clone, Debug, Default)]
pub struct RigFlags {
    pub baseline_mm: Option<f64>,
    pub focal_mm: Option<f64>,
    pub pixel_um: Option<f64>,
    pub focal_px: Option<f64>,
    pub doffs: Option<f64>,
    pub principal_point: Option<(f64, f64)>,
    pub sensor_width_mm: Option<f64>,
    /// The --calib file, read.
    pub calib: Option<Calib>,
    /// Its path, for messages.
    pub calib_path: Option<PathBuf>,
    /// The --calib file when it is a raw (OpenCV/ROS) calibration: pairs are rectified first.
    pub raw: Option<std::sync::Arc<crate::rectify_cmd::RawCalib>>,
}

impl RigFlags {
    /// Checks the flags and reads the --calib file (a file that cannot be read or parsed is a
    /// runtime error, exit status 1; conflicting flags are usage errors).
    pub fn from_args(args: &RigArgs) -> anyhow::Result<Self> {
        let mut flags = RigFlags::check(args)?;
        if let Some(path) = &args.calib {
            match crate::rectify_cmd::read_calib_flag(path, args.alpha)? {
                crate::rectify_cmd::CalibFlag::Middlebury(calib) => flags.calib = Some(calib),
                crate::rectify_cmd::CalibFlag::Raw(raw) => flags.raw = Some(raw),
            }
            flags.calib_path = Some(path.clone());
        }
        Ok(flags)
    }

    /// Everything but reading the --calib file.
    fn check(args: &RigArgs) -> Result<Self, UsageError> {
        let principal_point = match (args.cx, args.cy) {
            (Some(cx), Some(cy)) => Some((cx, cy)),
            (None, None) => None,
            _ => return Err(usage!("--cx and --cy must be given together")),
        };
        let focal_from = |flag: &str| {
            usage!(
                "conflicting focal lengths: {flag} and --focal-px both give it; give one of {FOCAL_SOURCES}"
            )
        };
        if args.focal_px.is_some() && args.focal.is_some() {
            return Err(focal_from("--focal"));
        }
        if args.calib.is_some() {
            for (given, flag) in [(args.focal.is_some(), "--focal"), (args.focal_px.is_some(), "--focal-px")]
            {
                if given {
                    return Err(usage!(
                        "conflicting focal lengths: {flag} and --calib (its cam0 matrix) both give it; \
                         give one of {FOCAL_SOURCES}"
                    ));
                }
            }
        }
        let flags = RigFlags {
            baseline_mm: args.baseline,
            focal_mm: args.focal,
            pixel_um: args.pixel,
            focal_px: args.focal_px,
            doffs: args.doffs,
            principal_point,
            sensor_width_mm: args.sensor_width,
            calib: None,
            calib_path: None,
            raw: None,
        };
        // Every value given is checked now, with stand-ins for the others.
        let rig = Rig::from_datasheet(
            flags.baseline_mm.unwrap_or(1.0),
            flags.focal_mm.unwrap_or(1.0),
            flags.pixel_um.unwrap_or(1.0),
        )
        .and_then(|rig| rig.with_doffs(flags.doffs.unwrap_or(0.0)))
        .map_err(rig_error)?;
        if let Some(px) = flags.focal_px {
            Rig::from_focal_px(1.0, px)
                .map_err(|_| usage!("invalid --focal-px {px} px (must be a finite number > 0 px)"))?;
        }
        if let Some((cx, cy)) = principal_point {
            rig.with_principal_point(cx, cy).map_err(rig_error)?;
        }
        if let Some(w) = flags.sensor_width_mm {
            if !(w.is_finite() && w > 0.0) {
                return Err(usage!("invalid --sensor-width {w} mm (must be a finite number > 0 mm)"));
            }
        }
        Ok(flags)
    }

    /// Unit-mistake warnings for the rig flags and the --calib file (see [`checks::rig_warnings`]).
    pub fn warnings(&self) -> Vec<String> {
        let baseline = match (self.baseline_mm, &self.calib, &self.calib_path) {
            (Some(mm), ..) => Some((mm, BaselineSource::Flag)),
            (None, Some(calib), Some(path)) => calib.baseline_mm.map(|mm| (mm, BaselineSource::Calib(path))),
            _ => None,
        };
        let mut warnings = checks::rig_warnings(baseline, self.pixel_um);
        // The unit of an OpenCV calibration's T is a guess unless --baseline overrides it.
        if let (Some(raw), None) = (&self.raw, self.baseline_mm) {
            warnings.extend(raw.unit_warning());
        }
        warnings
    }

    /// Whether any flag that describes the rig was given.
    pub fn any(&self) -> bool {
        self.baseline_mm.is_some()
            || self.focal_mm.is_some()
            || self.pixel_um.is_some()
            || self.focal_px.is_some()
            || self.doffs.is_some()
            || self.principal_point.is_some()
            || self.sensor_width_mm.is_some()
            || self.calib.is_some()
            || self.raw.is_some()
    }

    /// Whether the flags (with --calib) alone define the rig (no calib.txt needed).
    pub fn is_complete(&self) -> bool {
        self.raw.is_some() || self.resolve(None).is_ok()
    }

    /// The calibration in force for a pair: --calib, else the pair's own calib.txt.
    pub fn calib<'a>(&'a self, found: Option<&'a Calib>) -> Option<&'a Calib> {
        self.calib.as_ref().or(found)
    }

    /// The rig from the flags, with whatever they leave open taken from the calibration in force
    /// ([`RigFlags::calib`]). An incomplete rig is an error naming every missing flag.
    pub fn resolve(&self, found: Option<&Calib>) -> Result<RigSetup, UsageError> {
        let calib = self.calib(found);
        let mut missing = Vec::new();
        let baseline_mm = self.baseline_mm.or(calib.and_then(|c| c.baseline_mm));
        if baseline_mm.is_none() {
            missing.push(if calib.is_some() { "--baseline (the calib.txt has none)" } else { "--baseline" });
        }
        let focal_px = match (self.focal_mm, self.pixel_um, self.focal_px, calib) {
            (Some(focal), Some(pixel), _, _) => Some(focal * 1000.0 / pixel),
            (Some(_), None, _, _) => {
                missing.push("--pixel (to turn --focal into pixels)");
                None
            }
            (None, _, Some(px), _) => Some(px),
            (None, _, None, Some(calib)) => Some(calib.focal_px),
            (None, _, None, None) => {
                missing.push("the focal length (--focal and --pixel, --focal-px, or --calib)");
                None
            }
        };
        let (Some(baseline_mm), Some(focal_px)) = (baseline_mm, focal_px) else {
            return Err(usage!("incomplete rig: missing {}", missing.join(" and ")));
        };
        let rig = match (self.focal_mm, self.pixel_um) {
            (Some(focal), Some(pixel)) => {
                Rig::from_datasheet(baseline_mm, focal, pixel).map_err(rig_error)?
            }
            _ => Rig::from_focal_px(baseline_mm, focal_px).map_err(|err| match calib {
                Some(_) if self.focal_px.is_none() => match (&self.calib, &self.calib_path) {
                    (Some(_), Some(path)) => usage!("{}: {err}", path.display()),
                    _ => usage!("calib.txt: {err}"),
                },
                _ => rig_error(err),
            })?,
        };
        let doffs = self.doffs.or(calib.and_then(|c| c.doffs)).unwrap_or(0.0);
        let mut rig = rig.with_doffs(doffs).map_err(rig_error)?;
        if let Some((cx, cy)) = self.principal_point.or(calib.map(|c| (c.cx, c.cy))) {
            rig = rig.with_principal_point(cx, cy).map_err(rig_error)?;
        }
        // The focal length in mm, given or from the pixel pitch.
        let focal_mm = self.focal_mm.or(self.pixel_um.map(|p| rig.focal_px * p / 1000.0));
        let horizontal_fov_deg = match self.sensor_width_mm {
            Some(w) => {
                let f = focal_mm.ok_or_else(|| {
                    usage!(
                        "--sensor-width needs the focal length in mm: give --focal and --pixel, or --pixel \
                         with --focal-px or --calib"
                    )
                })?;
                Some(stereo_triangulation::design::horizontal_fov_deg(w, f))
            }
            None => None,
        };
        let input = RigInput {
            baseline_mm,
            focal_mm,
            pixel_um: self.pixel_um,
            sensor_width_mm: self.sensor_width_mm,
            horizontal_fov_deg,
        };
        Ok(RigSetup { rig, input })
    }
}

/// The matcher flags, checked: the matcher and the disparity search bounds.
#[derive(Clone, Debug)]
pub struct MatchSettings {
    pub min_disparity: i32,
    /// `None`: [`DisparityRange::default_for_width`].
    pub max_disparity: Option<i32>,
    /// The range is filled in once the width is known.
    pub matcher: Matcher,
    pub limits: Limits,
    pub extras: MatchExtras,
}

/// What the matcher adds to its disparity map: `--min-confidence`, and the extra EXR channels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MatchExtras {
    /// Pixels below this confidence are invalidated.
    pub min_confidence: Option<f32>,
    /// The EXR carries a `confidence` channel.
    pub confidence_channel: bool,
    /// The EXR carries a `disparity` channel.
    pub disparity_channel: bool,
}

/// Refusal limits, checked before an image is decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// `--max-pixels`: largest image, pixels.
    pub max_pixels: u64,
    /// `--max-memory`: working memory of one pair, bytes; `None` = what the system has available.
    pub max_memory: Option<u64>,
}

impl Default for Limits {
    fn default() -> Self {
        Limits { max_pixels: stereo_io::DEFAULT_MAX_PIXELS, max_memory: None }
    }
}

impl Limits {
    fn from_args(args: &MatchArgs) -> Self {
        Limits {
            max_pixels: args.max_pixels.unwrap_or(stereo_io::DEFAULT_MAX_PIXELS),
            max_memory: args.max_memory,
        }
    }
}

impl MatchSettings {
    pub fn from_args(args: &MatchArgs) -> Result<Self, UsageError> {
        let matcher = matcher(args)?;
        if let Some(max) = args.max_disparity {
            if max <= args.min_disparity {
                return Err(usage!(
                    "empty disparity range: --min-disparity {} must be below --max-disparity {max} \
                     (the search is min <= d < max)",
                    args.min_disparity
                ));
            }
        }
        Ok(MatchSettings {
            min_disparity: args.min_disparity,
            max_disparity: args.max_disparity,
            matcher,
            limits: Limits::from_args(args),
            extras: MatchExtras {
                min_confidence: args.min_confidence,
                confidence_channel: args.confidence,
                disparity_channel: args.exr_disparity,
            },
        })
    }
}

pub use stereo_pipeline::Matcher;
use stereo_pipeline::{DepthLimits, PipelineParams};

/// What a preview shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PreviewOf {
    Depth,
    Disparity,
}

/// The pair command, checked.
#[derive(Clone, Debug)]
pub struct PairConfig {
    pub left: PathBuf,
    pub right: PathBuf,
    /// `None`: disparity-only mode (no rig flag given).
    pub rig: Option<RigSetup>,
    pub min_disparity: i32,
    /// `None`: [`DisparityRange::default_for_width`].
    pub max_disparity: Option<i32>,
    /// The range is filled in by [`PairConfig::resolve_range`] once the width is known.
    pub matcher: Matcher,
    /// The depth EXR (always, with a rig).
    pub output: Option<PathBuf>,
    pub disparity: Option<PathBuf>,
    pub stats: Option<PathBuf>,
    pub points: Option<PathBuf>,
    pub points_step: usize,
    pub preview: Option<PathBuf>,
    pub preview_of: PreviewOf,
    pub depth_png: Option<PathBuf>,
    pub disparity_png: Option<PathBuf>,
    pub quiet: bool,
    /// The image size the rig was calibrated for (a Middlebury calib.txt's width and height),
    /// checked against the images before matching.
    pub expected_size: Option<(usize, usize)>,
    pub limits: Limits,
    pub extras: MatchExtras,
    /// `--min-depth`/`--max-depth` (only with a rig).
    pub depth_limits: Option<DepthLimits>,
    /// Compensate a measured vertical misalignment of the right view before matching.
    pub align: bool,
    /// Rectify the raw pair first (a raw --calib).
    pub rectify: Option<std::sync::Arc<stereo_rectify::Rectifier>>,
}

impl PairConfig {
    pub fn from_args(args: PairArgs) -> anyhow::Result<Self> {
        let mut flags = RigFlags::from_args(&args.rig)?;
        // A raw calibration: rectified for the images' size, the rig is the rectified one.
        let rectify = match (&flags.raw, &args.left) {
            (Some(raw), Some(left)) => {
                let (calib, rectifier) = raw.calib_for(raw.size_for(left)?)?;
                flags.calib = Some(calib);
                Some(rectifier)
            }
            _ => None,
        };
        let warnings = flags.warnings();
        let mut config = PairConfig::from_flags(args, flags)?;
        config.rectify = rectify;
        // Only once the arguments are known to be valid: a usage error stays one line.
        checks::print_warnings(&warnings);
        Ok(config)
    }

    fn from_flags(args: PairArgs, flags: RigFlags) -> Result<Self, UsageError> {
        let matcher = matcher(&args.matching)?;
        // clap enforces these for the pair command; a missing one here is a programming error
        // in `args`, reported rather than unwrapped.
        let required = |name: &str| usage!("the pair command needs {name}");
        let left = args.left.ok_or_else(|| required("LEFT"))?;
        let right = args.right.ok_or_else(|| required("RIGHT"))?;
        let rig = if flags.any() { Some(flags.resolve(None)?) } else { None };
        let settings = MatchSettings::from_args(&args.matching)?;
        let depth_limits = depth_limits(&args.depth_limits)?;
        if let (Some(limits), None) = (&depth_limits, &rig) {
            return Err(usage!(
                "{} needs a rig: give --baseline and the focal length (--focal and --pixel, --focal-px, \
                 or --calib)",
                checks::depth_limits_flag(limits)
            ));
        }
        let preview_of = match args.preview_of {
            Some(PreviewOfArg::Disparity) => PreviewOf::Disparity,
            Some(PreviewOfArg::Depth) | None => PreviewOf::Depth,
        };

        let output = if rig.is_some() {
            Some(args.output.unwrap_or_else(|| default_output(&left)))
        } else {
            let give = "give --baseline and the focal length (--focal and --pixel, --focal-px, or --calib)";
            let depth_outputs = [
                (args.output.is_some(), "-o/--output (the depth EXR)", ""),
                (args.depth_png.is_some(), "--depth-png", ""),
                (args.points.is_some(), "--points", ""),
                (args.matching.confidence, "--confidence (a channel of the depth EXR)", ""),
                (args.matching.exr_disparity, "--exr-disparity (a channel of the depth EXR)", ""),
                (
                    args.preview.is_some() && preview_of == PreviewOf::Depth,
                    "--preview (of depth, the default)",
                    "; or add --preview-of disparity",
                ),
            ];
            if let Some((_, flag, hint)) = depth_outputs.iter().find(|(given, ..)| *given) {
                return Err(usage!("{flag} needs a rig: {give}{hint}"));
            }
            if args.disparity.is_none() && args.disparity_png.is_none() && args.preview.is_none() {
                return Err(usage!(
                    "nothing to write: for a depth map {give}; for the disparity alone give --disparity \
                     PATH.pfm, --disparity-png PATH.png or --preview PATH.png --preview-of disparity"
                ));
            }
            None
        };
        let calib = flags.calib.as_ref();
        let max_disparity = settings.max_disparity.or_else(|| {
            let ndisp = calib?.ndisp?;
            Some(i32::try_from(ndisp).unwrap_or(i32::MAX))
        });
        let config = PairConfig {
            left,
            right,
            rig,
            min_disparity: settings.min_disparity,
            max_disparity,
            matcher,
            output,
            disparity: args.disparity,
            stats: args.stats,
            points: args.points,
            points_step: args.points_step as usize,
            preview: args.preview,
            preview_of,
            depth_png: args.depth_png,
            disparity_png: args.disparity_png,
            quiet: args.quiet,
            expected_size: calib.and_then(|c| Some((c.width?, c.height?))),
            limits: settings.limits,
            extras: settings.extras,
            depth_limits,
            align: !args.no_align,
            rectify: None,
        };
        config.check_paths()?;
        Ok(config)
    }

    /// The pipeline's parameters, searching `range`.
    pub fn pipeline_params(&self, range: DisparityRange) -> PipelineParams {
        let mut matcher = self.matcher.clone();
        matcher.set_range(range);
        let mut params = PipelineParams::new(matcher);
        params.align = self.align;
        params.min_confidence = self.extras.min_confidence;
        params.rig = self.rig.as_ref().map(|setup| setup.rig.clone());
        params.depth_limits = self.depth_limits;
        params
    }

    /// The disparity range for an image `width` pixels wide, checked against the width.
    pub fn resolve_range(&self, width: usize) -> Result<DisparityRange, UsageError> {
        let max = self.max_disparity.unwrap_or_else(|| DisparityRange::default_for_width(width).max);
        let range = DisparityRange::new(self.min_disparity, max).map_err(|_| {
            usage!(
                "empty disparity range: --min-disparity {} must be below the maximum {max}{} \
                 (the search is min <= d < max)",
                self.min_disparity,
                if self.max_disparity.is_some() {
                    ""
                } else {
                    " (the default for this width; set --max-disparity)"
                }
            )
        })?;
        if range.count() > width {
            return Err(usage!(
                "disparity range {}..{} ({} disparities) is wider than the image ({width} px); \
                 lower --max-disparity",
                range.min,
                range.max,
                range.count()
            ));
        }
        Ok(range)
    }

    /// Every output, in the order they are written (the names are printed as `NAME: PATH`).
    pub fn outputs(&self) -> Vec<(&'static str, &Path)> {
        [
            ("depth", &self.output),
            ("disparity", &self.disparity),
            ("disparity-png", &self.disparity_png),
            ("depth-png", &self.depth_png),
            ("points", &self.points),
            ("preview", &self.preview),
            ("stats", &self.stats),
        ]
        .into_iter()
        .filter_map(|(what, path)| Some((what, path.as_deref()?)))
        .collect()
    }

    /// Outputs must not overwrite an input or each other.
    fn check_paths(&self) -> Result<(), UsageError> {
        let outputs = self.outputs();
        for (i, (what, path)) in outputs.iter().enumerate() {
            let this = absolute(path);
            for input in [&self.left, &self.right] {
                if this == absolute(input) {
                    return Err(usage!(
                        "the {what} output {} would overwrite the input image",
                        path.display()
                    ));
                }
            }
            for (other, other_path) in &outputs[..i] {
                if this == absolute(other_path) {
                    return Err(usage!(
                        "the {what} and {other} outputs are the same file {}",
                        path.display()
                    ));
                }
            }
        }
        Ok(())
    }
}

fn depth_limits(args: &DepthLimitArgs) -> Result<Option<DepthLimits>, UsageError> {
    checks::depth_limits(args.min_depth, args.max_depth)
}

/// `path` made absolute with `..`, `.` and symbolic links of its folder resolved (the folder
/// usually exists; the file itself may not yet), so two spellings of one file compare equal.
fn absolute(path: &Path) -> PathBuf {
    if let Ok(real) = std::fs::canonicalize(path) {
        return real;
    }
    let folder = match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    };
    match (std::fs::canonicalize(folder), path.file_name()) {
        (Ok(folder), Some(name)) => folder.join(name),
        _ => std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf()),
    }
}

/// `LEFTSTEM_depth.exr` in the current directory.
fn default_output(left: &Path) -> PathBuf {
    let stem = left.file_stem().map(|s| s.to_string_lossy().into_owned()).filter(|s| !s.is_empty());
    PathBuf::from(format!("{}_depth.exr", stem.as_deref().unwrap_or("left")))
}

/// The library names rig parameters in words; the user knows them by their flags.
fn rig_error(err: stereo_triangulation::Error) -> UsageError {
    let stereo_triangulation::Error::InvalidParameter { name, value, unit, expected } = &err;
    let flag = match *name {
        "baseline" => "--baseline",
        "focal length" => "--focal",
        "pixel size" => "--pixel",
        "disparity offset" => "--doffs",
        "principal point x" => "--cx",
        "principal point y" => "--cy",
        _ => return usage!("{err}"),
    };
    usage!("invalid {flag} {value} {unit} (must be {expected})")
}

/// The matcher and its parameters, resolved by the library ([`MatcherOptions::resolve`]) from
/// the flags; its errors name the flags.
fn matcher(args: &MatchArgs) -> Result<Matcher, UsageError> {
    let options = MatcherOptions {
        matcher: args.matcher,
        preset: args.preset,
        fill: args.fill,
        speckle_size: args.speckle_size,
        single_pass: args.single_pass,
        paths: args.paths,
        search: args.search,
        downscale: args.downscale,
        p1: args.p1,
        p2: args.p2,
        edge_snap: args.edge_snap,
        confidence: args.confidence,
        min_confidence: args.min_confidence,
        uniqueness: args.uniqueness,
        lr_max_diff: args.lr_max_diff,
        lr_check: !args.no_lr_check,
        subpixel: args.subpixel,
        block_size: args.block_size,
        bm_cost: args.bm_cost,
    };
    options.resolve().map_err(|err| {
        let flag = |option: &str| format!("--{}", option.replace('_', "-"));
        match err {
            OptionError::OtherMatcher { option, matcher } => {
                usage!("{} applies only to --matcher {matcher}", flag(option))
            }
            OptionError::Invalid { option, message } => usage!("{} {message}", flag(option)),
        }
    })
}

/// The batch command, checked (the folders are checked when it runs).
#[derive(Clone, Debug)]
pub struct BatchConfig {
    pub input: PathBuf,
    pub out: PathBuf,
    pub rig: RigFlags,
    pub matching: MatchSettings,
    pub disparity: bool,
    pub stats: bool,
    pub points: bool,
    pub points_step: usize,
    pub preview: bool,
    pub preview_of: PreviewOf,
    pub depth_png: bool,
    pub disparity_png: bool,
    pub overwrite: bool,
    pub quiet: bool,
    pub list: bool,
    pub pattern: Option<Pattern>,
    pub shard: Option<Shard>,
    /// Pairs in flight.
    pub jobs: usize,
    pub threads: Option<u16>,
    pub depth_limits: Option<DepthLimits>,
}

impl BatchConfig {
    pub fn from_args(args: BatchArgs) -> anyhow::Result<Self> {
        let matching = MatchSettings::from_args(&args.matching)?;
        let rig = RigFlags::from_args(&args.rig)?;
        if args.rig.focal.is_some() && args.rig.pixel.is_none() {
            return Err(usage!("--focal needs --pixel (or give --focal-px)").into());
        }
        let pattern = match &args.pattern {
            Some(text) => {
                Some(Pattern::parse(text).map_err(|err| usage!("invalid --pattern {text:?}: {err}"))?)
            }
            None => None,
        };
        let shard = match &args.shard {
            Some(text) => Some(Shard::parse(text).map_err(|err| usage!("invalid --shard {text:?}: {err}"))?),
            None => None,
        };
        let depth_limits = depth_limits(&args.depth_limits)?;
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let jobs = args.jobs.map_or(cores.min(2), usize::from);
        // The rig flags and --calib; the pairs' own calib.txt files are read as the pairs run.
        checks::print_warnings(&rig.warnings());
        Ok(BatchConfig {
            input: args.input,
            out: args.out,
            rig,
            matching,
            disparity: args.disparity,
            stats: args.stats,
            points: args.points,
            points_step: args.points_step as usize,
            preview: args.preview,
            preview_of: match args.preview_of {
                Some(PreviewOfArg::Disparity) => PreviewOf::Disparity,
                Some(PreviewOfArg::Depth) | None => PreviewOf::Depth,
            },
            depth_png: args.depth_png,
            disparity_png: args.disparity_png,
            overwrite: args.overwrite,
            quiet: args.quiet,
            list: args.list,
            pattern,
            shard,
            jobs,
            threads: args.threads,
            depth_limits,
        })
    }
}

/// The batch-merge command.
#[derive(Clone, Debug)]
pub struct BatchMergeConfig {
    pub out: PathBuf,
}

impl BatchMergeConfig {
    pub fn from_args(args: BatchMergeArgs) -> Result<Self, UsageError> {
        Ok(BatchMergeConfig { out: args.out })
    }
}

/// The eval command, checked.
#[derive(Clone, Debug)]
pub struct EvalConfig {
    pub est: PathBuf,
    pub gt: PathBuf,
    pub gt_scale: f32,
    /// Whether --gt-scale was given (an 8-bit ground truth without it is warned about).
    pub gt_scale_given: bool,
    pub json: bool,
}

impl EvalConfig {
    pub fn from_args(args: EvalArgs) -> Result<Self, UsageError> {
        let gt_scale = args.gt_scale.unwrap_or(1.0);
        if !(gt_scale.is_finite() && gt_scale > 0.0) {
            return Err(usage!("--gt-scale must be a positive number, got {gt_scale}"));
        }
        Ok(EvalConfig {
            est: args.est,
            gt: args.gt,
            gt_scale,
            gt_scale_given: args.gt_scale.is_some(),
            json: args.json,
        })
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;
    use crate::args::Cli;
    use stereo_pipeline::{BmParams, PathCount, SgmParams, Subpixel};

    fn pair(args: &[&str]) -> Result<PairConfig, UsageError> {
        let mut all = vec!["stereo-depth", "in/left.png", "in/right.png"];
        all.extend(["--baseline", "80", "--focal", "12", "--pixel", "4"]);
        all.extend(args);
        bare(&all)
    }

    /// The pair command's config from the whole command line (no --calib: nothing is read).
    fn bare(all: &[&str]) -> Result<PairConfig, UsageError> {
        let args = Cli::try_parse_from(all).unwrap().pair;
        let flags = RigFlags::check(&args.rig)?;
        PairConfig::from_flags(args, flags)
    }

    #[test]
    fn defaults_come_from_the_libraries() {
        let config = pair(&[]).unwrap();
        assert_eq!(config.output, Some(PathBuf::from("left_depth.exr")));
        assert_eq!(config.rig.as_ref().unwrap().rig.focal_px, 3000.0);
        match &config.matcher {
            Matcher::Sgm(params) => assert_eq!(*params, SgmParams::default()),
            other => panic!("{other:?}"),
        }
        assert_eq!(config.resolve_range(288).unwrap(), DisparityRange::default_for_width(288));
        assert_eq!(config.resolve_range(288).unwrap(), DisparityRange { min: 0, max: 80 });
    }

    #[test]
    fn ranges_are_checked_against_the_width() {
        let config = pair(&["--min-disparity", "8", "--max-disparity", "72"]).unwrap();
        assert_eq!(config.resolve_range(64).unwrap(), DisparityRange { min: 8, max: 72 });
        assert!(config.resolve_range(63).unwrap_err().0.contains("wider than the image"));
        // The default maximum for a 64 px image is 16: a minimum of 16 leaves nothing.
        let config = pair(&["--min-disparity", "16"]).unwrap();
        assert!(config.resolve_range(64).unwrap_err().0.contains("empty disparity range"));
        assert!(pair(&["--max-disparity", "0"]).is_err());
    }

    #[test]
    fn matcher_options_are_resolved() {
        let config = pair(&["--matcher", "bm", "--block-size", "7", "--no-lr-check"]).unwrap();
        match &config.matcher {
            Matcher::Bm(params) => {
                assert_eq!((params.block_size, params.lr_max_diff), (7, None));
                assert_eq!(params.cost, BmParams::default().cost);
            }
            other => panic!("{other:?}"),
        }
        assert!(pair(&["--matcher", "bm", "--block-size", "8"]).is_err());
        let config = pair(&["--paths", "4", "--p1", "5", "--subpixel", "none"]).unwrap();
        match &config.matcher {
            Matcher::Sgm(p) => assert_eq!((p.paths, p.p1, p.subpixel), (PathCount::Four, 5, Subpixel::None)),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn rig_errors_name_the_flag() {
        let err =
            bare(&["x", "l.png", "r.png", "--baseline", "80", "--focal", "0", "--pixel", "4"]).unwrap_err();
        assert_eq!(err.0, "invalid --focal 0 mm (must be a finite number > 0 mm)");
        assert!(pair(&["--cx", "1", "--cy", "inf"]).unwrap_err().0.contains("--cy"));
    }

    #[test]
    fn rig_sources_conflict_or_complete() {
        let base = ["x", "l.png", "r.png"];
        let with = |extra: &[&str]| {
            let mut all = base.to_vec();
            all.extend(extra);
            bare(&all)
        };
        let err = with(&["--baseline", "80", "--focal", "12", "--focal-px", "3000"]).unwrap_err().0;
        assert!(err.contains("--focal") && err.contains("--focal-px"), "{err}");
        let err = with(&["--baseline", "80", "--disparity", "d.pfm"]).unwrap_err().0;
        assert!(err.starts_with("incomplete rig: missing the focal length"), "{err}");
        let err = with(&["--focal", "12", "--disparity", "d.pfm"]).unwrap_err().0;
        assert!(err.contains("--baseline") && err.contains("--pixel"), "{err}");
        let config = with(&["--baseline", "80", "--focal-px", "3000"]).unwrap();
        let setup = config.rig.unwrap();
        assert_eq!(setup.rig.focal_px, 3000.0);
        assert_eq!(setup.input.focal_mm, None);
        // --pixel with --focal-px gives the focal length in mm, and so the field of view.
        let config =
            with(&["--baseline", "80", "--focal-px", "3000", "--pixel", "4", "--sensor-width", "8"]).unwrap();
        let input = config.rig.unwrap().input;
        assert_eq!(input.focal_mm, Some(12.0));
        let fov = input.horizontal_fov_deg.unwrap();
        assert!((fov - 2.0 * (8.0f64 / 24.0).atan().to_degrees()).abs() < 1e-9, "{fov}");
        let err = with(&["--baseline", "80", "--focal-px", "3000", "--sensor-width", "8"]).unwrap_err().0;
        assert!(err.contains("--sensor-width"), "{err}");
    }

    #[test]
    fn disparity_only_mode() {
        let config = bare(&["x", "l.png", "r.png", "--disparity", "d.pfm"]).unwrap();
        assert!(config.rig.is_none() && config.output.is_none());
        let names: Vec<&str> = config.outputs().iter().map(|(what, _)| *what).collect();
        assert_eq!(names, ["disparity"]);
        for (flag, value) in
            [("-o", "z.exr"), ("--depth-png", "z.png"), ("--points", "p.ply"), ("--preview", "p.png")]
        {
            let err = bare(&["x", "l.png", "r.png", "--disparity", "d.pfm", flag, value]).unwrap_err().0;
            assert!(err.contains("needs a rig") && err.contains("--baseline"), "{err}");
        }
        assert!(bare(&["x", "l.png", "r.png", "--preview", "p.png", "--preview-of", "disparity"]).is_ok());
        let err = bare(&["x", "l.png", "r.png", "--stats", "s.json"]).unwrap_err().0;
        assert!(err.starts_with("nothing to write") && err.contains("--disparity"), "{err}");
    }
}

/// The checked settings of `calc`: the design (every number in range), the chart to draw.
#[derive(Debug)]
pub struct CalcConfig {
    pub design: Design,
    /// The chart's path and format (by its extension).
    pub chart: Option<(PathBuf, ChartFormat)>,
    pub json: bool,
    /// Unit-mistake warnings for the rig, printed once the arguments are known to be valid.
    pub warnings: Vec<String>,
}

impl CalcConfig {
    pub fn from_args(args: CalcArgs) -> Result<Self, UsageError> {
        let chart = match &args.chart {
            None => None,
            Some(path) => Some((
                path.clone(),
                ChartFormat::from_path(path)
                    .ok_or_else(|| usage!("invalid --chart {} (must end in .png or .svg)", path.display()))?,
            )),
        };
        let design = Design::new(&design_input(&args)).map_err(design_usage)?;
        let warnings = checks::rig_warnings(Some((args.baseline, BaselineSource::Flag)), Some(args.pixel));
        Ok(CalcConfig { design, chart, json: args.json, warnings })
    }
}

fn design_input(args: &CalcArgs) -> DesignInput {
    let sensor = match (args.sensor_width, args.width_px) {
        (Some(mm), _) => Some(SensorWidth::Mm(mm)),
        (None, Some(px)) => Some(SensorWidth::Px(px)),
        (None, None) => None,
    };
    let table = (args.table
        || args.table_min.is_some()
        || args.table_max.is_some()
        || args.table_step.is_some())
    .then_some(TableSpec { min_px: args.table_min, max_px: args.table_max, step_px: args.table_step });
    DesignInput {
        baseline_mm: args.baseline,
        focal_mm: args.focal,
        pixel_um: args.pixel,
        doffs_px: args.doffs,
        subpixel_step_px: args.subpixel,
        sensor,
        max_disparity_px: args.max_disparity,
        disparity_px: args.disparity,
        distance_m: args.distance,
        table,
    }
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

/// The library names parameters in words; the user knows them by their flags.
fn design_usage(err: DesignError) -> UsageError {
    let flag = match err.param {
        Param::Baseline => "--baseline",
        Param::Focal => "--focal",
        Param::Pixel => "--pixel",
        Param::Doffs => "--doffs",
        Param::SubpixelStep => "--subpixel",
        Param::SensorWidth => "--sensor-width",
        Param::WidthPx => "--width-px",
        Param::MaxDisparity => "--max-disparity",
        Param::Disparity => "--disparity",
        Param::Distance => "--distance",
        Param::TableMin => "--table-min",
        Param::TableMax => "--table-max",
        Param::TableStep => "--table-step",
    };
    UsageError(format!("invalid {flag} {} {} (must be {})", err.value, err.unit, err.expected))
}

/// The checked settings of `eval-folder`.
#[derive(Debug)]
pub struct EvalFolderConfig {
    pub dir: PathBuf,
    pub settings: MatchSettings,
    pub json: bool,
}

impl EvalFolderConfig {
    pub fn from_args(args: EvalFolderArgs) -> Result<Self, UsageError> {
        let settings = MatchSettings::from_args(&args.matching)?;
        Ok(EvalFolderConfig { dir: args.dir, settings, json: args.json })
    }
}
