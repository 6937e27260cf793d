//! Files: PFM disparity maps, OpenEXR depth maps, images and PLY point clouds (`stereo-io`).

use numpy::ndarray::Array3;
use numpy::prelude::*;
use numpy::{PyArray2, PyArray3, PyReadonlyArray2, PyUntypedArray};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use stereo_image::Image;

use crate::errors::{self, value_error};
use crate::input::{path_arg, type_name};
use crate::matcher::to_numpy;

/// A float32 (H, W) array as an image (copied).
fn map_arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<Image<f32>> {
    let Ok(array) = obj.cast::<PyUntypedArray>() else {
        return Err(pyo3::exceptions::PyTypeError::new_err(format!(
            "{what} must be a numpy array (H, W) of float32, not {}",
            type_name(obj)
        )));
    };
    if array.ndim() != 2 {
        return Err(value_error(format!("{what} has shape {:?}: want (H, W)", array.shape())));
    }
    let Ok(a) = obj.extract::<PyReadonlyArray2<'_, f32>>() else {
        let text = array.dtype().str().map(|s| s.to_string()).unwrap_or_default();
        return Err(value_error(format!("{what} has dtype {text}: want float32 (use .astype(np.float32))")));
    };
    let (h, w) = (array.shape()[0], array.shape()[1]);
    if w == 0 || h == 0 {
        return Err(value_error(format!("{what} is {w}x{h}")));
    }
    Image::from_vec(w, h, a.as_array().iter().copied().collect()).map_err(|e| value_error(e.to_string()))
}

/// Reads a PFM file (Middlebury's disparity maps) as float32 (H, W), top row first.
#[pyfunction]
pub fn read_pfm<'py>(py: Python<'py>, path: &Bound<'py, PyAny>) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let path = path_arg(path, "path")?;
    let map = py.detach(|| stereo_io::read_pfm(&path)).map_err(errors::io)?;
    Ok(to_numpy(py, map))
}

/// Writes a float32 (H, W) map as PFM (as ``--disparity``; NaN stays NaN), atomically.
#[pyfunction]
pub fn write_pfm(path: &Bound<'_, PyAny>, map: &Bound<'_, PyAny>) -> PyResult<()> {
    let path = path_arg(path, "path")?;
    let map = map_arg(map, "map")?;
    stereo_io::write_pfm(&path, &map).map_err(errors::io)
}

/// Writes a 32-bit float OpenEXR file, atomically: ``depth`` as channel ``Z`` (metres, as the
/// command line's depth map) and every ``channels`` entry (name -> float32 (H, W)) beside it,
/// e.g. ``channels={"confidence": res.confidence}``. All maps must have the same size.
#[pyfunction]
#[pyo3(signature = (path, depth = None, *, channels = None))]
pub fn write_exr(
    path: &Bound<'_, PyAny>,
    depth: Option<&Bound<'_, PyAny>>,
    channels: Option<&Bound<'_, PyDict>>,
) -> PyResult<()> {
    let path = path_arg(path, "path")?;
    let mut maps: Vec<(String, Image<f32>)> = Vec::new();
    if let Some(depth) = depth {
        maps.push(("Z".into(), map_arg(depth, "depth")?));
    }
    if let Some(channels) = channels {
        for (name, map) in channels.iter() {
            let name: String = name.extract().map_err(|_| value_error("channel names must be strings"))?;
            if name.is_empty() || maps.iter().any(|(n, _)| *n == name) {
                return Err(value_error(format!("channel name {name:?} is empty or repeated")));
            }
            let map = map_arg(&map, &format!("channel {name:?}"))?;
            maps.push((name, map));
        }
    }
    let Some((_, first)) = maps.first() else {
        return Err(value_error("nothing to write: give depth and/or channels"));
    };
    let size = first.size();
    if let Some((name, map)) = maps.iter().find(|(_, m)| m.size() != size) {
        return Err(value_error(format!(
            "channel {name:?} is {}x{}, the others {}x{}",
            map.width(),
            map.height(),
            size.0,
            size.1
        )));
    }
    let refs: Vec<(&str, &Image<f32>)> = maps.iter().map(|(n, m)| (n.as_str(), m)).collect();
    stereo_io::write_exr(&path, &refs).map_err(errors::io)
}

/// Reads an image file (PNG, PNM, TIFF or JPEG) as the command line reads it.
///
/// ``mode="gray"``: uint16 (H, W), the matchers' working grey (8-bit values times 257, colour
/// as Rec. 601 luma): exactly what ``stereo-depth`` matches. ``mode="rgb"``: uint8 (H, W, 3)
/// (16-bit samples keep their top 8 bits), e.g. to colour a point cloud.
#[pyfunction]
#[pyo3(signature = (path, mode = "gray"))]
pub fn read_image<'py>(py: Python<'py>, path: &Bound<'py, PyAny>, mode: &str) -> PyResult<Bound<'py, PyAny>> {
    let path = path_arg(path, "path")?;
    match mode {
        "gray" | "grey" => {
            let image = py.detach(|| stereo_io::load_gray(&path)).map_err(errors::io)?;
            Ok(to_numpy(py, image).into_any())
        }
        "rgb" => {
            let image = py.detach(|| stereo_io::load_rgb8(&path)).map_err(errors::io)?;
            let (w, h) = image.size();
            let flat: Vec<u8> = image.into_vec().into_iter().flatten().collect();
            let array = Array3::from_shape_vec((h, w, 3), flat).expect("h x w x 3");
            Ok(PyArray3::from_owned_array(py, array).into_any())
        }
        _ => Err(value_error(format!("invalid mode {mode:?} (want \"gray\" or \"rgb\")"))),
    }
}

/// Writes points as a binary little-endian PLY (``float x y z``, ``uchar red green blue``, the
/// command line's ``--points`` format), atomically. ``points``: float32 (N, 3); ``colors``:
/// uint8 (N, 3), or None for white.
#[pyfunction]
#[pyo3(signature = (path, points, colors = None))]
pub fn write_ply(
    path: &Bound<'_, PyAny>,
    points: PyReadonlyArray2<'_, f32>,
    colors: Option<PyReadonlyArray2<'_, u8>>,
) -> PyResult<()> {
    let path = path_arg(path, "path")?;
    let p = points.as_array();
    if p.ncols() != 3 {
        return Err(value_error(format!("points has shape {:?}: want (N, 3)", p.shape())));
    }
    let c = colors.as_ref().map(|c| c.as_array());
    if let Some(c) = &c {
        if c.shape() != [p.nrows(), 3] {
            return Err(value_error(format!("colors has shape {:?}: want ({}, 3)", c.shape(), p.nrows())));
        }
    }
    let vertices: Vec<stereo_io::PlyVertex> = (0..p.nrows())
        .map(|i| stereo_io::PlyVertex {
            position: [p[[i, 0]], p[[i, 1]], p[[i, 2]]],
            colour: c.as_ref().map_or([255; 3], |c| [c[[i, 0]], c[[i, 1]], c[[i, 2]]]),
        })
        .collect();
    stereo_io::write_ply(&path, &vertices, &["written by stereo_depth (Python)"]).map_err(errors::io)
}
