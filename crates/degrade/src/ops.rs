//! The individual stages, each on one float plane (row-major, values on [0, 1]).

use std::io::Cursor;

use image::codecs::jpeg::{JpegDecoder, JpegEncoder};
use image::{ExtendedColorType, ImageDecoder};

use crate::Error;

/// Catmull-Rom cubic weights for the four taps at offsets -1, 0, 1, 2 of fraction `t` in [0, 1).
/// Interpolating (`t = 0` gives exactly `[0, 1, 0, 0]`), so integer shifts are exact copies.
#[inline]
fn cubic_weights(t: f32) -> [f32; 4] {
    let t2 = t * t;
    let t3 = t2 * t;
    [
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    ]
}

/// Rotation by `degrees` about the image centre, then a vertical shift of `shift` px, resampled
/// with bicubic (Catmull-Rom) interpolation and replicated borders. Each output pixel samples
/// the source at the inverse mapping of its centre.
pub fn warp(plane: &[f32], width: usize, height: usize, degrees: f32, shift: f32) -> Vec<f32> {
    let (sin, cos) = (degrees as f64).to_radians().sin_cos();
    let (cx, cy) = ((width as f64 - 1.0) / 2.0, (height as f64 - 1.0) / 2.0);
    let clamp_x = |x: i64| x.clamp(0, width as i64 - 1) as usize;
    let clamp_y = |y: i64| y.clamp(0, height as i64 - 1) as usize;
    let mut out = vec![0.0; width * height];
    for y in 0..height {
        for x in 0..width {
            // Forward: p' = R(p − c) + c + (0, shift); so p = Rᵀ(p' − c − (0, shift)) + c.
            let dx = x as f64 - cx;
            let dy = y as f64 - cy - shift as f64;
            let sx = cos * dx + sin * dy + cx;
            let sy = -sin * dx + cos * dy + cy;
            let (fx, fy) = (sx.floor(), sy.floor());
            let wx = cubic_weights((sx - fx) as f32);
            let wy = cubic_weights((sy - fy) as f32);
            let (ix, iy) = (fx as i64, fy as i64);
            let mut sum = 0.0;
            for (j, wyj) in wy.iter().enumerate() {
                if *wyj == 0.0 {
                    continue;
                }
                let row = &plane[clamp_y(iy + j as i64 - 1) * width..][..width];
                let mut acc = 0.0;
                for (i, wxi) in wx.iter().enumerate() {
                    acc += wxi * row[clamp_x(ix + i as i64 - 1)];
                }
                sum += wyj * acc;
            }
            out[y * width + x] = sum;
        }
    }
    out
}

/// Separable Gaussian blur of standard deviation `sigma` px (radius ⌈3σ⌉, normalised kernel,
/// replicated borders).
pub fn blur(plane: &[f32], width: usize, height: usize, sigma: f32) -> Vec<f32> {
    let radius = (3.0 * sigma).ceil() as i64;
    let mut kernel: Vec<f32> =
        (-radius..=radius).map(|i| (-(i * i) as f32 / (2.0 * sigma * sigma)).exp()).collect();
    let total: f32 = kernel.iter().sum();
    kernel.iter_mut().for_each(|k| *k /= total);
    let mut tmp = vec![0.0; width * height];
    for y in 0..height {
        let row = &plane[y * width..][..width];
        for x in 0..width {
            let mut acc = 0.0;
            for (k, w) in kernel.iter().enumerate() {
                let xs = (x as i64 + k as i64 - radius).clamp(0, width as i64 - 1) as usize;
                acc += w * row[xs];
            }
            tmp[y * width + x] = acc;
        }
    }
    let mut out = vec![0.0; width * height];
    for y in 0..height {
        for (k, w) in kernel.iter().enumerate() {
            let ys = (y as i64 + k as i64 - radius).clamp(0, height as i64 - 1) as usize;
            let src = &tmp[ys * width..][..width];
            let dst = &mut out[y * width..][..width];
            for (d, s) in dst.iter_mut().zip(src) {
                *d += w * s;
            }
        }
    }
    out
}

/// Multiplies by `1 − f·(r/r_corner)²`, `r` measured from the image centre to the pixel centre.
pub fn vignette(plane: &mut [f32], width: usize, height: usize, f: f32) {
    let (cx, cy) = ((width as f32 - 1.0) / 2.0, (height as f32 - 1.0) / 2.0);
    let corner2 = cx * cx + cy * cy;
    if corner2 == 0.0 {
        return; // one pixel: it is the centre
    }
    for y in 0..height {
        for x in 0..width {
            let (dx, dy) = (x as f32 - cx, y as f32 - cy);
            plane[y * width + x] *= 1.0 - f * (dx * dx + dy * dy) / corner2;
        }
    }
}

/// SplitMix64: small, fast, and good enough for image noise; no dependency.
pub struct SplitMix64(u64);

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform on (0, 1]: never 0, so `ln` in Box–Muller is finite.
    fn next_open01(&mut self) -> f64 {
        ((self.next_u64() >> 11) + 1) as f64 / (1u64 << 53) as f64
    }

    /// Two independent standard normal samples (Box–Muller).
    pub fn normal_pair(&mut self) -> (f32, f32) {
        let r = (-2.0 * self.next_open01().ln()).sqrt();
        let theta = std::f64::consts::TAU * self.next_open01();
        ((r * theta.cos()) as f32, (r * theta.sin()) as f32)
    }
}

/// Adds N(0, σ²) to every sample, σ on the [0, 1] scale.
pub fn noise(plane: &mut [f32], sigma: f32, rng: &mut SplitMix64) {
    let mut chunks = plane.chunks_exact_mut(2);
    for pair in &mut chunks {
        let (a, b) = rng.normal_pair();
        pair[0] += sigma * a;
        pair[1] += sigma * b;
    }
    if let [last] = chunks.into_remainder() {
        *last += sigma * rng.normal_pair().0;
    }
}

/// Encodes the planes (1 = grey, 3 = RGB) as an 8-bit JPEG of `quality` and decodes it back.
pub fn jpeg(planes: &mut [Vec<f32>], width: usize, height: usize, quality: u8) -> Result<(), Error> {
    let channels = planes.len();
    let mut bytes = vec![0u8; width * height * channels];
    for (c, plane) in planes.iter().enumerate() {
        for (i, &v) in plane.iter().enumerate() {
            bytes[i * channels + c] = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
        }
    }
    let colour = if channels == 1 { ExtendedColorType::L8 } else { ExtendedColorType::Rgb8 };
    let mut encoded = Vec::new();
    JpegEncoder::new_with_quality(&mut encoded, quality)
        .encode(&bytes, width as u32, height as u32, colour)
        .map_err(|e| Error::Codec(format!("JPEG encoding: {e}")))?;
    let decoder =
        JpegDecoder::new(Cursor::new(&encoded)).map_err(|e| Error::Codec(format!("JPEG decoding: {e}")))?;
    if usize::from(decoder.color_type().channel_count()) != channels {
        return Err(Error::Codec("JPEG round trip changed the channel count".into()));
    }
    let mut decoded = vec![0u8; decoder.total_bytes() as usize];
    decoder.read_image(&mut decoded).map_err(|e| Error::Codec(format!("JPEG decoding: {e}")))?;
    for (c, plane) in planes.iter_mut().enumerate() {
        for (i, v) in plane.iter_mut().enumerate() {
            *v = decoded[i * channels + c] as f32 / 255.0;
        }
    }
    Ok(())
}
