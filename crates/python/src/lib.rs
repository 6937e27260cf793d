//! The `stereo_depth` Python module: numpy arrays (or image paths) in, disparity, depth and
//! points out, through the same pipeline the command line runs (`stereo-pipeline`), so the same
//! options give the same disparity, bit for bit.
//!
//! Built with maturin (`pip install ./crates/python`); see `docs/python.md`. Errors are Python
//! exceptions carrying the library's one-line message (see `errors.rs`); the matching itself runs
//! with the GIL released.

use pyo3::prelude::*;

mod calc;
mod errors;
mod files;
mod input;
mod matcher;
mod rig;

/// Metric depth from rectified stereo pairs: census SGM and block matching.
///
/// >>> import stereo_depth as sd
/// >>> m = sd.Matcher(max_disparity=64)
/// >>> disp = m.compute(left, right)          # float32 (H, W), NaN = invalid
/// >>> rig = sd.Rig(baseline_mm=80, focal_mm=12, pixel_um=4)
/// >>> depth = rig.depth(disp)                # float32 (H, W), metres
#[pymodule]
#[pyo3(name = "stereo_depth")]
fn stereo_depth(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // A Python process typically matches frame after frame: the matcher's strip buffers are
    // kept between calls (docs/python.md).
    stereo_disparity::keep_strip_buffers(true);
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<matcher::Matcher>()?;
    m.add_class::<matcher::DetailedResult>()?;
    m.add_class::<rig::Rig>()?;
    m.add_function(wrap_pyfunction!(calc::calc, m)?)?;
    m.add_function(wrap_pyfunction!(files::read_pfm, m)?)?;
    m.add_function(wrap_pyfunction!(files::write_pfm, m)?)?;
    m.add_function(wrap_pyfunction!(files::write_exr, m)?)?;
    m.add_function(wrap_pyfunction!(files::read_image, m)?)?;
    m.add_function(wrap_pyfunction!(files::write_ply, m)?)?;
    Ok(())
}
