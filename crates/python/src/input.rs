//! Images from Python: numpy arrays `(H, W)` grey or `(H, W, 3|4)` RGB/RGBA, `uint8` or
//! `uint16`, read in place whenever their rows are evenly spaced with the pixels of a row next to
//! each other (C-contiguous arrays, row crops `a[y0:y1]`, column crops `a[:, x0:x1]`, padded
//! rows); other layouts (reversed or column-strided axes, Fortran order, unaligned buffers) are
//! copied once by `numpy.ascontiguousarray`. Or a path (`str` / `os.PathLike`) to a PNG, PNM,
//! TIFF or JPEG file, decoded as the command line decodes it.

use std::path::{Path, PathBuf};

use numpy::prelude::*;
use numpy::{PyReadonlyArrayDyn, PyUntypedArray};
use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use stereo_image::{GrayImage, ImageRef};

use crate::errors::{self, value_error};

enum Source<'py> {
    U8(PyReadonlyArrayDyn<'py, u8>),
    U16(PyReadonlyArrayDyn<'py, u16>),
    Path(PathBuf),
}

/// One input image, borrowed from Python (or a path), checked.
pub struct Input<'py> {
    source: Source<'py>,
    pub width: usize,
    pub height: usize,
    /// 1 (grey), 3 (RGB) or 4 (RGBA).
    channels: usize,
    /// Row stride in samples (arrays).
    stride: usize,
    /// The array was copied to make it readable in place.
    pub copied: bool,
}

/// What the matcher reads: a view of the caller's buffer, or a file to decode.
pub enum View<'a> {
    Gray8(ImageRef<'a, u8>),
    Gray16(ImageRef<'a, u16>),
    Rgb8(ImageRef<'a, [u8; 3]>),
    Rgba8(ImageRef<'a, [u8; 4]>),
    Rgb16(ImageRef<'a, [u16; 3]>),
    Rgba16(ImageRef<'a, [u16; 4]>),
    Path(&'a Path),
}

impl View<'_> {
    /// The matchers' working 16-bit grey image: the same conversion the command line applies to
    /// a decoded file (`stereo_image::ToGray16`), so an array decoded from a PNG and the PNG
    /// itself give the same result.
    pub fn to_gray(&self, max_pixels: u64) -> PyResult<GrayImage> {
        Ok(match self {
            View::Gray8(v) => v.to_gray16(),
            View::Gray16(v) => v.to_gray16(),
            View::Rgb8(v) => v.to_gray16(),
            View::Rgba8(v) => v.to_gray16(),
            View::Rgb16(v) => v.to_gray16(),
            View::Rgba16(v) => v.to_gray16(),
            View::Path(path) => stereo_io::load_gray_limited(path, max_pixels).map_err(errors::io)?,
        })
    }
}

fn is_path(obj: &Bound<'_, PyAny>) -> bool {
    obj.is_instance_of::<pyo3::types::PyString>() || obj.hasattr("__fspath__").unwrap_or(false)
}

/// A path argument (`str` or `os.PathLike`).
pub fn path_arg(obj: &Bound<'_, PyAny>, what: &str) -> PyResult<PathBuf> {
    if !is_path(obj) {
        return Err(PyTypeError::new_err(format!(
            "{what} must be a path (str or os.PathLike), not {}",
            type_name(obj)
        )));
    }
    obj.extract::<PathBuf>()
}

pub fn type_name(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type().name().map(|n| n.to_string()).unwrap_or_else(|_| "?".into())
}

impl<'py> Input<'py> {
    /// Checks `obj` (named `name` in messages): a path is probed (its header, against
    /// `max_pixels`), an array's shape and dtype are checked.
    pub fn extract(obj: &Bound<'py, PyAny>, name: &str, max_pixels: u64) -> PyResult<Self> {
        if is_path(obj) {
            let path = obj.extract::<PathBuf>()?;
            let header = stereo_io::probe_image(&path).map_err(errors::io)?;
            let (width, height) = (header.width, header.height);
            if width == 0 || height == 0 {
                return Err(value_error(format!("{}: image is {width}x{height}", path.display())));
            }
            if header.pixels() > max_pixels {
                return Err(value_error(format!(
                    "{}: {width}x{height} image is over the max_pixels limit of {max_pixels}",
                    path.display()
                )));
            }
            return Ok(Input {
                source: Source::Path(path),
                width,
                height,
                channels: 1,
                stride: width,
                copied: false,
            });
        }
        let Ok(array) = obj.cast::<PyUntypedArray>() else {
            return Err(PyTypeError::new_err(format!(
                "{name} must be a numpy array (H, W) or (H, W, 3|4) of uint8 or uint16, or a path; got {}",
                type_name(obj)
            )));
        };
        let shape = array.shape().to_vec();
        let channels = match shape.len() {
            2 => 1,
            3 if matches!(shape[2], 3 | 4) => shape[2],
            _ => {
                return Err(value_error(format!(
                    "{name} has shape {shape:?}: want (H, W) grey or (H, W, 3) / (H, W, 4) RGB(A)"
                )))
            }
        };
        let (height, width) = (shape[0], shape[1]);
        if width == 0 || height == 0 {
            return Err(value_error(format!("{name} image is {width}x{height}")));
        }
        if height as u64 * width as u64 > max_pixels {
            return Err(value_error(format!(
                "{name}: {width}x{height} image is over the max_pixels limit of {max_pixels}"
            )));
        }
        let dtype = array.dtype();
        let py = obj.py();
        let u8_type = dtype.is_equiv_to(&numpy::dtype::<u8>(py));
        let u16_type = dtype.is_equiv_to(&numpy::dtype::<u16>(py));
        if !u8_type && !u16_type {
            let text = dtype.str().map(|s| s.to_string()).unwrap_or_else(|_| "?".into());
            return Err(value_error(format!(
                "{name} has dtype {text}: want uint8 or uint16 (native byte order), e.g. \
                 np.clip(img * 255, 0, 255).astype(np.uint8) for floats in [0, 1]"
            )));
        }
        let itemsize = if u8_type { 1 } else { 2 };
        let pixel = itemsize * channels as isize;
        let strides = array.strides();
        let row = strides[0];
        let in_place = array.is_aligned()
            && row > 0
            && row % pixel == 0
            && row as usize >= width * pixel as usize
            && strides[1] == pixel
            && (channels == 1 || strides[2] == itemsize);
        if !in_place {
            let numpy = py.import("numpy")?;
            let copy = numpy.call_method1("ascontiguousarray", (obj,))?;
            let mut input = Input::extract(&copy, name, max_pixels)?;
            input.copied = true;
            return Ok(input);
        }
        let stride = row as usize / itemsize as usize;
        let source = if u8_type { Source::U8(obj.extract()?) } else { Source::U16(obj.extract()?) };
        Ok(Input { source, width, height, channels, stride, copied: false })
    }

    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The samples from the first pixel to the last, as a slice.
    fn samples<T: numpy::Element>(&self, array: &PyReadonlyArrayDyn<'py, T>) -> &[T] {
        let len = (self.height - 1) * self.stride + self.width * self.channels;
        // SAFETY: the array is borrowed read-only for `self`'s lifetime; its rows are `stride`
        // samples apart with the pixels of a row contiguous (checked in `extract`), so these
        // `len` samples lie inside its buffer; it is aligned (checked).
        unsafe { std::slice::from_raw_parts(array.data() as *const T, len) }
    }

    /// The view the matcher reads.
    pub fn view(&self) -> PyResult<View<'_>> {
        let (w, h, stride) = (self.width, self.height, self.stride);
        let err = |e: stereo_image::Error| value_error(e.to_string());
        Ok(match &self.source {
            Source::Path(path) => View::Path(path),
            Source::U8(a) => {
                let s = self.samples(a);
                match self.channels {
                    1 => View::Gray8(ImageRef::with_stride(s, w, h, stride).map_err(err)?),
                    3 => View::Rgb8(ImageRef::from_interleaved(s, w, h, stride).map_err(err)?),
                    _ => View::Rgba8(ImageRef::from_interleaved(s, w, h, stride).map_err(err)?),
                }
            }
            Source::U16(a) => {
                let s = self.samples(a);
                match self.channels {
                    1 => View::Gray16(ImageRef::with_stride(s, w, h, stride).map_err(err)?),
                    3 => View::Rgb16(ImageRef::from_interleaved(s, w, h, stride).map_err(err)?),
                    _ => View::Rgba16(ImageRef::from_interleaved(s, w, h, stride).map_err(err)?),
                }
            }
        })
    }
}
