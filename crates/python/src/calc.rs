//! `stereo_depth.calc`: the rig design calculator (`stereo-depth calc --json`), as a dict.

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList};
use serde_json::Value;
use stereo_triangulation::design::{Design, DesignError, DesignInput, Param, SensorWidth, TableSpec};

use crate::errors::value_error;

/// The keyword a design parameter is given as.
fn keyword(param: Param) -> &'static str {
    match param {
        Param::Baseline => "baseline_mm",
        Param::Focal => "focal_mm",
        Param::Pixel => "pixel_um",
        Param::Doffs => "doffs",
        Param::SubpixelStep => "subpixel",
        Param::SensorWidth => "sensor_width_mm",
        Param::WidthPx => "width_px",
        Param::MaxDisparity => "max_disparity",
        Param::Disparity => "disparity_px",
        Param::Distance => "distance_m",
        Param::TableMin => "table_min",
        Param::TableMax => "table_max",
        Param::TableStep => "table_step",
    }
}

fn design_error(err: DesignError) -> PyErr {
    value_error(format!(
        "invalid {} {} {} (must be {})",
        keyword(err.param),
        err.value,
        err.unit,
        err.expected
    ))
}

fn to_py<'py>(py: Python<'py>, value: &Value) -> PyResult<Bound<'py, PyAny>> {
    Ok(match value {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_pyobject(py)?.to_owned().into_any(),
        Value::Number(n) => match (n.as_i64(), n.as_f64()) {
            (Some(i), _) => i.into_pyobject(py)?.into_any(),
            (None, Some(f)) => f.into_pyobject(py)?.into_any(),
            _ => py.None().into_bound(py),
        },
        Value::String(s) => s.into_pyobject(py)?.into_any(),
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(to_py(py, item)?)?;
            }
            list.into_any()
        }
        Value::Object(map) => {
            let dict = PyDict::new(py);
            for (k, v) in map {
                dict.set_item(k, to_py(py, v)?)?;
            }
            dict.into_any()
        }
    })
}

/// What a rig can measure, before capturing anything: ``stereo-depth calc --json`` as a dict.
///
/// With ``disparity_px`` the answer's ``distance_m``, ``disparity_mm`` and
/// ``depth_resolution_mm`` are at the top level (and under ``"disparity"``); with
/// ``distance_m`` its ``disparity_px``, ``disparity_mm``, ``depth_resolution_mm`` are under
/// ``"distance"`` (and at the top level when no disparity is asked). Also ``focal_px``,
/// ``horizontal_fov_deg`` (with ``sensor_width_mm`` or ``width_px``), ``working_range`` and,
/// with ``table=True`` (or a table_* bound), ``table``: a list of rows.
///
/// >>> sd.calc(baseline_mm=200, focal_mm=6, pixel_um=2.5, disparity_px=150)["distance_m"]
/// 3.2
#[pyfunction]
#[pyo3(signature = (
    *, baseline_mm, focal_mm, pixel_um, doffs = 0.0, subpixel = 1.0, sensor_width_mm = None,
    width_px = None, max_disparity = None, disparity_px = None, distance_m = None, table = false,
    table_min = None, table_max = None, table_step = None
))]
#[allow(clippy::too_many_arguments)]
pub fn calc<'py>(
    py: Python<'py>,
    baseline_mm: f64,
    focal_mm: f64,
    pixel_um: f64,
    doffs: f64,
    subpixel: f64,
    sensor_width_mm: Option<f64>,
    width_px: Option<f64>,
    max_disparity: Option<f64>,
    disparity_px: Option<f64>,
    distance_m: Option<f64>,
    table: bool,
    table_min: Option<f64>,
    table_max: Option<f64>,
    table_step: Option<f64>,
) -> PyResult<Bound<'py, PyDict>> {
    let sensor = match (sensor_width_mm, width_px) {
        (Some(_), Some(_)) => return Err(value_error("give sensor_width_mm or width_px, not both")),
        (Some(mm), None) => Some(SensorWidth::Mm(mm)),
        (None, Some(px)) => Some(SensorWidth::Px(px)),
        (None, None) => None,
    };
    let table = (table || table_min.is_some() || table_max.is_some() || table_step.is_some())
        .then_some(TableSpec { min_px: table_min, max_px: table_max, step_px: table_step });
    let input = DesignInput {
        doffs_px: doffs,
        subpixel_step_px: subpixel,
        sensor,
        max_disparity_px: max_disparity,
        disparity_px,
        distance_m,
        table,
        ..DesignInput::new(baseline_mm, focal_mm, pixel_um)
    };
    let design = Design::new(&input).map_err(design_error)?;
    let json = serde_json::to_value(&design).map_err(|e| value_error(e.to_string()))?;
    let dict = to_py(py, &json)?.cast_into::<PyDict>()?;
    // The answer to the question asked, at the top level.
    for key in ["distance", "disparity"] {
        if let Some(Value::Object(point)) = json.get(key) {
            for (k, v) in point {
                dict.set_item(k, to_py(py, v)?)?;
            }
        }
    }
    Ok(dict)
}
