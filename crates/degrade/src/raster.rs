//! A plain interleaved image of 8- or 16-bit samples, grey or RGB, and its PNG/JPEG/PNM
//! conversions through the `image` crate.

use std::io::Cursor;

use image::{DynamicImage, ImageBuffer, ImageFormat, Luma, Rgb};
use stereo_image::GrayImage;

use crate::Error;

/// Bits per sample of a [`Raster`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BitDepth {
    Eight,
    Sixteen,
}

impl BitDepth {
    /// The largest sample value: 255 or 65535.
    pub fn max_value(self) -> u16 {
        match self {
            BitDepth::Eight => u8::MAX as u16,
            BitDepth::Sixteen => u16::MAX,
        }
    }
}

/// A row-major, channel-interleaved image: `channels` (1 = grey, 3 = RGB) samples per pixel,
/// each stored in a `u16` at its native scale (0..=255 for 8-bit, 0..=65535 for 16-bit).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Raster {
    width: usize,
    height: usize,
    channels: usize,
    depth: BitDepth,
    data: Vec<u16>,
}

impl Raster {
    /// Wraps interleaved samples; fails when the channel count is not 1 or 3, the buffer length
    /// is not `width · height · channels`, or an 8-bit sample exceeds 255.
    pub fn new(
        width: usize,
        height: usize,
        channels: usize,
        depth: BitDepth,
        data: Vec<u16>,
    ) -> Result<Self, Error> {
        if channels != 1 && channels != 3 {
            return Err(Error::Raster(format!("{channels} channels; want 1 (grey) or 3 (RGB)")));
        }
        let want = width.checked_mul(height).and_then(|n| n.checked_mul(channels));
        if want != Some(data.len()) {
            return Err(Error::Raster(format!("{} samples for {width}x{height}x{channels}", data.len())));
        }
        if data.iter().any(|&v| v > depth.max_value()) {
            return Err(Error::Raster("an 8-bit sample exceeds 255".into()));
        }
        Ok(Raster { width, height, channels, depth, data })
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// 1 (grey) or 3 (RGB).
    pub fn channels(&self) -> usize {
        self.channels
    }

    pub fn depth(&self) -> BitDepth {
        self.depth
    }

    /// The interleaved samples, row-major.
    pub fn samples(&self) -> &[u16] {
        &self.data
    }

    /// Sample `c` of pixel `(x, y)`.
    pub fn get(&self, x: usize, y: usize, c: usize) -> u16 {
        self.data[(y * self.width + x) * self.channels + c]
    }

    /// A grey raster from the matchers' [`GrayImage`], whose 8-bit images hold `v · 257`: with
    /// [`BitDepth::Eight`] the samples are divided back by 257 (rounded).
    pub fn from_gray_image(image: &GrayImage, depth: BitDepth) -> Raster {
        let data = match depth {
            BitDepth::Sixteen => image.as_slice().to_vec(),
            BitDepth::Eight => image.as_slice().iter().map(|&v| ((v as u32 + 128) / 257) as u16).collect(),
        };
        Raster { width: image.width(), height: image.height(), channels: 1, depth, data }
    }

    /// The matchers' [`GrayImage`] (8-bit samples scaled by 257; RGB reduced to Rec. 601 luma).
    pub fn to_gray_image(&self) -> GrayImage {
        let scale = match self.depth {
            BitDepth::Eight => 257,
            BitDepth::Sixteen => 1,
        };
        GrayImage::from_fn(self.width, self.height, |x, y| {
            let luma = if self.channels == 1 {
                self.get(x, y, 0) as u32
            } else {
                let (r, g, b) =
                    (self.get(x, y, 0) as u32, self.get(x, y, 1) as u32, self.get(x, y, 2) as u32);
                (299 * r + 587 * g + 114 * b + 500) / 1000
            };
            (luma * scale) as u16
        })
    }

    /// Converts a decoded image, keeping its bit depth and colour: grey stays grey, RGB stays RGB,
    /// an alpha channel is dropped (stereo matching ignores it), float images become 16-bit.
    pub fn from_dynamic(image: DynamicImage) -> Raster {
        let (width, height) = (image.width() as usize, image.height() as usize);
        let (channels, depth, data): (usize, BitDepth, Vec<u16>) = match image {
            DynamicImage::ImageLuma8(_) | DynamicImage::ImageLumaA8(_) => {
                (1, BitDepth::Eight, image.into_luma8().into_raw().into_iter().map(u16::from).collect())
            }
            DynamicImage::ImageRgb8(_) | DynamicImage::ImageRgba8(_) => {
                (3, BitDepth::Eight, image.into_rgb8().into_raw().into_iter().map(u16::from).collect())
            }
            DynamicImage::ImageLuma16(_) | DynamicImage::ImageLumaA16(_) => {
                (1, BitDepth::Sixteen, image.into_luma16().into_raw())
            }
            _ => (3, BitDepth::Sixteen, image.into_rgb16().into_raw()),
        };
        Raster { width, height, channels, depth, data }
    }

    /// The same pixels as a `DynamicImage` (L8, Rgb8, L16 or Rgb16).
    pub fn to_dynamic(&self) -> DynamicImage {
        let (w, h) = (self.width as u32, self.height as u32);
        // The buffer length matches by construction, so `from_raw` cannot fail.
        let bytes = || self.data.iter().map(|&v| v as u8).collect::<Vec<u8>>();
        match (self.channels, self.depth) {
            (1, BitDepth::Eight) => {
                DynamicImage::ImageLuma8(ImageBuffer::<Luma<u8>, _>::from_raw(w, h, bytes()).expect("size"))
            }
            (_, BitDepth::Eight) => {
                DynamicImage::ImageRgb8(ImageBuffer::<Rgb<u8>, _>::from_raw(w, h, bytes()).expect("size"))
            }
            (1, BitDepth::Sixteen) => DynamicImage::ImageLuma16(
                ImageBuffer::<Luma<u16>, _>::from_raw(w, h, self.data.clone()).expect("size"),
            ),
            (_, BitDepth::Sixteen) => DynamicImage::ImageRgb16(
                ImageBuffer::<Rgb<u16>, _>::from_raw(w, h, self.data.clone()).expect("size"),
            ),
        }
    }

    /// Decodes a PNG, PNM or JPEG file's bytes (format guessed from the content).
    pub fn decode(bytes: &[u8]) -> Result<Raster, Error> {
        let reader = image::ImageReader::new(Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| Error::Codec(e.to_string()))?;
        if reader.format().is_none() {
            return Err(Error::Codec("not an image (unrecognised format; want PNG, PNM or JPEG)".into()));
        }
        let image = reader.decode().map_err(|e| Error::Codec(e.to_string()))?;
        Ok(Raster::from_dynamic(image))
    }

    /// The image as PNG bytes, at its own bit depth and channel count.
    pub fn encode_png(&self) -> Result<Vec<u8>, Error> {
        let mut out = Cursor::new(Vec::new());
        self.to_dynamic().write_to(&mut out, ImageFormat::Png).map_err(|e| Error::Codec(e.to_string()))?;
        Ok(out.into_inner())
    }

    /// Samples as floats on [0, 1], one plane per channel.
    pub(crate) fn to_planes(&self) -> Vec<Vec<f32>> {
        let max = self.depth.max_value() as f32;
        (0..self.channels)
            .map(|c| self.data.iter().skip(c).step_by(self.channels).map(|&v| v as f32 / max).collect())
            .collect()
    }

    /// Rounds and clips float planes on [0, 1] back to samples of `depth`.
    pub(crate) fn from_planes(width: usize, height: usize, depth: BitDepth, planes: &[Vec<f32>]) -> Raster {
        let channels = planes.len();
        let max = depth.max_value() as f32;
        let mut data = vec![0u16; width * height * channels];
        for (c, plane) in planes.iter().enumerate() {
            for (i, &v) in plane.iter().enumerate() {
                // A NaN (which no stage produces) would end as 0: float-to-int casts saturate.
                data[i * channels + c] = (v.clamp(0.0, 1.0) * max).round() as u16;
            }
        }
        Raster { width, height, channels, depth, data }
    }
}
