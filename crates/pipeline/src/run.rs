//! Running a plan: rectification check → match → confidence cut → depth limits → triangulation.

use std::time::{Duration, Instant};

use stereo_disparity::{block_match, sgm_detailed, Adaptation, DisparityMap, GrayImage, Image, SearchReport};
use stereo_image::{ImageRef, ToGray16};
use stereo_rectify::{Alignment, AlignmentVerdict};

use crate::{Error, Matcher, Plan};

/// What the pipeline measured of the pair's rectification, and what it did about it.
#[derive(Clone, Debug, PartialEq)]
pub struct Rectification {
    pub alignment: Alignment,
    /// The alignment was measured on this pair (not taken from
    /// [`crate::PipelineParams::known_alignment`]).
    pub measured: bool,
    /// The right view was resampled to line up with the left one before matching.
    pub compensated: bool,
}

impl Rectification {
    /// The rows are off: a vertical offset or rotation worth correcting.
    pub fn misaligned(&self) -> bool {
        matches!(self.alignment.verdict, AlignmentVerdict::Misaligned | AlignmentVerdict::BadlyMisaligned)
    }
}

/// Wall-clock time of each stage.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageTimings {
    pub rectification: Duration,
    pub matching: Duration,
    pub triangulation: Duration,
}

/// Everything the pipeline computed for one pair.
#[derive(Clone, Debug)]
#[non_exhaustive]
pub struct DepthResult {
    /// Disparity of the left view (px); NaN where invalid (rejected, or cut by the confidence or
    /// depth limits). Every other map agrees with it on which pixels are valid.
    pub disparity: DisparityMap,
    /// SGM's per-pixel confidence (0–1), when asked for.
    pub confidence: Option<Image<f32>>,
    /// SGM's per-pixel [`stereo_disparity::PixelStatus`] codes (0 = matched): with
    /// [`stereo_disparity::filled_mask`], which pixels a dense fill invented.
    pub status: Option<Image<u8>>,
    /// Depth along the optical axis (metres), with a rig.
    pub depth: Option<Image<f32>>,
    /// What SGM measured of the pair and adapted its cost to.
    pub adaptation: Option<Adaptation>,
    /// Which search SGM ran (full or coarse to fine) and the mean disparities per pixel.
    pub search: Option<SearchReport>,
    pub rectification: Rectification,
    /// Pixels the depth limits invalidated.
    pub depth_limits_cut: Option<usize>,
    pub timings: StageTimings,
}

impl Plan {
    /// Runs the pipeline on two borrowed views of any supported pixel type (8/16-bit grey, RGB,
    /// RGBA), read in place: the only pass over them converts to the matchers' 16-bit grey.
    pub fn run<P: ToGray16>(
        &self,
        left: ImageRef<'_, P>,
        right: ImageRef<'_, P>,
    ) -> Result<DepthResult, Error> {
        self.check_size(left.size())?;
        self.check_size(right.size())?;
        // Both views at once: a colour view's conversion is a few ns per pixel (10 ms for a
        // 1080p pair on one thread), a tenth of a fast match.
        let (left, right) = rayon::join(|| left.to_gray16(), || right.to_gray16());
        self.run_gray(&left, right)
    }

    /// Runs the pipeline on the matchers' working grey images (the right one may be resampled in
    /// place of a copy).
    pub fn run_gray(&self, left: &GrayImage, right: GrayImage) -> Result<DepthResult, Error> {
        // On a thread of the current rayon pool, so the check's and the matcher's parallel stages
        // start from the pool instead of each being handed over from the caller's thread
        // (`stereo_disparity::sgm_detailed` does the same for its own stages).
        rayon::scope(|_| self.run_gray_on_pool_thread(left, right))
    }

    fn run_gray_on_pool_thread(&self, left: &GrayImage, right: GrayImage) -> Result<DepthResult, Error> {
        self.check_size(left.size())?;
        self.check_size(right.size())?;
        let params = &self.params;

        let t = Instant::now();
        let (alignment, measured) = match params.known_alignment {
            Some(known) => (known, false),
            None => (stereo_rectify::estimate_alignment(left, &right, self.range()), true),
        };
        let mut rectification = Rectification { alignment, measured, compensated: false };
        rectification.compensated = rectification.misaligned() && params.align;
        let right = if rectification.compensated {
            stereo_rectify::compensate(&right, &rectification.alignment)
        } else {
            right
        };
        let rectification_time = t.elapsed();

        let t = Instant::now();
        let (mut disparity, confidence, (adaptation, search), status) = match &params.matcher {
            Matcher::Sgm(sgm) => {
                let out = sgm_detailed(left, &right, sgm)?;
                let (mut disparity, confidence, status) = (out.disparity, out.confidence, out.status);
                if let (Some(t), Some(c)) = (params.min_confidence, &confidence) {
                    for (d, &c) in disparity.as_mut_slice().iter_mut().zip(c.as_slice()) {
                        if c < t {
                            *d = f32::NAN;
                        }
                    }
                }
                (disparity, confidence, (Some(out.adaptation), Some(out.search)), Some(status))
            }
            Matcher::Bm(bm) => (block_match(left, &right, bm)?, None, (None, None), None),
        };
        let matching = t.elapsed();
        drop(right);

        // Cut once here, so every output agrees on which pixels are valid.
        let depth_limits_cut = match (&params.depth_limits, &params.rig) {
            (Some(limits), Some(rig)) => Some(limits.apply(&mut disparity, rig)),
            _ => None,
        };
        let t = Instant::now();
        let depth = params.rig.as_ref().map(|rig| stereo_triangulation::depth_map(&disparity, rig));
        let triangulation = t.elapsed();
        Ok(DepthResult {
            disparity,
            confidence,
            status,
            depth,
            adaptation,
            search,
            rectification,
            depth_limits_cut,
            timings: StageTimings { rectification: rectification_time, matching, triangulation },
        })
    }

    fn check_size(&self, size: (usize, usize)) -> Result<(), Error> {
        if size != self.size() {
            return Err(Error::PlannedFor { planned: self.size(), given: size });
        }
        Ok(())
    }
}
