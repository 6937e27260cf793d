//! The plan: everything about a pair that is known before a pixel is decoded, computed once.

use stereo_disparity::{DisparityRange, SgmParams};
use stereo_rectify::Alignment;
use stereo_triangulation::Rig;

use crate::{DepthLimits, Error, Matcher};

/// What the pipeline does with a pair.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub struct PipelineParams {
    /// The matcher and its parameters, including the disparities searched.
    pub matcher: Matcher,
    /// Measure the pair's vertical alignment and resample the right view when it is off by 0.3 px
    /// or more (the measurement is reported either way).
    pub align: bool,
    /// The rig's alignment measured before, on an earlier pair of the same rig and size (a
    /// stream's first frame: [`crate::DepthResult::rectification`]): used in place of measuring
    /// this pair, which saves the check's 1–2.5 ms per pair. `None` measures every pair.
    pub known_alignment: Option<Alignment>,
    /// SGM: invalidate pixels whose confidence is below this (0–1). Needs
    /// [`SgmParams::confidence`].
    pub min_confidence: Option<f32>,
    /// The rig: with it the result has a depth map (metres).
    pub rig: Option<Rig>,
    /// Invalidate depths outside this interval (needs a rig).
    pub depth_limits: Option<DepthLimits>,
}

impl Default for PipelineParams {
    fn default() -> Self {
        PipelineParams {
            matcher: Matcher::Sgm(SgmParams::default()),
            align: true,
            known_alignment: None,
            min_confidence: None,
            rig: None,
            depth_limits: None,
        }
    }
}

impl PipelineParams {
    /// Default parameters for a matcher (the range is part of its parameters).
    pub fn new(matcher: Matcher) -> Self {
        PipelineParams { matcher, ..PipelineParams::default() }
    }

    /// Checks the parameters that do not depend on the image size.
    pub fn validate(&self) -> Result<(), Error> {
        match &self.matcher {
            Matcher::Sgm(params) => params.validate()?,
            Matcher::Bm(params) => params.validate()?,
        }
        if let Some(t) = self.min_confidence {
            if !(0.0..=1.0).contains(&t) {
                return Err(Error::InvalidParameter {
                    name: "min_confidence",
                    message: format!("{t} is outside 0..=1"),
                });
            }
            if !matches!(&self.matcher, Matcher::Sgm(p) if p.confidence) {
                return Err(Error::InvalidParameter {
                    name: "min_confidence",
                    message: "needs SGM with confidence enabled".into(),
                });
            }
        }
        if self.depth_limits.is_some() && self.rig.is_none() {
            return Err(Error::InvalidParameter { name: "depth_limits", message: "needs a rig".into() });
        }
        Ok(())
    }
}

/// A memory limit for one pair: `bytes` in all, of which `other_bytes` are taken by the caller
/// (decoded images, output buffers).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryLimit {
    pub bytes: u64,
    pub other_bytes: u64,
}

/// A pair's work, planned from its size before any pixel is read: sizes checked, the range
/// checked against the width, the matcher's memory planned (and bounded to a limit) once.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    pub(crate) params: PipelineParams,
    width: usize,
    height: usize,
    planned_matcher_bytes: u64,
}

impl Plan {
    /// Plans a pair whose views are `left` and `right` (`(width, height)`) pixels.
    pub fn new(params: &PipelineParams, left: (usize, usize), right: (usize, usize)) -> Result<Plan, Error> {
        Plan::with_memory_limit(params, left, right, None)
    }

    /// [`Plan::new`], failing with [`Error::TooLarge`] when the matcher cannot fit `limit` (SGM is
    /// bounded to aggregate in strips first).
    pub fn with_memory_limit(
        params: &PipelineParams,
        left: (usize, usize),
        right: (usize, usize),
        limit: Option<MemoryLimit>,
    ) -> Result<Plan, Error> {
        params.validate()?;
        if left != right {
            return Err(stereo_disparity::Error::SizeMismatch { left, right }.into());
        }
        let (width, height) = left;
        if width == 0 || height == 0 {
            return Err(Error::EmptyImage { width, height });
        }
        let range = params.matcher.range();
        if range.count() > width {
            return Err(stereo_disparity::Error::RangeWiderThanImage {
                min: range.min,
                max: range.max,
                count: range.count(),
                width,
            }
            .into());
        }
        let mut params = params.clone();
        if let Some(limit) = limit {
            let planned = params.matcher.planned_bytes(width, height);
            if planned.saturating_add(limit.other_bytes) > limit.bytes {
                let fits = match limit.bytes.checked_sub(limit.other_bytes) {
                    Some(budget) => params.matcher.bound_to(width, height, budget),
                    None => false,
                };
                if !fits {
                    return Err(Error::TooLarge {
                        needed: params.matcher.minimum_bytes(width, height).saturating_add(limit.other_bytes),
                        limit: limit.bytes,
                    });
                }
            }
        }
        let planned_matcher_bytes = params.matcher.planned_bytes(width, height);
        Ok(Plan { params, width, height, planned_matcher_bytes })
    }

    /// The parameters the pair runs with (SGM possibly bounded to a memory limit).
    pub fn params(&self) -> &PipelineParams {
        &self.params
    }

    pub fn matcher(&self) -> &Matcher {
        &self.params.matcher
    }

    /// `(width, height)` of both views.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The disparities searched.
    pub fn range(&self) -> DisparityRange {
        self.params.matcher.range()
    }

    /// The matcher's planned working memory, bytes.
    pub fn planned_matcher_bytes(&self) -> u64 {
        self.planned_matcher_bytes
    }
}
