//! Decoding PNG / PNM / JPEG images with the `image` crate.

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use image::{DynamicImage, ImageError, ImageFormat, ImageReader};
use stereo_disparity::{GrayImage, Image};

use crate::{format_err, io_err, Error};

/// Rec. 601 luma of 16-bit channels, rounded, in integer arithmetic (exact for grey).
#[inline]
fn luma16(r: u16, g: u16, b: u16) -> u16 {
    let y = (299 * r as u32 + 587 * g as u32 + 114 * b as u32 + 500) / 1000;
    y as u16
}

#[inline]
fn expand8(v: u8) -> u16 {
    v as u16 * 257
}

#[inline]
fn float_to_u16(v: f32) -> u16 {
    if v.is_nan() {
        0
    } else {
        (v.clamp(0.0, 1.0) * 65535.0).round() as u16
    }
}

#[inline]
fn float_to_u8(v: f32) -> u8 {
    if v.is_nan() {
        0
    } else {
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    }
}

/// A short name of the format the extension suggests, for "not a PNG image" messages.
fn extension_format(path: &Path) -> Option<&'static str> {
    let ext = path.extension()?.to_str()?.to_ascii_lowercase();
    Some(match ext.as_str() {
        "png" => "PNG",
        "pgm" | "ppm" | "pbm" | "pnm" | "pam" => "PNM",
        "jpg" | "jpeg" => "JPEG",
        _ => return None,
    })
}

/// Opens and decodes an image, detecting the format from its content.
pub(crate) fn decode(path: &Path) -> Result<DynamicImage, Error> {
    let meta = std::fs::metadata(path).map_err(io_err(path))?;
    if meta.is_dir() {
        return Err(format_err(path, "is a directory, not an image file"));
    }
    if meta.len() == 0 {
        return Err(format_err(path, "empty file, not an image"));
    }
    let file = File::open(path).map_err(io_err(path))?;
    let reader = ImageReader::new(BufReader::new(file)).with_guessed_format().map_err(io_err(path))?;
    let Some(format) = reader.format() else {
        let message = match extension_format(path) {
            Some(name) => format!("not a {name} image (unrecognised format)"),
            None => "not an image (unrecognised format; want PNG, PNM or JPEG)".to_string(),
        };
        return Err(format_err(path, message));
    };
    let name = format_name(format);
    let img = reader.decode().map_err(|e| match e {
        ImageError::Unsupported(e) => {
            format_err(path, format!("unsupported {name} image ({e}); want PNG, PNM or JPEG"))
        }
        ImageError::Limits(e) => format_err(path, format!("{name} image too large ({e})")),
        ImageError::IoError(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
            format_err(path, format!("truncated {name} image ({e})"))
        }
        ImageError::IoError(e) => format_err(path, format!("cannot read {name} image: {e}")),
        e => format_err(path, format!("corrupt {name} image: {e}")),
    })?;
    if img.width() == 0 || img.height() == 0 {
        return Err(format_err(path, format!("image is {}x{}", img.width(), img.height())));
    }
    Ok(img)
}

fn format_name(format: ImageFormat) -> String {
    match format {
        ImageFormat::Png => "PNG".into(),
        ImageFormat::Pnm => "PNM".into(),
        ImageFormat::Jpeg => "JPEG".into(),
        other => format!("{other:?}"),
    }
}

fn collect<P, T: Copy>(
    path: &Path,
    width: u32,
    height: u32,
    pixels: impl Iterator<Item = P>,
    f: impl Fn(P) -> T,
) -> Result<Image<T>, Error> {
    let data: Vec<T> = pixels.map(f).collect();
    Image::from_vec(width as usize, height as usize, data).map_err(|e| format_err(path, e.to_string()))
}

/// Loads any 8/16-bit grey, grey+alpha, RGB or RGBA image (PNG, PNM or JPEG, detected from the
/// content) as the working 16-bit grey image: 8-bit values scaled by 257; colour converted with
/// Rec. 601 luma weights (0.299, 0.587, 0.114), rounded; 16-bit precision kept; alpha ignored.
/// Float images are clamped to `[0, 1]` and scaled to 65535.
pub fn load_gray(path: &Path) -> Result<GrayImage, Error> {
    let img = decode(path)?;
    let (w, h) = (img.width(), img.height());
    match img {
        DynamicImage::ImageLuma8(b) => collect(path, w, h, b.pixels(), |p| expand8(p.0[0])),
        DynamicImage::ImageLumaA8(b) => collect(path, w, h, b.pixels(), |p| expand8(p.0[0])),
        DynamicImage::ImageRgb8(b) => {
            collect(path, w, h, b.pixels(), |p| luma16(expand8(p.0[0]), expand8(p.0[1]), expand8(p.0[2])))
        }
        DynamicImage::ImageRgba8(b) => {
            collect(path, w, h, b.pixels(), |p| luma16(expand8(p.0[0]), expand8(p.0[1]), expand8(p.0[2])))
        }
        DynamicImage::ImageLuma16(b) => collect(path, w, h, b.pixels(), |p| p.0[0]),
        DynamicImage::ImageLumaA16(b) => collect(path, w, h, b.pixels(), |p| p.0[0]),
        DynamicImage::ImageRgb16(b) => collect(path, w, h, b.pixels(), |p| luma16(p.0[0], p.0[1], p.0[2])),
        DynamicImage::ImageRgba16(b) => collect(path, w, h, b.pixels(), |p| luma16(p.0[0], p.0[1], p.0[2])),
        DynamicImage::ImageRgb32F(b) => collect(path, w, h, b.pixels(), |p| {
            luma16(float_to_u16(p.0[0]), float_to_u16(p.0[1]), float_to_u16(p.0[2]))
        }),
        other => {
            let b = other.to_rgba16();
            collect(path, w, h, b.pixels(), |p| luma16(p.0[0], p.0[1], p.0[2]))
        }
    }
}

/// Loads an image as 8-bit RGB (e.g. the left view, to colour a point cloud): 16-bit samples
/// keep their top 8 bits, grey is replicated to all three channels, alpha is ignored.
pub fn load_rgb8(path: &Path) -> Result<Image<[u8; 3]>, Error> {
    let img = decode(path)?;
    let (w, h) = (img.width(), img.height());
    let top = |v: u16| (v >> 8) as u8;
    match img {
        DynamicImage::ImageLuma8(b) => collect(path, w, h, b.pixels(), |p| [p.0[0]; 3]),
        DynamicImage::ImageLumaA8(b) => collect(path, w, h, b.pixels(), |p| [p.0[0]; 3]),
        DynamicImage::ImageRgb8(b) => collect(path, w, h, b.pixels(), |p| p.0),
        DynamicImage::ImageRgba8(b) => collect(path, w, h, b.pixels(), |p| [p.0[0], p.0[1], p.0[2]]),
        DynamicImage::ImageLuma16(b) => collect(path, w, h, b.pixels(), |p| [top(p.0[0]); 3]),
        DynamicImage::ImageLumaA16(b) => collect(path, w, h, b.pixels(), |p| [top(p.0[0]); 3]),
        DynamicImage::ImageRgb16(b) => {
            collect(path, w, h, b.pixels(), |p| [top(p.0[0]), top(p.0[1]), top(p.0[2])])
        }
        DynamicImage::ImageRgba16(b) => {
            collect(path, w, h, b.pixels(), |p| [top(p.0[0]), top(p.0[1]), top(p.0[2])])
        }
        DynamicImage::ImageRgb32F(b) => collect(path, w, h, b.pixels(), |p| p.0.map(float_to_u8)),
        other => {
            let b = other.to_rgba16();
            collect(path, w, h, b.pixels(), |p| [top(p.0[0]), top(p.0[1]), top(p.0[2])])
        }
    }
}

/// Reads an 8/16-bit integer disparity image as raw sample values (grey; alpha ignored;
/// colour accepted only when all three channels are equal).
pub(crate) fn load_disparity_samples(path: &Path) -> Result<Image<u16>, Error> {
    let img = decode(path)?;
    let (w, h) = (img.width(), img.height());
    let equal = |r: u16, g: u16, b: u16| r == g && g == b;
    let colour_err = || format_err(path, "colour image is not a disparity map (channels differ)");
    let rgb: Vec<[u16; 3]> = match img {
        DynamicImage::ImageLuma8(b) => return collect(path, w, h, b.pixels(), |p| p.0[0] as u16),
        DynamicImage::ImageLumaA8(b) => return collect(path, w, h, b.pixels(), |p| p.0[0] as u16),
        DynamicImage::ImageLuma16(b) => return collect(path, w, h, b.pixels(), |p| p.0[0]),
        DynamicImage::ImageLumaA16(b) => return collect(path, w, h, b.pixels(), |p| p.0[0]),
        DynamicImage::ImageRgb8(b) => b.pixels().map(|p| p.0.map(u16::from)).collect(),
        DynamicImage::ImageRgba8(b) => b.pixels().map(|p| [p.0[0], p.0[1], p.0[2]].map(u16::from)).collect(),
        DynamicImage::ImageRgb16(b) => b.pixels().map(|p| p.0).collect(),
        DynamicImage::ImageRgba16(b) => b.pixels().map(|p| [p.0[0], p.0[1], p.0[2]]).collect(),
        other => {
            return Err(format_err(
                path,
                format!("want an 8- or 16-bit integer disparity image, got {:?}", other.color()),
            ))
        }
    };
    if !rgb.iter().all(|&[r, g, b]| equal(r, g, b)) {
        return Err(colour_err());
    }
    collect(path, w, h, rgb.into_iter(), |p| p[0])
}
