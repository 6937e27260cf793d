//! Reading stereo pairs and ground truth; writing PFM disparity maps and EXR depth maps.
//! Every writer writes to a temporary file beside the target and renames it into place, so a
//! reader never sees a half-written output.

use std::path::{Path, PathBuf};

use stereo_disparity::{DisparityMap, GrayImage, Image};

/// I/O errors, each naming the file.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{}: {message}", path.display())]
    Format { path: PathBuf, message: String },
}

/// Loads any 8/16-bit grey, grey+alpha, RGB or RGBA image as the working 16-bit grey image
/// (8-bit values scaled by 257; colour converted with Rec. 601 luma weights).
pub fn load_gray(path: &Path) -> Result<GrayImage, Error> {
    let _ = path;
    todo!()
}

/// Reads a grey PFM (`Pf`) disparity map, top row first; values as stored.
pub fn read_pfm(path: &Path) -> Result<Image<f32>, Error> {
    let _ = path;
    todo!()
}

/// Writes a Middlebury PFM: `Pf`, little-endian (scale -1), rows bottom to top.
pub fn write_pfm(path: &Path, map: &Image<f32>) -> Result<(), Error> {
    let _ = (path, map);
    todo!()
}

/// Reads a ground-truth disparity map: PFM as stored (non-finite and <= 0 are unknown), or an
/// 8/16-bit PNG/PGM with `disparity = value / scale` and 0 unknown. Unknown pixels become NaN.
pub fn read_disparity(path: &Path, scale: f32) -> Result<DisparityMap, Error> {
    let _ = (path, scale);
    todo!()
}

/// Writes a 32-bit float EXR with the given named channels (e.g. `("Z", depth)`), lossless ZIP
/// compression. All channels must have the same size.
pub fn write_exr(path: &Path, channels: &[(&str, &Image<f32>)]) -> Result<(), Error> {
    let _ = (path, channels);
    todo!()
}

/// Writes `bytes` to `path` atomically (temporary file in the same folder, then rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    let _ = (path, bytes);
    todo!()
}
