//! `stereo_depth.Matcher`: the command line's matching options as keywords, resolved exactly as
//! the command line resolves them (`src/config.rs`, `fn matcher`), run through the same
//! `stereo_pipeline::Plan`.

use std::sync::{Arc, Mutex};
use std::time::Instant;

use numpy::ndarray::Array2;
use numpy::PyArray2;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use stereo_image::{DisparityRange, GrayImage, Image};
use stereo_pipeline::{
    parse_named, BmCost, Downscale, MatcherKind, MatcherOptions, Named, OptionError, PathCount, Preset,
    Search, Subpixel,
};
use stereo_pipeline::{Alignment, AlignmentVerdict, DepthResult, MemoryLimit, PipelineParams, Plan};

use crate::errors::{self, no_panic, value_error};
use crate::input::{Input, View};

/// Matches rectified stereo pairs: census Semi-Global Matching (``matcher="sgm"``, the default)
/// or block matching (``matcher="bm"``).
///
/// Every keyword is a matching option of the ``stereo-depth`` command line (``--max-disparity``
/// is ``max_disparity``, ``--no-lr-check`` is ``lr_check=False``, ``--no-align`` is
/// ``align=False``); the same options give the same disparity, bit for bit. ``None`` takes the
/// default of the preset / matcher, as on the command line; ``Matcher(...).params`` shows the
/// resolved parameters.
///
/// Options (default in brackets):
///
/// - ``min_disparity`` [0]: smallest disparity searched (px).
/// - ``max_disparity`` [None: a quarter of the image width, rounded up to 16]: end of the search,
///   ``min <= d < max`` (``max - min`` is OpenCV's numDisparities).
/// - ``matcher`` ["sgm"]: "sgm" or "bm".
/// - ``preset`` ["balanced"]: SGM preset "fast", "balanced" or "accurate"; the options below
///   override single parameters of it.
/// - ``fill`` [False]: SGM: a dense map (speckles removed, every invalid pixel filled).
/// - ``speckle_size`` [None: 0, or 400 with fill]: SGM: invalidate regions smaller than this.
/// - ``edge_snap`` [None: 5]: SGM: move disparity edges onto image edges within this many px.
/// - ``confidence`` [False]: SGM: compute the per-pixel confidence (``compute_detailed``).
/// - ``min_confidence`` [None]: SGM: invalidate pixels whose confidence is below this (0-1).
/// - ``single_pass`` [False]: SGM: aggregate in one top-down pass (faster, less memory).
/// - ``paths`` [None: 8, 4 with preset "fast"]: SGM aggregation paths, 4 or 8.
/// - ``search`` [None: "auto"]: "full", "hierarchical" (coarse to fine) or "auto" (hierarchical
///   from 256 disparities, or 128 from 2 megapixels; else full).
/// - ``downscale`` [None: "auto", "coarse" with preset "fast"]: SGM: match the pair reduced this
///   many times on each side, then bring the disparities back to full size (about downscale³ less
///   work, coarser disparities); "auto" halves it while both views hold no detail finer than 2 px,
///   sensor noise discounted (by 3 where it would halve twice); "coarse" as "auto", but sharp
///   pairs are halved too where at least 16 disparities and 25 000 pixels remain, and where the
///   range is too short to halve (again) the rows once more (the rows alone, or by 4 after a
///   halving) where 25 000 pixels remain; 1: full resolution.
/// - ``p1`` [None: 20], ``p2`` [None: 80]: SGM penalties, in census bits.
/// - ``uniqueness`` [None: 0 (sgm), 10 (bm)]: uniqueness margin, percent; 0 disables it.
/// - ``lr_max_diff`` [None: 3 (sgm; 1 with fill), 1 (bm)]: left-right check tolerance, px.
/// - ``lr_check`` [True]: False disables the left-right check.
/// - ``subpixel`` [None: "equiangular" (sgm), "parabola" (bm)]: "none", "parabola" or
///   "equiangular".
/// - ``block_size`` [None: 11]: BM: odd window side, at least 3.
/// - ``bm_cost`` [None: "census"]: BM: "census" or "sad".
/// - ``align`` [True]: resample the right view when its rows are measured off the left's.
/// - ``rectification_check`` ["every"]: "every" measures each pair's vertical alignment (1-2.5 ms
///   per pair); "first" measures until a pair of a given size gives a verdict, then reuses that
///   alignment for the later pairs of that size (one rig streaming frames).
/// - ``max_memory`` [None: no limit]: bytes (int, or "512M", "4G"): SGM then aggregates in
///   strips that fit; a pair that cannot fit raises MemoryError.
/// - ``max_pixels`` [100M]: largest image accepted, pixels (int, or "250M").
/// - ``threads`` [None: the shared pool, one thread per core]: a private pool of this many
///   threads for this Matcher (e.g. 1 per Matcher when several Python threads match at once).
///
/// ``compute`` and ``compute_detailed`` release the GIL while they match, so Python threads
/// matching different pairs run in parallel. A Matcher can be shared between threads; it holds
/// no per-pair state beyond the alignment ``rectification_check="first"`` keeps.
#[pyclass(frozen, module = "stereo_depth")]
pub struct Matcher {
    /// The resolved matcher; its range is set per image width.
    matcher: stereo_pipeline::Matcher,
    min_disparity: i32,
    max_disparity: Option<i32>,
    min_confidence: Option<f32>,
    align: bool,
    /// `rectification_check="first"`: reuse the first alignment measured with a verdict.
    check_first: bool,
    /// That alignment, with the image size it was measured at.
    known_alignment: Mutex<Option<((usize, usize), Alignment)>>,
    max_memory: Option<u64>,
    max_pixels: u64,
    threads: Option<usize>,
    pool: Option<Arc<rayon::ThreadPool>>,
}

/// A library choice by its name (any case); the error lists the names.
fn named<T: Named>(what: &str, given: &str) -> PyResult<T> {
    parse_named::<T>(&given.to_ascii_lowercase()).map_err(|_| {
        let names: Vec<String> = T::ALL.iter().map(|v| format!("{:?}", v.name())).collect();
        value_error(format!("invalid {what} {given:?} (want {})", names.join(", ")))
    })
}

fn int_in<T: TryFrom<i64>>(what: &str, value: i64, lo: i64, hi: i64) -> PyResult<T> {
    if value < lo || value > hi {
        return Err(value_error(format!("{what} must be between {lo} and {hi}, got {value}")));
    }
    T::try_from(value).map_err(|_| value_error(format!("{what} {value} is out of range")))
}

/// An int, or a string `N` with an optional suffix K, M, G, T (times `unit`, `unit`², ...), > 0.
fn scaled(obj: &Bound<'_, PyAny>, what: &str, unit: u64) -> PyResult<u64> {
    if let Ok(n) = obj.extract::<i64>() {
        if n <= 0 {
            return Err(value_error(format!("{what} must be greater than 0, got {n}")));
        }
        return Ok(n as u64);
    }
    let text: String =
        obj.extract().map_err(|_| value_error(format!("{what} must be an int or a string like \"4G\"")))?;
    let units = if unit == 1024 { "bytes" } else { "pixels" };
    stereo_pipeline::parse_scaled(&text, unit, units)
        .map_err(|err| value_error(format!("invalid {what} {text:?}: {err}")))
}

/// ``downscale``: ``"auto"``, ``"coarse"`` or a factor from 1 to 8.
fn downscale_option(obj: &Bound<'_, PyAny>) -> PyResult<Downscale> {
    if let Ok(f) = obj.extract::<i64>() {
        let max = stereo_disparity::MAX_DOWNSCALE as i64;
        return int_in("downscale", f, 1, max).map(Downscale::By);
    }
    let text: String =
        obj.extract().map_err(|_| value_error("downscale must be \"auto\", \"coarse\" or an int"))?;
    text.parse::<Downscale>().map_err(|err| value_error(err.to_string()))
}

#[pymethods]
impl Matcher {
    #[new]
    #[pyo3(signature = (
        *, min_disparity = 0, max_disparity = None, matcher = "sgm", preset = "balanced",
        fill = false, speckle_size = None, edge_snap = None, confidence = false,
        min_confidence = None, single_pass = false, paths = None, search = None, downscale = None,
        p1 = None, p2 = None,
        uniqueness = None, lr_max_diff = None, lr_check = true, subpixel = None,
        block_size = None, bm_cost = None, align = true, rectification_check = "every",
        max_memory = None, max_pixels = None, threads = None
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        min_disparity: i64,
        max_disparity: Option<i64>,
        matcher: &str,
        preset: &str,
        fill: bool,
        speckle_size: Option<i64>,
        edge_snap: Option<i64>,
        confidence: bool,
        min_confidence: Option<f64>,
        single_pass: bool,
        paths: Option<i64>,
        search: Option<&str>,
        downscale: Option<&Bound<'_, PyAny>>,
        p1: Option<i64>,
        p2: Option<i64>,
        uniqueness: Option<i64>,
        lr_max_diff: Option<f64>,
        lr_check: bool,
        subpixel: Option<&str>,
        block_size: Option<i64>,
        bm_cost: Option<&str>,
        align: bool,
        rectification_check: &str,
        max_memory: Option<&Bound<'_, PyAny>>,
        max_pixels: Option<&Bound<'_, PyAny>>,
        threads: Option<i64>,
    ) -> PyResult<Self> {
        const I32: (i64, i64) = (i32::MIN as i64 + 1, i32::MAX as i64);
        let min_d: i32 = int_in("min_disparity", min_disparity, I32.0, I32.1)?;
        let max_d: Option<i32> =
            max_disparity.map(|m| int_in("max_disparity", m, I32.0, I32.1)).transpose()?;
        if let Some(max) = max_d {
            if max <= min_d {
                return Err(value_error(format!(
                    "empty disparity range: min_disparity {min_d} must be below max_disparity {max} \
                     (the search is min <= d < max)"
                )));
            }
        }
        if let Some(t) = min_confidence {
            if !(0.0..=1.0).contains(&t) {
                return Err(value_error(format!("min_confidence {t} must be between 0 and 1")));
            }
        }
        if lr_max_diff.is_some() && !lr_check {
            return Err(value_error("lr_max_diff cannot be given with lr_check=False"));
        }
        let subpixel = subpixel.map(|s| named::<Subpixel>("subpixel", s)).transpose()?;
        let uniqueness: Option<u32> =
            uniqueness.map(|u| int_in("uniqueness", u, 0, u32::MAX as i64)).transpose()?;
        let paths = paths
            .map(|p| match p {
                4 => Ok(PathCount::Four),
                8 => Ok(PathCount::Eight),
                _ => Err(value_error(format!("paths must be 4 or 8, got {p}"))),
            })
            .transpose()?;
        let block_size = match block_size {
            Some(b) if b < 3 || b % 2 == 0 => {
                return Err(value_error(format!("block_size must be odd and at least 3, got {b}")))
            }
            b => b.map(|b| b as usize),
        };
        // The same resolution as the command line's (stereo_pipeline::MatcherOptions).
        let options = MatcherOptions {
            matcher: named::<MatcherKind>("matcher", matcher)?,
            preset: named::<Preset>("preset", preset)?,
            fill,
            speckle_size: speckle_size.map(|s| int_in("speckle_size", s, 0, i64::MAX)).transpose()?,
            single_pass,
            paths,
            search: search.map(|s| named::<Search>("search", s)).transpose()?,
            downscale: downscale.map(downscale_option).transpose()?,
            p1: p1.map(|p| int_in("p1", p, 0, u16::MAX as i64)).transpose()?,
            p2: p2.map(|p| int_in("p2", p, 0, u16::MAX as i64)).transpose()?,
            edge_snap: edge_snap.map(|e| int_in("edge_snap", e, 0, i64::MAX)).transpose()?,
            confidence,
            min_confidence: min_confidence.map(|t| t as f32),
            uniqueness,
            lr_max_diff: lr_max_diff.map(|d| d as f32),
            lr_check,
            subpixel,
            block_size,
            bm_cost: bm_cost.map(|c| named::<BmCost>("bm_cost", c)).transpose()?,
        };
        let matcher = options.resolve().map_err(|err| match err {
            OptionError::OtherMatcher { option, matcher } => {
                value_error(format!("{option} applies only to matcher=\"{matcher}\""))
            }
            OptionError::Invalid { option, message } => value_error(format!("{option} {message}")),
        })?;
        let check_first = match rectification_check {
            "every" => false,
            "first" => true,
            other => {
                return Err(value_error(format!(
                    "rectification_check must be \"every\" or \"first\", got {other:?}"
                )))
            }
        };
        let max_memory = max_memory.map(|m| scaled(m, "max_memory", 1024)).transpose()?;
        let max_pixels = max_pixels
            .map(|m| scaled(m, "max_pixels", 1000))
            .transpose()?
            .unwrap_or(stereo_io::DEFAULT_MAX_PIXELS);
        let threads: Option<usize> = threads.map(|t| int_in("threads", t, 1, 4096)).transpose()?;
        let pool = match threads {
            Some(n) => {
                Some(Arc::new(rayon::ThreadPoolBuilder::new().num_threads(n).build().map_err(|e| {
                    pyo3::exceptions::PyRuntimeError::new_err(format!("cannot start {n} threads: {e}"))
                })?))
            }
            None => None,
        };
        Ok(Matcher {
            matcher,
            min_disparity: min_d,
            max_disparity: max_d,
            min_confidence: min_confidence.map(|t| t as f32),
            align,
            check_first,
            known_alignment: Mutex::new(None),
            max_memory,
            max_pixels,
            threads,
            pool,
        })
    }

    /// The disparity map of the left view: float32 (H, W) in pixels, NaN where invalid.
    ///
    /// ``left`` and ``right`` are numpy arrays (H, W) grey or (H, W, 3|4) RGB(A), uint8 or
    /// uint16 (read in place when their rows are evenly spaced; other layouts are copied once),
    /// or paths to image files. Colour is converted with Rec. 601 luma, 8-bit values are scaled
    /// to 16 bits, exactly as the command line converts a file. Raises ValueError for bad shapes,
    /// dtypes, sizes and parameters, OSError for files that cannot be read.
    fn compute<'py>(
        &self,
        py: Python<'py>,
        left: &Bound<'py, PyAny>,
        right: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let (result, _) = self.run(py, left, right)?;
        Ok(to_numpy(py, result.disparity))
    }

    /// Like ``compute``, with everything the pipeline computed: a ``DetailedResult`` with
    /// ``disparity``, ``confidence`` (with ``confidence=True`` or ``min_confidence``, else None),
    /// ``filled`` (bool mask of the pixels a dense fill invented), ``timings_ms``,
    /// ``rectification``, ``adaptation``, ``search`` and ``range``.
    fn compute_detailed<'py>(
        &self,
        py: Python<'py>,
        left: &Bound<'py, PyAny>,
        right: &Bound<'py, PyAny>,
    ) -> PyResult<DetailedResult> {
        let (result, run) = self.run(py, left, right)?;
        let (w, h) = result.disparity.size();
        // Only a dense fill invents disparities (without it, a pixel with a status can still hold
        // a value, e.g. one that edge snapping moved).
        let fill = matches!(&self.matcher, stereo_pipeline::Matcher::Sgm(p) if p.fill);
        let filled = match &result.status {
            Some(status) if fill => {
                stereo_disparity::filled_mask(&result.disparity, status).view().map(|v| v != 0)
            }
            _ => Image::new(w, h, false),
        };
        let timings = PyDict::new(py);
        let ms = |d: std::time::Duration| d.as_secs_f64() * 1000.0;
        timings.set_item("convert", run.convert_ms)?;
        timings.set_item("rectification", ms(result.timings.rectification))?;
        timings.set_item("match", ms(result.timings.matching))?;
        timings.set_item("total", run.total_ms)?;
        let a = &result.rectification.alignment;
        let rect = PyDict::new(py);
        rect.set_item("vertical_offset_px", a.vertical_offset_px)?;
        rect.set_item("rotation_deg", a.rotation_deg)?;
        rect.set_item("max_abs_offset_px", a.max_abs_offset_px)?;
        rect.set_item("negative_disparity_share", a.negative_disparity_share)?;
        rect.set_item("verdict", format!("{:?}", a.verdict).to_ascii_lowercase())?;
        rect.set_item("compensated", result.rectification.compensated)?;
        rect.set_item("measured", result.rectification.measured)?;
        let adaptation = match &result.adaptation {
            Some(a) => {
                let d = PyDict::new(py);
                d.set_item("radiometric_difference", a.radiometric_difference)?;
                d.set_item("tone_corrected_difference", a.corrected_radiometric_difference)?;
                d.set_item("clipped_alike", a.clipped_alike)?;
                d.set_item("intensity_term", a.intensity_term)?;
                d.set_item("census_residual", a.census_residual)?;
                d.set_item("blockiness", a.blockiness)?;
                d.set_item("census_smoothing", a.census_smoothing)?;
                d.set_item("defocused_view", a.defocused_view().map(|(view, _)| view))?;
                d.set_item("defocus_sigma", a.defocused_view().map(|(_, sigma)| sigma))?;
                d.set_item("census_tolerance", a.census_tolerance_grey())?;
                d.set_item("p1", a.p1)?;
                d.set_item("p2", a.p2)?;
                d.set_item("p2_edge_scale", a.p2_edge_scale)?;
                Some(d.into_any().unbind())
            }
            None => None,
        };
        let search = match &result.search {
            Some(r) => {
                let d = PyDict::new(py);
                d.set_item("search", if r.hierarchical { "hierarchical" } else { "full" })?;
                d.set_item("levels", r.levels)?;
                d.set_item("mean_disparities_searched", r.mean_range)?;
                d.set_item("downscale", r.downscale)?;
                d.set_item("rows_halved", r.rows_halved)?;
                Some(d.into_any().unbind())
            }
            None => None,
        };
        Ok(DetailedResult {
            disparity: to_numpy(py, result.disparity).into_any().unbind(),
            confidence: result.confidence.map(|c| to_numpy(py, c).into_any().unbind()),
            filled: to_numpy(py, filled).into_any().unbind(),
            timings_ms: timings.into_any().unbind(),
            rectification: rect.into_any().unbind(),
            adaptation,
            search,
            range: (run.range.min, run.range.max),
            copied: (run.copied.0, run.copied.1),
        })
    }

    /// The resolved matcher parameters, as a dict (the range is resolved per image width:
    /// ``max_disparity`` None means a quarter of the width, rounded up to 16).
    #[getter]
    fn params<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let d = PyDict::new(py);
        d.set_item("matcher", self.matcher.name())?;
        d.set_item("min_disparity", self.min_disparity)?;
        d.set_item("max_disparity", self.max_disparity)?;
        match &self.matcher {
            stereo_pipeline::Matcher::Sgm(p) => {
                d.set_item("paths", if p.paths == PathCount::Four { 4 } else { 8 })?;
                d.set_item("p1", p.p1)?;
                d.set_item("p2", p.p2)?;
                d.set_item("uniqueness", p.uniqueness_ratio)?;
                d.set_item("lr_max_diff", p.lr_max_diff)?;
                d.set_item("lr_left_neighbour", p.lr_left_neighbour)?;
                d.set_item("subpixel", p.subpixel.name())?;
                d.set_item("single_pass", p.single_pass)?;
                d.set_item("search", p.search.name())?;
                d.set_item("fill", p.fill)?;
                d.set_item("speckle_size", p.speckle_size)?;
                d.set_item("speckle_keep_border", p.speckle_keep_border)?;
                d.set_item("speckle_bridge", p.speckle_bridge)?;
                d.set_item("edge_snap", p.edge_snap_radius)?;
                d.set_item("edge_snap_passes", p.edge_snap_passes)?;
                d.set_item("wmf_radius", p.wmf_radius)?;
                d.set_item("median", p.median)?;
                d.set_item("confidence", p.confidence)?;
                d.set_item("adapt_to_pair", p.adapt_to_pair)?;
            }
            stereo_pipeline::Matcher::Bm(p) => {
                d.set_item("block_size", p.block_size)?;
                d.set_item("bm_cost", p.cost.name())?;
                d.set_item("uniqueness", p.uniqueness_ratio)?;
                d.set_item("lr_max_diff", p.lr_max_diff)?;
                d.set_item("subpixel", p.subpixel.name())?;
            }
        }
        d.set_item("min_confidence", self.min_confidence)?;
        d.set_item("align", self.align)?;
        d.set_item("rectification_check", if self.check_first { "first" } else { "every" })?;
        d.set_item("max_memory", self.max_memory)?;
        d.set_item("max_pixels", self.max_pixels)?;
        d.set_item("threads", self.threads)?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        let max = self.max_disparity.map_or("None".to_string(), |m| m.to_string());
        format!(
            "Matcher(matcher={:?}, min_disparity={}, max_disparity={max})",
            self.matcher.name(),
            self.min_disparity
        )
    }
}

/// What one call measured besides the result.
struct RunInfo {
    convert_ms: f64,
    total_ms: f64,
    range: DisparityRange,
    copied: (bool, bool),
}

impl Matcher {
    /// The range for an image `width` pixels wide, checked as the command line checks it.
    fn range(&self, width: usize) -> PyResult<DisparityRange> {
        let max = self.max_disparity.unwrap_or_else(|| DisparityRange::default_for_width(width).max);
        let range = DisparityRange::new(self.min_disparity, max).map_err(|_| {
            value_error(format!(
                "empty disparity range: min_disparity {} must be below the maximum {max}{} \
                 (the search is min <= d < max)",
                self.min_disparity,
                if self.max_disparity.is_some() {
                    ""
                } else {
                    " (the default for this width; set max_disparity)"
                }
            ))
        })?;
        if range.count() > width {
            return Err(value_error(format!(
                "disparity range {}..{} ({} disparities) is wider than the image ({width} px); lower \
                 max_disparity",
                range.min,
                range.max,
                range.count()
            )));
        }
        Ok(range)
    }

    fn plan(&self, size: (usize, usize)) -> PyResult<Plan> {
        let range = self.range(size.0)?;
        let mut matcher = self.matcher.clone();
        matcher.set_range(range);
        let mut params = PipelineParams::new(matcher);
        params.align = self.align;
        params.known_alignment = self.known_alignment(size);
        params.min_confidence = self.min_confidence;
        let limit = self.max_memory.map(|bytes| {
            // Both grey images, the disparity and one more map, as the command line counts them.
            let pixels = (size.0 * size.1) as u64;
            MemoryLimit { bytes, other_bytes: pixels * (2 * 2 + 4 + 4 + 8) }
        });
        Plan::with_memory_limit(&params, size, size, limit).map_err(errors::pipeline)
    }

    fn run(
        &self,
        py: Python<'_>,
        left: &Bound<'_, PyAny>,
        right: &Bound<'_, PyAny>,
    ) -> PyResult<(DepthResult, RunInfo)> {
        let left = Input::extract(left, "left", self.max_pixels)?;
        let right = Input::extract(right, "right", self.max_pixels)?;
        if left.size() != right.size() {
            return Err(errors::pipeline(
                stereo_disparity::Error::SizeMismatch { left: left.size(), right: right.size() }.into(),
            ));
        }
        let plan = self.plan(left.size())?;
        let copied = (left.copied, right.copied);
        let (lv, rv) = (left.view()?, right.view()?);
        let max_pixels = self.max_pixels;
        let work = || -> PyResult<(DepthResult, f64, f64)> {
            no_panic(|| {
                let start = Instant::now();
                let (l, r) = convert(&lv, &rv, max_pixels)?;
                let convert_ms = start.elapsed().as_secs_f64() * 1000.0;
                if l.size() != plan.size() || r.size() != plan.size() {
                    return Err(value_error("an image file changed while it was being read"));
                }
                let result = plan.run_gray(&l, r).map_err(errors::pipeline)?;
                Ok((result, convert_ms, start.elapsed().as_secs_f64() * 1000.0))
            })
        };
        let (result, convert_ms, total_ms) = py.detach(|| match &self.pool {
            Some(pool) => pool.install(work),
            None => work(),
        })?;
        if self.check_first && result.rectification.measured {
            self.remember_alignment(plan.size(), &result.rectification.alignment);
        }
        Ok((result, RunInfo { convert_ms, total_ms, range: plan.range(), copied }))
    }

    /// With `rectification_check="first"`: the alignment kept for pairs of this size.
    fn known_alignment(&self, size: (usize, usize)) -> Option<Alignment> {
        if !self.check_first {
            return None;
        }
        let known = self.known_alignment.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        known.filter(|(at, _)| *at == size).map(|(_, alignment)| alignment)
    }

    /// Keeps a measured alignment with a verdict (a flat or dark first frame gives none: the
    /// next pair is measured again); the latest size measured replaces an earlier one.
    fn remember_alignment(&self, size: (usize, usize), alignment: &Alignment) {
        if alignment.verdict != AlignmentVerdict::Unknown {
            let mut known = self.known_alignment.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
            *known = Some((size, *alignment));
        }
    }
}

/// Both views as working grey images, converted (or decoded) at once.
fn convert(left: &View<'_>, right: &View<'_>, max_pixels: u64) -> PyResult<(GrayImage, GrayImage)> {
    // Both at once: decoding a file, or converting a colour array (1.3 ms for a VGA RGB pair,
    // 10 ms for 1080p on one thread: a tenth of a fast match).
    let (l, r) = rayon::join(|| left.to_gray(max_pixels), || right.to_gray(max_pixels));
    Ok((l?, r?))
}

/// An image as a 2-D numpy array, without copying its pixels.
pub fn to_numpy<T: numpy::Element + Copy>(py: Python<'_>, image: Image<T>) -> Bound<'_, PyArray2<T>> {
    let (w, h) = image.size();
    let array = Array2::from_shape_vec((h, w), image.into_vec()).expect("an image holds h x w pixels");
    numpy::PyArray2::from_owned_array(py, array)
}

/// Everything ``Matcher.compute_detailed`` returns.
///
/// - ``disparity``: float32 (H, W), px, NaN invalid (as ``compute``).
/// - ``confidence``: float32 (H, W) in [0, 1] (SGM with ``confidence=True`` or
///   ``min_confidence``), else None; 0 where invalid or filled.
/// - ``filled``: bool (H, W), True where a dense fill (``fill=True``) invented the disparity.
/// - ``timings_ms``: dict ``convert`` (arrays/files to working grey), ``rectification``,
///   ``match``, ``total`` (all of them, inside the library), milliseconds.
/// - ``rectification``: dict ``vertical_offset_px``, ``rotation_deg``, ``max_abs_offset_px``,
///   ``negative_disparity_share``, ``verdict``, ``compensated``.
/// - ``adaptation``: dict of what SGM measured of the pair (None for BM).
/// - ``search``: dict ``search`` ("full" or "hierarchical", the coarse-to-fine search), ``levels``
///   (half-resolution levels below the full one), ``mean_disparities_searched`` per pixel (of the
///   matched pair), ``downscale`` (the factor the pair was reduced by; 1: full resolution) and
///   ``rows_halved`` (the rows halved once more than the columns: "coarse" on a range too short
///   to halve) (None for BM).
/// - ``range``: (min, max) disparities searched, ``min <= d < max``.
/// - ``copied``: (left, right): whether an input array had to be copied to be read.
#[pyclass(frozen, get_all, module = "stereo_depth")]
pub struct DetailedResult {
    disparity: Py<PyAny>,
    confidence: Option<Py<PyAny>>,
    filled: Py<PyAny>,
    timings_ms: Py<PyAny>,
    rectification: Py<PyAny>,
    adaptation: Option<Py<PyAny>>,
    search: Option<Py<PyAny>>,
    range: (i32, i32),
    copied: (bool, bool),
}

#[pymethods]
impl DetailedResult {
    fn __repr__(&self, py: Python<'_>) -> String {
        let shape = self.disparity.bind(py).getattr("shape").map(|s| s.to_string()).unwrap_or_default();
        format!("DetailedResult(disparity {shape}, range {:?})", self.range)
    }
}
