//! Middlebury-style accuracy metrics of a disparity map against ground truth.
//!
//! [`metrics`] reproduces `metrics()` of `tools/opencv-compare/stereo_eval.py` (with
//! `nonpositive_invalid=False`), including its JSON keys:
//!
//! * a ground-truth pixel is valid iff it is finite and > 0 (and inside the mask, if any);
//! * an estimated pixel is valid iff it is finite;
//! * `badT` is the percentage of GT-valid pixels with `|est - gt| > T` (strictly), where a
//!   hole (GT valid, estimate invalid) always counts as bad;
//! * `avgerr` and `rms` are the mean and root-mean-square of `|est - gt|` over GT-valid pixels
//!   with a valid estimate (`None`, JSON `null`, when there is none);
//! * `density` is the percentage of GT-valid pixels with a valid estimate;
//! * `bad2_est` is `bad2` over the estimated pixels only (holes not counted).
//!
//! Errors are `|f64(est) - f64(gt)|` and sums use NumPy's pairwise summation, so the numbers
//! agree with the Python tool to the last bit.
//!
//! ```
//! use stereo_image::DisparityMap;
//! use stereo_eval::metrics;
//!
//! let gt = DisparityMap::from_vec(4, 1, vec![10.0, 20.0, 30.0, f32::NAN])?;
//! let est = DisparityMap::from_vec(4, 1, vec![10.25, 21.5, f32::NAN, 5.0])?;
//! let m = metrics(&est, &gt)?;
//! assert_eq!((m.n_gt, m.n_est), (3, 2));
//! // Errors 0.25 and 1.5, plus one hole: bad1 = 2 of 3 pixels.
//! assert!((m.bad1 - 200.0 / 3.0).abs() < 1e-12);
//! assert_eq!(m.avgerr, Some(0.875));
//! println!("{}", m.to_table_row());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::fmt;

mod folder;

pub use folder::{
    average, discover_scenes, evaluate_folder, evaluate_scene, format_table, try_evaluate_folder,
    FolderError, SceneResult, SceneSpec,
};

use stereo_image::{DisparityMap, Image};

/// Why metrics cannot be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Error {
    /// The estimate (or mask) and the ground truth differ in size.
    #[error("size mismatch: {what} is {width}x{height}, ground truth is {gt_width}x{gt_height}")]
    SizeMismatch {
        /// `"estimate"` or `"mask"`.
        what: &'static str,
        width: usize,
        height: usize,
        gt_width: usize,
        gt_height: usize,
    },
    /// No ground-truth pixel is finite and > 0 (inside the mask).
    #[error("no pixel with valid ground truth (finite and > 0, inside the mask if one is given)")]
    NoValidGroundTruth,
}

/// The error thresholds of [`Metrics`], pixels.
pub const BAD_THRESHOLDS: [f64; 4] = [0.5, 1.0, 2.0, 4.0];

/// Accuracy of a disparity map against ground truth; see the crate docs for the definitions.
/// Serialises with the keys of `stereo_eval.py` (`"bad0.5"`, `"bad1"`, …).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Metrics {
    /// Pixels with valid ground truth (inside the mask).
    pub n_gt: usize,
    /// Of those, pixels with a valid estimate.
    pub n_est: usize,
    /// % of GT-valid pixels with error > 0.5 px or no estimate.
    #[serde(rename = "bad0.5")]
    pub bad0_5: f64,
    /// % of GT-valid pixels with error > 1 px or no estimate.
    pub bad1: f64,
    /// % of GT-valid pixels with error > 2 px or no estimate.
    pub bad2: f64,
    /// % of GT-valid pixels with error > 4 px or no estimate.
    pub bad4: f64,
    /// Mean absolute error over estimated GT-valid pixels, px.
    pub avgerr: Option<f64>,
    /// Root-mean-square error over estimated GT-valid pixels, px.
    pub rms: Option<f64>,
    /// % of GT-valid pixels with a valid estimate.
    pub density: f64,
    /// % of estimated GT-valid pixels with error > 2 px.
    pub bad2_est: Option<f64>,
}

impl Metrics {
    /// The column names of [`Metrics::to_table_row`], aligned with it.
    pub fn table_header() -> String {
        format!(
            "{:>7} {:>7} {:>7} {:>7} {:>7} {:>7} {:>7}",
            "bad0.5", "bad1", "bad2", "bad4", "avgerr", "rms", "density"
        )
    }

    /// `bad0.5 bad1 bad2 bad4 avgerr rms density` on one line, fixed-width columns
    /// (percentages and pixels with two decimals, `-` for a missing value).
    pub fn to_table_row(&self) -> String {
        let opt = |v: Option<f64>| v.map_or_else(|| "-".to_string(), |v| format!("{v:.2}"));
        format!(
            "{:>7.2} {:>7.2} {:>7.2} {:>7.2} {:>7} {:>7} {:>7.2}",
            self.bad0_5,
            self.bad1,
            self.bad2,
            self.bad4,
            opt(self.avgerr),
            opt(self.rms),
            self.density
        )
    }
}

impl fmt::Display for Metrics {
    /// `bad0.5 1.23% bad1 …` with labels, one line.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let opt = |v: Option<f64>| v.map_or_else(|| "n/a".to_string(), |v| format!("{v:.3}"));
        write!(
            f,
            "bad0.5 {:.2}%  bad1 {:.2}%  bad2 {:.2}%  bad4 {:.2}%  avgerr {}  rms {}  density {:.2}%",
            self.bad0_5,
            self.bad1,
            self.bad2,
            self.bad4,
            opt(self.avgerr),
            opt(self.rms),
            self.density
        )
    }
}

/// Metrics of `estimate` against `ground_truth` over every GT-valid pixel.
pub fn metrics(estimate: &DisparityMap, ground_truth: &DisparityMap) -> Result<Metrics, Error> {
    metrics_masked(estimate, ground_truth, None)
}

/// Metrics of `estimate` against `ground_truth` over the GT-valid pixels where `mask` is true
/// (every pixel when `mask` is `None`).
pub fn metrics_masked(
    estimate: &DisparityMap,
    ground_truth: &DisparityMap,
    mask: Option<&Image<bool>>,
) -> Result<Metrics, Error> {
    let (gt_width, gt_height) = ground_truth.size();
    let check = |what, (width, height): (usize, usize)| {
        if (width, height) == (gt_width, gt_height) {
            Ok(())
        } else {
            Err(Error::SizeMismatch { what, width, height, gt_width, gt_height })
        }
    };
    check("estimate", estimate.size())?;
    if let Some(mask) = mask {
        check("mask", mask.size())?;
    }

    let mut n = 0usize;
    let mut errors = Vec::new();
    for (i, (&e, &g)) in estimate.as_slice().iter().zip(ground_truth.as_slice()).enumerate() {
        if !(g.is_finite() && g > 0.0) || mask.is_some_and(|m| !m.as_slice()[i]) {
            continue;
        }
        n += 1;
        if e.is_finite() {
            errors.push((f64::from(e) - f64::from(g)).abs());
        }
    }
    if n == 0 {
        return Err(Error::NoValidGroundTruth);
    }
    let ne = errors.len();
    let holes = n - ne;
    let over = |t: f64| errors.iter().filter(|&&e| e > t).count();
    let percent = |count: usize, of: usize| 100.0 * count as f64 / of as f64;
    let bad = BAD_THRESHOLDS.map(|t| percent(over(t) + holes, n));
    let (avgerr, rms, bad2_est) = if ne == 0 {
        (None, None, None)
    } else {
        let squares: Vec<f64> = errors.iter().map(|e| e * e).collect();
        (
            Some(numpy_sum(&errors) / ne as f64),
            Some((numpy_sum(&squares) / ne as f64).sqrt()),
            Some(percent(over(2.0), ne)),
        )
    };
    Ok(Metrics {
        n_gt: n,
        n_est: ne,
        bad0_5: bad[0],
        bad1: bad[1],
        bad2: bad[2],
        bad4: bad[3],
        avgerr,
        rms,
        density: percent(ne, n),
        bad2_est,
    })
}

/// The sum of `a` as NumPy's `np.add.reduce` computes it for a contiguous float64 array
/// (`pairwise_sum` in `loops_utils.h.src`): blocks of up to 128 values are summed with 8
/// interleaved accumulators, larger arrays are split in two (at a multiple of 8) recursively.
fn numpy_sum(a: &[f64]) -> f64 {
    const BLOCK: usize = 128;
    let n = a.len();
    if n < 8 {
        a.iter().fold(0.0, |acc, &v| acc + v)
    } else if n <= BLOCK {
        let mut r = [0.0f64; 8];
        r.copy_from_slice(&a[..8]);
        let whole = n - n % 8;
        for chunk in a[8..whole].chunks_exact(8) {
            for (acc, &v) in r.iter_mut().zip(chunk) {
                *acc += v;
            }
        }
        let mut res = ((r[0] + r[1]) + (r[2] + r[3])) + ((r[4] + r[5]) + (r[6] + r[7]));
        for &v in &a[whole..] {
            res += v;
        }
        res
    } else {
        let mut n2 = n / 2;
        n2 -= n2 % 8;
        numpy_sum(&a[..n2]) + numpy_sum(&a[n2..])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(width: usize, height: usize, data: &[f32]) -> DisparityMap {
        DisparityMap::from_vec(width, height, data.to_vec()).unwrap()
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-12 * b.abs().max(1.0)
    }

    #[test]
    fn hand_computed() {
        let nan = f32::NAN;
        // GT: 8 valid pixels; 0, negative, NaN and inf GT pixels are excluded.
        let gt = map(4, 3, &[10.0, 10.0, 10.0, 10.0, 10.0, 10.0, 10.0, 10.0, 0.0, -5.0, nan, f32::INFINITY]);
        // Errors: 0, 0.5 (not > 0.5), 1 (not > 1), 2 (not > 2), 4 (not > 4), 4.5, hole, hole.
        // Estimates at GT-invalid pixels are ignored whatever they are.
        let est = map(4, 3, &[10.0, 9.5, 11.0, 8.0, 14.0, 5.5, nan, f32::INFINITY, 1.0, 100.0, 3.0, nan]);
        let m = metrics(&est, &gt).unwrap();
        assert_eq!((m.n_gt, m.n_est), (8, 6));
        // > 0.5: 1, 2, 4, 4.5 + 2 holes = 6 of 8.
        assert_eq!(m.bad0_5, 75.0);
        // > 1: 2, 4, 4.5 + 2 = 5
        assert_eq!(m.bad1, 62.5);
        // > 2: 4, 4.5 + 2 = 4
        assert_eq!(m.bad2, 50.0);
        // > 4: 4.5 + 2 = 3
        assert_eq!(m.bad4, 37.5);
        // (0 + 0.5 + 1 + 2 + 4 + 4.5) / 6 = 2
        assert_eq!(m.avgerr, Some(2.0));
        // sqrt((0 + 0.25 + 1 + 4 + 16 + 20.25) / 6) = sqrt(41.5 / 6)
        assert!(close(m.rms.unwrap(), (41.5f64 / 6.0).sqrt()));
        assert_eq!(m.density, 75.0);
        // > 2 among the 6 estimates: 2
        assert!(close(m.bad2_est.unwrap(), 100.0 / 3.0));
    }

    #[test]
    fn error_is_computed_in_f64() {
        // 0.1f32 - 0.6f32 in f64 is not exactly -0.5: 0.6f32 = 0.60000002384…, 0.1f32 =
        // 0.10000000149…, so the error is 0.50000002235… > 0.5.
        let m = metrics(&map(1, 1, &[0.1]), &map(1, 1, &[0.6])).unwrap();
        assert_eq!(m.bad0_5, 100.0);
        assert_eq!(m.avgerr, Some(f64::from(0.6f32) - f64::from(0.1f32)));
    }

    #[test]
    fn all_holes() {
        let m = metrics(&map(2, 1, &[f32::NAN, f32::NEG_INFINITY]), &map(2, 1, &[1.0, 2.0])).unwrap();
        assert_eq!((m.n_gt, m.n_est), (2, 0));
        assert_eq!([m.bad0_5, m.bad1, m.bad2, m.bad4], [100.0; 4]);
        assert_eq!((m.avgerr, m.rms, m.bad2_est), (None, None, None));
        assert_eq!(m.density, 0.0);
        let json = serde_json::to_value(&m).unwrap();
        assert!(json["avgerr"].is_null() && json["rms"].is_null() && json["bad2_est"].is_null());
        assert!(m.to_table_row().contains('-'));
        assert!(m.to_string().contains("avgerr n/a"));
    }

    #[test]
    fn perfect_estimate() {
        let gt = DisparityMap::from_fn(5, 4, |x, y| (x + y + 1) as f32 * 1.25);
        let m = metrics(&gt, &gt).unwrap();
        assert_eq!((m.n_gt, m.n_est), (20, 20));
        assert_eq!([m.bad0_5, m.bad1, m.bad2, m.bad4], [0.0; 4]);
        assert_eq!((m.avgerr, m.rms, m.bad2_est), (Some(0.0), Some(0.0), Some(0.0)));
        assert_eq!(m.density, 100.0);
    }

    #[test]
    fn size_mismatch() {
        let e = metrics(&DisparityMap::new(3, 2, 1.0), &DisparityMap::new(2, 3, 1.0)).unwrap_err();
        assert_eq!(
            e,
            Error::SizeMismatch { what: "estimate", width: 3, height: 2, gt_width: 2, gt_height: 3 }
        );
        assert_eq!(e.to_string(), "size mismatch: estimate is 3x2, ground truth is 2x3");
        let mask = Image::new(1, 1, true);
        let e = metrics_masked(&DisparityMap::new(2, 3, 1.0), &DisparityMap::new(2, 3, 1.0), Some(&mask))
            .unwrap_err();
        assert_eq!(e.to_string(), "size mismatch: mask is 1x1, ground truth is 2x3");
    }

    #[test]
    fn no_valid_ground_truth() {
        let gt = map(3, 1, &[0.0, f32::NAN, -1.0]);
        let e = metrics(&map(3, 1, &[1.0, 1.0, 1.0]), &gt).unwrap_err();
        assert_eq!(e, Error::NoValidGroundTruth);
        assert!(e.to_string().contains("no pixel with valid ground truth"));
        // Valid GT, but all masked out.
        let gt = map(2, 1, &[1.0, 2.0]);
        let mask = Image::new(2, 1, false);
        let e = metrics_masked(&gt, &gt, Some(&mask)).unwrap_err();
        assert_eq!(e, Error::NoValidGroundTruth);
        assert!(matches!(
            metrics(&DisparityMap::new(0, 0, 1.0), &DisparityMap::new(0, 0, 1.0)),
            Err(Error::NoValidGroundTruth)
        ));
    }

    #[test]
    fn mask_restricts_pixels() {
        let gt = map(4, 1, &[1.0, 2.0, 3.0, 4.0]);
        let est = map(4, 1, &[1.0, 5.0, f32::NAN, 4.0]);
        let mask = Image::from_vec(4, 1, vec![true, false, false, true]).unwrap();
        let m = metrics_masked(&est, &gt, Some(&mask)).unwrap();
        assert_eq!((m.n_gt, m.n_est), (2, 2));
        assert_eq!(m.bad0_5, 0.0);
        assert_eq!(metrics_masked(&est, &gt, None).unwrap(), metrics(&est, &gt).unwrap());
        let m = metrics(&est, &gt).unwrap();
        assert_eq!((m.n_gt, m.n_est, m.bad2, m.bad4), (4, 3, 50.0, 25.0));
    }

    #[test]
    fn json_keys_match_stereo_eval_py() {
        let m = metrics(&map(2, 1, &[1.0, 3.5]), &map(2, 1, &[1.0, 2.0])).unwrap();
        let json = serde_json::to_string(&m).unwrap();
        assert_eq!(
            json,
            r#"{"n_gt":2,"n_est":2,"bad0.5":50.0,"bad1":50.0,"bad2":0.0,"bad4":0.0,"avgerr":0.75,"rms":1.0606601717798212,"density":100.0,"bad2_est":0.0}"#
        );
    }

    #[test]
    fn table_row_layout() {
        let m = metrics(&map(2, 1, &[1.0, 3.5]), &map(2, 1, &[1.0, 2.0])).unwrap();
        assert_eq!(m.to_table_row(), "  50.00   50.00    0.00    0.00    0.75    1.06  100.00");
        assert_eq!(Metrics::table_header().len(), m.to_table_row().len());
        assert_eq!(
            m.to_string(),
            "bad0.5 50.00%  bad1 50.00%  bad2 0.00%  bad4 0.00%  avgerr 0.750  rms 1.061  density 100.00%"
        );
    }

    #[test]
    fn numpy_pairwise_sum() {
        // Small and block sizes equal the plain sum for exactly representable values.
        for n in [0usize, 1, 7, 8, 9, 100, 128, 129, 1000, 4099] {
            let v: Vec<f64> = (0..n).map(|i| (i % 17) as f64 * 0.5).collect();
            assert_eq!(numpy_sum(&v), v.iter().sum::<f64>(), "n = {n}");
        }
        // Pairwise blocks: 1e16 + 1 + 1 … loses the ones when added one at a time, but the
        // 8 accumulators keep them together: r0 = 1e16 + 1 = 1e16 (ties to even), r1..r7 = 2.
        let mut v = vec![1.0f64; 16];
        v[0] = 1e16;
        assert_eq!(numpy_sum(&v), 1e16 + 14.0);
        assert_eq!(v.iter().fold(0.0, |a, &b| a + b), 1e16);
    }
}
