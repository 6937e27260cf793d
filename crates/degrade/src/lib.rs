//! Realistic, seeded camera degradations of stereo images, to measure matchers on pairs that are
//! not clean benchmarks: gain, gamma, bias, vignetting, sensor noise, JPEG, defocus, and the
//! small vertical shift and rotation of an imperfectly rectified rig.
//!
//! [`degrade`] works on a [`Raster`] (8- or 16-bit, grey or RGB) in f32 on [0, 1] per channel
//! and rounds and clips back to the input's bit depth. The stages run in camera-pipeline order:
//!
//! 1. geometry: rotation about the image centre and vertical shift, one bicubic (Catmull-Rom)
//!    resampling with replicated borders;
//! 2. defocus blur (separable Gaussian);
//! 3. vignetting (lens fall-off);
//! 4. gain, then bias (each clipped to [0, 1]), then gamma;
//! 5. Gaussian noise (seeded);
//! 6. JPEG encode + decode (8-bit; 16-bit images go through 8 bits and are scaled back).
//!
//! A stage whose parameter is unset is skipped, so an unset (or neutral) parameter leaves the
//! image byte-identical.
//!
//! ```
//! use stereo_degrade::{degrade, BitDepth, Degradation, Raster};
//!
//! let pixels: Vec<u16> = (0..64 * 48).map(|i| (i % 200) as u16).collect();
//! let image = Raster::new(64, 48, 1, BitDepth::Eight, pixels).unwrap();
//! let spec: Degradation = "gain=1.6,noise=2,jpeg=80".parse().unwrap();
//! let out = degrade(&image, &spec, 7).unwrap();
//! assert_eq!((out.width(), out.height(), out.channels()), (64, 48, 1));
//! // Seeded: the same seed gives the same image.
//! assert_eq!(out, degrade(&image, &spec, 7).unwrap());
//! ```

mod ops;
mod params;
mod raster;

pub use params::{Degradation, KEYS};
pub use raster::{BitDepth, Raster};

/// Bad parameters, spec syntax, or an image that cannot be converted.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A parameter's value is out of range or not a number.
    #[error("{name}: {message}")]
    Param { name: &'static str, message: String },
    /// A key that is not a degradation.
    #[error("unknown degradation {key:?} (known: {known})")]
    UnknownKey { key: String, known: String },
    /// The spec is not a comma list of `key=value`.
    #[error("bad degradation spec: {0}")]
    Syntax(String),
    /// Interleaved samples that do not form an image.
    #[error("invalid raster: {0}")]
    Raster(String),
    /// Image encoding or decoding failed.
    #[error("{0}")]
    Codec(String),
}

/// An independent seed for stream `stream` (e.g. 0 = left view, 1 = right view) of `seed`, so
/// the views of a pair get unrelated noise from one user seed.
pub fn derive_seed(seed: u64, stream: u64) -> u64 {
    let mut rng = ops::SplitMix64::new(seed ^ stream.wrapping_mul(0xD1B5_4A32_D192_ED03));
    rng.next_u64()
}

/// Applies `d` to `image` (order in the crate documentation); `seed` drives the noise.
/// Fails when a parameter is out of range (the error names it).
pub fn degrade(image: &Raster, d: &Degradation, seed: u64) -> Result<Raster, Error> {
    d.validate()?;
    if d.is_identity() {
        return Ok(image.clone());
    }
    let (w, h) = (image.width(), image.height());
    let mut planes = image.to_planes();
    let rotate = d.rotate.unwrap_or(0.0);
    let vshift = d.vshift.unwrap_or(0.0);
    if (rotate != 0.0 || vshift != 0.0) && w > 0 && h > 0 {
        planes = planes.iter().map(|p| ops::warp(p, w, h, rotate, vshift)).collect();
    }
    if let Some(sigma) = d.blur.filter(|&s| s > 0.0 && w > 0 && h > 0) {
        planes = planes.iter().map(|p| ops::blur(p, w, h, sigma)).collect();
    }
    if let Some(f) = d.vignette.filter(|&f| f != 0.0) {
        planes.iter_mut().for_each(|p| ops::vignette(p, w, h, f));
    }
    for plane in &mut planes {
        if let Some(g) = d.gain {
            plane.iter_mut().for_each(|v| *v = (*v * g).min(1.0));
        }
        if let Some(b) = d.bias {
            plane.iter_mut().for_each(|v| *v = (*v + b / 255.0).clamp(0.0, 1.0));
        }
        if let Some(gamma) = d.gamma.filter(|&g| g != 1.0) {
            plane.iter_mut().for_each(|v| *v = v.clamp(0.0, 1.0).powf(gamma));
        }
    }
    if let Some(sigma) = d.noise.filter(|&s| s > 0.0) {
        let mut rng = ops::SplitMix64::new(seed);
        planes.iter_mut().for_each(|p| ops::noise(p, sigma / 255.0, &mut rng));
    }
    if let Some(q) = d.jpeg {
        if w > 0 && h > 0 {
            ops::jpeg(&mut planes, w, h, q)?;
        }
    }
    Ok(Raster::from_planes(w, h, image.depth(), &planes))
}

#[cfg(test)]
mod tests;
