//! Checked, resolved settings built from the raw command line. Everything that can be checked
//! without reading the images is checked here, so a bad argument fails before any work is done.

use std::fmt;
use std::path::{Path, PathBuf};

use stereo_disparity::{BmCost, BmParams, DisparityRange, PathCount, SgmParams, Subpixel};
use stereo_triangulation::Rig;

use crate::args::{BmCostArg, EvalArgs, MatcherArg, PairArgs, PathsArg, SubpixelArg};

/// An invalid argument: reported like clap's own errors, with exit status 2.
#[derive(Debug)]
pub struct UsageError(pub String);

impl fmt::Display for UsageError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for UsageError {}

macro_rules! usage {
    ($($arg:tt)*) => {
        UsageError(format!($($arg)*))
    };
}

/// The rig as the user gave it (datasheet units), kept for the report.
#[derive(Clone, Debug)]
pub struct RigInput {
    pub baseline_mm: f64,
    pub focal_mm: f64,
    pub pixel_um: f64,
}

/// Which matcher runs, with every parameter except the disparity range resolved.
#[derive(Clone, Debug)]
pub enum Matcher {
    Sgm(SgmParams),
    Bm(BmParams),
}

impl Matcher {
    pub fn name(&self) -> &'static str {
        match self {
            Matcher::Sgm(_) => "sgm",
            Matcher::Bm(_) => "bm",
        }
    }

    pub fn set_range(&mut self, range: DisparityRange) {
        match self {
            Matcher::Sgm(p) => p.range = range,
            Matcher::Bm(p) => p.range = range,
        }
    }
}

/// The pair command, checked.
#[derive(Clone, Debug)]
pub struct PairConfig {
    pub left: PathBuf,
    pub right: PathBuf,
    pub rig_input: RigInput,
    pub rig: Rig,
    pub min_disparity: i32,
    /// `None`: [`DisparityRange::default_for_width`].
    pub max_disparity: Option<i32>,
    /// The range is filled in by [`PairConfig::resolve_range`] once the width is known.
    pub matcher: Matcher,
    pub output: PathBuf,
    pub disparity: Option<PathBuf>,
    pub stats: Option<PathBuf>,
    pub quiet: bool,
}

impl PairConfig {
    pub fn from_args(args: PairArgs) -> Result<Self, UsageError> {
        let matcher = matcher(&args)?;
        // clap enforces these for the pair command; a missing one here is a programming error
        // in `args`, reported rather than unwrapped.
        let required = |name: &str| usage!("the pair command needs {name}");
        let left = args.left.ok_or_else(|| required("LEFT"))?;
        let right = args.right.ok_or_else(|| required("RIGHT"))?;
        let baseline_mm = args.baseline.ok_or_else(|| required("--baseline"))?;
        let focal_mm = args.focal.ok_or_else(|| required("--focal"))?;
        let pixel_um = args.pixel.ok_or_else(|| required("--pixel"))?;
        let mut rig = Rig::from_datasheet(baseline_mm, focal_mm, pixel_um)
            .and_then(|rig| rig.with_doffs(args.doffs))
            .map_err(rig_error)?;
        match (args.cx, args.cy) {
            (Some(cx), Some(cy)) => rig = rig.with_principal_point(cx, cy).map_err(rig_error)?,
            (None, None) => {}
            _ => return Err(usage!("--cx and --cy must be given together")),
        }

        if let Some(max) = args.max_disparity {
            if max <= args.min_disparity {
                return Err(usage!(
                    "empty disparity range: --min-disparity {} must be below --max-disparity {max} \
                     (the search is min <= d < max)",
                    args.min_disparity
                ));
            }
        }

        let output = match args.output {
            Some(path) => path,
            None => default_output(&left),
        };
        let config = PairConfig {
            left,
            right,
            rig_input: RigInput { baseline_mm, focal_mm, pixel_um },
            rig,
            min_disparity: args.min_disparity,
            max_disparity: args.max_disparity,
            matcher,
            output,
            disparity: args.disparity,
            stats: args.stats,
            quiet: args.quiet,
        };
        config.check_paths()?;
        Ok(config)
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

    /// Every output, in the order they are written.
    pub fn outputs(&self) -> Vec<(&'static str, &Path)> {
        let mut outputs = vec![("depth", self.output.as_path())];
        if let Some(path) = &self.disparity {
            outputs.push(("disparity", path));
        }
        if let Some(path) = &self.stats {
            outputs.push(("stats", path));
        }
        outputs
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

fn absolute(path: &Path) -> PathBuf {
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf())
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

fn subpixel(arg: SubpixelArg) -> Subpixel {
    match arg {
        SubpixelArg::None => Subpixel::None,
        SubpixelArg::Parabola => Subpixel::Parabola,
        SubpixelArg::Equiangular => Subpixel::Equiangular,
    }
}

fn lr_max_diff(args: &PairArgs, default: Option<f32>) -> Result<Option<f32>, UsageError> {
    if args.no_lr_check {
        return Ok(None);
    }
    match args.lr_max_diff {
        Some(diff) if !(diff.is_finite() && diff >= 0.0) => {
            Err(usage!("--lr-max-diff must be a non-negative number of pixels, got {diff}"))
        }
        Some(diff) => Ok(Some(diff)),
        None => Ok(default),
    }
}

/// The matcher and its parameters; options of the other matcher are rejected, not ignored.
fn matcher(args: &PairArgs) -> Result<Matcher, UsageError> {
    let reject = |given: bool, flag: &str, matcher: &str| {
        if given {
            Err(usage!("{flag} applies only to --matcher {matcher}"))
        } else {
            Ok(())
        }
    };
    match args.matcher {
        MatcherArg::Sgm => {
            reject(args.block_size.is_some(), "--block-size", "bm")?;
            reject(args.bm_cost.is_some(), "--bm-cost", "bm")?;
            let defaults = SgmParams::default();
            let params = SgmParams {
                paths: match args.paths {
                    Some(PathsArg::Four) => PathCount::Four,
                    Some(PathsArg::Eight) => PathCount::Eight,
                    None => defaults.paths,
                },
                p1: args.p1.unwrap_or(defaults.p1),
                p2: args.p2.unwrap_or(defaults.p2),
                uniqueness_ratio: args.uniqueness.unwrap_or(defaults.uniqueness_ratio),
                lr_max_diff: lr_max_diff(args, defaults.lr_max_diff)?,
                subpixel: args.subpixel.map(subpixel).unwrap_or(defaults.subpixel),
                ..defaults
            };
            Ok(Matcher::Sgm(params))
        }
        MatcherArg::Bm => {
            reject(args.paths.is_some(), "--paths", "sgm")?;
            reject(args.p1.is_some(), "--p1", "sgm")?;
            reject(args.p2.is_some(), "--p2", "sgm")?;
            let defaults = BmParams::default();
            let block_size = args.block_size.unwrap_or(defaults.block_size);
            if block_size < 3 || block_size % 2 == 0 {
                return Err(usage!("--block-size must be odd and at least 3, got {block_size}"));
            }
            let params = BmParams {
                block_size,
                cost: match args.bm_cost {
                    Some(BmCostArg::Sad) => BmCost::Sad,
                    Some(BmCostArg::Census) => BmCost::Census,
                    None => defaults.cost,
                },
                uniqueness_ratio: args.uniqueness.unwrap_or(defaults.uniqueness_ratio),
                lr_max_diff: lr_max_diff(args, defaults.lr_max_diff)?,
                subpixel: args.subpixel.map(subpixel).unwrap_or(defaults.subpixel),
                ..defaults
            };
            Ok(Matcher::Bm(params))
        }
    }
}

/// The eval command, checked.
#[derive(Clone, Debug)]
pub struct EvalConfig {
    pub est: PathBuf,
    pub gt: PathBuf,
    pub gt_scale: f32,
    pub json: bool,
}

impl EvalConfig {
    pub fn from_args(args: EvalArgs) -> Result<Self, UsageError> {
        if !(args.gt_scale.is_finite() && args.gt_scale > 0.0) {
            return Err(usage!("--gt-scale must be a positive number, got {}", args.gt_scale));
        }
        Ok(EvalConfig { est: args.est, gt: args.gt, gt_scale: args.gt_scale, json: args.json })
    }
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use super::*;
    use crate::args::Cli;

    fn pair(args: &[&str]) -> Result<PairConfig, UsageError> {
        let mut all = vec!["stereo-depth", "in/left.png", "in/right.png"];
        all.extend(["--baseline", "80", "--focal", "12", "--pixel", "4"]);
        all.extend(args);
        PairConfig::from_args(Cli::try_parse_from(all).unwrap().pair)
    }

    #[test]
    fn defaults_come_from_the_libraries() {
        let config = pair(&[]).unwrap();
        assert_eq!(config.output, PathBuf::from("left_depth.exr"));
        assert_eq!(config.rig.focal_px, 3000.0);
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
        let err = PairConfig::from_args(
            Cli::try_parse_from(["x", "l.png", "r.png", "--baseline", "80", "--focal", "0", "--pixel", "4"])
                .unwrap()
                .pair,
        )
        .unwrap_err();
        assert_eq!(err.0, "invalid --focal 0 mm (must be a finite number > 0 mm)");
        assert!(pair(&["--cx", "1", "--cy", "inf"]).unwrap_err().0.contains("--cy"));
    }
}
