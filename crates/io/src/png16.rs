//! 16-bit grey PNG maps: depth in millimetres and KITTI-convention disparity (× 256), 0 = invalid;
//! and a summary of any PNG for `stereo-depth info`.

use std::io::Cursor;
use std::path::Path;

use image::{DynamicImage, ImageBuffer, ImageFormat, Luma};
use stereo_image::{DisparityMap, Image};

use crate::{format_err, raster, write_atomic, Error};

/// The deepest depth a millimetre PNG can hold: 65535 mm = 65.535 m.
pub const DEPTH_PNG_MAX_MM: u16 = u16::MAX;

/// KITTI's disparity PNG scale: `value = round(disparity × 256)`.
pub const KITTI_SCALE: f32 = 256.0;

/// A depth map (metres, NaN / non-positive = invalid) as millimetres: `round(Z · 1000)`, 0 where
/// the depth is invalid, rounds to 0, or is beyond [`DEPTH_PNG_MAX_MM`]. Returns the map and
/// the number of valid pixels too deep to store (written as 0).
pub fn depth_to_mm(depth: &Image<f32>) -> (Image<u16>, usize) {
    let mut too_deep = 0;
    let data = depth
        .as_slice()
        .iter()
        .map(|&z| {
            if !(z.is_finite() && z > 0.0) {
                return 0;
            }
            let mm = (f64::from(z) * 1000.0).round();
            if mm > f64::from(DEPTH_PNG_MAX_MM) {
                too_deep += 1;
                0
            } else {
                mm as u16
            }
        })
        .collect();
    let (w, h) = depth.size();
    (Image::from_vec(w, h, data).expect("same size as the depth map"), too_deep)
}

/// A disparity map (pixels) in the KITTI convention: `round(d · 256)`, 0 where the disparity is
/// invalid (NaN), `<= 0`, or rounds to 0; disparities of 256 px and more saturate at 65535.
pub fn disparity_to_kitti(disparity: &DisparityMap) -> Image<u16> {
    let data = disparity
        .as_slice()
        .iter()
        .map(|&d| {
            if !(d.is_finite() && d > 0.0) {
                0
            } else {
                (f64::from(d) * f64::from(KITTI_SCALE)).round().min(f64::from(u16::MAX)) as u16
            }
        })
        .collect();
    let (w, h) = disparity.size();
    Image::from_vec(w, h, data).expect("same size as the disparity map")
}

/// Writes a 16-bit greyscale PNG atomically.
pub fn write_png16(path: &Path, image: &Image<u16>) -> Result<(), Error> {
    let (w, h) = image.size();
    if w == 0 || h == 0 {
        return Err(format_err(path, format!("cannot write a {w}x{h} PNG (empty image)")));
    }
    let buffer: Option<ImageBuffer<Luma<u16>, Vec<u16>>> =
        ImageBuffer::from_raw(w as u32, h as u32, image.as_slice().to_vec());
    write_png_buffer(path, buffer)
}

/// Writes an 8-bit greyscale PNG atomically.
pub fn write_png8(path: &Path, image: &Image<u8>) -> Result<(), Error> {
    let (w, h) = image.size();
    if w == 0 || h == 0 {
        return Err(format_err(path, format!("cannot write a {w}x{h} PNG (empty image)")));
    }
    let buffer: Option<ImageBuffer<Luma<u8>, Vec<u8>>> =
        ImageBuffer::from_raw(w as u32, h as u32, image.as_slice().to_vec());
    write_png_buffer(path, buffer)
}

/// Encodes `buffer` (`None`: its size did not match) as PNG and writes it atomically.
pub(crate) fn write_png_buffer<P>(
    path: &Path,
    buffer: Option<ImageBuffer<P, Vec<P::Subpixel>>>,
) -> Result<(), Error>
where
    P: image::Pixel + image::PixelWithColorType,
    [P::Subpixel]: image::EncodableLayout,
{
    let buffer = buffer.ok_or_else(|| format_err(path, "PNG buffer size mismatch"))?;
    let mut bytes = Cursor::new(Vec::new());
    buffer
        .write_to(&mut bytes, ImageFormat::Png)
        .map_err(|e| format_err(path, format!("cannot encode the PNG: {e}")))?;
    write_atomic(path, bytes.get_ref())
}

/// What a PNG (or other raster image) holds, for `stereo-depth info`.
#[derive(Clone, Debug, PartialEq)]
pub struct PngInfo {
    pub width: usize,
    pub height: usize,
    /// Bits per sample: 8, 16 or 32 (float).
    pub bit_depth: u8,
    /// Samples per pixel: 1 grey, 2 grey + alpha, 3 RGB, 4 RGBA.
    pub channels: u8,
    /// Smallest and largest sample of the first channel, over all pixels.
    pub min: f64,
    pub max: f64,
    /// Smallest sample of the first channel that is not 0 (`None` when all are 0).
    pub min_nonzero: Option<f64>,
    /// Pixels whose first channel is not 0.
    pub nonzero: usize,
}

/// Reads an image and summarises its first channel (see [`PngInfo`]).
pub fn read_png_info(path: &Path) -> Result<PngInfo, Error> {
    let img = raster::decode(path, raster::DEFAULT_MAX_PIXELS)?;
    let (width, height) = (img.width() as usize, img.height() as usize);
    let channels = img.color().channel_count();
    let bit_depth = (img.color().bits_per_pixel() / u16::from(channels)) as u8;
    let first: Vec<f64> = match &img {
        DynamicImage::ImageLuma16(b) => b.pixels().map(|p| f64::from(p.0[0])).collect(),
        DynamicImage::ImageLumaA16(b) => b.pixels().map(|p| f64::from(p.0[0])).collect(),
        DynamicImage::ImageRgb16(b) => b.pixels().map(|p| f64::from(p.0[0])).collect(),
        DynamicImage::ImageRgba16(b) => b.pixels().map(|p| f64::from(p.0[0])).collect(),
        DynamicImage::ImageRgb32F(b) => b.pixels().map(|p| f64::from(p.0[0])).collect(),
        DynamicImage::ImageRgba32F(b) => b.pixels().map(|p| f64::from(p.0[0])).collect(),
        other => other.to_luma_alpha8().pixels().map(|p| f64::from(p.0[0])).collect(),
    };
    let first: Vec<f64> = if channels >= 3 && bit_depth == 8 {
        img.to_rgb8().pixels().map(|p| f64::from(p.0[0])).collect()
    } else {
        first
    };
    let min = first.iter().copied().fold(f64::INFINITY, f64::min);
    let max = first.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let min_nonzero = first.iter().copied().filter(|&v| v != 0.0).reduce(f64::min);
    let nonzero = first.iter().filter(|&&v| v != 0.0).count();
    Ok(PngInfo { width, height, bit_depth, channels, min, max, min_nonzero, nonzero })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn millimetres_and_kitti() {
        let depth = Image::from_vec(5, 1, vec![0.6, f32::NAN, 70.0, 0.0001, -1.0]).unwrap();
        let (mm, too_deep) = depth_to_mm(&depth);
        assert_eq!(mm.as_slice(), &[600, 0, 0, 0, 0]);
        assert_eq!(too_deep, 1);
        let disp = DisparityMap::from_vec(5, 1, vec![45.0, f32::NAN, -3.0, 0.001, 10.3]).unwrap();
        assert_eq!(disparity_to_kitti(&disp).as_slice(), &[11520, 0, 0, 0, 2637]);
    }
}
