//! Helpers of the end-to-end tests: run the real binary in a temporary folder, write inputs,
//! read its outputs independently of the program (EXR through the `exr` crate).

#![allow(dead_code)]

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use stereo_disparity::{DisparityMap, GrayImage, Image};

/// The sample scene's rig (data/slanted/README): baseline 80 mm, focal 12 mm, pixels 4 µm.
pub const RIG: [&str; 6] = ["--baseline", "80", "--focal", "12", "--pixel", "4"];
/// `B·f/p` of [`RIG`]: `Z[m] = B[mm]·f[mm] / (d·p[µm]) = DEPTH_PER_DISPARITY / d`.
pub const DEPTH_PER_DISPARITY: f64 = 80.0 * 12.0 / 4.0;

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// `data/slanted/NAME`, failing clearly when the sample scene is missing.
pub fn slanted(name: &str) -> PathBuf {
    let path = repo().join("data/slanted").join(name);
    assert!(path.is_file(), "sample scene file {} is missing", path.display());
    path
}

/// The outcome of one run of the binary.
pub struct Run {
    pub code: Option<i32>,
    pub stdout: String,
    pub stderr: String,
}

impl Run {
    fn from_output(output: Output) -> Run {
        Run {
            code: output.status.code(),
            stdout: String::from_utf8_lossy(&output.stdout).into_owned(),
            stderr: String::from_utf8_lossy(&output.stderr).into_owned(),
        }
    }

    #[track_caller]
    pub fn assert_success(&self) -> &Self {
        assert_eq!(self.code, Some(0), "stdout:\n{}\nstderr:\n{}", self.stdout, self.stderr);
        self
    }

    /// Exit status `code` (never a panic's 101), and exactly one line on stderr in the program's
    /// error format.
    #[track_caller]
    pub fn assert_error(&self, code: i32) -> &str {
        assert_ne!(self.code, Some(101), "panicked:\n{}", self.stderr);
        assert_eq!(self.code, Some(code), "stdout:\n{}\nstderr:\n{}", self.stdout, self.stderr);
        assert!(
            self.stderr.starts_with("stereo-depth: error: ")
                && self.stderr.ends_with('\n')
                && self.stderr.lines().count() == 1,
            "stderr is not one error line: {:?}",
            self.stderr
        );
        self.stderr.trim_end()
    }

    /// Exit status `code` (never 101) and exactly one `stereo-depth: ` line on stderr (an error,
    /// or the batch command's failure count).
    #[track_caller]
    pub fn assert_error_line(&self, code: i32) -> &str {
        assert_ne!(self.code, Some(101), "panicked:\n{}", self.stderr);
        assert_eq!(self.code, Some(code), "stdout:\n{}\nstderr:\n{}", self.stdout, self.stderr);
        assert!(
            self.stderr.starts_with("stereo-depth: ") && self.stderr.lines().count() == 1,
            "stderr is not one line: {:?}",
            self.stderr
        );
        self.stderr.trim_end()
    }

    /// The path printed as `WHAT: PATH` on stdout.
    pub fn printed_path(&self, what: &str) -> Option<PathBuf> {
        let prefix = format!("{what}: ");
        self.stdout.lines().find_map(|line| line.strip_prefix(&prefix)).map(PathBuf::from)
    }
}

/// Runs the binary with `args` in the folder `cwd`.
pub fn run_in(cwd: &Path, args: &[&str]) -> Run {
    let output = Command::new(env!("CARGO_BIN_EXE_stereo-depth"))
        .args(args)
        .current_dir(cwd)
        .stdin(Stdio::null())
        .output()
        .expect("cannot start stereo-depth");
    Run::from_output(output)
}

pub fn s(path: &Path) -> &str {
    path.to_str().expect("test paths are UTF-8")
}

/// Every file name in `dir`, sorted.
pub fn list(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> =
        fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    names
}

/// Writes a 16-bit binary PGM (P5, big-endian samples), which the program reads like a PNG.
pub fn write_pgm16(path: &Path, image: &GrayImage) {
    let mut bytes = format!("P5\n{} {}\n65535\n", image.width(), image.height()).into_bytes();
    for &v in image.as_slice() {
        bytes.extend_from_slice(&v.to_be_bytes());
    }
    fs::write(path, bytes).unwrap();
}

/// Renders a synthetic scene of `width × height` into `dir` as `left.pgm`, `right.pgm` and
/// `gt.pfm`; returns the scene.
pub fn write_scene(dir: &Path, width: usize, height: usize) -> stereo_scene::Scene {
    let params = stereo_scene::SceneParams { width, height, ..stereo_scene::SceneParams::default() };
    let scene = stereo_scene::render(&params);
    write_pgm16(&dir.join("left.pgm"), &scene.left);
    write_pgm16(&dir.join("right.pgm"), &scene.right);
    stereo_io::write_pfm(&dir.join("gt.pfm"), &scene.gt_left).unwrap();
    scene
}

/// A single-channel EXR as read by the `exr` crate: channel names and the samples of `Z`.
pub struct Exr {
    pub channels: Vec<String>,
    pub width: usize,
    pub height: usize,
    pub z: Image<f32>,
}

pub fn read_exr(path: &Path) -> Exr {
    use exr::prelude::{read_first_flat_layer_from_file, FlatSamples};
    let image = read_first_flat_layer_from_file(path).expect("depth map is a readable EXR");
    let layer = &image.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    let channels: Vec<String> = layer.channel_data.list.iter().map(|c| c.name.to_string()).collect();
    let z = layer
        .channel_data
        .list
        .iter()
        .find(|c| c.name.to_string() == "Z")
        .map(|c| match &c.sample_data {
            FlatSamples::F32(samples) => Image::from_vec(width, height, samples.clone()).unwrap(),
            other => panic!("channel Z holds {other:?}, not f32"),
        })
        .unwrap_or_else(|| Image::new(0, 0, f32::NAN));
    Exr { channels, width, height, z }
}

/// Left pixels whose ground-truth point is hidden in, or falls outside, the right view (as
/// `occlusion_mask_from_gt` of stereo_eval.py, plus the left border band).
pub fn occluded(gt: &DisparityMap) -> Image<bool> {
    let (width, height) = gt.size();
    let mut mask = Image::new(width, height, false);
    for y in 0..height {
        // Smallest right-view position x' - d' of the pixels right of x.
        let mut right_min = f64::INFINITY;
        for x in (0..width).rev() {
            let d = gt.get(x, y) as f64;
            if d.is_finite() && d > 0.0 {
                let t = x as f64 - d;
                if right_min < t - 0.5 || t < -0.5 {
                    mask.set(x, y, true);
                }
                right_min = right_min.min(t);
            }
        }
    }
    mask
}

/// `image` moved down by `rows` whole pixels (the top row repeated into the gap): a right view
/// whose rectification left it lower than the left view.
pub fn shifted_down(image: &GrayImage, rows: usize) -> GrayImage {
    let (width, height) = image.size();
    Image::from_fn(width, height, |x, y| image.get(x, y.saturating_sub(rows)))
}

/// Every output of one pair run on data/slanted.
pub struct Outputs {
    pub exr: PathBuf,
    pub pfm: PathBuf,
    pub depth_png: PathBuf,
    pub disparity_png: PathBuf,
    pub points: PathBuf,
    pub preview: PathBuf,
    pub stats: PathBuf,
}

impl Outputs {
    pub fn in_dir(dir: &Path) -> Outputs {
        Outputs {
            exr: dir.join("depth.exr"),
            pfm: dir.join("disp.pfm"),
            depth_png: dir.join("depth.png"),
            disparity_png: dir.join("disp.png"),
            points: dir.join("points.ply"),
            preview: dir.join("preview.png"),
            stats: dir.join("stats.json"),
        }
    }

    pub fn args(&self) -> Vec<&str> {
        vec![
            "-o",
            s(&self.exr),
            "--disparity",
            s(&self.pfm),
            "--depth-png",
            s(&self.depth_png),
            "--disparity-png",
            s(&self.disparity_png),
            "--points",
            s(&self.points),
            "--preview",
            s(&self.preview),
            "--stats",
            s(&self.stats),
        ]
    }
}

/// Runs data/slanted with `rig` and `extra`, writing every output into `dir`; asserts success.
pub fn run_slanted(dir: &Path, rig: &[&str], extra: &[&str]) -> (Run, Outputs) {
    let (left, right) = (slanted("left.png"), slanted("right.png"));
    let outputs = Outputs::in_dir(dir);
    let mut args = vec![s(&left), s(&right), "--max-disparity", "64"];
    args.extend(rig);
    args.extend(outputs.args());
    args.extend(extra);
    let run = run_in(dir, &args);
    run.assert_success();
    (run, outputs)
}
