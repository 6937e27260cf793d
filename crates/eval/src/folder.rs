//! Evaluation of a matcher over a whole folder of scenes with ground truth.
//!
//! Two layouts are read (see [`discover_scenes`]):
//!
//! * a `scenes.tsv` table (the layout of `../shared/data`): a tab-separated header with at least
//!   the columns `scene`, `left`, `right`, `gt_left` and `gt_scale`, and optionally
//!   `suggested_ndisp` (the searched range; otherwise a quarter of the width), one row per scene,
//!   files relative to `DIR/<scene>/`;
//! * Middlebury 2014/2021 scene folders: `DIR/<SCENE>/im0.png`, `im1.png`, `disp0GT.pfm` (or
//!   `disp0.pfm`) and `calib.txt` (whose `ndisp` is the searched range); `DIR` may also be one
//!   such scene folder itself. A `mask0nocc.png` beside them adds non-occluded metrics
//!   (pixels where the mask is 255).
//!
//! ```no_run
//! use stereo_disparity::{sgm, DisparityRange, SgmParams};
//! use stereo_eval::{evaluate_folder, format_table};
//!
//! let results = evaluate_folder("../shared/data".as_ref(), |left, right, ndisp| {
//!     let range = DisparityRange::new(0, ndisp as i32).unwrap();
//!     sgm(left, right, &SgmParams { range, ..SgmParams::default() }).unwrap()
//! })?;
//! print!("{}", format_table(&results));
//! # Ok::<(), stereo_eval::FolderError>(())
//! ```

use std::path::{Path, PathBuf};
use std::time::Instant;

use stereo_image::{DisparityMap, GrayImage, Image};

use crate::{metrics_masked, Metrics};

/// Why a folder cannot be evaluated.
#[derive(Debug, thiserror::Error)]
pub enum FolderError {
    /// Neither a `scenes.tsv` nor Middlebury scene folders were found.
    #[error("{}: no scenes.tsv and no Middlebury scene folders (im0.png, im1.png, disp0GT.pfm, calib.txt)", .0.display())]
    NoScenes(PathBuf),
    /// A listing or calibration file is malformed.
    #[error("{}: {message}", path.display())]
    Format { path: PathBuf, message: String },
    /// An image or ground-truth file cannot be read.
    #[error(transparent)]
    Io(#[from] stereo_io::Error),
    /// The matcher failed on a scene.
    #[error("scene {scene}: matcher failed: {message}")]
    Matcher { scene: String, message: String },
    /// The metrics cannot be computed (size mismatch, no valid ground truth).
    #[error("scene {scene}: {source}")]
    Metrics { scene: String, source: crate::Error },
}

/// One scene of a folder: where its files are and how many disparities to search.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneSpec {
    pub name: String,
    pub left: PathBuf,
    pub right: PathBuf,
    pub ground_truth: PathBuf,
    /// `disparity = value / scale` for PNG/PGM ground truth (1 for PFM).
    pub gt_scale: f32,
    /// The number of disparities to search (`0..ndisp`); `None`: a quarter of the width,
    /// rounded up to a multiple of 16.
    pub ndisp: Option<usize>,
    /// Middlebury `mask0nocc.png`: 255 marks non-occluded pixels.
    pub nonocc_mask: Option<PathBuf>,
}

/// The result of one scene.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SceneResult {
    pub name: String,
    pub width: usize,
    pub height: usize,
    /// Disparities searched.
    pub ndisp: usize,
    /// Over every pixel with ground truth (holes counted as bad).
    pub metrics: Metrics,
    /// Over the non-occluded pixels, when the scene has a mask.
    pub nonocc: Option<Metrics>,
    /// Wall-clock time of the matcher call.
    pub seconds: f64,
}

/// The scenes of `dir`, from its `scenes.tsv` or its Middlebury scene folders (sorted by name).
pub fn discover_scenes(dir: &Path) -> Result<Vec<SceneSpec>, FolderError> {
    let tsv = dir.join("scenes.tsv");
    if tsv.is_file() {
        return read_scenes_tsv(dir, &tsv);
    }
    if let Some(scene) = middlebury_scene(dir)? {
        return Ok(vec![scene]);
    }
    let entries = std::fs::read_dir(dir).map_err(|e| FolderError::Format {
        path: dir.to_path_buf(),
        message: format!("cannot list the folder: {e}"),
    })?;
    let mut dirs: Vec<PathBuf> =
        entries.filter_map(|e| e.ok().map(|e| e.path())).filter(|p| p.is_dir()).collect();
    dirs.sort();
    let mut scenes = Vec::new();
    for d in dirs {
        if let Some(scene) = middlebury_scene(&d)? {
            scenes.push(scene);
        }
    }
    if scenes.is_empty() {
        return Err(FolderError::NoScenes(dir.to_path_buf()));
    }
    Ok(scenes)
}

fn read_scenes_tsv(dir: &Path, tsv: &Path) -> Result<Vec<SceneSpec>, FolderError> {
    let format = |message: String| FolderError::Format { path: tsv.to_path_buf(), message };
    let text = std::fs::read_to_string(tsv).map_err(|e| format(format!("cannot read: {e}")))?;
    let mut lines = text.lines().filter(|l| !l.trim().is_empty() && !l.starts_with('#'));
    let header: Vec<&str> = lines.next().ok_or_else(|| format("empty file".into()))?.split('\t').collect();
    let column = |name: &str| header.iter().position(|h| h.trim() == name);
    let need = |name: &str| column(name).ok_or_else(|| format(format!("no {name:?} column in the header")));
    let (scene, left, right, gt, scale) =
        (need("scene")?, need("left")?, need("right")?, need("gt_left")?, need("gt_scale")?);
    let ndisp = column("suggested_ndisp").or_else(|| column("ndisp"));
    let mut scenes = Vec::new();
    for (number, line) in lines.enumerate() {
        let fields: Vec<&str> = line.split('\t').map(str::trim).collect();
        let field = |i: usize| {
            fields.get(i).copied().ok_or_else(|| format(format!("row {}: too few columns", number + 1)))
        };
        let name = field(scene)?.to_string();
        let base = dir.join(&name);
        let gt_scale: f32 = field(scale)?.parse().map_err(|_| {
            format(format!("row {}: gt_scale {:?} is not a number", number + 1, fields[scale]))
        })?;
        let ndisp = match ndisp {
            Some(i) => Some(field(i)?.parse::<usize>().map_err(|_| {
                format(format!("row {}: ndisp {:?} is not a whole number", number + 1, fields[i]))
            })?),
            None => None,
        };
        scenes.push(SceneSpec {
            left: base.join(field(left)?),
            right: base.join(field(right)?),
            ground_truth: base.join(field(gt)?),
            gt_scale,
            ndisp,
            nonocc_mask: None,
            name,
        });
    }
    if scenes.is_empty() {
        return Err(format("no scene rows".into()));
    }
    Ok(scenes)
}

/// `dir` as a Middlebury scene folder, if it is one.
fn middlebury_scene(dir: &Path) -> Result<Option<SceneSpec>, FolderError> {
    let (left, right, calib) = (dir.join("im0.png"), dir.join("im1.png"), dir.join("calib.txt"));
    let gt = ["disp0GT.pfm", "disp0.pfm"].iter().map(|f| dir.join(f)).find(|p| p.is_file());
    let (Some(gt), true, true, true) = (gt, left.is_file(), right.is_file(), calib.is_file()) else {
        return Ok(None);
    };
    let ndisp = stereo_io::read_calib(&calib)?.ndisp;
    let mask = dir.join("mask0nocc.png");
    let name = dir
        .canonicalize()
        .ok()
        .and_then(|p| p.file_name().map(|n| n.to_string_lossy().into_owned()))
        .unwrap_or_else(|| dir.display().to_string());
    Ok(Some(SceneSpec {
        name,
        left,
        right,
        ground_truth: gt,
        gt_scale: 1.0,
        ndisp,
        nonocc_mask: mask.is_file().then_some(mask),
    }))
}

/// Runs `matcher(left, right, ndisp)` on every scene of `dir` (see [`discover_scenes`]) and
/// scores its map against the ground truth. Panics of the matcher propagate; use
/// [`try_evaluate_folder`] for a fallible matcher.
pub fn evaluate_folder<M>(dir: &Path, mut matcher: M) -> Result<Vec<SceneResult>, FolderError>
where
    M: FnMut(&GrayImage, &GrayImage, usize) -> DisparityMap,
{
    try_evaluate_folder(dir, |l, r, n| Ok::<_, std::convert::Infallible>(matcher(l, r, n)))
}

/// [`evaluate_folder`] with a matcher that may fail; its error ends the evaluation.
pub fn try_evaluate_folder<M, E>(dir: &Path, mut matcher: M) -> Result<Vec<SceneResult>, FolderError>
where
    M: FnMut(&GrayImage, &GrayImage, usize) -> Result<DisparityMap, E>,
    E: std::fmt::Display,
{
    let scenes = discover_scenes(dir)?;
    let mut results = Vec::with_capacity(scenes.len());
    for scene in &scenes {
        results.push(evaluate_scene(scene, &mut matcher)?);
    }
    Ok(results)
}

/// Runs `matcher` on one scene and scores it.
pub fn evaluate_scene<M, E>(scene: &SceneSpec, mut matcher: M) -> Result<SceneResult, FolderError>
where
    M: FnMut(&GrayImage, &GrayImage, usize) -> Result<DisparityMap, E>,
    E: std::fmt::Display,
{
    let left = stereo_io::load_gray(&scene.left)?;
    let right = stereo_io::load_gray(&scene.right)?;
    let gt = stereo_io::read_disparity(&scene.ground_truth, scene.gt_scale)?;
    let (width, height) = left.size();
    let ndisp = scene.ndisp.unwrap_or_else(|| stereo_image::DisparityRange::default_for_width(width).count());
    let start = Instant::now();
    let estimate = matcher(&left, &right, ndisp)
        .map_err(|e| FolderError::Matcher { scene: scene.name.clone(), message: e.to_string() })?;
    let seconds = start.elapsed().as_secs_f64();
    let scored = |mask: Option<&Image<bool>>| {
        metrics_masked(&estimate, &gt, mask)
            .map_err(|source| FolderError::Metrics { scene: scene.name.clone(), source })
    };
    let all = scored(None)?;
    let nonocc = match &scene.nonocc_mask {
        Some(path) => {
            let raw = stereo_io::read_disparity(path, 1.0)?;
            let mask = Image::from_vec(
                raw.width(),
                raw.height(),
                raw.as_slice().iter().map(|&v| v >= 255.0).collect(),
            )
            .map_err(|e| FolderError::Format { path: path.clone(), message: e.to_string() })?;
            Some(scored(Some(&mask))?)
        }
        None => None,
    };
    Ok(SceneResult { name: scene.name.clone(), width, height, ndisp, metrics: all, nonocc, seconds })
}

/// The mean of each metric over `results` (`avgerr`/`rms` over the scenes that have one), or
/// `None` for no scenes.
pub fn average(results: &[SceneResult]) -> Option<Metrics> {
    if results.is_empty() {
        return None;
    }
    let n = results.len() as f64;
    let mean = |f: &dyn Fn(&Metrics) -> f64| results.iter().map(|r| f(&r.metrics)).sum::<f64>() / n;
    let mean_opt = |f: &dyn Fn(&Metrics) -> Option<f64>| {
        let v: Vec<f64> = results.iter().filter_map(|r| f(&r.metrics)).collect();
        (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
    };
    Some(Metrics {
        n_gt: results.iter().map(|r| r.metrics.n_gt).sum(),
        n_est: results.iter().map(|r| r.metrics.n_est).sum(),
        bad0_5: mean(&|m| m.bad0_5),
        bad1: mean(&|m| m.bad1),
        bad2: mean(&|m| m.bad2),
        bad4: mean(&|m| m.bad4),
        avgerr: mean_opt(&|m| m.avgerr),
        rms: mean_opt(&|m| m.rms),
        density: mean(&|m| m.density),
        bad2_est: mean_opt(&|m| m.bad2_est),
    })
}

/// A per-scene table (`scene`, the [`Metrics::to_table_row`] columns, seconds) ending with the
/// average row (means over the scenes; the time is the total).
pub fn format_table(results: &[SceneResult]) -> String {
    let name_width = results.iter().map(|r| r.name.len()).max().unwrap_or(0).max(7);
    let mut out = format!("{:<name_width$} {} {:>8}\n", "scene", Metrics::table_header(), "time_s");
    for r in results {
        out += &format!("{:<name_width$} {} {:>8.3}\n", r.name, r.metrics.to_table_row(), r.seconds);
    }
    if let Some(avg) = average(results) {
        let total: f64 = results.iter().map(|r| r.seconds).sum();
        out += &format!("{:<name_width$} {} {:>8.3}\n", "average", avg.to_table_row(), total);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_gray(path: &Path, w: usize, h: usize, f: impl Fn(usize, usize) -> u16) {
        // An 8-bit binary PGM (load_gray detects the format from the content).
        let mut bytes = format!("P5\n{w} {h}\n255\n").into_bytes();
        for y in 0..h {
            for x in 0..w {
                bytes.push(f(x, y) as u8);
            }
        }
        std::fs::write(path, bytes).unwrap();
    }

    fn texture(x: i64, y: i64) -> u16 {
        let h = (x.wrapping_mul(0x9E37_79B9) ^ y.wrapping_mul(0x85EB_CA6B)).wrapping_mul(0xC2B2_AE35);
        ((h >> 16) & 0xff) as u16
    }

    fn temp_dir(tag: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("stereo-eval-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn scenes_tsv_layout_is_read_and_scored() {
        let dir = temp_dir("tsv");
        std::fs::create_dir_all(dir.join("a")).unwrap();
        write_gray(&dir.join("a/l.pgm"), 40, 10, |x, y| texture(x as i64, y as i64));
        write_gray(&dir.join("a/r.pgm"), 40, 10, |x, y| texture(x as i64 + 3, y as i64));
        // GT: 3 px at scale 4 = 12; the first column unknown.
        write_gray(&dir.join("a/gt.pgm"), 40, 10, |x, _| if x == 0 { 0 } else { 12 });
        std::fs::write(
            dir.join("scenes.tsv"),
            "scene\tleft\tright\tgt_left\tgt_right\tgt_scale\tsuggested_ndisp\na\tl.pgm\tr.pgm\tgt.pgm\t-\t4\t16\n",
        )
        .unwrap();
        let mut seen = Vec::new();
        let results = evaluate_folder(&dir, |l, _, nd| {
            seen.push((l.size(), nd));
            DisparityMap::new(40, 10, 3.0)
        })
        .unwrap();
        assert_eq!(seen, vec![((40, 10), 16)]);
        assert_eq!(results.len(), 1);
        let r = &results[0];
        assert_eq!((r.name.as_str(), r.ndisp, r.metrics.n_gt), ("a", 16, 390));
        assert_eq!(r.metrics.bad2, 0.0);
        let table = format_table(&results);
        assert_eq!(table.lines().count(), 3);
        assert!(table.lines().last().unwrap().starts_with("average"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn middlebury_folders_are_read() {
        let dir = temp_dir("mb");
        for (scene, d) in [("Bravo", 2.0f32), ("Alpha", 5.0)] {
            let s = dir.join(scene);
            std::fs::create_dir_all(&s).unwrap();
            write_gray(&s.join("im0.png"), 30, 8, |x, y| texture(x as i64, y as i64));
            write_gray(&s.join("im1.png"), 30, 8, |x, y| texture(x as i64, y as i64));
            stereo_io::write_pfm(&s.join("disp0GT.pfm"), &DisparityMap::new(30, 8, d)).unwrap();
            std::fs::write(s.join("calib.txt"), "cam0=[100 0 15; 0 100 4; 0 0 1]\nndisp=24\n").unwrap();
        }
        let results = evaluate_folder(&dir, |_, _, _| DisparityMap::new(30, 8, 5.0)).unwrap();
        let names: Vec<&str> = results.iter().map(|r| r.name.as_str()).collect();
        assert_eq!(names, ["Alpha", "Bravo"]);
        assert_eq!(results[0].ndisp, 24);
        assert_eq!((results[0].metrics.bad2, results[1].metrics.bad2), (0.0, 100.0));
        assert_eq!(average(&results).unwrap().bad2, 50.0);
        // One scene folder given directly.
        let one = evaluate_folder(&dir.join("Alpha"), |_, _, _| DisparityMap::new(30, 8, f32::NAN)).unwrap();
        assert_eq!((one.len(), one[0].metrics.density), (1, 0.0));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn empty_folder_and_failing_matcher_are_errors() {
        let dir = temp_dir("empty");
        assert!(matches!(
            evaluate_folder(&dir, |_, _, _| DisparityMap::new(1, 1, 0.0)),
            Err(FolderError::NoScenes(_))
        ));
        std::fs::remove_dir_all(&dir).unwrap();
        let dir = temp_dir("fail");
        let s = dir.join("X");
        std::fs::create_dir_all(&s).unwrap();
        write_gray(&s.join("im0.png"), 8, 8, |_, _| 0);
        write_gray(&s.join("im1.png"), 8, 8, |_, _| 0);
        stereo_io::write_pfm(&s.join("disp0GT.pfm"), &DisparityMap::new(8, 8, 1.0)).unwrap();
        std::fs::write(s.join("calib.txt"), "cam0=[10 0 4; 0 10 4; 0 0 1]\nndisp=4\n").unwrap();
        let e = try_evaluate_folder(&dir, |_, _, _| Err::<DisparityMap, _>("boom")).unwrap_err();
        assert_eq!(e.to_string(), "scene X: matcher failed: boom");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
