//! `stereo_depth.Rig`: triangulation (`stereo-triangulation`) of numpy disparity maps.

use numpy::ndarray::Array2;
use numpy::prelude::*;
use numpy::{PyArray2, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArray};
use pyo3::prelude::*;
use pyo3::types::PyTuple;
use stereo_image::DisparityMap;
use stereo_pipeline::DepthLimits;

use crate::errors::{self, value_error};
use crate::input::{path_arg, type_name};
use crate::matcher::to_numpy;

/// A rectified stereo rig: the baseline and the focal length in pixels.
///
/// ``Rig(baseline_mm=80, focal_mm=12, pixel_um=4)`` (datasheet values), or
/// ``Rig(baseline_mm=80, focal_px=3000)``, or ``Rig.from_calib("calib.txt")`` (Middlebury).
/// ``doffs`` [0] is the disparity offset between the principal points (px), added to every
/// disparity; ``cx``, ``cy`` [None: the image centre] the principal point (px).
///
/// Depth ``Z = baseline * focal_px / ((d + doffs) * 1000)`` metres; points are in the left
/// camera's frame, metres, x right, y down, z forward.
#[pyclass(frozen, module = "stereo_depth")]
pub struct Rig {
    rig: stereo_triangulation::Rig,
    /// From a calib.txt: (width, height) and ndisp.
    calib_size: Option<(usize, usize)>,
    ndisp: Option<usize>,
}

/// A disparity map from Python: float32 or float64 (H, W), copied into the library's map.
fn disparity_arg(obj: &Bound<'_, PyAny>) -> PyResult<DisparityMap> {
    let Ok(array) = obj.cast::<PyUntypedArray>() else {
        return Err(pyo3::exceptions::PyTypeError::new_err(format!(
            "disparity must be a numpy array (H, W) of float32, not {}",
            type_name(obj)
        )));
    };
    if array.ndim() != 2 {
        return Err(value_error(format!("disparity has shape {:?}: want (H, W)", array.shape())));
    }
    let (h, w) = (array.shape()[0], array.shape()[1]);
    let data: Vec<f32> = if let Ok(a) = obj.extract::<PyReadonlyArray2<'_, f32>>() {
        a.as_array().iter().copied().collect()
    } else if let Ok(a) = obj.extract::<PyReadonlyArray2<'_, f64>>() {
        a.as_array().iter().map(|&v| v as f32).collect()
    } else {
        let text = array.dtype().str().map(|s| s.to_string()).unwrap_or_default();
        return Err(value_error(format!("disparity has dtype {text}: want float32 (or float64)")));
    };
    DisparityMap::from_vec(w, h, data).map_err(|e| value_error(e.to_string()))
}

impl Rig {
    fn limited(
        &self,
        disparity: &mut DisparityMap,
        min_depth: Option<f64>,
        max_depth: Option<f64>,
    ) -> PyResult<()> {
        if let Some(limits) = DepthLimits::new(min_depth, max_depth).map_err(errors::pipeline)? {
            limits.apply(disparity, &self.rig);
        }
        Ok(())
    }
}

#[pymethods]
impl Rig {
    #[new]
    #[pyo3(signature = (baseline_mm, *, focal_mm = None, pixel_um = None, focal_px = None, doffs = 0.0, cx = None, cy = None))]
    fn new(
        baseline_mm: f64,
        focal_mm: Option<f64>,
        pixel_um: Option<f64>,
        focal_px: Option<f64>,
        doffs: f64,
        cx: Option<f64>,
        cy: Option<f64>,
    ) -> PyResult<Self> {
        let rig = match (focal_mm, pixel_um, focal_px) {
            (Some(f), Some(p), None) => stereo_triangulation::Rig::from_datasheet(baseline_mm, f, p),
            (None, _, Some(px)) => stereo_triangulation::Rig::from_focal_px(baseline_mm, px),
            (Some(_), _, Some(_)) => {
                return Err(value_error(
                    "conflicting focal lengths: give focal_mm with pixel_um, or focal_px",
                ))
            }
            (Some(_), None, None) => return Err(value_error("focal_mm needs pixel_um (or give focal_px)")),
            (None, _, None) => {
                return Err(value_error("incomplete rig: give focal_mm and pixel_um, or focal_px"))
            }
        }
        .map_err(errors::rig)?;
        let mut rig = rig.with_doffs(doffs).map_err(errors::rig)?;
        match (cx, cy) {
            (Some(cx), Some(cy)) => rig = rig.with_principal_point(cx, cy).map_err(errors::rig)?,
            (None, None) => {}
            _ => return Err(value_error("cx and cy must be given together")),
        }
        Ok(Rig { rig, calib_size: None, ndisp: None })
    }

    /// The rig of a Middlebury ``calib.txt`` (cam0's focal length and principal point, doffs,
    /// baseline); ``baseline_mm`` overrides or supplies the baseline. ``calib_size`` and
    /// ``ndisp`` keep the file's width/height and ndisp.
    #[staticmethod]
    #[pyo3(signature = (path, *, baseline_mm = None))]
    fn from_calib(path: &Bound<'_, PyAny>, baseline_mm: Option<f64>) -> PyResult<Self> {
        let path = path_arg(path, "path")?;
        let calib = stereo_io::read_calib(&path).map_err(errors::io)?;
        let Some(baseline) = baseline_mm.or(calib.baseline_mm) else {
            return Err(value_error(format!("{}: no baseline; give baseline_mm", path.display())));
        };
        let rig = stereo_triangulation::Rig::from_focal_px(baseline, calib.focal_px)
            .and_then(|r| r.with_doffs(calib.doffs.unwrap_or(0.0)))
            .and_then(|r| r.with_principal_point(calib.cx, calib.cy))
            .map_err(|e| value_error(format!("{}: {e}", path.display())))?;
        let calib_size = calib.width.zip(calib.height);
        Ok(Rig { rig, calib_size, ndisp: calib.ndisp })
    }

    #[getter]
    fn baseline_mm(&self) -> f64 {
        self.rig.baseline_mm
    }
    #[getter]
    fn focal_px(&self) -> f64 {
        self.rig.focal_px
    }
    #[getter]
    fn doffs(&self) -> f64 {
        self.rig.doffs
    }
    /// (cx, cy) in px, or None for the image centre.
    #[getter]
    fn principal_point(&self) -> Option<(f64, f64)> {
        self.rig.principal_point
    }
    /// (width, height) the calib.txt was made for, or None.
    #[getter]
    fn calib_size(&self) -> Option<(usize, usize)> {
        self.calib_size
    }
    /// The calib.txt's ndisp (use as ``max_disparity``), or None.
    #[getter]
    fn ndisp(&self) -> Option<usize> {
        self.ndisp
    }

    /// Depth in metres of one disparity (px), or None where it has none (``d + doffs <= 0``).
    fn depth_at(&self, disparity_px: f64) -> Option<f64> {
        self.rig.depth(disparity_px)
    }

    /// The disparity (px) seen at ``distance_m`` metres.
    fn disparity_at(&self, distance_m: f64) -> PyResult<f64> {
        if !(distance_m.is_finite() && distance_m > 0.0) {
            return Err(value_error(format!("distance_m must be a finite number > 0, got {distance_m}")));
        }
        Ok(stereo_triangulation::design::disparity_at(&self.rig, distance_m))
    }

    /// The depth map: float32 (H, W) metres, NaN where the disparity is invalid or has no
    /// depth. ``min_depth`` / ``max_depth`` (metres) invalidate depths outside them, as the
    /// command line's ``--min-depth`` / ``--max-depth``.
    #[pyo3(signature = (disparity, *, min_depth = None, max_depth = None))]
    fn depth<'py>(
        &self,
        py: Python<'py>,
        disparity: &Bound<'py, PyAny>,
        min_depth: Option<f64>,
        max_depth: Option<f64>,
    ) -> PyResult<Bound<'py, PyArray2<f32>>> {
        let mut disparity = disparity_arg(disparity)?;
        self.limited(&mut disparity, min_depth, max_depth)?;
        let depth = py.detach(|| stereo_triangulation::depth_map(&disparity, &self.rig));
        Ok(to_numpy(py, depth))
    }

    /// The 3-D points of the valid pixels, row by row: float32 (N, 3) metres, x right, y down,
    /// z forward (the left camera's frame). ``step`` keeps every step-th pixel in both
    /// directions. With ``colors`` (an (H, W, 3) uint8 image, e.g. the left view) returns
    /// ``(points, colors)`` with the (N, 3) uint8 colour of each point.
    #[pyo3(signature = (disparity, *, step = 1, colors = None, min_depth = None, max_depth = None))]
    fn points<'py>(
        &self,
        py: Python<'py>,
        disparity: &Bound<'py, PyAny>,
        step: usize,
        colors: Option<PyReadonlyArray3<'py, u8>>,
        min_depth: Option<f64>,
        max_depth: Option<f64>,
    ) -> PyResult<Bound<'py, PyAny>> {
        if step == 0 {
            return Err(value_error("step must be at least 1"));
        }
        let mut disparity = disparity_arg(disparity)?;
        self.limited(&mut disparity, min_depth, max_depth)?;
        let points = py.detach(|| stereo_triangulation::points(&disparity, &self.rig, step));
        let mut xyz = Vec::with_capacity(points.len() * 3);
        for p in &points {
            xyz.extend([p.position.x as f32, p.position.y as f32, p.position.z as f32]);
        }
        let xyz =
            PyArray2::from_owned_array(py, Array2::from_shape_vec((points.len(), 3), xyz).expect("N x 3"));
        let Some(colors) = colors else { return Ok(xyz.into_any()) };
        let c = colors.as_array();
        let (w, h) = disparity.size();
        if c.shape() != [h, w, 3] {
            return Err(value_error(format!(
                "colors has shape {:?}: want (H, W, 3) = ({h}, {w}, 3) like the disparity",
                c.shape()
            )));
        }
        let mut rgb = Vec::with_capacity(points.len() * 3);
        for p in &points {
            rgb.extend([c[[p.y, p.x, 0]], c[[p.y, p.x, 1]], c[[p.y, p.x, 2]]]);
        }
        let rgb =
            PyArray2::from_owned_array(py, Array2::from_shape_vec((points.len(), 3), rgb).expect("N x 3"));
        Ok(PyTuple::new(py, [xyz.into_any(), rgb.into_any()])?.into_any())
    }

    fn __repr__(&self) -> String {
        let mut s = format!("Rig(baseline_mm={}, focal_px={}", self.rig.baseline_mm, self.rig.focal_px);
        if self.rig.doffs != 0.0 {
            s += &format!(", doffs={}", self.rig.doffs);
        }
        if let Some((cx, cy)) = self.rig.principal_point {
            s += &format!(", cx={cx}, cy={cy}");
        }
        s + ")"
    }
}
