//! Which matcher runs, and the working memory it plans for a pair.

use std::fmt;
use std::str::FromStr;

use stereo_disparity::{parse_named, BmParams, DisparityRange, Named, SgmParams};

/// The matcher and its parameters (the searched range is inside them).
#[derive(Clone, Debug, PartialEq)]
pub enum Matcher {
    /// Census Semi-Global Matching (the default).
    Sgm(SgmParams),
    /// Window block matching.
    Bm(BmParams),
}

impl Default for Matcher {
    fn default() -> Self {
        Matcher::Sgm(SgmParams::default())
    }
}

impl Matcher {
    /// `"sgm"` or `"bm"`, as on the command line and in the statistics.
    pub fn name(&self) -> &'static str {
        self.kind().name()
    }

    /// The disparities searched.
    pub fn range(&self) -> DisparityRange {
        match self {
            Matcher::Sgm(p) => p.range,
            Matcher::Bm(p) => p.range,
        }
    }

    pub fn set_range(&mut self, range: DisparityRange) {
        match self {
            Matcher::Sgm(p) => p.range = range,
            Matcher::Bm(p) => p.range = range,
        }
    }

    /// The matcher's working memory for a `width × height` pair, bytes.
    pub fn planned_bytes(&self, width: usize, height: usize) -> u64 {
        match self {
            Matcher::Sgm(params) => sgm_bytes(width, height, params),
            Matcher::Bm(params) => {
                // Two prefiltered/census images and two disparity maps, plus per-thread cost rows.
                let pixels = (width * height) as u64;
                let threads = rayon::current_num_threads() as u64;
                let rows = 3 * 4 * (width * params.range.count()) as u64;
                pixels * (16 + 16 + 4 + 4) + threads * rows
            }
        }
    }

    /// The least the matcher can run in (SGM: one-row strips).
    pub fn minimum_bytes(&self, width: usize, height: usize) -> u64 {
        match self {
            Matcher::Sgm(params) => {
                let smallest = SgmParams { max_memory: Some(1), ..params.clone() };
                sgm_bytes(width, height, &smallest)
            }
            Matcher::Bm(_) => self.planned_bytes(width, height),
        }
    }

    /// Bounds the matcher to `budget` bytes when it can trade speed for memory (SGM aggregates
    /// in strips); `false` when even that does not fit.
    pub(crate) fn bound_to(&mut self, width: usize, height: usize, budget: u64) -> bool {
        if let Matcher::Sgm(params) = self {
            let mut bounded = params.clone();
            bounded.max_memory = Some(usize::try_from(budget).unwrap_or(usize::MAX));
            if sgm_bytes(width, height, &bounded) <= budget {
                *params = bounded;
                return true;
            }
        }
        false
    }
}

/// [`stereo_disparity::planned_memory_bytes`], for sizes its `usize` arithmetic can hold: an
/// absurd header (e.g. 2147483647 x 1 with the default range of a quarter of the width) would
/// overflow it, so beyond a sure bound a lower estimate (path state rows and per-pixel maps)
/// stands in, which is far over any real limit anyway.
fn sgm_bytes(width: usize, height: usize, params: &SgmParams) -> u64 {
    let nd = params.range.count() as u128;
    let rough = (width as u128) * (nd + 2) * 64 + (width as u128) * (height as u128) * 64;
    if rough > (usize::MAX >> 8) as u128 {
        return u64::try_from(rough).unwrap_or(u64::MAX);
    }
    stereo_disparity::planned_memory_bytes(width, height, params) as u64
}

/// Which matcher, by name: `"sgm"` or `"bm"` (the [`Matcher`] without its parameters).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MatcherKind {
    #[default]
    Sgm,
    Bm,
}

impl Named for MatcherKind {
    const WHAT: &'static str = "matcher";
    const ALL: &'static [Self] = &[MatcherKind::Sgm, MatcherKind::Bm];
    fn name(self) -> &'static str {
        match self {
            MatcherKind::Sgm => "sgm",
            MatcherKind::Bm => "bm",
        }
    }
    fn help(self) -> &'static str {
        match self {
            MatcherKind::Sgm => "census Semi-Global Matching (Hirschmüller 2008)",
            MatcherKind::Bm => "window block matching, winner-takes-all",
        }
    }
}

impl fmt::Display for MatcherKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for MatcherKind {
    type Err = stereo_disparity::Error;
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        parse_named(text)
    }
}

impl Matcher {
    /// Its kind, by name.
    pub fn kind(&self) -> MatcherKind {
        match self {
            Matcher::Sgm(_) => MatcherKind::Sgm,
            Matcher::Bm(_) => MatcherKind::Bm,
        }
    }
}
