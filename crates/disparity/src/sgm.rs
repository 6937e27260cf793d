//! Semi-Global Matching: census (or AD-census) costs, path aggregation, winner-takes-all, checks.

use crate::aggregate::{aggregate_and_select, stream_and_select, Inputs, P2Table, MAX_P2};
use crate::buffer::ScratchBuffer;
use crate::census::census_transform_tolerant;
use crate::confidence::census_confidence;
use crate::cost::infeasible_cost;
use crate::hierarchical::{aggregate_bands, stream_bands, Bands};
use crate::memory;
use crate::post::{Adaptation, SearchReport, SgmOutput};
use crate::radiometric::{blockiness, CoarseMatch};
use crate::tone::{AttenuatedView, ToneCorrection, ToneSample, Vignetting};
use crate::widen::{replicate, widen_disparity};
use crate::wta::Selection;
use crate::{
    check_pair, DisparityMap, DisparityRange, Downscale, Error, GrayImage, Image, MatchingCost, Search,
    SgmParams, AUTO_DOWNSCALE_MIN_PIXELS, AUTO_DOWNSCALE_SMOOTHNESS, COARSE_MIN_DISPARITIES,
    COARSE_MIN_PIXELS,
};
use rayon::prelude::*;
use std::borrow::Cow;

/// Semi-Global Matching of a rectified pair (Hirschmüller 2008) with census or AD-census costs
/// ([`SgmParams::matching_cost`]).
///
/// Returns the left view's disparity map; NaN where no disparity in the range fits, or where the
/// uniqueness or left-right check rejects the match.
pub fn sgm(left: &GrayImage, right: &GrayImage, params: &SgmParams) -> Result<DisparityMap, Error> {
    sgm_detailed(left, right, params).map(|output| output.disparity)
}

/// [`sgm`] with the per-pixel [`crate::PixelStatus`] image: why each invalid pixel was rejected
/// and, with [`SgmParams::fill`], which pixels were filled ([`SgmOutput::filled_mask`]).
pub fn sgm_detailed(left: &GrayImage, right: &GrayImage, params: &SgmParams) -> Result<SgmOutput, Error> {
    crate::on_pool_thread(|| sgm_on_pool_thread(left, right, params, 1))
}

/// `area_reduction`: the caller's view has this many times the pixels of `left` (1, or the
/// [`SgmParams::downscale`] factors' product when `left` is the reduced view).
fn sgm_on_pool_thread(
    left: &GrayImage,
    right: &GrayImage,
    params: &SgmParams,
    area_reduction: usize,
) -> Result<SgmOutput, Error> {
    check_pair(left, right)?;
    params.validate()?;
    if let Some((factors, small_left, small_right)) = reduction(left, right, params) {
        return match_downscaled(left, small_left, small_right, factors, params);
    }
    let (width, height) = left.size();
    if width < params.census.width || height < params.census.height {
        return Err(Error::ImageTooSmall {
            width,
            height,
            window_width: params.census.width,
            window_height: params.census.height,
        });
    }
    crate::check_range(&params.range, width)?;
    let Adapted { params: adapted, census_left, census_right, views, adaptation } =
        adapt_to_pair(left, right, params, census_transform_tolerant);
    let params = &adapted;

    memory::plan(width, height, params).check(width, height, params)?;
    let (matching_left, matching_right, edges_left) = views.resolve(left, right);
    let (disparity, search) =
        match_census(matching_left, matching_right, &census_left, &census_right, params);
    let confidence = params.confidence.then(|| {
        let bits = (params.census.width * params.census.height - 1) as u32;
        census_confidence(&disparity, &census_left, &census_right, bits)
    });
    drop((census_left, census_right));

    let mut output = crate::post::finish(disparity, edges_left, params, area_reduction);
    if let Some(mut confidence) = confidence {
        // Pixels the post-processing invalidated or filled were not matched: no confidence.
        for ((c, &status), d) in confidence
            .as_mut_slice()
            .iter_mut()
            .zip(output.status.as_slice())
            .zip(output.disparity.as_slice())
        {
            if status != 0 || !d.is_finite() {
                *c = 0.0;
            }
        }
        output.confidence = Some(confidence);
    }
    output.adaptation = adaptation;
    output.search = search;
    Ok(output)
}

/// Both views reduced by the factors `(columns, rows)` ([`crate::radiometric::downsample_by`]).
fn reduce_pair(
    left: &GrayImage,
    right: &GrayImage,
    (columns, rows): (usize, usize),
) -> (GrayImage, GrayImage) {
    rayon::join(
        || crate::radiometric::downsample_by(left, columns, rows),
        || crate::radiometric::downsample_by(right, columns, rows),
    )
}

/// The reduction [`SgmParams::downscale`] asks for on this pair, if any: the factors of the
/// columns and of the rows, and both views reduced by them.
fn reduction(
    left: &GrayImage,
    right: &GrayImage,
    params: &SgmParams,
) -> Option<((usize, usize), GrayImage, GrayImage)> {
    let reduced = |factors| {
        let (l, r) = reduce_pair(left, right, factors);
        (factors, l, r)
    };
    match params.downscale {
        Downscale::By(f) if f > 1 => Some(reduced((f, f))),
        Downscale::By(_) => None,
        Downscale::Auto | Downscale::Coarse => {
            if params.range.count() < 2 {
                return None;
            }
            // Coarse where the range is too short to halve (again): the rows are halved once
            // more than the columns (the disparities keep the matched pair's resolution).
            let (width, height) = left.size();
            let rows_halved_too = |f: usize| {
                let (w, h) = (width / f, height / (2 * f));
                params.downscale == Downscale::Coarse
                    && params.range.count() / (2 * f) < COARSE_MIN_DISPARITIES
                    && w * h >= COARSE_MIN_PIXELS
                    && h >= params.census.height
            };
            if let Some((f, l, r)) = halved_pair(left, right, params) {
                if f == 2 && rows_halved_too(2) {
                    drop((l, r));
                    return Some(reduced((2, 4)));
                }
                return Some(((f, f), l, r));
            }
            rows_halved_too(1).then(|| reduced((1, 2)))
        }
    }
}

/// The pair as [`Downscale::Auto`] (or [`Downscale::Coarse`]) reduces both its sides, if it
/// does, and the factor. Halved while the halved pair keeps the floor and both halved views kept the gradient
/// energy of views with no detail finer than 2 px (each level's energies computed once); but a
/// disparity matched reduced by f carries f times the reduced match's subpixel error, so the
/// last of two or more halvings becomes a reduction by 1.5 (4 → 3, 8 → 6): at 4 a half-pixel
/// error of the reduced match is already a 2 px error (docs/performance.md).
fn halved_pair(
    left: &GrayImage,
    right: &GrayImage,
    params: &SgmParams,
) -> Option<(usize, GrayImage, GrayImage)> {
    let fits = |(w, h): (usize, usize), min_pixels: usize| {
        let (hw, hh) = (w / 2, h / 2);
        hw * hh >= min_pixels && hw >= params.census.width && hh >= params.census.height
    };
    let halvable = |size| fits(size, AUTO_DOWNSCALE_MIN_PIXELS);
    let energies =
        |(l, r): (&GrayImage, &GrayImage)| rayon::join(|| gradient_energy(l), || gradient_energy(r));
    let mut halved: Option<(GrayImage, GrayImage)> = None;
    let mut halvings = 0;
    // Coarse: the first halving needs no smoothness (so no full-resolution energies), only a
    // range and a size that survive it.
    let mut energy = if params.downscale == Downscale::Coarse
        && params.range.count() / 2 >= COARSE_MIN_DISPARITIES
        && fits(left.size(), COARSE_MIN_PIXELS)
    {
        let next = reduce_pair(left, right, (2, 2));
        let next_energy = energies((&next.0, &next.1));
        (halved, halvings) = (Some(next), 1);
        next_energy
    } else if halvable(left.size()) {
        energies((left, right))
    } else {
        return None;
    };
    // The sensor noise, estimated once and only where the raw energies fail the test (a pair
    // that passes without the noise passes with it discounted).
    let mut noise: Option<f64> = None;
    loop {
        let (l, r) = halved.as_ref().map_or((left, right), |(l, r)| (l, r));
        if !halvable(l.size()) {
            break;
        }
        let next = reduce_pair(l, r, (2, 2));
        let next_energy = energies((&next.0, &next.1));
        let both_smooth = |variance: f64| {
            smooth_enough(energy.0, next_energy.0, variance)
                && smooth_enough(energy.1, next_energy.1, variance)
        };
        if !both_smooth(0.0) {
            // The rig's noise: the larger of the two views' estimates, as a view resampled for
            // its vertical offset (or blurred) lost part of its noise to the interpolation; at
            // most σ MAX_SENSOR_NOISE. Each halving (a 2 × 2 mean) divides its variance by 4.
            let rig_noise = *noise.get_or_insert_with(|| {
                let (l, r) = rayon::join(|| noise_variance(left), || noise_variance(right));
                l.max(r).min((MAX_SENSOR_NOISE * 257.0).powi(2))
            });
            if !both_smooth(rig_noise / 4f64.powi(halvings)) {
                break;
            }
        }
        halvings += 1;
        (halved, energy) = (Some(next), next_energy);
    }
    match halvings {
        0 => None,
        1 => halved.map(|(l, r)| (2, l, r)),
        _ => {
            drop(halved);
            let f = 3 << (halvings - 2);
            let (l, r) = reduce_pair(left, right, (f, f));
            Some((f, l, r))
        }
    }
}

/// The most sensor noise [`Downscale::Auto`] discounts, σ in 8-bit grey levels. One view cannot
/// tell noise from a texture that changes at every pixel (only the other view can: the texture
/// is in both); above this it is taken for texture, and such a pair stays at full resolution.
/// Camera noise is usually σ 1–5 grey levels; issue 13's strongest is 6.
const MAX_SENSOR_NOISE: f64 = 8.0;

/// [`Downscale::Auto`]'s test for one view and one halving: the halved view's gradient energy
/// is at least [`AUTO_DOWNSCALE_SMOOTHNESS`] times this level's, both net of the white noise of
/// `variance` (this level's) they hold. Noise, independent from pixel to pixel, adds twice its
/// variance to the energy and reads as detail at every pixel; discounted, a noisy view of a
/// smooth scene halves like a clean one (measured: 4× enlargements with σ 6 grey-level noise
/// matched at full resolution for equal or worse bad2, docs/performance.md).
fn smooth_enough(energy: f64, halved_energy: f64, variance: f64) -> bool {
    (halved_energy - 0.5 * variance).max(0.0)
        >= AUTO_DOWNSCALE_SMOOTHNESS * (energy - 2.0 * variance).max(0.0)
}

/// A view's white-noise variance in squared 16-bit samples, as Immerkær (1996) estimates it but
/// with a median, which edges and texture (a minority of the pixels) do not move: white noise of
/// σ gives the 3 × 3 Laplacian `[1 −2 1; −2 4 −2; 1 −2 1]` a response of σ·6 standard deviation,
/// whose median absolute value is 0.6745 of that. Every 4th row is sampled; an integer
/// histogram makes it the same on any number of threads.
fn noise_variance(image: &GrayImage) -> f64 {
    const BINS: usize = 1 << 16;
    let (w, h) = image.size();
    if w < 3 || h < 3 {
        return 0.0;
    }
    let histogram = (1..h - 1)
        .into_par_iter()
        .step_by(4)
        .fold(
            || vec![0u32; BINS],
            |mut histogram, y| {
                let (above, row, below) = (image.row(y - 1), image.row(y), image.row(y + 1));
                let at = |r: &[u16], x: usize| i32::from(r[x]);
                for x in 1..w - 1 {
                    let corners = at(above, x - 1) + at(above, x + 1) + at(below, x - 1) + at(below, x + 1);
                    let sides = at(above, x) + at(row, x - 1) + at(row, x + 1) + at(below, x);
                    let response = corners - 2 * sides + 4 * at(row, x);
                    histogram[(response.unsigned_abs() as usize).min(BINS - 1)] += 1;
                }
                histogram
            },
        )
        .reduce(
            || vec![0u32; BINS],
            |mut a, b| {
                a.iter_mut().zip(b).for_each(|(a, b)| *a += b);
                a
            },
        );
    let count: u64 = histogram.iter().map(|&n| u64::from(n)).sum();
    let mut seen = 0u64;
    let median = histogram
        .iter()
        .position(|&n| {
            seen += u64::from(n);
            2 * seen >= count
        })
        .unwrap_or(0);
    (median as f64 / (6.0 * 0.6745)).powi(2)
}

/// The mean squared difference between horizontal and vertical neighbours (summed per row, then
/// over the rows in order: the same value on any number of threads).
fn gradient_energy(image: &GrayImage) -> f64 {
    let (w, h) = image.size();
    if w < 2 || h < 2 {
        return 0.0;
    }
    let rows: Vec<f64> = (0..h - 1)
        .into_par_iter()
        .map(|y| row_gradient_energy(image.row(y), image.row(y + 1)) as f64)
        .collect();
    rows.iter().sum::<f64>() / ((w * (h - 1) + (w - 1) * (h - 1)) as f64)
}

/// The squared steps from each pixel of `row` to the one below it and to its right neighbour,
/// summed: an integer, so the same however it is vectorised.
#[inline(always)]
fn row_gradient_energy_generic(row: &[u16], below: &[u16], _level: crate::kernels::Level) -> u64 {
    // A squared step of 16-bit samples fits in u32.
    let square = |a: u16, b: u16| u64::from(u32::from(a.abs_diff(b)).pow(2));
    let vertical: u64 = row.iter().zip(below).map(|(&a, &b)| square(a, b)).sum();
    let horizontal: u64 = row[..row.len() - 1].iter().zip(&row[1..]).map(|(&a, &b)| square(a, b)).sum();
    vertical + horizontal
}

crate::kernels::multiversion! {
    /// [`row_gradient_energy_generic`] compiled for the detected level (the 32-bit products
    /// vectorise only with AVX2 or later).
    fn row_gradient_energy(row: &[u16], below: &[u16]) -> u64 => row_gradient_energy_generic;
}

/// [`SgmParams::downscale`]: the pair reduced by the factors `(f, rows)` of its columns and rows
/// (box filter, as the coarse levels; `rows` is `f`, or 2 with `f` 1 where only the rows were
/// halved) matched with the range divided by `f` (rounded outwards) and every other parameter
/// as given, then brought back: each reduced pixel covers `f × rows` pixels (the last row and
/// column repeat where the size is not a multiple) with its disparity, status and confidence,
/// the disparity times `f`. A disparity that lands outside the range asked for is rejected
/// ([`crate::PixelStatus::RangeEnd`]).
fn match_downscaled(
    left: &GrayImage,
    small_left: GrayImage,
    small_right: GrayImage,
    factors @ (f, rows): (usize, usize),
    params: &SgmParams,
) -> Result<SgmOutput, Error> {
    let (width, height) = left.size();
    let (small_width, small_height) = small_left.size();
    if small_width < params.census.width || small_height < params.census.height {
        return Err(Error::InvalidParameter {
            name: "downscale",
            message: format!(
                "{width}x{height} reduced by {f} is {small_width}x{small_height}, smaller than the {}x{} census window",
                params.census.width, params.census.height
            ),
        });
    }
    let range = params.range;
    crate::check_range(&range, width)?;
    let small_range = crate::radiometric::reduced_range(range, f);
    // At most as many disparities as the reduced pair is wide (rounding outwards can add one).
    let small_range =
        DisparityRange { max: small_range.max.min(small_range.min + small_width as i32), ..small_range };
    // The factor was decided on the full pair (auto included): the reduced pair is matched as it is.
    let small_params = SgmParams { range: small_range, downscale: Downscale::By(1), ..params.clone() };
    let mut small = sgm_on_pool_thread(&small_left, &small_right, &small_params, f * rows)?;
    drop((small_left, small_right));

    // A disparity that lands outside the range asked for is rejected, decided on the reduced map.
    let scale = f as f32;
    let (lo, hi) = (range.min as f32, (range.max - 1) as f32);
    let range_end = crate::PixelStatus::RangeEnd as u8;
    let chunk = small_width * 16;
    let statuses = small.status.as_mut_slice().par_chunks_mut(chunk);
    small.disparity.as_mut_slice().par_chunks_mut(chunk).zip(statuses).for_each(|(disparity, status)| {
        for (d, s) in disparity.iter_mut().zip(status) {
            let v = *d * scale;
            if v.is_nan() || (lo..=hi).contains(&v) {
                *d = v;
            } else {
                (*d, *s) = (f32::NAN, range_end);
            }
        }
    });
    let (small_disparity, small_status) = (small.disparity.as_slice(), small.status.as_slice());
    let disparity = widen_disparity(small_disparity, small_width, factors, width, height);
    let status = replicate(small_status, small_width, factors, width, height);
    let confidence =
        small.confidence.as_ref().map(|c| replicate(c.as_slice(), small_width, factors, width, height));
    Ok(SgmOutput {
        disparity,
        status,
        confidence,
        adaptation: small.adaptation,
        search: SearchReport { downscale: f, rows_halved: rows != f, ..small.search },
    })
}

/// What [`SgmParams::adapt_to_pair`] does before aggregation, shared by the matcher and its scalar
/// reference (each with its own census transform): the coarse match, the census images (of
/// smoothed views where the cost is noisy or blocky), the cost without its intensity term where the
/// views differ radiometrically (unless mapping the right view's tones onto the left's makes them
/// agree), and the penalties scaled for a noisy cost.
pub(crate) fn adapt_to_pair(
    left: &GrayImage,
    right: &GrayImage,
    params: &SgmParams,
    census: impl Fn(&GrayImage, crate::CensusWindow, u16, &mut Image<u64>) + Sync,
) -> Adapted {
    let (width, height) = left.size();
    let mut census_left = Image::new(width, height, 0u64);
    let mut census_right = Image::new(width, height, 0u64);
    // The census of the views as given (the pair's noise is measured on them: clipped alike, the
    // flat areas would match perfectly and hide it) beside the coarse match and the views'
    // relative blur, which are too small to keep both threads busy.
    let ((coarse, input_blur), _) = rayon::join(
        || {
            let coarse = params.adapt_to_pair.then(|| CoarseMatch::new(left, right, params, sgm)).flatten();
            (coarse, params.adapt_to_pair.then(|| crate::radiometric::relative_blur(left, right)).flatten())
        },
        || {
            rayon::join(
                || census(left, params.census, 0, &mut census_left),
                || census(right, params.census, 0, &mut census_right),
            )
        },
    );
    let radiometric_difference = coarse.as_ref().and_then(|c| c.radiometric_difference(None));
    let wants_intensity_term = matches!(params.matching_cost, MatchingCost::AdCensus { .. });
    let differs = views_differ(radiometric_difference);
    // Shadows or highlights clipped in one view only: the other view clipped alike, so that census
    // sees both flat there, and census alone (docs/robustness.md).
    // The coarse match's pixel pairs, which both the clipping and the tone correction read.
    let samples: Vec<_> = match (&coarse, differs) {
        (Some(c), true) => c.tone_samples().collect(),
        _ => Vec::new(),
    };
    let clipped = differs
        .then(|| crate::radiometric::Clipping::matching(left, right, &samples))
        .flatten()
        .map(|c| c.apply(left, right));
    let (input_left, input_right) = (left, right);
    let (left, right) = clipped.as_ref().map_or((left, right), |(l, r)| (l, r));
    // Otherwise views that differ in exposure, gamma or vignetting: the right view's tones mapped
    // onto the left's, and the intensity term kept on that view if the two then agree
    // (docs/robustness.md).
    let corrected = (wants_intensity_term && differs && clipped.is_none())
        .then(|| coarse.as_ref().and_then(|c| correct_tones(c, &samples, left, right)))
        .flatten();
    let corrected_difference = corrected.as_ref().map(|(_, _, d)| *d);
    let (corrected_left, corrected_right) = match corrected {
        Some((l, r, d)) if d <= MAX_CORRECTED_DIFFERENCE => (l, Some(r)),
        _ => (None, None),
    };
    let intensity_term = wants_intensity_term && (!differs || corrected_right.is_some());
    let matching_cost = if intensity_term { params.matching_cost } else { MatchingCost::Census };
    let residual = coarse.as_ref().and_then(|c| c.census_residual(&census_left, &census_right));
    if clipped.is_some() {
        rayon::join(
            || census(left, params.census, 0, &mut census_left),
            || census(right, params.census, 0, &mut census_right),
        );
    }
    let blockiness = params.adapt_to_pair.then(|| blockiness(input_left).min(blockiness(input_right)));
    // A noisy census (sensor noise, a blurred view, JPEG blocks) compares smoothed views instead:
    // single noisy pixels then flip fewer bits, block edges fade, and the two views' sharpness is
    // closer (docs/robustness.md).
    let census_smoothing = smooths_census(residual, blockiness);
    // A one-sided defocus (JPEG blocks excepted: their views are equally sharp). A defocused left
    // view is the reference, whose blur widens every edge the map is drawn on: it is sharpened
    // at the measured blur, for census, the intensity term and the post-processing's edges
    // (docs/robustness.md).
    let relative_blur = match clipped {
        _ if blockiness.is_some_and(|b| b > CLEAN_BLOCKINESS) => None,
        Some(_) => crate::radiometric::relative_blur(left, right),
        None => input_blur,
    };
    // The blur σ of a defocused left view (`relative_blur`'s `false`: the right view is the
    // sharper), which every view of it the matcher reads is sharpened by.
    let left_defocus = match relative_blur {
        Some((false, sigma)) => Some(sigma),
        _ => None,
    };
    let sharpened_left = left_defocus.map(|sigma| crate::radiometric::unsharp_mask(left, sigma));
    let census_view_left = sharpened_left.as_ref().unwrap_or(left);
    // With a one-sided defocus under the census smoothing, the sharper view is blurred to nearly
    // match the other instead of both being smoothed (docs/robustness.md).
    let sharper_view_blur = relative_blur
        .filter(|_| census_smoothing)
        .map(|(left_sharper, sigma)| (left_sharper, sigma * crate::radiometric::MATCHED_BLUR_FRACTION));
    // Both views smoothed for noise or JPEG: what differences of a grey level or less remain are
    // mostly noise, and in flat areas they gave the views unrelated bit strings. (A one-sided blur
    // has no such noise: measured worse there, docs/robustness.md.)
    let census_tolerance =
        if census_smoothing && sharper_view_blur.is_none() { NOISY_CENSUS_TOLERANCE } else { 0 };
    if census_smoothing {
        let sigma = crate::radiometric::NOISY_CENSUS_SMOOTHING;
        let (l, r) = match sharper_view_blur {
            Some((true, s)) => (Cow::Owned(crate::radiometric::gaussian_blur(left, s)), Cow::Borrowed(right)),
            Some((false, s)) => {
                (Cow::Borrowed(census_view_left), Cow::Owned(crate::radiometric::gaussian_blur(right, s)))
            }
            None => {
                let (l, r) = rayon::join(
                    || crate::radiometric::gaussian_blur(left, sigma),
                    || crate::radiometric::gaussian_blur(right, sigma),
                );
                (Cow::Owned(l), Cow::Owned(r))
            }
        };
        rayon::join(
            || census(&l, params.census, census_tolerance, &mut census_left),
            || census(&r, params.census, census_tolerance, &mut census_right),
        );
    } else if sharpened_left.is_some() {
        census(census_view_left, params.census, 0, &mut census_left);
    }
    // The dense output's stricter left-right check and fill do better with the penalties of the
    // views census now compares, where one view was blurred to match the other
    // (docs/robustness.md).
    let penalty_residual = if params.fill && sharper_view_blur.is_some() {
        coarse.as_ref().and_then(|c| c.census_residual(&census_left, &census_right))
    } else {
        residual
    };
    let mut adapted =
        SgmParams { matching_cost, ..scaled_penalties(params, penalty_scale(penalty_residual, blockiness)) };
    // Noise and JPEG blocks leave weak texture (dark or flat areas) without a reliable cost, where
    // only a strong smoothness term finds the surface; a P2 that stays strong there but drops
    // across image edges keeps depth edges free. Measured better for the default output on noisy
    // and JPEG pairs, worse for the dense one and for a one-sided blur (docs/robustness.md).
    // Views clipped alike are flat wherever either view was clipped, weak texture of another
    // kind: the same P2 carries the surface across it (measured better on 13 of the 16 clipped
    // gain 1.6 and bias -40 pairs, with either view the clipped one; docs/robustness.md).
    let weak_texture = (census_smoothing || clipped.is_some()) && sharper_view_blur.is_none();
    if weak_texture && !params.fill && params.p2_edge_scale == 0 {
        adapted.p2 = adapted.p2.saturating_mul(NOISY_P2_FACTOR).min(MAX_P2);
        adapted.p2_edge_scale = NOISY_P2_EDGE_SCALE;
    }
    let adaptation = Adaptation {
        radiometric_difference,
        corrected_radiometric_difference: corrected_difference,
        clipped_alike: clipped.is_some(),
        intensity_term,
        census_residual: residual,
        blockiness,
        census_smoothing,
        relative_blur,
        sharper_view_blur,
        census_tolerance,
        p1: adapted.p1,
        p2: adapted.p2,
        p2_edge_scale: adapted.p2_edge_scale,
    };
    let (matching_left, matching_right) = match clipped {
        Some((l, r)) => (Some(l), Some(corrected_right.unwrap_or(r))),
        // A vignetted left view that is also the defocused one: the intensity term compares it
        // corrected and sharpened (wood2, left view vignetted 40 % and blurred 1.5 px: bad2
        // 18.06 / 2.62 → 17.91 / 2.55, docs/robustness.md).
        None => match (corrected_left, left_defocus) {
            (Some(l), Some(sigma)) => (Some(crate::radiometric::unsharp_mask(&l, sigma)), corrected_right),
            (l, _) => (l, corrected_right),
        },
    };
    let views = AdaptedViews { left: matching_left, right: matching_right, sharpened_left };
    Adapted { params: adapted, census_left, census_right, views, adaptation }
}

/// What [`adapt_to_pair`] makes of the pair.
pub(crate) struct Adapted {
    pub(crate) params: SgmParams,
    pub(crate) census_left: Image<u64>,
    pub(crate) census_right: Image<u64>,
    pub(crate) views: AdaptedViews,
    pub(crate) adaptation: Adaptation,
}

/// The views [`adapt_to_pair`] made in place of the input views; `None`: the view as given.
pub(crate) struct AdaptedViews {
    /// The views the matcher compares: clipped alike ([`crate::radiometric::Clipping`]), the
    /// right one's tones mapped onto the left's and a vignetting undone in either
    /// ([`ToneCorrection`]; a corrected left view that is the defocused one also sharpened).
    left: Option<GrayImage>,
    right: Option<GrayImage>,
    /// The left view sharpened where it is the defocused one of a one-sided blur
    /// ([`crate::radiometric::unsharp_mask`]): matched where `left` is `None`, and the view whose
    /// edges the post-processing follows.
    sharpened_left: Option<GrayImage>,
}

impl AdaptedViews {
    /// The left and right views to match, and the left view whose edges the post-processing
    /// follows, given the input views.
    pub(crate) fn resolve<'a>(
        &'a self,
        left: &'a GrayImage,
        right: &'a GrayImage,
    ) -> (&'a GrayImage, &'a GrayImage, &'a GrayImage) {
        let sharpened = self.sharpened_left.as_ref();
        (
            self.left.as_ref().or(sharpened).unwrap_or(left),
            self.right.as_ref().unwrap_or(right),
            sharpened.unwrap_or(left),
        )
    }
}

/// The right view with its tones mapped onto the left's ([`ToneCorrection`], fitted to the coarse
/// match), the left view where the vignetting undone was its own, and the radiometric difference
/// that remains; `None` where the fit fails or where the mapped view would mislead the intensity
/// term: levels stretched apart by more than [`MAX_TONE_EXPANSION`] (its quantisation steps
/// become false texture) or a strong gamma ([`MAX_TONE_NONLINEARITY`]).
fn correct_tones(
    coarse: &CoarseMatch,
    samples: &[ToneSample],
    left: &GrayImage,
    right: &GrayImage,
) -> Option<(Option<GrayImage>, GrayImage, f32)> {
    // A tone curve alone, with a quadratic vignetting, and with a radial one (fewer unknowns: on
    // teddy it fits where the quadratic one trades against the curve): the one that leaves the
    // smaller difference (the first of equals). A vignetting is fitted over the right view's
    // positions unless fitting it over the left view's explains the matched levels clearly
    // better (a vignetted left view: docs/robustness.md).
    let aspect = right.width() as f32 / right.height() as f32;
    let fits = |view| {
        [None, Some(Vignetting::Quadratic), Some(Vignetting::Radial { aspect })]
            .into_iter()
            .filter(move |v| v.is_some() || view == AttenuatedView::Right)
            .filter_map(move |v| Some((v.is_some(), ToneCorrection::fit(samples, v, view)?)))
            .collect::<Vec<_>>()
    };
    let (in_right, in_left) = rayon::join(|| fits(AttenuatedView::Right), || fits(AttenuatedView::Left));
    let best_residual = |fits: &[(bool, ToneCorrection)]| {
        fits.iter().filter(|f| f.0).filter_map(|f| f.1.median_residual(samples)).min_by(f32::total_cmp)
    };
    let left_vignetted = match (best_residual(&in_left), best_residual(&in_right)) {
        (Some(left), Some(right)) => left < LEFT_VIGNETTING_RESIDUAL_RATIO * right,
        _ => false,
    };
    let (correction, difference) = if left_vignetted { in_left } else { in_right }
        .into_iter()
        .filter_map(|(_, correction)| {
            let difference = coarse.radiometric_difference(Some(&correction))?;
            Some((correction, difference))
        })
        .min_by(|a, b| a.1.total_cmp(&b.1))?;
    let plausible = correction.expansion(samples) <= MAX_TONE_EXPANSION
        && correction.nonlinearity(samples) <= MAX_TONE_NONLINEARITY;
    plausible.then(|| {
        let (left, right) = correction.apply(left, right);
        (left, right, difference)
    })
}

/// A vignetting is fitted over the left view's positions where that leaves a median residual
/// below this share of the right view's: 0.62 on wood2 with its left view vignetted 40 %, 0.97 or
/// more on the 44 other fitted gain, gamma, bias, vignetting and combined pairs of
/// docs/robustness.md.
const LEFT_VIGNETTING_RESIDUAL_RATIO: f32 = 0.8;

/// The largest [`ToneCorrection::expansion`] accepted (gain 0.6 measures 1.7–1.9) …
const MAX_TONE_EXPANSION: f32 = 2.5;
/// … the largest [`ToneCorrection::nonlinearity`] (8-bit levels): gains, biases and vignetting
/// measure 0.6–9.3 on the seven scenes, gammas 0.5 and 2 6–43. A camera applies its gamma to each
/// colour channel, so a coloured surface follows another grey-level curve than a grey one: on cones
/// with gamma 2 (18.6) the corrected intensity term made the red cones worse (bad2 14.64 → 17.17) …
const MAX_TONE_NONLINEARITY: f32 = 10.0;
/// … and the largest radiometric difference left after the correction for the intensity term to
/// compare the corrected view (clean pairs measure 0.2–5.8 uncorrected).
const MAX_CORRECTED_DIFFERENCE: f32 = 3.0;

/// Whether the two views render surfaces too differently for AD-census' intensity term, given
/// their measured [`Adaptation::radiometric_difference`]. The term only helps while both views
/// render a surface alike; when they differ (exposure, gamma, vignetting) it misleads, and the cost
/// falls back to census alone, which no monotonic change of intensity affects.
fn views_differ(radiometric_difference: Option<f32>) -> bool {
    matches!(radiometric_difference, Some(d) if d > crate::radiometric::MAX_RADIOMETRIC_DIFFERENCE)
}

/// How much to raise P1 and P2 for a pair whose census cost is noisy at the true match
/// ([`CoarseMatch::census_residual`], in differing bits) or whose views carry JPEG blocks
/// ([`blockiness`], the smaller of the two views'): noise, JPEG and a one-sided blur flip census
/// bits, and stronger smoothness keeps those flips from choosing the winner. 1 up to what clean
/// pairs show, then proportional, at most 2 (docs/robustness.md).
pub(crate) fn penalty_scale(residual: Option<f32>, blockiness: Option<f32>) -> f32 {
    let noisy = residual.map_or(1.0, |r| r / crate::radiometric::CLEAN_CENSUS_RESIDUAL);
    let blocky = blockiness.map_or(1.0, |b| 1.0 + (b - CLEAN_BLOCKINESS) / BLOCKINESS_PER_STEP);
    noisy.max(blocky).clamp(1.0, 2.0)
}

/// Whether census compares smoothed views: a census residual above the clean pairs' or JPEG blocks.
pub(crate) fn smooths_census(residual: Option<f32>, blockiness: Option<f32>) -> bool {
    residual.is_some_and(|r| r > crate::radiometric::CLEAN_CENSUS_RESIDUAL)
        || blockiness.is_some_and(|b| b > CLEAN_BLOCKINESS)
}

/// How much more P2 the default output takes on a noisy or JPEG pair ([`adapt_to_pair`]) …
const NOISY_P2_FACTOR: u16 = 2;
/// … lowered across image edges as `P2 · s / (s + ΔI)` with this `s` ([`SgmParams::p2_edge_scale`]).
const NOISY_P2_EDGE_SCALE: u16 = 30;

/// The census tolerance on noisy and JPEG pairs (both views smoothed): one 8-bit grey level in
/// samples. Measured 0, ½, 1 and 1½ levels on noise σ 6 and JPEG 50 (docs/robustness.md).
const NOISY_CENSUS_TOLERANCE: u16 = 257;

/// The largest [`blockiness`] of an uncompressed view (1.02 on the Middlebury scenes) …
const CLEAN_BLOCKINESS: f32 = 1.05;
/// … and how much more doubles the penalties (JPEG at quality 50 measures 1.22–1.90).
const BLOCKINESS_PER_STEP: f32 = 0.15;

/// `params` with P1 and P2 scaled by `scale` (P2 at most [`MAX_P2`]).
pub(crate) fn scaled_penalties(params: &SgmParams, scale: f32) -> SgmParams {
    let scale = |p: u16| (f32::from(p) * scale).round() as u16;
    SgmParams { p1: scale(params.p1), p2: scale(params.p2).min(MAX_P2), ..params.clone() }
}

/// The smallest disparity range [`Search::Auto`] searches coarse to fine …
pub(crate) const AUTO_HIERARCHICAL_MIN_DISPARITIES: usize = 256;
/// … or, on images of at least [`AUTO_HIERARCHICAL_MIN_PIXELS`], this range: there the full
/// search loses accuracy (measured on the 4× enlarged venus, 1736×1532 with 128 disparities:
/// bad2 19.3 full, 13.5 coarse to fine, at 0.9× the speed; docs/performance.md).
pub(crate) const AUTO_HIERARCHICAL_MIN_DISPARITIES_LARGE: usize = 128;
pub(crate) const AUTO_HIERARCHICAL_MIN_PIXELS: usize = 2_000_000;

/// Whether `params.search` asks for the coarse-to-fine search on a `width × height` pair.
fn searches_hierarchically(width: usize, height: usize, params: &SgmParams) -> bool {
    let wanted = match params.search {
        Search::Full => false,
        Search::Hierarchical => true,
        Search::Auto => {
            let nd = params.range.count();
            nd >= AUTO_HIERARCHICAL_MIN_DISPARITIES
                || (nd >= AUTO_HIERARCHICAL_MIN_DISPARITIES_LARGE
                    && width * height >= AUTO_HIERARCHICAL_MIN_PIXELS)
        }
    };
    // The half-resolution pair must still hold a census window.
    wanted && width / 2 >= params.census.width && height / 2 >= params.census.height
}

/// The match before post-processing: coarse to fine where [`searches_hierarchically`] says so
/// (and it fits [`SgmParams::max_memory`]), else the full search.
fn match_census(
    left: &GrayImage,
    right: &GrayImage,
    census_left: &Image<u64>,
    census_right: &Image<u64>,
    params: &SgmParams,
) -> (DisparityMap, SearchReport) {
    let (width, height) = left.size();
    if searches_hierarchically(width, height, params) {
        if let Some(found) = match_coarse_to_fine(left, right, census_left, census_right, params) {
            return found;
        }
    }
    let disparity = aggregate_census(left, Some(right), census_left, census_right, params);
    let report = SearchReport {
        hierarchical: false,
        levels: 0,
        mean_range: params.range.count() as f32,
        downscale: 1,
        rows_halved: false,
    };
    (disparity, report)
}

/// The coarse-to-fine search ([`crate::hierarchical`]): the half-resolution pair matched over
/// the halved range (itself coarse to fine while its range is large), then this level over the
/// bands around it. `None` where the coarse level cannot be matched or the bands would not fit
/// [`SgmParams::max_memory`].
fn match_coarse_to_fine(
    left: &GrayImage,
    right: &GrayImage,
    census_left: &Image<u64>,
    census_right: &Image<u64>,
    params: &SgmParams,
) -> Option<(DisparityMap, SearchReport)> {
    let (width, height) = left.size();
    let range = params.range;
    let coarse_range = crate::radiometric::reduced_range(range, 2);
    let coarse_params = SgmParams {
        range: coarse_range,
        adapt_to_pair: false,
        search: if params.search == Search::Full { Search::Full } else { Search::Auto },
        // The levels below are the search's own: the pair at this level was not reduced.
        downscale: Downscale::By(1),
        fill: false,
        speckle_size: params.speckle_size / 4,
        speckle_keep_border: params.speckle_keep_border / 4,
        speckle_bridge: params.speckle_bridge / 2,
        edge_snap_passes: 0,
        wmf_radius: 0,
        confidence: false,
        max_memory: None,
        ..params.clone()
    };
    let (coarse_left, coarse_right) =
        rayon::join(|| crate::radiometric::downsample(left, 2), || crate::radiometric::downsample(right, 2));
    let coarse = sgm_detailed(&coarse_left, &coarse_right, &coarse_params).ok()?;
    drop((coarse_left, coarse_right));
    let bands = Bands::from_coarse(&coarse.disparity, width, height, range);
    // The sums of the rows one pass finished before the other, at most the whole band volume
    // (none in single-pass mode).
    let volume = if params.single_pass { 0 } else { 2 * bands.entries() };
    if params.max_memory.is_some_and(|limit| volume + 24 * width * height > limit) {
        return None;
    }
    let p2 = P2Table::new(params.p1, params.p2, params.p2_edge_scale);
    let inputs = aggregation_inputs(left, Some(right), census_left, census_right, params, &p2);
    let level = crate::kernels::features().level;
    let disparity = if params.single_pass {
        let plan = memory::plan(width, height, params);
        stream_bands(&inputs, &bands, level, plan.stream_strips, plan.strips.overlap)
    } else {
        aggregate_bands(&inputs, &bands, level)
    };
    let report = SearchReport {
        hierarchical: true,
        levels: coarse.search.levels + 1,
        mean_range: bands.mean_searched(range),
        downscale: 1,
        rows_halved: false,
    };
    Some((disparity, report))
}

/// What the aggregation reads: the images, census images, cost and penalties of `params`.
/// `right` supplies the intensity term of AD-census; without it the cost is census alone.
pub(crate) fn aggregation_inputs<'a>(
    left: &'a GrayImage,
    right: Option<&'a GrayImage>,
    census_left: &'a Image<u64>,
    census_right: &'a Image<u64>,
    params: &SgmParams,
    p2: &'a P2Table,
) -> Inputs<'a> {
    let matching_cost = if right.is_some() { params.matching_cost } else { MatchingCost::Census };
    let census_bits = (params.census.width * params.census.height - 1) as u32;
    Inputs {
        image: left,
        census_left,
        census_right,
        ad: match (matching_cost, right) {
            (MatchingCost::AdCensus { weight, cap }, Some(right)) => {
                Some((left, right, u16::from(weight), u16::from(cap)))
            }
            _ => None,
        },
        range: params.range,
        worst: infeasible_cost(census_bits, matching_cost),
        paths: params.paths,
        p1: params.p1,
        p2,
        selection: Selection {
            range: params.range,
            uniqueness_ratio: params.uniqueness_ratio,
            lr_max_diff: params.lr_max_diff,
            lr_left_neighbour: params.lr_left_neighbour,
            subpixel: params.subpixel,
        },
    }
}

/// Path aggregation over the whole range (costs computed on the fly from the census images) and
/// winner-takes-all with the checks, before post-processing. `right` supplies the intensity term
/// of AD-census; without it the cost is census alone (the stage benchmark).
pub(crate) fn aggregate_census(
    left: &GrayImage,
    right: Option<&GrayImage>,
    census_left: &Image<u64>,
    census_right: &Image<u64>,
    params: &SgmParams,
) -> DisparityMap {
    let (width, height) = left.size();
    let nd = params.range.count();
    let plan = memory::plan(width, height, params);
    let mut disparity = DisparityMap::new(width, height, f32::NAN);
    let p2 = P2Table::new(params.p1, params.p2, params.p2_edge_scale);
    let inputs = aggregation_inputs(left, right, census_left, census_right, params, &p2);
    if params.single_pass {
        stream_and_select(&inputs, plan.stream_strips, plan.strips.overlap, disparity.as_mut_slice());
    } else {
        // The only volume: one strip of aggregated path costs (every entry is written before it
        // is read, and the strips reuse it).
        let rows = plan.strips.rows.min(height);
        let mut volume = ScratchBuffer::<u16>::new(rows * width * nd);
        aggregate_and_select(&inputs, plan.strips, volume.as_mut_slice(), disparity.as_mut_slice());
    }
    disparity
}

/// The peak working memory [`sgm`] plans for a `width × height` pair, in bytes: both census
/// images, the disparity map (twice while the median runs), the `O(W·D)` path state of each
/// aggregation pass and the `u16` sum volume of one strip (`2·W·D` bytes per strip row; strips
/// sized for speed by default, or to fit [`SgmParams::max_memory`]) with, where it fits beside
/// them, the strip's matching costs kept for the second pass (about as much again for `u16`
/// costs, half as much for the 8-bit costs of AVX2, AVX-512 and NEON; AVX-512 keeps them only while
/// [`keep_strip_buffers`](crate::keep_strip_buffers) is on); in single-pass mode one row of sums
/// per strip instead. The input images are not counted. If `max_memory` is too small
/// to plan anything, the smallest plan (one-row strips), which [`sgm`] refuses.
pub fn planned_memory_bytes(width: usize, height: usize, params: &SgmParams) -> usize {
    memory::plan(width, height, params).bytes
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DisparityRange, PathCount};

    fn texture(x: i64, y: i64) -> u16 {
        // A hash: every pixel differs from its neighbours, so every shift is unambiguous.
        let h = (x.wrapping_mul(0x9E37_79B9) ^ y.wrapping_mul(0x85EB_CA6B)).wrapping_mul(0xC2B2_AE35);
        ((h >> 16) & 0xffff) as u16
    }

    #[test]
    fn downscale_matches_the_reduced_pair_and_widens_its_map() {
        // A 101x61 pair shifted by 10 px (odd sizes: the last column and row repeat), matched
        // reduced by 2 against the explicit composition: box-reduce, match over 0..12 (24 / 2),
        // widen the map with its disparities doubled (the reference widening) and repeat each
        // status 2x2. And the shift comes back.
        let left = GrayImage::from_fn(101, 61, |x, y| texture(x as i64 / 2, y as i64 / 2));
        let right = GrayImage::from_fn(101, 61, |x, y| texture((x as i64 + 10) / 2, y as i64 / 2));
        let params = SgmParams { range: DisparityRange::new(0, 24).unwrap(), ..SgmParams::default() };
        let reduced =
            sgm_detailed(&left, &right, &SgmParams { downscale: Downscale::By(2), ..params.clone() })
                .unwrap();
        let small = sgm_detailed(
            &crate::radiometric::downsample(&left, 2),
            &crate::radiometric::downsample(&right, 2),
            &SgmParams { range: DisparityRange::new(0, 12).unwrap(), ..params },
        )
        .unwrap();
        assert_eq!(reduced.disparity.size(), (101, 61));
        assert_eq!(reduced.search.downscale, 2);
        let doubled: Vec<f32> = small.disparity.as_slice().iter().map(|&d| d * 2.0).collect();
        let widened = crate::widen::widen_disparity_reference(&doubled, 50, (2, 2), 101, 61);
        let mut right_px = 0;
        for y in 0..61 {
            for x in 0..101 {
                let (sx, sy) = ((x / 2).min(49), (y / 2).min(29));
                let expected = widened.get(x, y);
                let got = reduced.disparity.get(x, y);
                assert_eq!(got.to_bits(), expected.to_bits(), "({x},{y})");
                assert_eq!(reduced.status.get(x, y), small.status.get(sx, sy));
                right_px += usize::from((got - 10.0).abs() <= 1.0);
            }
        }
        assert!(right_px > 101 * 61 * 3 / 4, "{right_px}");
        // Too small once reduced: an error that names the option.
        let tiny = GrayImage::from_fn(20, 20, |x, y| texture(x as i64, y as i64));
        let err = sgm_detailed(
            &tiny,
            &tiny,
            &SgmParams {
                downscale: Downscale::By(4),
                range: DisparityRange::new(0, 4).unwrap(),
                ..SgmParams::default()
            },
        );
        assert!(err.unwrap_err().to_string().contains("downscale"));
    }

    /// A view with no detail finer than a few pixels: the hash texture sampled every 4 px and
    /// interpolated bilinearly in between, shifted by `shift` px.
    fn enlarged(w: usize, h: usize, shift: i64) -> GrayImage {
        enlarged_by(w, h, shift, 4.0)
    }

    /// [`enlarged`] with the texture sampled every `step` px.
    fn enlarged_by(w: usize, h: usize, shift: i64, step: f64) -> GrayImage {
        let at = |x: i64, y: i64| f64::from(texture(x, y));
        GrayImage::from_fn(w, h, |x, y| {
            let (fx, fy) = ((x as i64 + shift) as f64 / step, y as f64 / step);
            let (x0, y0) = (fx.floor() as i64, fy.floor() as i64);
            let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
            let top = at(x0, y0) * (1.0 - tx) + at(x0 + 1, y0) * tx;
            let bottom = at(x0, y0 + 1) * (1.0 - tx) + at(x0 + 1, y0 + 1) * tx;
            (top * (1.0 - ty) + bottom * ty).round() as u16
        })
    }

    #[test]
    fn auto_downscale_halves_smooth_pairs_only_and_not_below_its_floor() {
        let params = SgmParams { range: DisparityRange::new(0, 32).unwrap(), ..SgmParams::default() };
        let sharp = GrayImage::from_fn(800, 500, |x, y| texture(x as i64, y as i64));
        assert!(reduction(&sharp, &sharp, &params).is_none());
        let smooth = enlarged(800, 500, 0);
        let energy = gradient_energy(&crate::radiometric::downsample(&smooth, 2)) / gradient_energy(&smooth);
        assert!(energy > AUTO_DOWNSCALE_SMOOTHNESS, "{energy}");
        assert!(
            matches!(reduction(&smooth, &smooth, &params), Some(((2, 2), l, _)) if l.size() == (400, 250))
        );
        // One sharp view keeps the full resolution; so does a pair that would halve below the floor
        // (300 x 250 is 75 000 pixels); an explicit factor is obeyed.
        assert!(reduction(&smooth, &sharp, &params).is_none());
        let small = enlarged(600, 500, 0);
        assert!(reduction(&small, &small, &params).is_none());
        let once = SgmParams { downscale: Downscale::By(1), ..params.clone() };
        assert!(reduction(&smooth, &smooth, &once).is_none());
        // End to end: the smooth pair is matched halved and its 6 px shift comes back.
        let right = enlarged(800, 500, 6);
        let out = sgm_detailed(&smooth, &right, &params).unwrap();
        assert_eq!((out.search.downscale, out.disparity.size()), (2, (800, 500)));
        let near = out.disparity.as_slice().iter().filter(|d| (*d - 6.0).abs() <= 1.0).count();
        assert!(near > 800 * 500 * 3 / 4, "{near}");
    }

    #[test]
    fn coarse_downscale_halves_sharp_pairs_where_range_and_size_allow() {
        // A sharp pair Auto keeps at full resolution: Coarse halves it once (and no more: the
        // halved views are sharp too), where the halved range keeps 16 disparities and the halved
        // pair 25 000 pixels (340 x 300 halves to 25 500).
        let coarse = |count: i32| SgmParams {
            range: DisparityRange::new(0, count).unwrap(),
            downscale: Downscale::Coarse,
            ..SgmParams::default()
        };
        let sharp = |w: usize, h: usize| GrayImage::from_fn(w, h, |x, y| texture(x as i64, y as i64));
        let (pair, small) = (sharp(340, 300), sharp(340, 290));
        let auto = SgmParams { downscale: Downscale::Auto, ..coarse(32) };
        assert!(reduction(&pair, &pair, &auto).is_none());
        assert!(
            matches!(reduction(&pair, &pair, &coarse(32)), Some(((2, 2), l, _)) if l.size() == (170, 150))
        );
        assert!(reduction(&small, &small, &coarse(32)).is_none());
        // A range too short to halve: the rows alone are halved, where 25 000 pixels remain.
        assert!(
            matches!(reduction(&pair, &pair, &coarse(31)), Some(((1, 2), l, _)) if l.size() == (340, 150))
        );
        assert!(reduction(&sharp(160, 300), &sharp(160, 300), &coarse(31)).is_none());
        assert!(reduction(&pair, &pair, &SgmParams { downscale: Downscale::Auto, ..coarse(16) }).is_none());
        // Pairs Auto reduces are reduced alike.
        // Halved, and the halved range (16) too short to halve again: the rows are halved once
        // more, where 25 000 pixels remain (340 x 150); not with a range that halves twice.
        let (large, large_right) =
            (sharp(680, 600), GrayImage::from_fn(680, 600, |x, y| texture(x as i64 + 10, y as i64)));
        assert!(
            matches!(reduction(&large, &large, &coarse(32)), Some(((2, 4), l, _)) if l.size() == (340, 150))
        );
        assert!(matches!(reduction(&large, &large, &coarse(64)), Some(((2, 2), _, _))));
        let smooth = enlarged(800, 500, 0);
        assert!(
            matches!(reduction(&smooth, &smooth, &coarse(32)), Some(((2, 4), l, _)) if l.size() == (400, 125))
        );
        assert!(
            matches!(reduction(&smooth, &smooth, &coarse(64)), Some(((2, 2), l, _)) if l.size() == (400, 250))
        );
        let smoother = enlarged_by(1600, 1000, 0, 8.0);
        assert!(matches!(reduction(&smoother, &smoother, &coarse(48)), Some(((3, 3), _, _))));
        // End to end: the same map as an explicit halving, and the fast preset's default.
        let right = GrayImage::from_fn(340, 300, |x, y| texture(x as i64 + 10, y as i64));
        let out = sgm_detailed(&pair, &right, &coarse(32)).unwrap();
        let halved =
            sgm_detailed(&pair, &right, &SgmParams { downscale: Downscale::By(2), ..coarse(32) }).unwrap();
        assert_eq!((out.search.downscale, out.disparity.size()), (2, (340, 300)));
        assert!(out
            .disparity
            .as_slice()
            .iter()
            .zip(halved.disparity.as_slice())
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        let near = out.disparity.as_slice().iter().filter(|d| (*d - 10.0).abs() <= 1.0).count();
        assert!(near > 340 * 300 / 2, "{near}");
        // Rows halved: full size, the disparities at full resolution (10 exactly, as the pair's
        // shift is whole), reported.
        let rows = sgm_detailed(&pair, &right, &coarse(16)).unwrap();
        assert_eq!(
            (rows.search.downscale, rows.search.rows_halved, rows.disparity.size()),
            (1, true, (340, 300))
        );
        let exact = rows.disparity.as_slice().iter().filter(|d| (*d - 10.0).abs() <= 0.25).count();
        assert!(exact > 340 * 300 / 2, "{exact}");
        assert!(!out.search.rows_halved);
        // Halved with the rows halved again: full size, disparities as coarse as the halving's.
        let both = sgm_detailed(&large, &large_right, &coarse(32)).unwrap();
        assert_eq!(
            (both.search.downscale, both.search.rows_halved, both.disparity.size()),
            (2, true, (680, 600))
        );
        let near = both.disparity.as_slice().iter().filter(|d| (*d - 10.0).abs() <= 1.0).count();
        assert!(near > 680 * 600 / 2, "{near}");
        assert_eq!(SgmParams::preset(crate::Preset::Fast).downscale, Downscale::Coarse);
    }

    /// `image` plus white, roughly Gaussian noise of `sigma` grey levels (16-bit samples: 257 per
    /// grey level), independent per pixel and per `seed`: a sum of 12 hashed uniforms.
    fn noisy(image: &GrayImage, sigma: f64, seed: i64) -> GrayImage {
        GrayImage::from_fn(image.width(), image.height(), |x, y| {
            let uniform = |k: i64| f64::from(texture(x as i64 * 12 + k, y as i64 + seed * 100_003)) / 65536.0;
            let gaussian = (0..12).map(uniform).sum::<f64>() - 6.0;
            (f64::from(image.get(x, y)) + gaussian * sigma * 257.0).round().clamp(0.0, 65535.0) as u16
        })
    }

    /// [`enlarged_by`] (every 4 px) with the texture's contrast cut to a quarter of the range.
    fn soft(w: usize, h: usize, shift: i64) -> GrayImage {
        let full = enlarged(w, h, shift);
        GrayImage::from_fn(w, h, |x, y| 24_000 + full.get(x, y) / 4)
    }

    #[test]
    fn sensor_noise_is_estimated_through_texture() {
        let sigma = |image: &GrayImage| noise_variance(image).sqrt() / 257.0;
        let flat = GrayImage::new(600, 400, 30_000);
        assert_eq!(sigma(&flat), 0.0);
        for true_sigma in [2.0, 6.0] {
            for image in [flat.clone(), soft(600, 400, 0)] {
                let estimate = sigma(&noisy(&image, true_sigma, 1));
                assert!((estimate / true_sigma - 1.0).abs() < 0.08, "{estimate} for {true_sigma}");
            }
        }
    }

    #[test]
    fn auto_downscale_discounts_sensor_noise() {
        // A smooth pair with σ 6 grey-level noise in each view (independent): the noise, at every
        // pixel, keeps the raw energies from passing the test; net of it the pair halves as the
        // clean pair does. A sharp pair with the same noise stays at full resolution.
        let params = SgmParams { range: DisparityRange::new(0, 32).unwrap(), ..SgmParams::default() };
        let (left, right) = (soft(800, 500, 0), soft(800, 500, 6));
        assert!(matches!(reduction(&left, &right, &params), Some(((2, 2), _, _))));
        let (left, right) = (noisy(&left, 6.0, 1), noisy(&right, 6.0, 2));
        let halved = crate::radiometric::downsample(&left, 2);
        assert!(gradient_energy(&halved) < AUTO_DOWNSCALE_SMOOTHNESS * gradient_energy(&left));
        assert!(matches!(reduction(&left, &right, &params), Some(((2, 2), l, _)) if l.size() == (400, 250)));
        let sharp = GrayImage::from_fn(800, 500, |x, y| 24_000 + texture(x as i64, y as i64) / 4);
        assert!(reduction(&noisy(&sharp, 6.0, 1), &noisy(&sharp, 6.0, 2), &params).is_none());
    }

    #[test]
    fn auto_downscale_replaces_a_second_halving_by_a_reduction_by_three() {
        // No detail finer than 8 px: smooth enough to halve twice (the quarter, 400 x 250, keeps
        // the floor), which becomes one reduction by 3, so that the reduced match's subpixel
        // error is scaled by 3, not 4.
        let params = SgmParams { range: DisparityRange::new(0, 48).unwrap(), ..SgmParams::default() };
        let left = enlarged_by(1600, 1000, 0, 8.0);
        let quarter = crate::radiometric::downsample(&crate::radiometric::downsample(&left, 2), 2);
        let energy = gradient_energy(&quarter) / gradient_energy(&crate::radiometric::downsample(&left, 2));
        assert!(energy > AUTO_DOWNSCALE_SMOOTHNESS, "{energy}");
        assert!(matches!(reduction(&left, &left, &params), Some(((3, 3), l, _)) if l.size() == (533, 333)));
        let right = enlarged_by(1600, 1000, 12, 8.0);
        let out = sgm_detailed(&left, &right, &params).unwrap();
        assert_eq!((out.search.downscale, out.disparity.size()), (3, (1600, 1000)));
        let near = out.disparity.as_slice().iter().filter(|d| (*d - 12.0).abs() <= 1.5).count();
        assert!(near > 1600 * 1000 * 3 / 4, "{near}");
    }

    #[test]
    fn constant_shift_is_recovered_exactly() {
        for paths in [PathCount::Four, PathCount::Eight] {
            let left = GrayImage::from_fn(80, 40, |x, y| texture(x as i64, y as i64));
            let right = GrayImage::from_fn(80, 40, |x, y| texture(x as i64 + 7, y as i64));
            let params =
                SgmParams { range: DisparityRange::new(0, 24).unwrap(), paths, ..SgmParams::default() };
            let d = sgm(&left, &right, &params).unwrap();
            let mut good = 0;
            for y in 0..40 {
                // Away from the borders, where the census windows of both views are whole.
                for x in 12..75 {
                    let v = d.get(x, y);
                    assert!(v.is_nan() || (v - 7.0).abs() < 0.5, "({x},{y}): {v}");
                    good += usize::from(!v.is_nan());
                }
            }
            assert!(good > 63 * 40 * 95 / 100, "{paths:?}: only {good} valid");
        }
    }

    #[test]
    fn negative_minimum_disparity_is_supported() {
        let left = GrayImage::from_fn(60, 30, |x, y| texture(x as i64, y as i64));
        let right = GrayImage::from_fn(60, 30, |x, y| texture(x as i64 - 3, y as i64));
        let params = SgmParams { range: DisparityRange::new(-8, 8).unwrap(), ..SgmParams::default() };
        let d = sgm(&left, &right, &params).unwrap();
        assert!((d.get(30, 15) + 3.0).abs() < 0.5);
    }

    /// A random pair: textured with a shift, random levels, or two-level noise.
    fn random_pair(w: usize, h: usize, kind: u8, shift: i64, seed: u64) -> (GrayImage, GrayImage) {
        let mut s = seed | 1;
        let mut next = move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let tex: Vec<u16> = (0..(w + 200) * h).map(|_| next() as u16).collect();
        let at = |x: i64, y: usize| tex[y * (w + 200) + (x + 100) as usize];
        let left = GrayImage::from_fn(w, h, |x, y| match kind {
            0 => at(x as i64, y),
            1 => (at(x as i64, y) % 4) * 20000,
            _ => at(x as i64, y) & 0x8000,
        });
        let right = GrayImage::from_fn(w, h, |x, y| match kind {
            0 => at(x as i64 + shift, y),
            1 => (at(x as i64 + shift + 1, y) % 4) * 20000,
            _ => at(x as i64 + shift, y) & 0x8000,
        });
        (left, right)
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]

        /// The fused, SIMD pipeline gives the original scalar pipeline's maps bit for bit.
        #[test]
        fn sgm_matches_the_scalar_reference(
            w in 9usize..90, h in 7usize..40, nd_frac in 0.0f64..1.0, min in -12i32..12, kind in 0u8..3,
            four in proptest::prelude::any::<bool>(), p1 in 1u16..60, p2_extra in 1u16..300, edge in 0u16..60,
            uniq in 0u32..20, lr in proptest::prelude::any::<Option<u8>>(), sub in 0u8..3, median in proptest::prelude::any::<bool>(),
            window in 0usize..4, seed in proptest::prelude::any::<u64>(), strip_rows in 1usize..40,
            ad in proptest::prelude::any::<Option<(u8, u8)>>(),
        ) {
            let nd = ((w as f64 * nd_frac.min(0.8)) as usize).max(1) as i32;
            let (cw, ch) = [(3, 3), (5, 5), (9, 7), (7, 9)][window];
            proptest::prop_assume!(w >= cw && h >= ch);
            let params = SgmParams {
                range: DisparityRange::new(min, min + nd).unwrap(),
                census: crate::CensusWindow { width: cw, height: ch },
                paths: if four { PathCount::Four } else { PathCount::Eight },
                p1,
                p2: (p1 + p2_extra).min(MAX_P2),
                p2_edge_scale: edge,
                uniqueness_ratio: uniq,
                lr_max_diff: lr.map(|v| f32::from(v % 4) * 0.75),
                subpixel: [crate::Subpixel::None, crate::Subpixel::Parabola, crate::Subpixel::Equiangular][sub as usize],
                median,
                matching_cost: match ad {
                    None => crate::MatchingCost::Census,
                    Some((weight, cap)) => crate::MatchingCost::AdCensus { weight: weight % 9, cap: cap % (crate::MAX_AD_CAP + 1) },
                },
                ..SgmParams::default()
            };
            let (left, right) = random_pair(w, h, kind, (seed % nd as u64) as i64 + i64::from(min), seed);
            let fast = sgm(&left, &right, &params).unwrap();
            let reference = crate::reference::sgm_reference(&left, &right, &params);
            // Strips whose backward warm-up reaches the bottom of the image are exact too, with
            // the cost rows shared between the passes or made by each.
            let strips = crate::aggregate::StripPlan { rows: strip_rows, overlap: h, shared_costs: seed % 2 == 0 };
            let striped = crate::memory::tests::with_strips(strips, || sgm(&left, &right, &params).unwrap());
            for (i, ((a, b), c)) in fast.as_slice().iter().zip(reference.as_slice()).zip(striped.as_slice()).enumerate() {
                proptest::prop_assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()), "pixel {}: {} vs {}", i, a, b);
                proptest::prop_assert!(c.to_bits() == b.to_bits() || (c.is_nan() && b.is_nan()), "strips of {} rows, pixel {}: {} vs {}", strip_rows, i, c, b);
            }
        }
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(24))]

        /// The default costs and penalties, which run the 8-bit passes on AVX-512: striped with
        /// the cost rows shared between the passes (as while `keep_strip_buffers` is on) or made
        /// by each, the maps are the scalar reference's bit for bit.
        #[test]
        fn shared_cost_rows_match_the_scalar_reference(
            w in 20usize..80, h in 12usize..40, nd in 4i32..40, kind in 0u8..3, seed in proptest::prelude::any::<u64>(),
            strip_rows in 1usize..30, shared in proptest::prelude::any::<bool>(), four in proptest::prelude::any::<bool>(),
        ) {
            let params = SgmParams {
                range: DisparityRange::new(0, nd.min(w as i32 - 9)).unwrap(),
                paths: if four { PathCount::Four } else { PathCount::Eight },
                ..SgmParams::default()
            };
            proptest::prop_assert_eq!(
                crate::aggregate::u8_passes(crate::memory::worst_cost(&params), params.p1, params.p2),
                crate::kernels::features().level.u8_passes()
            );
            let (left, right) = random_pair(w, h, kind, (seed % 8) as i64, seed);
            let reference = crate::reference::sgm_reference(&left, &right, &params);
            let strips = crate::aggregate::StripPlan { rows: strip_rows, overlap: h, shared_costs: shared };
            let striped = crate::memory::tests::with_strips(strips, || sgm(&left, &right, &params).unwrap());
            for (i, (c, b)) in striped.as_slice().iter().zip(reference.as_slice()).enumerate() {
                proptest::prop_assert!(c.to_bits() == b.to_bits() || (c.is_nan() && b.is_nan()), "strips of {} rows, pixel {}: {} vs {}", strip_rows, i, c, b);
            }
        }
    }

    #[test]
    fn planned_memory_is_one_strip_of_sums_plus_per_pixel_buffers() {
        for (w, h, nd) in [(640usize, 480usize, 64i32), (1280, 720, 128), (6000, 4000, 320)] {
            let params = SgmParams { range: DisparityRange::new(0, nd).unwrap(), ..SgmParams::default() };
            let planned = planned_memory_bytes(w, h, &params);
            let row = 2 * w * nd as usize;
            // Census (16 B/px), disparities (8 B/px), O(W·D) path state, and 96.. rows of sums
            // (and as many of matching costs where the passes share them: `u16` passes; nd is a
            // multiple of 16 here).
            assert!(planned >= 24 * w * h + 96 * row.min(row * h / 96), "{w}x{h}/{nd}: {planned}");
            assert!(
                planned <= 25 * w * h + 2 * (16 << 20).max(100 * row) + 64 * w * nd as usize,
                "{w}x{h}/{nd}: {planned}"
            );
            let bounded = SgmParams { max_memory: Some(planned / 2 + 24 * w * h), ..params.clone() };
            assert!(planned_memory_bytes(w, h, &bounded) <= planned / 2 + 24 * w * h);
            let streaming = SgmParams { single_pass: true, ..params };
            assert!(planned_memory_bytes(w, h, &streaming) < 25 * w * h + 256 * w * nd as usize);
        }
    }

    #[test]
    fn bad_input_is_rejected() {
        let a = GrayImage::new(40, 20, 0);
        let b = GrayImage::new(41, 20, 0);
        let p = SgmParams { range: DisparityRange { min: 0, max: 16 }, ..SgmParams::default() };
        assert!(matches!(sgm(&a, &b, &p), Err(Error::SizeMismatch { .. })));
        let wide = SgmParams { range: DisparityRange { min: 0, max: 64 }, ..p.clone() };
        assert!(matches!(sgm(&a, &a, &wide), Err(Error::RangeWiderThanImage { .. })));
        let empty = SgmParams { range: DisparityRange { min: 8, max: 8 }, ..p.clone() };
        assert!(matches!(sgm(&a, &a, &empty), Err(Error::EmptyRange { .. })));
        let pen = SgmParams { p1: 50, p2: 10, ..p.clone() };
        assert!(matches!(sgm(&a, &a, &pen), Err(Error::InvalidParameter { .. })));
        let tiny = GrayImage::new(5, 5, 0);
        let small = SgmParams { range: DisparityRange { min: 0, max: 2 }, ..p };
        assert!(matches!(sgm(&tiny, &tiny, &small), Err(Error::ImageTooSmall { .. })));
    }
}
