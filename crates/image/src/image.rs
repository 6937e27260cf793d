//! Plain row-major image buffers shared by every stage of the pipeline.

use crate::Error;
use crate::ImageRef;

/// A row-major image of `width × height` samples of `T`.
///
/// The working grey image is [`GrayImage`] (16 bits, so 16-bit PNGs keep their precision) and a
/// disparity map is [`DisparityMap`] (f32 pixels, NaN where no disparity is known).
#[derive(Clone, Debug, PartialEq)]
pub struct Image<T> {
    width: usize,
    height: usize,
    data: Vec<T>,
}

/// The working grey image every matcher takes: 8-bit inputs are scaled by 257 to use the full range.
pub type GrayImage = Image<u16>;

/// A disparity map of the left view: left pixel `(x, y)` matches right pixel `(x - d, y)`;
/// NaN marks pixels without a valid disparity.
pub type DisparityMap = Image<f32>;

impl<T: Copy> Image<T> {
    /// An image filled with `value`.
    pub fn new(width: usize, height: usize, value: T) -> Self {
        Image { width, height, data: vec![value; width * height] }
    }

    /// Wraps a row-major buffer; fails when its length is not `width * height`.
    pub fn from_vec(width: usize, height: usize, data: Vec<T>) -> Result<Self, Error> {
        if width.checked_mul(height) != Some(data.len()) {
            return Err(Error::BufferSize { width, height, len: data.len() });
        }
        Ok(Image { width, height, data })
    }

    /// An image whose pixel `(x, y)` is `f(x, y)`.
    pub fn from_fn(width: usize, height: usize, mut f: impl FnMut(usize, usize) -> T) -> Self {
        let mut data = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                data.push(f(x, y));
            }
        }
        Image { width, height, data }
    }

    pub fn width(&self) -> usize {
        self.width
    }

    pub fn height(&self) -> usize {
        self.height
    }

    /// `(width, height)`.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// The pixel at column `x`, row `y`. Panics when out of bounds, like slice indexing.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> T {
        self.data[y * self.width + x]
    }

    #[inline]
    pub fn set(&mut self, x: usize, y: usize, value: T) {
        self.data[y * self.width + x] = value;
    }

    /// Row `y` as a slice of `width` samples.
    #[inline]
    pub fn row(&self, y: usize) -> &[T] {
        &self.data[y * self.width..(y + 1) * self.width]
    }

    #[inline]
    pub fn row_mut(&mut self, y: usize) -> &mut [T] {
        &mut self.data[y * self.width..(y + 1) * self.width]
    }

    /// All samples, row after row.
    pub fn as_slice(&self) -> &[T] {
        &self.data
    }

    pub fn as_mut_slice(&mut self) -> &mut [T] {
        &mut self.data
    }

    pub fn into_vec(self) -> Vec<T> {
        self.data
    }

    /// A borrowed view of the whole image.
    pub fn view(&self) -> ImageRef<'_, T> {
        ImageRef::from_parts(&self.data, self.width, self.height, self.width)
    }
}
