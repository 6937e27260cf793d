//! The matcher options as a user gives them (a preset, `fill`, then single overrides), resolved
//! to [`Matcher`] parameters in one place: the command line and the Python package both call
//! [`MatcherOptions::resolve`], so the same options give the same parameters everywhere.

use stereo_disparity::{BmCost, BmParams, Downscale, PathCount, Preset, Search, SgmParams, Subpixel};

use crate::{Matcher, MatcherKind};

/// What a front end collects: the matcher, a preset, and the options that override single
/// parameters of it (`None`: the preset's value). The disparity range is set apart
/// ([`Matcher::set_range`]) once the image width is known.
#[derive(Clone, Debug, PartialEq)]
pub struct MatcherOptions {
    pub matcher: MatcherKind,
    /// SGM: the preset the other options override.
    pub preset: Preset,
    /// SGM: a dense map ([`SgmParams::with_fill`]).
    pub fill: bool,
    pub speckle_size: Option<usize>,
    pub single_pass: bool,
    pub paths: Option<PathCount>,
    /// SGM: the full or the coarse-to-fine search ([`Search`]).
    pub search: Option<Search>,
    /// SGM: match the pair reduced ([`SgmParams::downscale`]).
    pub downscale: Option<Downscale>,
    pub p1: Option<u16>,
    pub p2: Option<u16>,
    pub edge_snap: Option<usize>,
    /// SGM: compute the per-pixel confidence.
    pub confidence: bool,
    /// SGM: invalidate pixels below this confidence (turns `confidence` on).
    pub min_confidence: Option<f32>,
    pub uniqueness: Option<u32>,
    /// The left-right tolerance (px); with `lr_check` false there is no check.
    pub lr_max_diff: Option<f32>,
    pub lr_check: bool,
    pub subpixel: Option<Subpixel>,
    /// BM: the window side (odd).
    pub block_size: Option<usize>,
    pub bm_cost: Option<BmCost>,
}

/// An option that cannot be used as given. `option` is the option's name in words with
/// underscores (`"block_size"`); front ends spell it their way (`--block-size`).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum OptionError {
    /// The option belongs to the other matcher.
    #[error("{option} applies only to matcher {matcher}")]
    OtherMatcher { option: &'static str, matcher: MatcherKind },
    /// The value is out of range; `message` follows the option's name ("must be ...").
    #[error("{option} {message}")]
    Invalid { option: &'static str, message: String },
}

impl Default for MatcherOptions {
    /// The command line's defaults: SGM, balanced, left-right check on, nothing overridden.
    fn default() -> Self {
        MatcherOptions {
            matcher: MatcherKind::Sgm,
            preset: Preset::Balanced,
            fill: false,
            speckle_size: None,
            single_pass: false,
            paths: None,
            search: None,
            downscale: None,
            p1: None,
            p2: None,
            edge_snap: None,
            confidence: false,
            min_confidence: None,
            uniqueness: None,
            lr_max_diff: None,
            lr_check: true,
            subpixel: None,
            block_size: None,
            bm_cost: None,
        }
    }
}

impl MatcherOptions {
    /// The matcher's parameters: the preset's, then `fill`, then each option given. Options of the
    /// other matcher are rejected, not ignored.
    pub fn resolve(&self) -> Result<Matcher, OptionError> {
        let reject = |given: bool, option: &'static str, matcher: MatcherKind| match given {
            true => Err(OptionError::OtherMatcher { option, matcher }),
            false => Ok(()),
        };
        match self.matcher {
            MatcherKind::Sgm => {
                reject(self.block_size.is_some(), "block_size", MatcherKind::Bm)?;
                reject(self.bm_cost.is_some(), "bm_cost", MatcherKind::Bm)?;
                if let Some(t) = self.min_confidence {
                    if !(0.0..=1.0).contains(&t) {
                        let message = format!("{t} must be between 0 and 1");
                        return Err(OptionError::Invalid { option: "min_confidence", message });
                    }
                }
                let defaults = SgmParams::preset(self.preset);
                let defaults = SgmParams {
                    speckle_size: self.speckle_size.unwrap_or(defaults.speckle_size),
                    single_pass: self.single_pass || defaults.single_pass,
                    ..defaults
                };
                let defaults = if self.fill { defaults.with_fill() } else { defaults };
                let defaults =
                    SgmParams { confidence: self.confidence || self.min_confidence.is_some(), ..defaults };
                Ok(Matcher::Sgm(SgmParams {
                    paths: self.paths.unwrap_or(defaults.paths),
                    search: self.search.unwrap_or(defaults.search),
                    downscale: self.downscale(defaults.downscale)?,
                    p1: self.p1.unwrap_or(defaults.p1),
                    p2: self.p2.unwrap_or(defaults.p2),
                    uniqueness_ratio: self.uniqueness.unwrap_or(defaults.uniqueness_ratio),
                    lr_max_diff: self.lr_max_diff(defaults.lr_max_diff)?,
                    subpixel: self.subpixel.unwrap_or(defaults.subpixel),
                    edge_snap_radius: self.edge_snap.unwrap_or(defaults.edge_snap_radius),
                    ..defaults
                }))
            }
            MatcherKind::Bm => {
                let sgm = MatcherKind::Sgm;
                reject(self.paths.is_some(), "paths", sgm)?;
                reject(self.search.is_some(), "search", sgm)?;
                reject(self.downscale.is_some(), "downscale", sgm)?;
                reject(self.p1.is_some(), "p1", sgm)?;
                reject(self.p2.is_some(), "p2", sgm)?;
                reject(self.preset != Preset::Balanced, "preset", sgm)?;
                reject(self.fill, "fill", sgm)?;
                reject(self.speckle_size.is_some(), "speckle_size", sgm)?;
                reject(self.single_pass, "single_pass", sgm)?;
                reject(self.edge_snap.is_some(), "edge_snap", sgm)?;
                reject(self.confidence, "confidence", sgm)?;
                reject(self.min_confidence.is_some(), "min_confidence", sgm)?;
                let defaults = BmParams::default();
                let block_size = self.block_size.unwrap_or(defaults.block_size);
                if block_size < 3 || block_size.is_multiple_of(2) {
                    return Err(OptionError::Invalid {
                        option: "block_size",
                        message: format!("must be odd and at least 3, got {block_size}"),
                    });
                }
                Ok(Matcher::Bm(BmParams {
                    block_size,
                    cost: self.bm_cost.unwrap_or(defaults.cost),
                    uniqueness_ratio: self.uniqueness.unwrap_or(defaults.uniqueness_ratio),
                    lr_max_diff: self.lr_max_diff(defaults.lr_max_diff)?,
                    subpixel: self.subpixel.unwrap_or(defaults.subpixel),
                    ..defaults
                }))
            }
        }
    }

    fn downscale(&self, default: Downscale) -> Result<Downscale, OptionError> {
        match self.downscale {
            Some(Downscale::By(f)) if !(1..=stereo_disparity::MAX_DOWNSCALE).contains(&f) => {
                Err(OptionError::Invalid {
                    option: "downscale",
                    message: format!(
                        "must be auto, coarse or between 1 and {}, got {f}",
                        stereo_disparity::MAX_DOWNSCALE
                    ),
                })
            }
            Some(d) => Ok(d),
            None => Ok(default),
        }
    }

    fn lr_max_diff(&self, default: Option<f32>) -> Result<Option<f32>, OptionError> {
        if !self.lr_check {
            return Ok(None);
        }
        match self.lr_max_diff {
            Some(diff) if !(diff.is_finite() && diff >= 0.0) => Err(OptionError::Invalid {
                option: "lr_max_diff",
                message: format!("must be a non-negative number of pixels, got {diff}"),
            }),
            Some(diff) => Ok(Some(diff)),
            None => Ok(default),
        }
    }
}
