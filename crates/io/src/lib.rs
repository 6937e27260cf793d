//! Reading stereo pairs and ground truth; writing PFM disparity maps and EXR depth maps.
//! Every writer writes to a temporary file beside the target and renames it into place, so a
//! reader never sees a half-written output.
//!
//! Every error names the file and says what is wrong in one line, e.g.
//! `left.png: not a PNG image (unrecognised format)`.
//!
//! # Example
//!
//! ```
//! use stereo_image::Image;
//! use stereo_io::{read_pfm, write_pfm};
//!
//! let dir = std::env::temp_dir().join(format!("stereo-io-doctest-{}", std::process::id()));
//! std::fs::create_dir_all(&dir)?;
//! let path = dir.join("disp.pfm");
//!
//! let map = Image::from_fn(4, 3, |x, y| if x == 0 { f32::NAN } else { (x + 10 * y) as f32 });
//! write_pfm(&path, &map)?;
//! let back = read_pfm(&path)?;
//! assert_eq!(back.size(), (4, 3));
//! assert_eq!(back.get(2, 1), 12.0);
//! assert!(back.get(0, 2).is_nan());
//!
//! std::fs::remove_dir_all(&dir)?;
//! Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::path::{Path, PathBuf};

use stereo_image::DisparityMap;

mod atomic;
mod calib;
mod exr;
mod pfm;
mod ply;
mod png16;
mod preview;
mod raster;

pub use atomic::{atomic_temp_path, write_atomic};
pub use calib::{parse_calib, read_calib, Calib};
pub use exr::{exr_channel_names, read_exr_channel, write_exr};
pub use pfm::{decode_pfm, encode_pfm, read_pfm, write_pfm};
pub use ply::{encode_ply, read_ply_info, write_ply, PlyInfo, PlyProperty, PlyVertex};
pub use png16::{
    depth_to_mm, disparity_to_kitti, read_png_info, write_png16, write_png8, PngInfo, DEPTH_PNG_MAX_MM,
    KITTI_SCALE,
};
pub use preview::{label as preview_label, render_preview, turbo, write_png_rgb8, ColourScale, Preview};
pub use raster::{
    decode_gray, load_gray, load_gray_and_rgb8_limited, load_gray_limited, load_rgb8, load_rgb8_limited,
    probe_image, ImageHeader, DEFAULT_MAX_PIXELS,
};

/// I/O errors, each naming the file.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The operating system failed to open, read, write or rename the file.
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    /// The file's content (or the requested output) is not acceptable.
    #[error("{}: {message}", path.display())]
    Format { path: PathBuf, message: String },
}

impl Error {
    /// The file the error is about.
    pub fn path(&self) -> &Path {
        match self {
            Error::Io { path, .. } | Error::Format { path, .. } => path,
        }
    }
}

pub(crate) fn format_err(path: &Path, message: impl Into<String>) -> Error {
    Error::Format { path: path.to_path_buf(), message: message.into() }
}

pub(crate) fn io_err(path: &Path) -> impl Fn(std::io::Error) -> Error + '_ {
    move |source| Error::Io { path: path.to_path_buf(), source }
}

/// Reads a ground-truth disparity map: PFM as stored (non-finite and <= 0 are unknown), or an
/// 8/16-bit PNG/PGM/TIFF with `disparity = value / scale` and 0 unknown. Unknown pixels become NaN.
///
/// The format is chosen by extension (`.pfm`; `.png`, `.pgm`, `.ppm`, `.tif`, `.tiff`); colour images are accepted
/// only when all channels are equal. `scale` must be finite and > 0 (it is not applied to PFM).
pub fn read_disparity(path: &Path, scale: f32) -> Result<DisparityMap, Error> {
    if !(scale.is_finite() && scale > 0.0) {
        return Err(format_err(path, format!("disparity scale must be finite and > 0 (got {scale})")));
    }
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    match ext.as_deref() {
        Some("pfm") => {
            let mut map = read_pfm(path)?;
            for v in map.as_mut_slice() {
                if !(v.is_finite() && *v > 0.0) {
                    *v = f32::NAN;
                }
            }
            Ok(map)
        }
        Some("png" | "pgm" | "ppm" | "tif" | "tiff") => {
            let raw = raster::load_disparity_samples(path)?;
            let data =
                raw.as_slice().iter().map(|&v| if v == 0 { f32::NAN } else { v as f32 / scale }).collect();
            let (w, h) = raw.size();
            DisparityMap::from_vec(w, h, data).map_err(|e| format_err(path, e.to_string()))
        }
        _ => Err(format_err(path, "unknown disparity format (want a .pfm, .png, .pgm or .tif file)")),
    }
}
