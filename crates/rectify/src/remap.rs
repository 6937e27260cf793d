//! Bilinear remapping through a [`RectifyMap`], in parallel over rows.
//!
//! Like OpenCV's `remap(INTER_LINEAR, BORDER_CONSTANT)`: sample positions are rounded to 1/32 px
//! and interpolated with integer weights; neighbours outside the source image count as 0.

use rayon::prelude::*;
use stereo_image::Image;

/// Sub-pixel steps per pixel (OpenCV's `INTER_TAB_SIZE`).
const TAB: i32 = 32;
const TAB_BITS: u32 = 5;

/// For every destination pixel, the source position to sample (`x`, `y` in px; OpenCV's
/// `CV_32FC1` map pair).
#[derive(Clone, PartialEq)]
pub struct RectifyMap {
    width: usize,
    height: usize,
    x: Vec<f32>,
    y: Vec<f32>,
}

/// The size only: a map holds millions of positions.
impl std::fmt::Debug for RectifyMap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "RectifyMap({}x{})", self.width, self.height)
    }
}

impl RectifyMap {
    /// # Panics
    /// When the vectors do not hold `width × height` values.
    pub fn new(width: usize, height: usize, x: Vec<f32>, y: Vec<f32>) -> Self {
        assert_eq!(x.len(), width * height);
        assert_eq!(y.len(), width * height);
        RectifyMap { width, height, x, y }
    }

    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The source x positions, row-major.
    pub fn x(&self) -> &[f32] {
        &self.x
    }

    /// The source y positions, row-major.
    pub fn y(&self) -> &[f32] {
        &self.y
    }

    /// The map as two images (x, y), e.g. to write them as PFM.
    pub fn to_images(&self) -> (Image<f32>, Image<f32>) {
        let x = Image::from_vec(self.width, self.height, self.x.clone()).expect("sizes match");
        let y = Image::from_vec(self.width, self.height, self.y.clone()).expect("sizes match");
        (x, y)
    }

    /// Resamples `src` through the map: the result has the map's size.
    pub fn remap<P: Sample>(&self, src: &Image<P>) -> Image<P> {
        let (sw, sh) = src.size();
        let mut out = vec![P::default(); self.width * self.height];
        let w = self.width.max(1);
        let data = src.as_slice();
        out.par_chunks_mut(w).enumerate().for_each(|(row, out_row)| {
            let mx = &self.x[row * w..row * w + out_row.len()];
            let my = &self.y[row * w..row * w + out_row.len()];
            for ((o, &fx), &fy) in out_row.iter_mut().zip(mx).zip(my) {
                *o = sample(data, sw, sh, fx, fy);
            }
        });
        Image::from_vec(self.width, self.height, out).expect("sizes match")
    }
}

#[inline]
fn sample<P: Sample>(data: &[P], w: usize, h: usize, fx: f32, fy: f32) -> P {
    // Out-of-range or NaN positions: nothing to sample (saturating casts keep this safe).
    let ix = (fx * TAB as f32).round_ties_even() as i32;
    let iy = (fy * TAB as f32).round_ties_even() as i32;
    let (x0, y0) = (ix >> TAB_BITS, iy >> TAB_BITS);
    let (ax, ay) = ((ix & (TAB - 1)) as u32, (iy & (TAB - 1)) as u32);
    let t = TAB as u32;
    let weights = [(t - ax) * (t - ay), ax * (t - ay), (t - ax) * ay, ax * ay];
    let (wi, hi) = (w as i32, h as i32);
    if x0 >= 0 && y0 >= 0 && x0 + 1 < wi && y0 + 1 < hi {
        let i = y0 as usize * w + x0 as usize;
        return P::blend([data[i], data[i + 1], data[i + w], data[i + w + 1]], weights);
    }
    if x0 + 1 < 0 || y0 + 1 < 0 || x0 >= wi || y0 >= hi {
        return P::default();
    }
    let at = |x: i32, y: i32| {
        if x >= 0 && y >= 0 && x < wi && y < hi {
            data[y as usize * w + x as usize]
        } else {
            P::default()
        }
    };
    P::blend([at(x0, y0), at(x0 + 1, y0), at(x0, y0 + 1), at(x0 + 1, y0 + 1)], weights)
}

/// A pixel type [`RectifyMap::remap`] can interpolate.
pub trait Sample: Copy + Default + Send + Sync {
    /// The weighted mean of four pixels; the weights sum to 1024.
    fn blend(p: [Self; 4], w: [u32; 4]) -> Self;
}

impl Sample for u8 {
    #[inline]
    fn blend(p: [u8; 4], w: [u32; 4]) -> u8 {
        ((p[0] as u32 * w[0] + p[1] as u32 * w[1] + p[2] as u32 * w[2] + p[3] as u32 * w[3] + 512) >> 10)
            as u8
    }
}

impl Sample for u16 {
    #[inline]
    fn blend(p: [u16; 4], w: [u32; 4]) -> u16 {
        ((p[0] as u32 * w[0] + p[1] as u32 * w[1] + p[2] as u32 * w[2] + p[3] as u32 * w[3] + 512) >> 10)
            as u16
    }
}

impl Sample for [u8; 3] {
    #[inline]
    fn blend(p: [[u8; 3]; 4], w: [u32; 4]) -> [u8; 3] {
        std::array::from_fn(|c| u8::blend([p[0][c], p[1][c], p[2][c], p[3][c]], w))
    }
}

impl Sample for f32 {
    #[inline]
    fn blend(p: [f32; 4], w: [u32; 4]) -> f32 {
        (p[0] * w[0] as f32 + p[1] * w[1] as f32 + p[2] * w[2] as f32 + p[3] * w[3] as f32) / 1024.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn identity_and_shift() {
        let src = Image::from_fn(5, 4, |x, y| (x * 10 + y * 100) as u16);
        let (w, h) = src.size();
        let ident = RectifyMap::new(
            w,
            h,
            (0..w * h).map(|i| (i % w) as f32).collect(),
            (0..w * h).map(|i| (i / w) as f32).collect(),
        );
        assert_eq!(ident.remap(&src), src);
        let half = RectifyMap::new(1, 1, vec![1.5], vec![2.0]);
        assert_eq!(half.remap(&src).get(0, 0), 215);
        // Beyond the border: zero; half outside: blended with zero.
        let out = RectifyMap::new(2, 1, vec![-3.0, 4.5], vec![0.0, 0.0]);
        let r = out.remap(&src);
        assert_eq!((r.get(0, 0), r.get(1, 0)), (0, 20));
    }
}
