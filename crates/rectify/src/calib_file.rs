//! Calibration files, detected from their content:
//!
//! - OpenCV `FileStorage` YAML or XML as written after `stereoCalibrate` (`K1 D1 K2 D2 R T`,
//!   optionally `R1 R2 P1 P2 Q` from `stereoRectify`), and the same keys in plain YAML or JSON;
//! - ROS `camera_info` YAML, one file per camera (the other camera's file is found beside it);
//! - Middlebury `calib.txt` (an already rectified pair), read by [`stereo_io::parse_calib`].
//!
//! Errors are one line naming the file and the missing or bad key.

use std::fmt;
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Matrix3x4, Vector3};

use crate::camera::{rodrigues, Camera};
use crate::tree::{self, Node};

/// A calibration file that cannot be used, naming the file.
#[derive(Clone, Debug, PartialEq)]
pub struct CalibError {
    pub path: PathBuf,
    pub message: String,
}

impl fmt::Display for CalibError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.message)
    }
}

impl std::error::Error for CalibError {}

fn err(path: &Path, message: impl Into<String>) -> CalibError {
    CalibError { path: path.to_path_buf(), message: message.into() }
}

/// Which kind of file a calibration came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CalibFormat {
    /// OpenCV `FileStorage` YAML (`%YAML:1.0`, `!!opencv-matrix`) or plain YAML with its keys.
    OpenCvYaml,
    /// OpenCV `FileStorage` XML.
    OpenCvXml,
    /// JSON with OpenCV's keys.
    Json,
    /// Two ROS `camera_info` YAML files.
    RosCameraInfo,
}

impl CalibFormat {
    pub fn name(self) -> &'static str {
        match self {
            CalibFormat::OpenCvYaml => "OpenCV YAML",
            CalibFormat::OpenCvXml => "OpenCV XML",
            CalibFormat::Json => "JSON",
            CalibFormat::RosCameraInfo => "ROS camera_info",
        }
    }
}

/// The rectification a file already gives (ROS `R`/`P`, OpenCV `R1 R2 P1 P2`).
#[derive(Clone, Debug, PartialEq)]
pub struct GivenRectification {
    pub r1: Matrix3<f64>,
    pub r2: Matrix3<f64>,
    pub p1: Matrix3x4<f64>,
    pub p2: Matrix3x4<f64>,
}

/// A raw (unrectified) stereo calibration.
#[derive(Clone, Debug, PartialEq)]
pub struct StereoCalibration {
    pub left: Camera,
    pub right: Camera,
    /// Rotation and translation from the left to the right camera (`x_r = R x_l + T`), when the
    /// file gives them; the rectification is then computed (Bouguet, as `cv::stereoRectify`).
    pub extrinsics: Option<(Matrix3<f64>, Vector3<f64>)>,
    /// The rectification in the file, used when it has no extrinsics.
    pub given: Option<GivenRectification>,
    /// The image size the cameras were calibrated at, when the file says.
    pub image_size: Option<(usize, usize)>,
    /// Millimetres per unit of the file's translations (`T`, `P2[0][3]`): 1000 for metres.
    pub mm_per_unit: f64,
    /// How the unit was decided, for the user.
    pub unit_note: String,
    pub format: CalibFormat,
    /// The files read (two for ROS).
    pub paths: Vec<PathBuf>,
}

/// What a `--calib` file holds.
#[derive(Clone, Debug, PartialEq)]
pub enum CalibrationFile {
    /// A Middlebury `calib.txt`: the pair is already rectified.
    Middlebury(stereo_io::Calib),
    /// A raw stereo calibration: the pair is rectified first.
    Stereo(Box<StereoCalibration>),
}

/// Reads a calibration file of any supported format, detected from the content. For ROS
/// `camera_info`, `path` is either camera's file (the other is found beside it: `left` ↔ `right`
/// in the name) or a folder holding both.
pub fn read_calibration(path: &Path) -> Result<CalibrationFile, CalibError> {
    if path.is_dir() {
        return read_ros_folder(path).map(|c| CalibrationFile::Stereo(Box::new(c)));
    }
    let text = read_text(path)?;
    if looks_like_middlebury(&text) {
        return stereo_io::parse_calib(&text)
            .map(CalibrationFile::Middlebury)
            .map_err(|m| err(path, format!("invalid Middlebury calib.txt: {m}")));
    }
    let unknown = |detail: &str| {
        err(
            path,
            format!(
                "not a calibration file: neither Middlebury key=value lines (cam0=[f 0 cx; 0 f cy; 0 0 1]) nor \
                 OpenCV/ROS YAML, XML or JSON ({detail})"
            ),
        )
    };
    if text.trim().is_empty() {
        return Err(unknown("empty file"));
    }
    let node = tree::parse(&text).map_err(|m| unknown(&m))?;
    if node.get("camera_matrix").is_some() {
        return read_ros_pair(path, node).map(|c| CalibrationFile::Stereo(Box::new(c)));
    }
    let start = text.trim_start();
    let format = if start.starts_with('<') {
        CalibFormat::OpenCvXml
    } else if start.starts_with('{') {
        CalibFormat::Json
    } else {
        CalibFormat::OpenCvYaml
    };
    read_opencv(path, &node, format).map(|c| CalibrationFile::Stereo(Box::new(c)))
}

fn read_text(path: &Path) -> Result<String, CalibError> {
    let bytes = std::fs::read(path).map_err(|e| err(path, e.to_string()))?;
    String::from_utf8(bytes).map_err(|_| err(path, "not a calibration file (not UTF-8 text)"))
}

/// Middlebury files are `key=value` lines: a `cam0=` line, or a first line `key=...` (no `:`
/// before the `=`, so YAML/JSON/XML are not taken for one).
fn looks_like_middlebury(text: &str) -> bool {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    if text.lines().any(|l| l.trim_start().starts_with("cam0=") || l.trim_start().starts_with("cam0 =")) {
        return true;
    }
    let Some(first) = text.lines().map(str::trim).find(|l| !l.is_empty() && !l.starts_with('#')) else {
        return false;
    };
    match first.split_once('=') {
        Some((key, _)) => {
            !key.is_empty() && key.trim().chars().all(|c| c.is_ascii_alphanumeric() || c == '_')
        }
        None => false,
    }
}

/// The `data` of an `!!opencv-matrix` mapping, or the node itself.
fn data_of(node: &Node) -> &Node {
    node.get("data").unwrap_or(node)
}

/// A `rows × cols` matrix from an `!!opencv-matrix` mapping (`rows`, `cols`, `data`), a ROS
/// mapping (same keys), a flat list or a list of rows.
fn matrix(path: &Path, node: &Node, key: &str, rows: usize, cols: usize) -> Result<Vec<f64>, CalibError> {
    let data = match node {
        Node::Map(_) => {
            let data = node.get("data").ok_or_else(|| err(path, format!("{key}: no data")))?;
            for (dim, want) in [("rows", rows), ("cols", cols)] {
                if let Some(v) = node.get(dim).and_then(Node::text) {
                    if v.parse::<usize>().ok().is_none() {
                        return Err(err(path, format!("{key}: {dim}: {v} is not a whole number")));
                    }
                    let _ = want;
                }
            }
            data
        }
        other => other,
    };
    let values = data.numbers().map_err(|m| err(path, format!("{key}: {m}")))?;
    if values.len() != rows * cols {
        return Err(err(
            path,
            format!("{key}: {} numbers, want {rows}x{cols} = {}", values.len(), rows * cols),
        ));
    }
    Ok(values)
}

fn camera_matrix(path: &Path, node: &Node, key: &str) -> Result<Matrix3<f64>, CalibError> {
    let v = matrix(path, node, key, 3, 3)?;
    let k = Matrix3::from_row_slice(&v);
    let ok = k[(0, 0)] > 0.0
        && k[(1, 1)] > 0.0
        && k[(1, 0)] == 0.0
        && k[(2, 0)] == 0.0
        && k[(2, 1)] == 0.0
        && (k[(2, 2)] - 1.0).abs() < 1e-9;
    if !ok {
        return Err(err(
            path,
            format!("{key}: not a camera matrix [fx 0 cx; 0 fy cy; 0 0 1] with fx, fy > 0"),
        ));
    }
    Ok(k)
}

fn distortion(path: &Path, node: &Node, key: &str) -> Result<Vec<f64>, CalibError> {
    let data = match node {
        Node::Map(_) => node.get("data").ok_or_else(|| err(path, format!("{key}: no data")))?,
        other => other,
    };
    let values = data.numbers().map_err(|m| err(path, format!("{key}: {m}")))?;
    match values.len() {
        0 | 4 | 5 | 8 => Ok(values),
        12 | 14 if values[8..].iter().all(|&v| v == 0.0) => Ok(values[..8].to_vec()),
        12 | 14 => Err(err(path, format!("{key}: thin-prism and tilt coefficients are not supported"))),
        n => Err(err(path, format!("{key}: {n} coefficients, want 4, 5 or 8 (k1 k2 p1 p2 [k3 [k4 k5 k6]])"))),
    }
}

fn rotation(path: &Path, node: &Node, key: &str) -> Result<Matrix3<f64>, CalibError> {
    let values = match node {
        Node::Map(_) => node.get("data").ok_or_else(|| err(path, format!("{key}: no data")))?,
        other => other,
    }
    .numbers()
    .map_err(|m| err(path, format!("{key}: {m}")))?;
    let r = match values.len() {
        9 => Matrix3::from_row_slice(&values),
        3 => rodrigues(&Vector3::new(values[0], values[1], values[2])),
        n => {
            return Err(err(
                path,
                format!("{key}: {n} numbers, want a 3x3 rotation matrix or a rotation vector"),
            ))
        }
    };
    let off = (r * r.transpose() - Matrix3::identity()).abs().max();
    if off > 1e-3 || (r.determinant() - 1.0).abs() > 1e-3 {
        return Err(err(path, format!("{key}: not a rotation matrix (R·Rᵀ ≠ I or det ≠ 1)")));
    }
    Ok(r)
}

fn size_from(path: &Path, node: &Node) -> Result<Option<(usize, usize)>, CalibError> {
    let whole = |key: &str, n: &Node| -> Result<usize, CalibError> {
        let v = n.numbers().map_err(|m| err(path, format!("{key}: {m}")))?;
        match v.as_slice() {
            [x] if *x >= 1.0 && x.fract() == 0.0 => Ok(*x as usize),
            _ => Err(err(path, format!("{key}: not a whole number of pixels"))),
        }
    };
    if let Some((key, n)) = node.get_any(&["imageSize", "image_size", "ImageSize", "size"]) {
        let v = data_of(n).numbers().map_err(|m| err(path, format!("{key}: {m}")))?;
        return match v.as_slice() {
            [w, h] if *w >= 1.0 && *h >= 1.0 && w.fract() == 0.0 && h.fract() == 0.0 => {
                Ok(Some((*w as usize, *h as usize)))
            }
            _ => Err(err(path, format!("{key}: want [width, height]"))),
        };
    }
    match (node.get_any(&["image_width", "width"]), node.get_any(&["image_height", "height"])) {
        (Some((kw, w)), Some((kh, h))) => Ok(Some((whole(kw, w)?, whole(kh, h)?))),
        _ => Ok(None),
    }
}

/// Decides the unit of a translation of length `norm`: OpenCV files carry whatever unit the
/// calibration target was measured in. Below 5 it is taken as metres (a 5 mm baseline is rarer
/// than a 5 m one), otherwise millimetres.
fn unit_for(norm: f64) -> (f64, String) {
    if norm < 5.0 {
        (
            1000.0,
            format!(
                "T (length {norm:.6}) has no unit in the file: taken as metres, baseline {:.3} mm; \
                 give --baseline MM to override",
                norm * 1000.0
            ),
        )
    } else {
        (
            1.0,
            format!(
                "T (length {norm:.3}) has no unit in the file: taken as millimetres; give --baseline MM \
                 to override"
            ),
        )
    }
}

fn read_opencv(path: &Path, node: &Node, format: CalibFormat) -> Result<StereoCalibration, CalibError> {
    if !matches!(node, Node::Map(_)) {
        return Err(err(path, "not a calibration file: want a mapping of keys (K1, D1, K2, D2, R, T)"));
    }
    let find = |names: &[&'static str]| node.get_any(names);
    let k1 = find(&["K1", "M1", "cameraMatrix1", "camera_matrix_1"]);
    let k2 = find(&["K2", "M2", "cameraMatrix2", "camera_matrix_2"]);
    let (Some((k1_key, k1)), Some((k2_key, k2))) = (k1, k2) else {
        let missing = if k1.is_none() { "K1" } else { "K2" };
        return Err(err(
            path,
            format!(
                "no {missing} (camera matrix): want an OpenCV stereo calibration (K1 D1 K2 D2 R T), a ROS \
                 camera_info or a Middlebury calib.txt"
            ),
        ));
    };
    let left_k = camera_matrix(path, k1, k1_key)?;
    let right_k = camera_matrix(path, k2, k2_key)?;
    let d = |names: &[&'static str]| -> Result<Vec<f64>, CalibError> {
        match find(names) {
            Some((key, n)) => distortion(path, n, key),
            None => Err(err(path, format!("no {} (distortion coefficients; give [] for none)", names[0]))),
        }
    };
    // cv::fisheye files say nothing of their model: `distortion_model: fisheye` (or
    // `equidistant`, as ROS names it) marks them.
    let fisheye = match find(&["distortion_model", "model"]) {
        None => false,
        Some((key, n)) => match n.text().unwrap_or("") {
            "fisheye" | "equidistant" => true,
            "plumb_bob" | "rational_polynomial" | "pinhole" | "" => false,
            other => {
                return Err(err(
                    path,
                    format!(
                        "{key}: {other} is not supported (plumb_bob, rational_polynomial and fisheye are)"
                    ),
                ))
            }
        },
    };
    let camera = |k: Matrix3<f64>, names: &[&'static str]| -> Result<Camera, CalibError> {
        let coefficients = d(names)?;
        if !fisheye {
            return Ok(Camera::new(k, coefficients));
        }
        let four: [f64; 4] = coefficients.as_slice().try_into().map_err(|_| {
            err(
                path,
                format!(
                    "{}: {} coefficients, want 4 (k1 k2 k3 k4) for fisheye",
                    names[0],
                    coefficients.len()
                ),
            )
        })?;
        Ok(Camera::equidistant(k, four))
    };
    let left = camera(left_k, &["D1", "distCoeffs1", "dist_coeffs_1"])?;
    let right = camera(right_k, &["D2", "distCoeffs2", "dist_coeffs_2"])?;
    let image_size = size_from(path, node)?;

    let r = find(&["R", "rotation"]);
    let t = find(&["T", "translation"]);
    let extrinsics = match (r, t) {
        (Some((rk, r)), Some((tk, t))) => {
            let r = rotation(path, r, rk)?;
            let t = matrix(path, t, tk, 3, 1)?;
            let t = Vector3::new(t[0], t[1], t[2]);
            if t.norm() == 0.0 {
                return Err(err(path, format!("{tk}: zero translation (no baseline)")));
            }
            Some((r, t))
        }
        (Some(_), None) => return Err(err(path, "R without T (the translation between the cameras)")),
        (None, Some(_)) => return Err(err(path, "T without R (the rotation between the cameras)")),
        (None, None) => None,
    };
    let given = match (find(&["R1"]), find(&["R2"]), find(&["P1"]), find(&["P2"])) {
        (Some((_, r1)), Some((_, r2)), Some((_, p1)), Some((_, p2))) => Some(GivenRectification {
            r1: rotation(path, r1, "R1")?,
            r2: rotation(path, r2, "R2")?,
            p1: Matrix3x4::from_row_slice(&matrix(path, p1, "P1", 3, 4)?),
            p2: Matrix3x4::from_row_slice(&matrix(path, p2, "P2", 3, 4)?),
        }),
        _ => None,
    };
    if extrinsics.is_none() && given.is_none() {
        return Err(err(path, "no R and T (rotation and translation between the cameras)"));
    }
    let norm = match (&extrinsics, &given) {
        (Some((_, t)), _) => t.norm(),
        (None, Some(g)) => (g.p2[(0, 3)] / g.p2[(0, 0)]).abs(),
        (None, None) => unreachable!(),
    };
    let (mm_per_unit, unit_note) = unit_for(norm);
    Ok(StereoCalibration {
        left,
        right,
        extrinsics,
        given,
        image_size,
        mm_per_unit,
        unit_note,
        format,
        paths: vec![path.to_path_buf()],
    })
}

/// One ROS `camera_info` file.
struct RosCamera {
    camera: Camera,
    r: Matrix3<f64>,
    p: Matrix3x4<f64>,
    size: (usize, usize),
}

fn read_ros_camera(path: &Path, node: &Node) -> Result<RosCamera, CalibError> {
    let get = |key: &str| node.get(key).ok_or_else(|| err(path, format!("no {key} (ROS camera_info)")));
    let model = node.get("distortion_model").and_then(Node::text).unwrap_or("plumb_bob");
    let fisheye = match model {
        "plumb_bob" | "rational_polynomial" | "" => false,
        "equidistant" | "fisheye" => true,
        other => {
            return Err(err(
                path,
                format!(
                    "distortion_model: {other} is not supported (plumb_bob, rational_polynomial and \
                     equidistant are)"
                ),
            ))
        }
    };
    let k = camera_matrix(path, get("camera_matrix")?, "camera_matrix")?;
    let camera = if fisheye {
        let v = data_of(get("distortion_coefficients")?)
            .numbers()
            .map_err(|m| err(path, format!("distortion_coefficients: {m}")))?;
        let d: [f64; 4] = v.as_slice().try_into().map_err(|_| {
            err(
                path,
                format!(
                    "distortion_coefficients: {} coefficients, want 4 (k1 k2 k3 k4) for equidistant",
                    v.len()
                ),
            )
        })?;
        Camera::equidistant(k, d)
    } else {
        Camera::new(k, distortion(path, get("distortion_coefficients")?, "distortion_coefficients")?)
    };
    let r = rotation(path, get("rectification_matrix")?, "rectification_matrix")?;
    let p = Matrix3x4::from_row_slice(&matrix(path, get("projection_matrix")?, "projection_matrix", 3, 4)?);
    if !(p[(0, 0)] > 0.0 && p[(1, 1)] > 0.0) {
        return Err(err(path, "projection_matrix: the focal lengths must be > 0"));
    }
    let size = size_from(path, node)?.ok_or_else(|| err(path, "no image_width and image_height"))?;
    Ok(RosCamera { camera, r, p, size })
}

/// The sibling file with `left` ↔ `right` swapped in its name (any case).
fn sibling(path: &Path) -> Option<PathBuf> {
    let name = path.file_name()?.to_str()?;
    for (from, to) in [
        ("left", "right"),
        ("right", "left"),
        ("Left", "Right"),
        ("Right", "Left"),
        ("LEFT", "RIGHT"),
        ("RIGHT", "LEFT"),
    ] {
        if let Some(i) = name.rfind(from) {
            let other = format!("{}{}{}", &name[..i], to, &name[i + from.len()..]);
            return Some(path.with_file_name(other));
        }
    }
    None
}

fn read_ros_pair(path: &Path, node: Node) -> Result<StereoCalibration, CalibError> {
    let first = read_ros_camera(path, &node)?;
    let other_path = sibling(path).filter(|p| p.is_file()).ok_or_else(|| {
        err(
            path,
            "a ROS camera_info describes one camera: the other camera's file was not found (name them \
             left.yaml and right.yaml, or give the folder holding both)",
        )
    })?;
    let other_node = tree::parse(&read_text(&other_path)?).map_err(|m| err(&other_path, m))?;
    if other_node.get("camera_matrix").is_none() {
        return Err(err(&other_path, "no camera_matrix (not a ROS camera_info)"));
    }
    let other = read_ros_camera(&other_path, &other_node)?;
    ros_stereo(vec![(path.to_path_buf(), first), (other_path, other)])
}

fn read_ros_folder(dir: &Path) -> Result<StereoCalibration, CalibError> {
    let entries = std::fs::read_dir(dir).map_err(|e| err(dir, e.to_string()))?;
    let mut cameras = Vec::new();
    let mut names: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    names.sort();
    for path in names {
        let is_yaml = path.extension().and_then(|e| e.to_str()).is_some_and(|e| e == "yaml" || e == "yml");
        if !is_yaml || !path.is_file() {
            continue;
        }
        let Ok(text) = read_text(&path) else { continue };
        let Ok(node) = tree::parse(&text) else { continue };
        if node.get("camera_matrix").is_some() {
            cameras.push((path.clone(), read_ros_camera(&path, &node)?));
        }
    }
    if cameras.len() != 2 {
        return Err(err(
            dir,
            format!(
                "is a directory: want a calibration file, or a folder holding the two ROS camera_info \
                 YAML files (found {})",
                cameras.len()
            ),
        ));
    }
    ros_stereo(cameras)
}

/// Orders two ROS cameras (the right one has `P[0][3] = -fx'·Tx` non-zero) and checks that
/// they describe one rectified rig.
fn ros_stereo(mut cameras: Vec<(PathBuf, RosCamera)>) -> Result<StereoCalibration, CalibError> {
    let tx = |c: &RosCamera| c.p[(0, 3)];
    if tx(&cameras[0].1) != 0.0 && tx(&cameras[1].1) == 0.0 {
        cameras.swap(0, 1);
    }
    let (right_path, right) = cameras.pop().unwrap();
    let (left_path, left) = cameras.pop().unwrap();
    if tx(&right) == 0.0 {
        return Err(err(
            &right_path,
            "projection_matrix: P[0][3] is 0 in both files, so neither is the right camera (its P[0][3] = -fx·baseline)",
        ));
    }
    if tx(&left) != 0.0 {
        return Err(err(
            &left_path,
            "projection_matrix: P[0][3] is not 0 in either file: which is the left camera?",
        ));
    }
    if left.size != right.size {
        return Err(err(
            &right_path,
            format!(
                "image_width/image_height {}x{} differ from {}'s {}x{}",
                right.size.0,
                right.size.1,
                left_path.display(),
                left.size.0,
                left.size.1
            ),
        ));
    }
    if (left.p[(0, 0)] - right.p[(0, 0)]).abs() > 1e-6 * left.p[(0, 0)]
        || (left.p[(1, 2)] - right.p[(1, 2)]).abs() > 1e-3
    {
        return Err(err(
            &right_path,
            format!(
                "projection_matrix: focal length or cy differs from {}'s (not one rectified rig)",
                left_path.display()
            ),
        ));
    }
    if right.p[(1, 3)] != 0.0 {
        return Err(err(&right_path, "projection_matrix: P[1][3] ≠ 0 (a vertical rig is not supported)"));
    }
    let baseline = -tx(&right) / right.p[(0, 0)];
    if baseline <= 0.0 {
        return Err(err(
            &right_path,
            "projection_matrix: P[0][3] > 0 puts this camera left of the other (want -fx·baseline < 0)",
        ));
    }
    Ok(StereoCalibration {
        left: left.camera,
        right: right.camera,
        extrinsics: None,
        given: Some(GivenRectification { r1: left.r, r2: right.r, p1: left.p, p2: right.p }),
        image_size: Some(left.size),
        mm_per_unit: 1000.0,
        unit_note: format!("baseline {baseline:.6} m (ROS projection_matrix, metres)"),
        format: CalibFormat::RosCameraInfo,
        paths: vec![left_path, right_path],
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sibling_names() {
        assert_eq!(sibling(Path::new("/a/left.yaml")), Some(PathBuf::from("/a/right.yaml")));
        assert_eq!(sibling(Path::new("cam_Right_info.yml")), Some(PathBuf::from("cam_Left_info.yml")));
        assert_eq!(sibling(Path::new("cam0.yaml")), None);
    }
}
