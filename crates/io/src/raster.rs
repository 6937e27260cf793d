//! Decoding PNG / PNM / TIFF / JPEG images with the `image` crate.

use std::fs::File;
use std::io::{BufRead, BufReader, Cursor, Seek, SeekFrom};
use std::path::Path;

use image::{DynamicImage, ImageDecoder, ImageError, ImageFormat, ImageReader, Limits};
// One grey conversion for files and in-memory views (stereo_image::ImageRef::to_gray16).
use stereo_image::{expand8, luma16, GrayImage, Image};

use crate::{format_err, io_err, Error};

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
        "tif" | "tiff" => "TIFF",
        _ => return None,
    })
}

/// The largest image [`load_gray`] and [`load_rgb8`] decode: 100 megapixels. Larger images need
/// [`load_gray_limited`] / [`load_rgb8_limited`] with an explicit limit.
pub const DEFAULT_MAX_PIXELS: u64 = 100_000_000;

/// What an image's header declares, read without decoding its pixels ([`probe_image`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImageHeader {
    pub width: usize,
    pub height: usize,
    /// Bytes per pixel of the decoded image (e.g. 2 for 16-bit grey, 6 for 16-bit RGB).
    pub bytes_per_pixel: usize,
    /// Bits per channel: 8 or 16 (32 for float images).
    pub bits_per_channel: usize,
    /// `"PNG"`, `"PNM"`, `"TIFF"` or `"JPEG"`.
    pub format: &'static str,
}

impl ImageHeader {
    pub fn pixels(&self) -> u64 {
        self.width as u64 * self.height as u64
    }

    /// The bytes the decoder allocates for the whole image.
    pub fn decoded_bytes(&self) -> u64 {
        self.pixels().saturating_mul(self.bytes_per_pixel as u64)
    }
}

/// Checks that `path` is a non-empty file and opens a reader with the format guessed from the
/// content.
fn open(path: &Path) -> Result<(ImageReader<BufReader<File>>, &'static str), Error> {
    let meta = std::fs::metadata(path).map_err(io_err(path))?;
    if meta.is_dir() {
        return Err(format_err(path, "is a directory, not an image file"));
    }
    if meta.len() == 0 {
        return Err(format_err(path, "empty file, not an image"));
    }
    let file = File::open(path).map_err(io_err(path))?;
    let reader = ImageReader::new(BufReader::new(file)).with_guessed_format().map_err(io_err(path))?;
    let format = guessed(path, reader.format())?;
    Ok((reader, format))
}

/// The short name of a guessed format, or the "not an image" error.
fn guessed(path: &Path, format: Option<ImageFormat>) -> Result<&'static str, Error> {
    match format {
        Some(format) => Ok(format_name(format)),
        None => Err(format_err(
            path,
            match extension_format(path) {
                Some(name) => format!("not a {name} image (unrecognised format)"),
                None => "not an image (unrecognised format; want PNG, PNM, TIFF or JPEG)".to_string(),
            },
        )),
    }
}

fn decode_error(path: &Path, name: &str, e: ImageError) -> Error {
    match e {
        ImageError::Unsupported(e) => {
            format_err(path, format!("unsupported {name} image ({e}); want PNG, PNM, TIFF or JPEG"))
        }
        ImageError::Limits(e) => format_err(path, format!("{name} image too large ({e})")),
        ImageError::IoError(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => {
            format_err(path, format!("truncated {name} image ({e})"))
        }
        ImageError::IoError(e) => format_err(path, format!("cannot read {name} image: {e}")),
        e => format_err(path, format!("corrupt {name} image: {e}")),
    }
}

/// Reads an image's header (format, size, sample type) without decoding the pixels, so the size
/// can be checked before anything large is allocated.
pub fn probe_image(path: &Path) -> Result<ImageHeader, Error> {
    let (reader, name) = open(path)?;
    header_of(path, name, reader)
}

fn header_of<R: BufRead + Seek>(
    path: &Path,
    name: &'static str,
    reader: ImageReader<R>,
) -> Result<ImageHeader, Error> {
    // Reading the header allocates nothing in proportion to the size; the default allocation
    // limit would refuse a large declared size here with a message that does not give the size.
    let mut reader = reader;
    reader.no_limits();
    let decoder = reader.into_decoder().map_err(|e| decode_error(path, name, e))?;
    let (width, height) = decoder.dimensions();
    let colour = decoder.color_type();
    let bytes_per_pixel = usize::from(colour.bytes_per_pixel());
    let channels = usize::from(colour.channel_count()).max(1);
    Ok(ImageHeader {
        width: width as usize,
        height: height as usize,
        bytes_per_pixel,
        bits_per_channel: bytes_per_pixel * 8 / channels,
        format: name,
    })
}

/// Refuses an image whose header declares more than `max_pixels` pixels (or no pixels), before
/// any pixel is decoded.
fn check_size(path: &Path, header: &ImageHeader, max_pixels: u64) -> Result<(), Error> {
    let (w, h) = (header.width, header.height);
    if w == 0 || h == 0 {
        return Err(format_err(path, format!("image is {w}x{h}")));
    }
    if header.pixels() > max_pixels {
        return Err(format_err(
            path,
            format!(
                "{} image is {w}x{h} = {} pixels, more than the limit of {max_pixels} pixels",
                header.format,
                header.pixels()
            ),
        ));
    }
    Ok(())
}

/// Decodes with the size checked first: the header's dimensions against `max_pixels`, and the
/// decoder's allocations bounded by what an image of that size needs.
fn decode_reader<R: BufRead + Seek>(
    path: &Path,
    name: &'static str,
    reader: ImageReader<R>,
    max_pixels: u64,
) -> Result<DynamicImage, Error> {
    // The header is read on a first pass over the same bytes (`into_decoder` consumes the reader).
    let format = format_of(name);
    let mut inner = reader.into_inner();
    let start = inner.stream_position().map_err(io_err(path))?;
    let header = header_of(path, name, ImageReader::with_format(&mut inner, format))?;
    inner.seek(SeekFrom::Start(start)).map_err(io_err(path))?;
    let mut reader = ImageReader::with_format(inner, format);
    check_size(path, &header, max_pixels)?;
    let mut limits = Limits::default();
    // 16 bytes per pixel (32-bit float RGBA) is the most any supported decoder returns; the
    // margin covers the decoders' own row buffers.
    limits.max_alloc = Some(max_pixels.saturating_mul(16).saturating_add(64 << 20));
    reader.limits(limits);
    let img = reader.decode().map_err(|e| decode_error(path, name, e))?;
    if img.width() == 0 || img.height() == 0 {
        return Err(format_err(path, format!("image is {}x{}", img.width(), img.height())));
    }
    Ok(img)
}

fn format_of(name: &str) -> ImageFormat {
    match name {
        "PNG" => ImageFormat::Png,
        "PNM" => ImageFormat::Pnm,
        "TIFF" => ImageFormat::Tiff,
        _ => ImageFormat::Jpeg,
    }
}

/// Opens and decodes an image, detecting the format from its content; at most `max_pixels`.
pub(crate) fn decode(path: &Path, max_pixels: u64) -> Result<DynamicImage, Error> {
    let (reader, name) = open(path)?;
    if name == "JPEG" {
        // JPEG decoders fill a truncated scan with grey: check the end marker on the bytes.
        let bytes = std::fs::read(path).map_err(io_err(path))?;
        check_jpeg_end(path, &bytes)?;
        let reader = ImageReader::with_format(Cursor::new(bytes), ImageFormat::Jpeg);
        return decode_reader(path, name, reader, max_pixels);
    }
    decode_reader(path, name, reader, max_pixels)
}

/// A JPEG must hold an end-of-image marker (FF D9) after its last start-of-scan (FF DA): in the
/// entropy-coded data an FF byte is always followed by 00 or a restart marker, so a file cut
/// anywhere in or before its last scan has none. The decoders themselves accept such files and
/// return grey for the missing rows, a silent wrong answer.
fn check_jpeg_end(path: &Path, bytes: &[u8]) -> Result<(), Error> {
    let marker = |m: u8| bytes.windows(2).rposition(|w| w == [0xFF, m]);
    match (marker(0xDA), marker(0xD9)) {
        (Some(scan), Some(end)) if end > scan => Ok(()),
        (None, _) => Ok(()), // no scan at all: the decoder reports it
        _ => Err(format_err(path, "truncated JPEG image (no end-of-image marker after the scan data)")),
    }
}

/// Decodes image bytes (PNG, PNM, TIFF or JPEG, detected from the content) as [`load_gray`] does a
/// file, refusing more than `max_pixels` pixels before decoding; errors name `name`.
pub fn decode_gray(bytes: &[u8], name: &Path, max_pixels: u64) -> Result<GrayImage, Error> {
    if bytes.is_empty() {
        return Err(format_err(name, "empty file, not an image"));
    }
    let reader = ImageReader::new(Cursor::new(bytes)).with_guessed_format().map_err(io_err(name))?;
    let format = guessed(name, reader.format())?;
    if format == "JPEG" {
        check_jpeg_end(name, bytes)?;
    }
    to_gray(name, decode_reader(name, format, reader, max_pixels)?)
}

fn format_name(format: ImageFormat) -> &'static str {
    match format {
        ImageFormat::Png => "PNG",
        ImageFormat::Pnm => "PNM",
        ImageFormat::Jpeg => "JPEG",
        ImageFormat::Tiff => "TIFF",
        // The crate is built with these four formats only.
        _ => "unsupported",
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

/// Loads any 8/16-bit grey, grey+alpha, RGB or RGBA image (PNG, PNM, TIFF or JPEG, detected from the
/// content) as the working 16-bit grey image: 8-bit values scaled by 257; colour converted with
/// Rec. 601 luma weights (0.299, 0.587, 0.114), rounded; 16-bit precision kept; alpha ignored.
/// Float images are clamped to `[0, 1]` and scaled to 65535.
pub fn load_gray(path: &Path) -> Result<GrayImage, Error> {
    load_gray_limited(path, DEFAULT_MAX_PIXELS)
}

/// [`load_gray`] of an image of at most `max_pixels` pixels (checked on the header, before
/// decoding).
pub fn load_gray_limited(path: &Path, max_pixels: u64) -> Result<GrayImage, Error> {
    to_gray(path, decode(path, max_pixels)?)
}

fn to_gray(path: &Path, img: DynamicImage) -> Result<GrayImage, Error> {
    let (w, h) = (img.width(), img.height());
    match img {
        // The 8-bit layouts read from the raw samples (the per-pixel iterator kept these loops
        // from being vectorised: a tenth of a small pair's run).
        DynamicImage::ImageLuma8(b) => collect(path, w, h, b.as_raw().iter(), |&v| expand8(v)),
        DynamicImage::ImageLumaA8(b) => collect(path, w, h, b.pixels(), |p| expand8(p.0[0])),
        DynamicImage::ImageRgb8(b) => collect(path, w, h, b.as_raw().chunks_exact(3), |p| {
            luma16(expand8(p[0]), expand8(p[1]), expand8(p[2]))
        }),
        DynamicImage::ImageRgba8(b) => collect(path, w, h, b.as_raw().chunks_exact(4), |p| {
            luma16(expand8(p[0]), expand8(p[1]), expand8(p[2]))
        }),
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
    load_rgb8_limited(path, DEFAULT_MAX_PIXELS)
}

/// [`load_rgb8`] of an image of at most `max_pixels` pixels (checked before decoding).
pub fn load_rgb8_limited(path: &Path, max_pixels: u64) -> Result<Image<[u8; 3]>, Error> {
    to_rgb8(path, &decode(path, max_pixels)?)
}

/// The working grey image and the 8-bit RGB colours of one image, decoded once (the left view
/// of a pair whose point cloud is coloured): the same values as [`load_gray_limited`] and
/// [`load_rgb8_limited`].
pub fn load_gray_and_rgb8_limited(
    path: &Path,
    max_pixels: u64,
) -> Result<(GrayImage, Image<[u8; 3]>), Error> {
    let img = decode(path, max_pixels)?;
    let colour = to_rgb8(path, &img)?;
    Ok((to_gray(path, img)?, colour))
}

fn to_rgb8(path: &Path, img: &DynamicImage) -> Result<Image<[u8; 3]>, Error> {
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
    let img = decode(path, DEFAULT_MAX_PIXELS)?;
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
