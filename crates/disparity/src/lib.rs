//! Disparity from rectified stereo pairs: census-based Semi-Global Matching (Hirschmüller 2008)
//! and window block matching.
//!
//! Conventions: images are rectified, and the left pixel `(x, y)` matches the right pixel
//! `(x - d, y)` for a disparity `d` in the searched [`DisparityRange`] `min <= d < max`.
//! Pixels without a trustworthy match are NaN in the returned [`DisparityMap`].
//!
//! # Example
//!
//! ```
//! use stereo_disparity::{sgm, DisparityRange, GrayImage, SgmParams};
//!
//! // A random texture and the same texture shifted 5 px to the left: disparity 5 everywhere.
//! let texture = |x: i64, y: i64| ((x * 7919 + y * 104_729) % 65_521) as u16;
//! let left = GrayImage::from_fn(64, 32, |x, y| texture(x as i64, y as i64));
//! let right = GrayImage::from_fn(64, 32, |x, y| texture(x as i64 + 5, y as i64));
//! let params = SgmParams { range: DisparityRange::new(0, 16)?, ..SgmParams::default() };
//! let disparity = sgm(&left, &right, &params)?;
//! assert!((disparity.get(40, 16) - 5.0).abs() < 0.5);
//! Ok::<(), Box<dyn std::error::Error>>(())
//! ```

mod aggregate;
mod bm;
mod buffer;
mod census;
mod confidence;
mod cost;
mod far_islands;
mod fill;
mod filter;
mod hierarchical;
mod kernels;
mod memory;
mod names;
mod planes;
mod post;
mod radiometric;
#[cfg(test)]
mod reference;
mod sgm;
mod snap;
mod speckle;
#[doc(hidden)]
pub mod stages;
mod status;
mod tone;
mod widen;
mod winner;
mod wta;

pub use bm::block_match;
pub use buffer::keep_strip_buffers;
pub use fill::{fill_invalid, filled_mask};
pub use filter::weighted_median;
pub use names::{parse_named, Named};
pub use post::{Adaptation, SearchReport, SgmOutput};
pub use sgm::{planned_memory_bytes, sgm, sgm_detailed};
pub use speckle::remove_speckles;
pub use status::PixelStatus;
pub use stereo_image::{DisparityMap, DisparityRange, GrayImage, Image, ImageRef};

/// Errors a matcher reports instead of panicking on unusable input.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Left and right images differ in size.
    #[error("left image is {}x{} but right image is {}x{}; a rectified pair has equal sizes", left.0, left.1, right.0, right.1)]
    SizeMismatch { left: (usize, usize), right: (usize, usize) },
    /// The disparity range `min..max` contains no disparity.
    #[error("disparity range is empty: min {min} must be below max {max}")]
    EmptyRange { min: i32, max: i32 },
    /// More disparities are searched than the image is wide.
    #[error("disparity range {min}..{max} ({count} disparities) is wider than the image ({width} px)")]
    RangeWiderThanImage { min: i32, max: i32, count: usize, width: usize },
    /// The image is smaller than the matching window.
    #[error("image is {width}x{height}, smaller than the {window_width}x{window_height} matching window")]
    ImageTooSmall { width: usize, height: usize, window_width: usize, window_height: usize },
    /// A parameter is outside its accepted range.
    #[error("invalid parameter {name}: {message}")]
    InvalidParameter { name: &'static str, message: String },
    /// An image buffer or a disparity range that does not describe what it was given for.
    #[error(transparent)]
    Image(#[from] stereo_image::Error),
}

/// Runs `work` on a thread of the current rayon pool (the global one unless the caller installed
/// another); on such a thread already, in place. Called from any other thread (a program's main
/// thread, a Python thread), each of a match's few dozen parallel stages would otherwise be
/// handed to the pool and waited for, a sleep and a wake-up of the caller each: 95 context
/// switches per call of tsukuba's fast match on two threads against 20–26 (docs/perf-notes.md).
pub(crate) fn on_pool_thread<R: Send>(work: impl FnOnce() -> R + Send) -> R {
    // `scope` runs its body on a worker of the current pool, blocking the caller once.
    rayon::scope(|_| work())
}

/// Checks that `range` holds at least one disparity and fits an image `width` pixels wide.
pub(crate) fn check_range(range: &DisparityRange, width: usize) -> Result<(), Error> {
    if range.max <= range.min {
        return Err(Error::EmptyRange { min: range.min, max: range.max });
    }
    if range.count() > width {
        return Err(Error::RangeWiderThanImage {
            min: range.min,
            max: range.max,
            count: range.count(),
            width,
        });
    }
    Ok(())
}

/// How many path directions SGM aggregates over.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathCount {
    /// Horizontal and vertical only: faster, more streaking.
    Four,
    /// Horizontal, vertical and both diagonals (Hirschmüller's recommended default).
    Eight,
}

/// How SGM searches the disparity range.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Search {
    /// Every pixel over the whole range.
    Full,
    /// Coarse to fine (tSGM): a half-resolution match over the whole range, then each pixel only
    /// in a band around the coarse result. Time and memory scale with the bands, not the range.
    Hierarchical,
    /// Hierarchical for ranges of 256 disparities or more, and from 128 on images of 2
    /// megapixels or more, where it measured more accurate than the full search and about as
    /// fast or faster; full otherwise (there the hierarchical search is about as accurate but
    /// slower: docs/performance.md).
    #[default]
    Auto,
}

/// Whether SGM matches the pair reduced, each side by the same factor (box filter, the range
/// divided alike), and brings the result back to full size, the disparities times `f`:
/// interpolated between the reduced pixels where they lie on one surface (within one reduced
/// pixel of each other), repeated over each reduced pixel's `f × f` pixels elsewhere (depth
/// edges, holes) and for the statuses and confidences. About `f³` less work, for disparities `f`
/// times coarser and no detail below `f` pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Downscale {
    /// Halve the pair, again and again, while both views hold no detail finer than 2 px (at
    /// least [`AUTO_DOWNSCALE_SMOOTHNESS`] of the gradient energy per pixel survives halving, as
    /// in an image enlarged from a smaller one or seen through soft optics; sensor noise, which
    /// would read as detail at every pixel, estimated and discounted) and the halved pair
    /// keeps at least [`AUTO_DOWNSCALE_MIN_PIXELS`]; there matching the halved pair measured as
    /// accurate or more, at a fraction of the time (docs/performance.md). Where it would halve
    /// twice or more, the last halving becomes a reduction by 1.5 (factor 3 instead of 4, 6
    /// instead of 8): the reduced match's subpixel error is multiplied by the factor, and at 4 a
    /// half-pixel error is already a 2 px one. Sharp pairs are matched at full resolution.
    #[default]
    Auto,
    /// As [`Downscale::Auto`], but a pair with detail at every pixel is halved too, once, where
    /// the halved range keeps at least [`COARSE_MIN_DISPARITIES`] disparities and the halved pair
    /// at least [`COARSE_MIN_PIXELS`] pixels: [`Preset::Fast`]'s default, which trades the
    /// finest detail and half the disparity resolution for about an eighth of the work (measured
    /// on the seven Middlebury scenes, still fewer bad pixels than OpenCV's SGBM_3WAY,
    /// docs/performance.md). Where the range is too short to halve, the rows alone are halved
    /// (if [`COARSE_MIN_PIXELS`] remain): half the work, the disparities at full resolution, no
    /// vertical detail below 2 px (tsukuba's 16 disparities: bad2 4.25 → 4.28); likewise a
    /// pair halved once whose halved range is too short to halve again has its rows halved once
    /// more (columns by 2, rows by 4: tsukuba 2×'s 32 disparities, bad2 7.21 → 7.09). Pairs
    /// `Auto` already reduces are reduced alike (the same rule for their rows).
    Coarse,
    /// Reduce by this factor (1: full resolution), at most [`MAX_DOWNSCALE`].
    By(usize),
}

/// [`Downscale::Coarse`] halves a sharp pair only where the halved range keeps this many
/// disparities: below it the reduced match's disparity steps (2 px at full size) are too coarse
/// for the range (tsukuba's 16 disparities halved to 8: bad2 4.25 → 9.81, above SGBM_3WAY's
/// 6.01), and only the rows are halved.
pub const COARSE_MIN_DISPARITIES: usize = 16;

/// [`Downscale::Coarse`] halves a sharp pair only where the halved pair keeps this many pixels
/// (a quarter of [`AUTO_DOWNSCALE_MIN_PIXELS`]; venus, 434 × 383, halves to 41 447).
pub const COARSE_MIN_PIXELS: usize = 25_000;

/// [`Downscale::Auto`] halves a pair only while the gradient energy per pixel of each halved
/// view is at least this many times the full view's: 4 for an image with no detail finer than
/// 2 px (halving doubles every gradient), about 1 for detail at every pixel. Measured: 1.0–2.2
/// for the seven Middlebury scenes, clean or degraded (the sharper view of a one-sided blur);
/// 2.8–3.2 for their 2× and 3.5–3.6 for their 4× enlargements.
pub const AUTO_DOWNSCALE_SMOOTHNESS: f64 = 2.6;

/// [`Downscale::Auto`] keeps at least this many pixels (384 × 288 is 110 592): the smallest
/// Middlebury scene the matcher's parameters were chosen on. Below it the census window and
/// the filters cover too much of the scene (the 288 × 216 `data/slanted`, smooth enough to
/// halve, loses 0.75 bad2 at 144 × 108).
pub const AUTO_DOWNSCALE_MIN_PIXELS: usize = 100_000;

impl std::fmt::Display for Downscale {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Downscale::Auto => f.write_str("auto"),
            Downscale::Coarse => f.write_str("coarse"),
            Downscale::By(n) => write!(f, "{n}"),
        }
    }
}

impl std::str::FromStr for Downscale {
    type Err = Error;
    /// `auto`, `coarse`, or a factor from 1 to [`MAX_DOWNSCALE`].
    fn from_str(text: &str) -> Result<Self, Error> {
        match text {
            "auto" => return Ok(Downscale::Auto),
            "coarse" => return Ok(Downscale::Coarse),
            _ => {}
        }
        match text.parse::<usize>() {
            Ok(f) if (1..=MAX_DOWNSCALE).contains(&f) => Ok(Downscale::By(f)),
            _ => Err(Error::InvalidParameter {
                name: "downscale",
                message: format!(
                    "{text:?} must be \"auto\", \"coarse\" or a factor from 1 to {MAX_DOWNSCALE}"
                ),
            }),
        }
    }
}

#[cfg(feature = "serde")]
impl serde::Serialize for Downscale {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

#[cfg(feature = "serde")]
impl<'de> serde::Deserialize<'de> for Downscale {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let text = <std::borrow::Cow<'de, str>>::deserialize(deserializer)?;
        text.parse().map_err(serde::de::Error::custom)
    }
}

/// How the integer winner-takes-all disparity is refined below one pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Subpixel {
    /// Integer disparities only.
    None,
    /// A parabola through the costs at `d-1, d, d+1`.
    Parabola,
    /// Two lines of equal and opposite slope through the same three costs; suits census/L1 costs.
    Equiangular,
}

/// The census transform window (odd width and height; at most 64 comparisons).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct CensusWindow {
    pub width: usize,
    pub height: usize,
}

impl CensusWindow {
    pub(crate) fn check(&self) -> Result<(), Error> {
        if self.width.is_multiple_of(2)
            || self.height.is_multiple_of(2)
            || self.width * self.height > 65
            || self.width * self.height < 9
        {
            return Err(Error::InvalidParameter {
                name: "census window",
                message: format!(
                    "{}x{} must have odd sides and between 9 and 65 pixels (e.g. 9x7)",
                    self.width, self.height
                ),
            });
        }
        Ok(())
    }
}

/// The per-pixel matching cost SGM aggregates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum MatchingCost {
    /// Hamming distance between the census bit strings (0 ..= window pixels − 1).
    Census,
    /// AD-census: the census Hamming distance plus `min(weight · BT, cap)`, BT being the
    /// Birchfield–Tomasi sampling-insensitive absolute difference in 8-bit grey levels
    /// (Mei et al. 2011 combine the two terms the same way, additively in integer units).
    /// `cap` is at most [`MAX_AD_CAP`].
    AdCensus { weight: u8, cap: u8 },
}

/// The largest [`MatchingCost::AdCensus`] cap: costs stay below 192, so path costs (at most
/// cost + P2) summed over eight paths fit `u16` for every accepted P2.
pub const MAX_AD_CAP: u8 = 127;

/// Semi-Global Matching parameters. Costs are Hamming distances between census bit strings
/// (plus, for [`MatchingCost::AdCensus`], the capped intensity term), so `p1`/`p2` are in
/// "differing bits".
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct SgmParams {
    pub range: DisparityRange,
    pub census: CensusWindow,
    /// The matching cost: census alone or AD-census.
    pub matching_cost: MatchingCost,
    /// Measure the pair first (a census-only match at a quarter of the resolution, about 2 % of
    /// the work) and adapt to it: AD-census drops its intensity term where the two views render
    /// surfaces differently (exposure, gamma, vignetting), and P1/P2 rise (up to 2×) where the
    /// census cost is noisy at the true match (sensor noise, JPEG, a blurred view); see
    /// [`Adaptation`]. Clean pairs are matched as without it.
    pub adapt_to_pair: bool,
    pub paths: PathCount,
    /// Penalty for a disparity change of one pixel along a path.
    pub p1: u16,
    /// Penalty for a larger disparity jump along a path (before adaptation to the image gradient).
    pub p2: u16,
    /// Lowers P2 across image edges: `P2 · s / (s + ΔI)` for an intensity step ΔI (8-bit grey
    /// levels) between neighbours on the path, never below `P1 + 1`; 0 keeps P2 constant.
    pub p2_edge_scale: u16,
    /// A match is kept only if every disparity more than one pixel away costs at least
    /// `(100 + uniqueness_ratio) %` of the best; 0 disables the check.
    pub uniqueness_ratio: u32,
    /// Left-right consistency: the largest allowed difference (px) between the left disparity and
    /// the right view's disparity at the matched pixel; `None` disables the check.
    pub lr_max_diff: Option<f32>,
    /// Left-right check: a pixel the check calls occluded still passes when the right view's
    /// disparity one pixel to the left of the matched pixel agrees. The right view's disparities
    /// come from the left volume, whose foreground spreads about a pixel into the background
    /// beside a depth edge; without this, background pixels matched correctly right after such
    /// an edge are rejected (docs/accuracy.md: 65–87 % of the pixels it keeps are right on six
    /// of the seven scenes). Off for [`SgmParams::with_fill`], whose fill does better with them.
    pub lr_left_neighbour: bool,
    pub subpixel: Subpixel,
    /// A 3×3 median over valid disparities after the checks.
    pub median: bool,
    /// Single-pass ("streaming") aggregation: only the directions from above and the left
    /// (→ ↓ ↘ ↙ and ← for [`PathCount::Eight`], like OpenCV's `MODE_SGBM`; → ↓ ← for
    /// [`PathCount::Four`]), so no `W·H·D` volume is kept: `O(W·D)` memory per strip (2–8
    /// strips, by the image's height) and about twice the speed, at some accuracy cost.
    pub single_pass: bool,
    /// How the range is searched ([`Search::Auto`]: coarse to fine for large ranges).
    pub search: Search,
    /// Whether the pair is matched reduced ([`Downscale`]): by default where it holds no detail
    /// finer than the reduction.
    pub downscale: Downscale,
    /// Upper bound (bytes) on the working memory the matcher plans (see
    /// [`planned_memory_bytes`]): the two-pass aggregation then runs on horizontal strips short
    /// enough to fit. `None` uses the default plan (strips sized for speed, see
    /// [`planned_memory_bytes`]). A bound too small for even one-row strips is an error. With
    /// [`keep_strip_buffers`] on, up to 64 MiB of a call's strip buffers stay allocated after it
    /// for the next call of the same size (returned when a call needs other sizes).
    pub max_memory: Option<usize>,
    /// Speckle filter: 4-connected regions of valid pixels whose neighbours differ by at most
    /// [`SgmParams::speckle_max_diff`] and that hold fewer than this many pixels are invalidated
    /// (after the median); 0 disables it.
    pub speckle_size: usize,
    /// The largest disparity difference (px) between neighbours of one speckle region.
    pub speckle_max_diff: f32,
    /// Speckle regions that touch the image border and hold at least this many pixels are kept
    /// (0: none are): the border cuts them, so their size in the image says little about the
    /// surface they belong to (a ground plane at the bottom edge, a wall at the left edge).
    /// [`SgmParams::with_fill`] sets [`DENSE_SPECKLE_KEEP_BORDER`].
    pub speckle_keep_border: usize,
    /// Holes (invalid pixels) up to this many pixels across do not split a speckle region: a
    /// surface cut into pieces by a few pixels that failed the checks (a thin lamp arm, a slanted
    /// plane's stripes) is measured as one region (0: 4-connected pixels only, as OpenCV's
    /// `filterSpeckles`). [`SgmParams::with_fill`] sets [`DENSE_SPECKLE_BRIDGE`].
    pub speckle_bridge: usize,
    /// Dense output: invalid pixels are filled, first those inside a segment of the left view
    /// (similar grey) whose matched pixels lie on one disparity plane, from that plane (an
    /// occlusion never in front of its row's neighbours), then the rest, occlusions from the
    /// background side and mismatches by interpolation ([`fill_invalid`]); [`sgm_detailed`]
    /// says which were filled.
    pub fill: bool,
    /// Edge snapping ([`SgmParams::fill`] or not): each disparity jump moves to the strongest
    /// intensity edge of the left image within this many pixels inside the foreground, and the
    /// pixels passed over take the background's disparity; undoes most of the edge fattening of
    /// the census window (whose half width is 4 px for 9×7). 0 disables it.
    pub edge_snap_radius: usize,
    /// How many times edge snapping runs (each pass can move an edge by up to the radius).
    pub edge_snap_passes: usize,
    /// Edge-aware weighted median radius (px; 0 disables it): see [`weighted_median`].
    pub wmf_radius: usize,
    /// Its colour sigma (8-bit grey levels).
    pub wmf_sigma_color: f32,
    /// Run the weighted median only at depth edges (where its window's disparities span more
    /// than 1 px): nearly the same result at a fraction of the cost.
    pub wmf_edges_only: bool,
    /// Compute the per-pixel confidence of [`SgmOutput::confidence`] ([`sgm_detailed`]).
    pub confidence: bool,
}

impl Default for SgmParams {
    fn default() -> Self {
        SgmParams {
            range: DisparityRange::default(),
            census: CensusWindow { width: 9, height: 7 },
            matching_cost: MatchingCost::AdCensus { weight: 2, cap: 40 },
            adapt_to_pair: true,
            paths: PathCount::Eight,
            // Chosen by measurement on the seven Middlebury scenes (bad2, holes counted): a high
            // P1 with a moderate P2, no uniqueness test (it removed more right than wrong
            // pixels) and a 2 px left-right tolerance.
            p1: 20,
            p2: 80,
            p2_edge_scale: 0,
            uniqueness_ratio: 0,
            // 3 px (was 2): better bad2 on all seven scenes (docs/accuracy.md); the right view's
            // disparities come from the left volume and are noisier than a second matching.
            lr_max_diff: Some(3.0),
            lr_left_neighbour: true,
            subpixel: Subpixel::Equiangular,
            median: true,
            single_pass: false,
            search: Search::Auto,
            downscale: Downscale::Auto,
            max_memory: None,
            speckle_size: 0,
            speckle_max_diff: 1.0,
            speckle_keep_border: 0,
            speckle_bridge: 0,
            fill: false,
            // Radius 5, one pass: better bad2 on all seven scenes, about 1 ms per scene
            // (docs/accuracy.md, "Edge snapping").
            edge_snap_radius: 5,
            edge_snap_passes: 1,
            wmf_radius: 0,
            wmf_sigma_color: 10.0,
            wmf_edges_only: false,
            confidence: false,
        }
    }
}

/// Ready-made [`SgmParams`] trade-offs between speed and accuracy (`--preset`); see
/// [`SgmParams::preset`]. Measurements in `docs/accuracy.md`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Preset {
    /// Three path directions (→ ↓ ←) in one top-down pass, like OpenCV's SGBM_3WAY, on the pair
    /// halved where its range allows ([`Downscale::Coarse`]): the fastest mode, with
    /// O(width × disparities) memory per strip of rows.
    Fast,
    /// The default parameters ([`SgmParams::default`]).
    #[default]
    Balanced,
    /// Balanced plus an edge-aware weighted median (radius 5) that pulls disparity edges onto
    /// image edges: fewer errors at depth discontinuities, several times slower post-processing.
    Accurate,
}

impl SgmParams {
    /// Checks every parameter on its own (those that depend on the image size are checked by
    /// the matcher): the same errors [`sgm`] returns, before any work.
    pub fn validate(&self) -> Result<(), Error> {
        if self.range.max <= self.range.min {
            return Err(Error::EmptyRange { min: self.range.min, max: self.range.max });
        }
        crate::post::check(self)?;
        self.census.check()?;
        if self.p1 == 0 || self.p1 >= self.p2 || self.p2 > aggregate::MAX_P2 {
            return Err(Error::InvalidParameter {
                name: "p1/p2",
                message: format!(
                    "need 0 < P1 < P2 <= {}, got P1 = {} and P2 = {}",
                    aggregate::MAX_P2,
                    self.p1,
                    self.p2
                ),
            });
        }
        if let Some(d) = self.lr_max_diff {
            if d.is_nan() || d < 0.0 {
                return Err(Error::InvalidParameter {
                    name: "left-right max difference",
                    message: format!("{d} must be a number >= 0"),
                });
            }
        }

        if let MatchingCost::AdCensus { cap, .. } = self.matching_cost {
            if cap > MAX_AD_CAP {
                return Err(Error::InvalidParameter {
                    name: "AD-census cap",
                    message: format!("{cap} must be at most {MAX_AD_CAP}"),
                });
            }
        }
        if let Downscale::By(f) = self.downscale {
            if !(1..=MAX_DOWNSCALE).contains(&f) {
                return Err(Error::InvalidParameter {
                    name: "downscale",
                    message: format!("{f} must be between 1 and {MAX_DOWNSCALE}"),
                });
            }
        }
        let nd = self.range.count();
        if nd >= usize::from(u16::MAX) {
            return Err(Error::InvalidParameter {
                name: "disparity range",
                message: format!("{nd} disparities; at most {} are supported", u16::MAX - 1),
            });
        }
        Ok(())
    }

    /// The parameters of `preset` (range: the default; set it for the pair). Every field can be
    /// changed afterwards.
    pub fn preset(preset: Preset) -> Self {
        let balanced = SgmParams::default();
        match preset {
            Preset::Fast => SgmParams {
                paths: PathCount::Four,
                single_pass: true,
                downscale: Downscale::Coarse,
                ..balanced
            },
            Preset::Balanced => balanced,
            Preset::Accurate => SgmParams { wmf_radius: 5, wmf_sigma_color: 20.0, ..balanced },
        }
    }

    /// Dense output (`--fill`): [`SgmParams::fill`] on and, unless a speckle size is already
    /// set, speckles under [`DENSE_SPECKLE_SIZE`] pixels removed first so the fill replaces them
    /// (but not those at the image border with [`DENSE_SPECKLE_KEEP_BORDER`] pixels or more),
    /// regions being joined across holes up to [`DENSE_SPECKLE_BRIDGE`] pixels wide.
    /// A dense map can afford a strict check, since what it rejects gets filled from the
    /// background: the left-right tolerance tightens to [`DENSE_LR_MAX_DIFF`], edge snapping runs
    /// twice, and without a weighted median of its own (Accurate has one) a small one (radius 2,
    /// σc 20) runs at the depth edges. Chosen by measurement (docs/accuracy.md).
    pub fn with_fill(self) -> Self {
        let speckle_size = if self.speckle_size == 0 { DENSE_SPECKLE_SIZE } else { self.speckle_size };
        let speckle_keep_border =
            if self.speckle_keep_border == 0 { DENSE_SPECKLE_KEEP_BORDER } else { self.speckle_keep_border };
        let speckle_bridge =
            if self.speckle_bridge == 0 { DENSE_SPECKLE_BRIDGE } else { self.speckle_bridge };
        let lr_max_diff = self.lr_max_diff.map(|d| d.min(DENSE_LR_MAX_DIFF));
        let (wmf_radius, wmf_sigma_color, wmf_edges_only) = if self.wmf_radius == 0 {
            (2, 20.0, true)
        } else {
            (self.wmf_radius, self.wmf_sigma_color, self.wmf_edges_only)
        };
        SgmParams {
            fill: true,
            speckle_size,
            speckle_keep_border,
            speckle_bridge,
            lr_max_diff,
            lr_left_neighbour: false,
            edge_snap_passes: self.edge_snap_passes.max(2),
            wmf_radius,
            wmf_sigma_color,
            wmf_edges_only,
            ..self
        }
    }
}

/// The largest factor of [`Downscale::By`].
pub const MAX_DOWNSCALE: usize = 8;

/// The speckle size [`SgmParams::with_fill`] uses: chosen by measurement of the filled maps.
pub const DENSE_SPECKLE_SIZE: usize = 400;

/// The [`SgmParams::speckle_keep_border`] of [`SgmParams::with_fill`]: chosen by measurement
/// of the filled maps (docs/accuracy.md).
pub const DENSE_SPECKLE_KEEP_BORDER: usize = 100;

/// The [`SgmParams::speckle_bridge`] of [`SgmParams::with_fill`] (px): chosen by measurement of
/// the filled maps, clean and degraded (docs/accuracy.md).
pub const DENSE_SPECKLE_BRIDGE: usize = 3;

/// The left-right tolerance (px) [`SgmParams::with_fill`] tightens to: pixels fattened across a
/// depth edge fail the check more often and get filled from the background instead.
pub const DENSE_LR_MAX_DIFF: f32 = 1.0;

/// The window cost block matching uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BmCost {
    /// Sum of absolute differences on an x-Sobel prefiltered image (as OpenCV's StereoBM).
    Sad,
    /// Sum of Hamming distances of per-pixel 5x5 census strings: robust to gain and bias changes.
    Census,
}

/// Block matching parameters.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct BmParams {
    pub range: DisparityRange,
    /// Side of the square matching window (odd, at least 3).
    pub block_size: usize,
    pub cost: BmCost,
    /// As in [`SgmParams::uniqueness_ratio`].
    pub uniqueness_ratio: u32,
    /// As in [`SgmParams::lr_max_diff`].
    pub lr_max_diff: Option<f32>,
    pub subpixel: Subpixel,
}

impl BmParams {
    /// Checks every parameter on its own (those that depend on the image size are checked by
    /// the matcher): the same errors [`block_match`] returns, before any work.
    pub fn validate(&self) -> Result<(), Error> {
        if self.range.max <= self.range.min {
            return Err(Error::EmptyRange { min: self.range.min, max: self.range.max });
        }
        let block = self.block_size;
        if block.is_multiple_of(2) || !(3..=bm::MAX_BLOCK_SIZE).contains(&block) {
            return Err(Error::InvalidParameter {
                name: "block size",
                message: format!("{block} must be odd and between 3 and {}", bm::MAX_BLOCK_SIZE),
            });
        }
        if let Some(t) = self.lr_max_diff {
            if t.is_nan() || t < 0.0 {
                return Err(Error::InvalidParameter {
                    name: "lr max diff",
                    message: format!("{t} must be a non-negative number of pixels"),
                });
            }
        }
        Ok(())
    }
}

impl Default for BmParams {
    fn default() -> Self {
        BmParams {
            range: DisparityRange::default(),
            block_size: 11,
            cost: BmCost::Census,
            uniqueness_ratio: 10,
            lr_max_diff: Some(1.0),
            subpixel: Subpixel::Parabola,
        }
    }
}

pub(crate) fn check_pair(left: &GrayImage, right: &GrayImage) -> Result<(), Error> {
    if left.size() != right.size() {
        return Err(Error::SizeMismatch { left: left.size(), right: right.size() });
    }
    Ok(())
}
