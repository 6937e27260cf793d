//! Post-processing after winner-takes-all: median, speckle removal, the status image and the
//! optional dense fill.

use rayon::prelude::*;

use crate::fill::fill_invalid;
use crate::filter::{median_3x3, weighted_median, weighted_median_at_edges};
use crate::planes::fill_from_segment_planes;
use crate::snap::snap_edges;
use crate::speckle::remove_speckles_keeping_border;
use crate::status::{tagged_nan, untag, PixelStatus};
use crate::winner::RangeEnds;
use crate::{DisparityMap, DisparityRange, Error, GrayImage, Image, SgmParams};

/// The full result of [`crate::sgm_detailed`].
#[derive(Clone, Debug, PartialEq)]
pub struct SgmOutput {
    /// The left view's disparity map (dense when [`SgmParams::fill`] is set and anything matched).
    pub disparity: DisparityMap,
    /// Per pixel, why it has no matched disparity: a [`crate::PixelStatus`] code (0 = matched).
    /// With [`SgmParams::fill`], every pixel whose status is not 0 but whose disparity is finite
    /// was filled.
    pub status: Image<u8>,
    /// With [`SgmParams::confidence`]: per pixel, a confidence in `[0, 1]` (census agreement at
    /// the match times the share of neighbours within 1 px); 0 for invalid and filled pixels.
    pub confidence: Option<Image<f32>>,
    /// What the matcher measured of the pair and how it adapted ([`SgmParams::adapt_to_pair`]).
    pub adaptation: Adaptation,
    /// Which search ran ([`SgmParams::search`]) and how much of the range it covered.
    pub search: SearchReport,
}

/// Which search [`crate::sgm_detailed`] ran and how many disparities a pixel searched.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SearchReport {
    /// Whether the coarse-to-fine search ran ([`crate::Search`]).
    pub hierarchical: bool,
    /// Half-resolution levels matched below the full resolution (0 for the full search).
    pub levels: u32,
    /// The mean number of disparities a full-resolution pixel searched (the range's size for the
    /// full search), counted on the matched pair (reduced by `downscale`).
    pub mean_range: f32,
    /// The factor the pair was reduced by before matching ([`crate::SgmParams::downscale`]; 1:
    /// matched at full resolution).
    pub downscale: usize,
    /// Whether the rows were halved once more than the columns before matching
    /// ([`crate::Downscale::Coarse`] on a range too short to halve: with `downscale` 1 the rows
    /// alone, with 2 the rows by 4).
    pub rows_halved: bool,
}

/// What [`crate::sgm_detailed`] measured of the pair before matching (a census-only match at a
/// quarter of the resolution), and how it adapted the cost and the penalties.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Adaptation {
    /// How differently the two views render the same surfaces, in 8-bit grey levels (the largest
    /// median grey-level difference between matched pixels over a 3×3 grid of tiles); `None` when
    /// not measured (adaptation off, or a pair too small or too poorly matched to tell).
    pub radiometric_difference: Option<f32>,
    /// What remains of [`Adaptation::radiometric_difference`] after mapping the right view's
    /// tones onto the left's (a tone curve and a smooth gain field fitted to the matched pixels);
    /// measured only where the views differ (above 9 grey levels), the cost is AD-census and the
    /// correction is plausible (no strong gamma, no view clipped much more than the other). At 3
    /// or less the intensity term compares the left view with the corrected right view.
    pub corrected_radiometric_difference: Option<f32>,
    /// Whether one view's shadows or highlights were clipped (black or white over 2.5 % more of
    /// the image than in the other view) and the other view was clipped alike before census.
    pub clipped_alike: bool,
    /// Whether the AD-census intensity term was used: it is dropped (census alone) when the
    /// views differ, e.g. in exposure, gamma or vignetting, and the tone correction does not
    /// make them agree.
    pub intensity_term: bool,
    /// The median census Hamming distance at the coarse matches (full resolution): how noisy the
    /// cost is at the true match (noise, JPEG, a blurred view raise it); `None` when not measured.
    pub census_residual: Option<f32>,
    /// JPEG's 8×8 block artefacts: the steps across the block grid over the steps between its
    /// lines, the smaller of the two views' (about 1 for camera images); `None` when not measured.
    pub blockiness: Option<f32>,
    /// Whether census compared Gaussian-smoothed views (σ 1 px), for a high residual or JPEG blocks.
    pub census_smoothing: bool,
    /// A one-sided defocus (one view's sharpness at least twice the other's): `(left view is the
    /// sharper, σ px)` of the Gaussian blur that brings the sharper view to the other's
    /// sharpness; a defocused left view is sharpened by an unsharp mask of that σ. `None` when
    /// the views are about equally sharp (or not measured).
    pub relative_blur: Option<(bool, f32)>,
    /// A one-sided defocus: `(left view is the sharper, σ px)` of the Gaussian blur the sharper
    /// view received before census, instead of the σ 1 smoothing of both views; `None` when the
    /// views are about equally sharp (or not measured).
    pub sharper_view_blur: Option<(bool, f32)>,
    /// How much darker than the centre (in 16-bit samples, 257 per 8-bit grey level) a neighbour
    /// had to be to set its census bit: one grey level where both views were smoothed for noise
    /// or JPEG, else 0.
    pub census_tolerance: u16,
    /// The penalties used: [`SgmParams::p1`] and [`SgmParams::p2`], raised for a noisy cost.
    pub p1: u16,
    pub p2: u16,
    /// [`SgmParams::p2_edge_scale`] used: set on noisy and JPEG pairs (P2 strong in flat areas,
    /// lowered across image edges), else as given.
    pub p2_edge_scale: u16,
}

impl Adaptation {
    /// [`Adaptation::census_tolerance`] in 8-bit grey levels.
    pub fn census_tolerance_grey(&self) -> f32 {
        f32::from(self.census_tolerance) / 257.0
    }

    /// [`Adaptation::relative_blur`] as the defocused (softer) view, `"left"` or `"right"`, and
    /// the σ (px) between the views.
    pub fn defocused_view(&self) -> Option<(&'static str, f32)> {
        self.relative_blur.map(|(left_sharper, sigma)| (if left_sharper { "right" } else { "left" }, sigma))
    }
}

impl SgmOutput {
    /// 255 where the disparity was filled rather than matched, 0 elsewhere.
    pub fn filled_mask(&self) -> Image<u8> {
        crate::fill::filled_mask(&self.disparity, &self.status)
    }
}

/// Checks the post-processing parameters.
pub(crate) fn check(params: &SgmParams) -> Result<(), Error> {
    if params.speckle_max_diff.is_nan() || params.speckle_max_diff < 0.0 {
        return Err(Error::InvalidParameter {
            name: "speckle max difference",
            message: format!("{} must be a number >= 0", params.speckle_max_diff),
        });
    }
    Ok(())
}

/// [`SgmParams::wmf_edges_only`]: the weighted median runs where its window spans more than
/// this many pixels of disparity (measured: 1 px keeps its full effect on the seven Middlebury
/// scenes, docs/accuracy.md).
const WMF_EDGE_JUMP: f32 = 1.0;

/// Range-end rejection, the median (if enabled), then [`after_median`].
pub(crate) fn finish(
    mut disparity: DisparityMap,
    left: &GrayImage,
    params: &SgmParams,
    area_reduction: usize,
) -> SgmOutput {
    reject_range_ends(&mut disparity, params.range);
    if params.median {
        disparity = median_3x3(&disparity);
    }
    after_median(disparity, left, params, area_reduction)
}

/// Rejects ([`PixelStatus::RangeEnd`]) every winner at an end of the disparities searched for it: the range's first and last disparity, and near the left border,
/// where the search stops at the image edge (disparity `x`), that edge while it lies in the lowest
/// quarter of the range. Such a winner says only that the true minimum may lie beyond; too small
/// a disparity puts the point far behind the scene. Higher up the edge stays: the true disparity
/// can only be larger, the point only nearer, and measured on the Middlebury scenes most of those
/// winners are right (docs/robustness.md). Winner-takes-all refines no subpixel offset at the
/// ends, so these pixels are exactly the ones whose disparity equals an end (an interior winner
/// moves by at most half a pixel).
pub(crate) fn reject_range_ends(disparity: &mut DisparityMap, range: DisparityRange) {
    let width = disparity.width();
    let ends = RangeEnds::disparities(range);
    let (first, last) = (range.min as f32, (range.max - 1) as f32);
    // The columns whose search covered the whole range (an interval: both ends of the feasible
    // disparities grow with x): only the range's own ends are ends there (`at_end` with `lo ==
    // first` and `hi == last`), a test the compiler vectorises.
    let is_full = |x: usize| crate::wta::feasible_left(x, width, range).len() == range.count();
    let start = (0..width).find(|&x| is_full(x)).unwrap_or(width);
    let end = (start..width).find(|&x| !is_full(x)).unwrap_or(width);
    let tag = tagged_nan(PixelStatus::RangeEnd);
    // The other columns' searched ends (`lo`, `hi`), computed once: every row tests its pixels
    // against them in a loop the compiler vectorises (a NaN is at no end).
    let searched = |x: usize| {
        let ks = crate::wta::feasible_left(x, width, range);
        (range.min as f32 + ks.start as f32, range.min as f32 + ks.end as f32 - 1.0)
    };
    let (left_band, right_band): (Vec<_>, Vec<_>) =
        ((0..start).map(searched).collect(), (end..width).map(searched).collect());
    let rows_per_task = disparity.height().div_ceil(16).max(1);
    disparity.as_mut_slice().par_chunks_mut(width.max(1) * rows_per_task).for_each(|rows| {
        // Copies, not captured references, so that the loops below vectorise.
        let (first, last, tag, ends) = (first, last, tag, ends);
        let band = |cells: &mut [f32], searched: &[(f32, f32)]| {
            for (d, &(lo, hi)) in cells.iter_mut().zip(searched) {
                *d = if ends.at_end(*d, lo, hi) { tag } else { *d };
            }
        };
        for row in rows.chunks_exact_mut(width.max(1)) {
            let (left, rest) = row.split_at_mut(start);
            let (full, right) = rest.split_at_mut(end - start);
            band(left, &left_band);
            band(right, &right_band);
            for d in full {
                *d = if (*d == first) | (*d == last) { tag } else { *d };
            }
        }
    });
}

/// How far (px) behind the surface beside it a border winner must lie for [`reject_border_cut`]
/// on the dense output: the step within which neighbours belong to one surface for the speckle
/// filter and the far islands.
const BORDER_CUT_STEP: f32 = 1.0;

/// On the other outputs, the share of the surface's disparity below which a border winner is
/// rejected: a point more than a third farther than the surface beside it.
const BORDER_CUT_RATIO: f32 = 0.75;

/// Rejects ([`PixelStatus::RangeEnd`]) the winners near the left border whose right census
/// window leaves the right image (`x - d` below `half_width`) and that lie behind the row's
/// first pixel whose window stays inside: more than [`BORDER_CUT_STEP`] behind it where the
/// output is `dense`, below [`BORDER_CUT_RATIO`] of its disparity otherwise. Where a surface's
/// true match leaves the right image, the pixels beside the border take a winner in the right
/// image's first columns, at a disparity falling towards the border (a ramp of flying points
/// behind the scene); the fill then continues the surface beside them. Without the fill a
/// rejected pixel is a hole, and the 1 px step turned right pixels into holes (bad2 up to +0.32
/// on six of the seven Middlebury scenes), the ratio only the far end of the ramp
/// (docs/robustness.md).
fn reject_border_cut(disparity: &mut DisparityMap, half_width: usize, dense: bool) {
    let width = disparity.width();
    disparity.as_mut_slice().par_chunks_exact_mut(width.max(1)).for_each(|row| {
        let inside = row.iter().enumerate().find(|&(x, &d)| !d.is_nan() && x as f32 - d >= half_width as f32);
        let Some((first_inside, &reference)) = inside else {
            return;
        };
        let limit = if dense { reference - BORDER_CUT_STEP } else { reference * BORDER_CUT_RATIO };
        for d in &mut row[..first_inside] {
            if !d.is_nan() && *d < limit {
                *d = tagged_nan(PixelStatus::RangeEnd);
            }
        }
    });
}

/// Far islands ([`crate::far_islands`]), speckle removal, the status image (plain NaNs from here on), the fill, edge snapping and the
/// weighted median.
/// `area_reduction`: the input view had this many times the pixels of `left` (the pair was reduced
/// before matching), which the fill's segmentation follows.
pub(crate) fn after_median(
    mut disparity: DisparityMap,
    left: &GrayImage,
    params: &SgmParams,
    area_reduction: usize,
) -> SgmOutput {
    reject_border_cut(&mut disparity, params.census.width / 2, params.fill);
    crate::far_islands::reject_far_islands_tagged(&mut disparity, params.range);
    remove_speckles_keeping_border(
        &mut disparity,
        params.speckle_size,
        params.speckle_max_diff,
        params.speckle_keep_border,
        params.speckle_bridge,
    );
    let status = untag(&mut disparity);
    if params.fill {
        fill_from_segment_planes(&mut disparity, &status, left, params.range, area_reduction);
        fill_invalid(&mut disparity, &status);
    }
    for _ in 0..params.edge_snap_passes {
        disparity = snap_edges(&disparity, left, params.edge_snap_radius);
    }
    if params.wmf_radius > 0 {
        disparity = if params.wmf_edges_only {
            weighted_median_at_edges(
                &disparity,
                left,
                params.wmf_radius,
                params.wmf_sigma_color,
                WMF_EDGE_JUMP,
            )
        } else {
            weighted_median(&disparity, left, params.wmf_radius, params.wmf_sigma_color, false)
        };
    }
    SgmOutput {
        disparity,
        status,
        confidence: None,
        adaptation: Adaptation::default(),
        search: SearchReport::default(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::status::status_of;

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

        /// Integer winners (and holes) at every disparity of ranges with negative, zero and
        /// positive minimums: the per-pixel test of every column gives the same map.
        #[test]
        fn range_ends_match_the_per_pixel_test(w in 1usize..60, min in -20i32..20, count in 1i32..40, seed in proptest::prelude::any::<u64>()) {
            let range = DisparityRange::new(min, min + count).unwrap();
            let mut s = seed | 1;
            let mut next = move || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s };
            let map = DisparityMap::from_fn(w, 3, |_, _| match next() % 8 {
                0 => f32::NAN,
                k => (min + (next() % count as u64) as i32) as f32 + if k == 1 { 0.5 } else { 0.0 },
            });
            let mut fast = map.clone();
            reject_range_ends(&mut fast, range);
            let ends = RangeEnds::disparities(range);
            let mut slow = map;
            for y in 0..3 {
                for x in 0..w {
                    let d = slow.get(x, y);
                    let ks = crate::wta::feasible_left(x, w, range);
                    let (lo, hi) = (min as f32 + ks.start as f32, min as f32 + ks.end as f32 - 1.0);
                    if !d.is_nan() && ends.at_end(d, lo, hi) {
                        slow.set(x, y, tagged_nan(PixelStatus::RangeEnd));
                    }
                }
            }
            for (a, b) in fast.as_slice().iter().zip(slow.as_slice()) {
                proptest::prop_assert!(a.to_bits() == b.to_bits());
            }
        }
    }

    #[test]
    fn border_ramps_behind_the_surface_are_rejected() {
        // Row 0: a ramp falling towards the border in front of a surface at 5 px (the first pixel
        // whose 9-wide window stays inside is x = 9, 9 - 5 >= 4). Row 1: the surface reaches the
        // border. Row 2: a nearer pixel and one within the step stay. Row 3: nothing valid.
        let ramp = [1.5, 2.0, 2.5, 3.0];
        let mut d = DisparityMap::from_fn(20, 4, |x, y| match (x, y) {
            (0..=3, 0) => ramp[x],
            (0, 2) => 8.0,
            (1, 2) => 4.2,
            (_, 3) => f32::NAN,
            _ => 5.0,
        });
        let before = d.clone();
        reject_border_cut(&mut d, 4, true);
        for (x, y) in (0..20).flat_map(|x| (0..4).map(move |y| (x, y))) {
            if y == 0 && x < 4 {
                assert_eq!(status_of(d.get(x, y)), PixelStatus::RangeEnd, "({x}, {y})");
            } else {
                assert_eq!(d.get(x, y).to_bits(), before.get(x, y).to_bits(), "({x}, {y})");
            }
        }
    }

    #[test]
    fn without_the_fill_only_the_far_end_of_a_border_ramp_goes() {
        // Before a surface at 8 px (first window inside: x = 12): winners at 7.0 (within the step),
        // 6.5 (more than 1 px behind: rejected for the fill, kept without it as it lies within
        // a third of the surface's depth) and 5.0 (beyond: rejected on both outputs).
        let row = [5.0, 6.5, 7.0];
        let d = DisparityMap::from_fn(24, 1, |x, _| if x < 3 { row[x] } else { 8.0 });
        let (mut dense, mut sparse) = (d.clone(), d);
        reject_border_cut(&mut dense, 4, true);
        reject_border_cut(&mut sparse, 4, false);
        let status = |m: &DisparityMap| (0..3).map(|x| status_of(m.get(x, 0))).collect::<Vec<_>>();
        assert_eq!(status(&dense), [PixelStatus::RangeEnd, PixelStatus::RangeEnd, PixelStatus::Matched]);
        assert_eq!(status(&sparse), [PixelStatus::RangeEnd, PixelStatus::Matched, PixelStatus::Matched]);
        assert_eq!(sparse.get(1, 0), 6.5);
    }
}
