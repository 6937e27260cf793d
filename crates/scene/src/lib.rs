//! Synthetic rectified stereo scenes with exact ground-truth disparity.
//!
//! A scene is a slanted background plane, optionally occluded by a fronto-parallel foreground
//! rectangle, both painted with a deterministic, seeded continuous texture. The texture is defined
//! on each surface in *left-image* coordinates, so the left view shows it unchanged and the right
//! view shows it warped by the surface's disparity. Both views are rendered by supersampling each
//! pixel's area, and the ground truth is the exact disparity of the visible surface at each pixel
//! centre.
//!
//! Conventions (as in [`stereo_image`]): pixel `(x, y)` covers `[x - 0.5, x + 0.5) ×
//! [y - 0.5, y + 0.5)` with its centre at `(x, y)`; the left pixel `(x, y)` matches the right
//! pixel `(x - d, y)`; nearer surfaces have larger disparities and hide farther ones.
//!
//! # Example
//!
//! ```
//! use stereo_scene::{render, SceneParams};
//!
//! let params = SceneParams { width: 96, height: 64, ..SceneParams::default() };
//! let scene = render(&params);
//! assert_eq!(scene.left.size(), (96, 64));
//!
//! // The background plane's disparity at a pixel centre is exactly a + b·x + c·y.
//! let (a, b, c) = params.plane;
//! let d = scene.gt_left.get(3, 5);
//! assert!((d as f64 - (a + b * 3.0 + c * 5.0)).abs() < 1e-4);
//!
//! // Pixels near the left border see points that leave the right image: occluded.
//! assert!(scene.occluded.get(0, 5));
//! ```

use stereo_image::{DisparityMap, GrayImage, Image};

/// An axis-aligned rectangle in continuous left-image coordinates covering
/// `[x0, x1) × [y0, y1)` (pixel `(x, y)` has its centre at `(x, y)`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rect {
    pub x0: f64,
    pub y0: f64,
    pub x1: f64,
    pub y1: f64,
}

impl Rect {
    /// Whether the point `(u, v)` lies inside.
    pub fn contains(&self, u: f64, v: f64) -> bool {
        u >= self.x0 && u < self.x1 && v >= self.y0 && v < self.y1
    }
}

/// A fronto-parallel rectangle at a constant disparity, in front of the background where its
/// disparity is larger.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Foreground {
    /// Where the rectangle is seen in the left image.
    pub rect: Rect,
    pub disparity: f64,
}

/// Everything that defines a scene; [`render`] is a pure function of these.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneParams {
    pub width: usize,
    pub height: usize,
    /// Seeds the texture and the noise: the same parameters always give the same images.
    pub seed: u64,
    /// Background disparity `d(x, y) = a + b·x + c·y` in left coordinates; `b < 1` is required
    /// (otherwise the plane would fold over in the right view).
    pub plane: (f64, f64, f64),
    pub foreground: Option<Foreground>,
    /// Standard deviation of independent Gaussian noise added to each image, in 16-bit grey levels.
    pub noise: f32,
    /// Samples per pixel side for the area average (`4` means 4×4 samples); at least 1.
    pub supersampling: usize,
}

impl Default for SceneParams {
    /// 320×240: a plane slanting from 8 px (left edge) to about 24 px (right edge), and a
    /// 36 px rectangle in front of it, no noise.
    fn default() -> Self {
        SceneParams {
            width: 320,
            height: 240,
            seed: 0x5EED_0001,
            plane: (8.0, 0.045, 0.007),
            foreground: Some(Foreground {
                rect: Rect { x0: 139.5, y0: 69.5, x1: 219.5, y1: 159.5 },
                disparity: 36.0,
            }),
            noise: 0.0,
            supersampling: 4,
        }
    }
}

/// A rendered rectified pair with its ground truth.
#[derive(Clone, Debug)]
pub struct Scene {
    pub left: GrayImage,
    pub right: GrayImage,
    /// Exact disparity of the surface seen at each left pixel centre (dense, no NaN).
    pub gt_left: DisparityMap,
    /// Exact disparity of the surface seen at each right pixel centre (dense, no NaN):
    /// right pixel `(x, y)` matches left `(x + d, y)`.
    pub gt_right: DisparityMap,
    /// Left pixels whose centre point is hidden in the right view or projects outside it
    /// (`x - d` outside `[-0.5, width - 0.5)`).
    pub occluded: Image<bool>,
    /// Right pixels whose centre point is hidden in the left view or projects outside it.
    pub occluded_right: Image<bool>,
}

/// Which surface a point belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Surface {
    Plane,
    Foreground,
}

/// The visible surface at a point of one view: which one, its disparity, and the left-image
/// coordinate `u` of the seen point (where its texture is sampled).
#[derive(Clone, Copy, Debug)]
struct Hit {
    surface: Surface,
    disparity: f64,
    u: f64,
}

struct Geometry {
    plane: (f64, f64, f64),
    foreground: Option<Foreground>,
}

impl Geometry {
    fn plane_disparity(&self, u: f64, v: f64) -> f64 {
        let (a, b, c) = self.plane;
        a + b * u + c * v
    }

    /// The surface seen at `(u, v)` in the left view.
    fn left(&self, u: f64, v: f64) -> Hit {
        let plane = Hit { surface: Surface::Plane, disparity: self.plane_disparity(u, v), u };
        match self.foreground {
            Some(f) if f.rect.contains(u, v) && f.disparity >= plane.disparity => {
                Hit { surface: Surface::Foreground, disparity: f.disparity, u }
            }
            _ => plane,
        }
    }

    /// The surface seen at `(ur, v)` in the right view.
    fn right(&self, ur: f64, v: f64) -> Hit {
        let (a, b, c) = self.plane;
        // ur = u - (a + b·u + c·v)  =>  u = (ur + a + c·v) / (1 - b)
        let u = (ur + a + c * v) / (1.0 - b);
        let plane = Hit { surface: Surface::Plane, disparity: u - ur, u };
        match self.foreground {
            Some(f) if f.rect.contains(ur + f.disparity, v) && f.disparity >= plane.disparity => {
                Hit { surface: Surface::Foreground, disparity: f.disparity, u: ur + f.disparity }
            }
            _ => plane,
        }
    }
}

/// Renders both views and the ground truth.
///
/// # Panics
///
/// When `width` or `height` is 0, `supersampling` is 0, or the plane's `b >= 1`.
pub fn render(params: &SceneParams) -> Scene {
    let (w, h) = (params.width, params.height);
    assert!(w > 0 && h > 0, "scene must be at least 1x1");
    assert!(params.supersampling > 0, "supersampling must be at least 1");
    assert!(params.plane.1 < 1.0, "plane slope b must be below 1");
    let geometry = Geometry { plane: params.plane, foreground: params.foreground };
    let mut seeds = SplitMix64::new(params.seed);
    let plane_texture = Texture::new(seeds.next_u64());
    let foreground_texture = Texture::new(seeds.next_u64());
    let texture = |hit: Hit, v: f64| match hit.surface {
        Surface::Plane => plane_texture.value(hit.u, v),
        Surface::Foreground => foreground_texture.value(hit.u, v),
    };

    let n = params.supersampling;
    let offsets: Vec<f64> = (0..n).map(|i| (i as f64 + 0.5) / n as f64 - 0.5).collect();
    let area_average = |x: usize, y: usize, view: &dyn Fn(f64, f64) -> Hit| {
        let mut sum = 0.0;
        for &dy in &offsets {
            let v = y as f64 + dy;
            for &dx in &offsets {
                sum += texture(view(x as f64 + dx, v), v);
            }
        }
        sum / (n * n) as f64
    };
    let left_view = |u: f64, v: f64| geometry.left(u, v);
    let right_view = |u: f64, v: f64| geometry.right(u, v);

    let mut noise = SplitMix64::new(seeds.next_u64());
    let mut grey = |value: f64| {
        let noisy = value + params.noise as f64 * noise.gaussian();
        noisy.round().clamp(0.0, 65535.0) as u16
    };
    let left = GrayImage::from_fn(w, h, |x, y| grey(area_average(x, y, &left_view)));
    let right = GrayImage::from_fn(w, h, |x, y| grey(area_average(x, y, &right_view)));

    let inside = |x: f64| (-0.5..w as f64 - 0.5).contains(&x);
    let gt_left = DisparityMap::from_fn(w, h, |x, y| geometry.left(x as f64, y as f64).disparity as f32);
    let gt_right = DisparityMap::from_fn(w, h, |x, y| geometry.right(x as f64, y as f64).disparity as f32);
    let occluded = Image::from_fn(w, h, |x, y| {
        let v = y as f64;
        let hit = geometry.left(x as f64, v);
        let ur = x as f64 - hit.disparity;
        !inside(ur) || geometry.right(ur, v).surface != hit.surface
    });
    let occluded_right = Image::from_fn(w, h, |x, y| {
        let v = y as f64;
        let hit = geometry.right(x as f64, v);
        !inside(hit.u) || geometry.left(hit.u, v).surface != hit.surface
    });
    Scene { left, right, gt_left, gt_right, occluded, occluded_right }
}

/// Converts a 16-bit grey image to 8 bits (rounded `v · 255 / 65535`), e.g. for saving as PNG.
pub fn to_u8(image: &GrayImage) -> Image<u8> {
    let (w, h) = image.size();
    Image::from_fn(w, h, |x, y| ((image.get(x, y) as u32 * 255 + 32767) / 65535) as u8)
}

/// A sum of plane waves plus two octaves of value noise, mapped smoothly into the 16-bit range.
///
/// Wave periods are 5–40 px and noise cells 3 and 6 px, far enough from the 2 px Nyquist limit
/// that subpixel shifts change the sampled image smoothly.
struct Texture {
    waves: Vec<Wave>,
    noise_seeds: [u64; 2],
}

struct Wave {
    kx: f64,
    ky: f64,
    phase: f64,
    amplitude: f64,
}

const WAVES: usize = 12;
const NOISE_CELLS: [f64; 2] = [6.0, 3.0];
const NOISE_AMPLITUDES: [f64; 2] = [0.7, 0.7];

impl Texture {
    fn new(seed: u64) -> Self {
        let mut rng = SplitMix64::new(seed);
        let waves = (0..WAVES)
            .map(|_| {
                let period = 5.0 * 8f64.powf(rng.next_f64()); // 5..40 px, log-uniform
                let angle = std::f64::consts::PI * rng.next_f64();
                let k = std::f64::consts::TAU / period;
                Wave {
                    kx: k * angle.cos(),
                    ky: k * angle.sin(),
                    phase: std::f64::consts::TAU * rng.next_f64(),
                    amplitude: 0.5 + rng.next_f64(),
                }
            })
            .collect();
        Texture { waves, noise_seeds: [rng.next_u64(), rng.next_u64()] }
    }

    /// The grey value (0..=65535, as f64) at continuous point `(u, v)`.
    fn value(&self, u: f64, v: f64) -> f64 {
        let mut sum = 0.0;
        for w in &self.waves {
            sum += w.amplitude * (w.kx * u + w.ky * v + w.phase).sin();
        }
        // Each wave's variance is amplitude²/2 ≈ 0.58 on average: normalise to about unit variance.
        sum /= (WAVES as f64 * 0.58).sqrt();
        for ((&cell, &amp), &seed) in NOISE_CELLS.iter().zip(&NOISE_AMPLITUDES).zip(&self.noise_seeds) {
            sum += amp * value_noise(u / cell, v / cell, seed);
        }
        // Soft limit into the range, so nothing is clipped flat.
        32767.5 + 32000.0 * (0.4 * sum).tanh()
    }
}

/// Smooth (C²) value noise on the integer lattice, values in [-1, 1] scaled to about unit variance.
fn value_noise(u: f64, v: f64, seed: u64) -> f64 {
    let (i, j) = (u.floor(), v.floor());
    let (fu, fv) = (fade(u - i), fade(v - j));
    let (i, j) = (i as i64, j as i64);
    let at = |di: i64, dj: i64| lattice(i + di, j + dj, seed);
    let top = at(0, 0) + (at(1, 0) - at(0, 0)) * fu;
    let bottom = at(0, 1) + (at(1, 1) - at(0, 1)) * fu;
    (top + (bottom - top) * fv) * 1.7
}

fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// A hash of a lattice point to [-1, 1).
fn lattice(i: i64, j: i64, seed: u64) -> f64 {
    let h = mix64(seed ^ mix64((i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ (j as u64)));
    (h >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// SplitMix64 (Steele, Lea & Flood 2014): tiny, fast and good enough for textures and noise.
#[derive(Clone, Debug)]
pub struct SplitMix64 {
    state: u64,
}

impl SplitMix64 {
    pub fn new(seed: u64) -> Self {
        SplitMix64 { state: seed }
    }

    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        mix64(self.state)
    }

    /// Uniform in `[0, 1)`.
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Standard normal (Box–Muller).
    pub fn gaussian(&mut self) -> f64 {
        let u1 = 1.0 - self.next_f64(); // (0, 1]
        let u2 = self.next_f64();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

#[cfg(test)]
mod tests;
