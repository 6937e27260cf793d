//! Library errors as Python exceptions, each with the library's one-line message:
//! `ValueError` for shapes, dtypes, sizes and parameters, `OSError` (`FileNotFoundError`,
//! `PermissionError`) for files, `MemoryError` for a pair over the memory limit.

use std::panic::{catch_unwind, AssertUnwindSafe};

use pyo3::exceptions::{
    PyFileNotFoundError, PyMemoryError, PyOSError, PyPermissionError, PyRuntimeError, PyValueError,
};
use pyo3::PyErr;

pub fn value_error(message: impl Into<String>) -> PyErr {
    PyValueError::new_err(message.into())
}

pub fn pipeline(err: stereo_pipeline::Error) -> PyErr {
    match err {
        stereo_pipeline::Error::TooLarge { .. } => PyMemoryError::new_err(err.to_string()),
        _ => PyValueError::new_err(err.to_string()),
    }
}

pub fn rig(err: stereo_triangulation::Error) -> PyErr {
    PyValueError::new_err(err.to_string())
}

pub fn io(err: stereo_io::Error) -> PyErr {
    let message = err.to_string();
    match &err {
        stereo_io::Error::Io { source, .. } => match source.kind() {
            std::io::ErrorKind::NotFound => PyFileNotFoundError::new_err(message),
            std::io::ErrorKind::PermissionDenied => PyPermissionError::new_err(message),
            _ => PyOSError::new_err(message),
        },
        // A file that is not what it should be (a broken PNG, a PFM with a bad header): like
        // Pillow's UnidentifiedImageError, an OSError.
        stereo_io::Error::Format { .. } => PyOSError::new_err(message),
    }
}

/// Runs `f`, turning a panic (a bug: the library reports bad input as errors) into a
/// `RuntimeError` instead of unwinding into Python.
pub fn no_panic<T>(f: impl FnOnce() -> Result<T, PyErr>) -> Result<T, PyErr> {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(result) => result,
        Err(payload) => {
            let what = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Err(PyRuntimeError::new_err(format!("stereo_depth internal error (please report): {what}")))
        }
    }
}
