//! Borrowed, strided views over a caller's pixels: a numpy array, a camera frame, a crop of a
//! larger image. Nothing is copied until a stage needs a buffer of its own.

use crate::{Error, Image};

/// A read-only view of `width × height` pixels of `T` in a caller's buffer, row `y` starting at
/// sample `y * stride` (so `stride >= width`; a crop or a padded camera row has `stride > width`).
///
/// `T` is one pixel: `u8`/`u16` grey, `[u8; 3]`/`[u16; 3]` RGB, `[u8; 4]`/`[u16; 4]` RGBA.
/// Interleaved colour buffers (`&[u8]` of `3 * width` samples per row) become pixel views with
/// [`ImageRef::from_interleaved`], without copying.
#[derive(Clone, Copy, Debug)]
pub struct ImageRef<'a, T> {
    data: &'a [T],
    width: usize,
    height: usize,
    stride: usize,
}

impl<'a, T: Copy> ImageRef<'a, T> {
    /// A view of a contiguous row-major buffer of exactly `width * height` pixels.
    pub fn new(data: &'a [T], width: usize, height: usize) -> Result<Self, Error> {
        if width.checked_mul(height) != Some(data.len()) {
            return Err(Error::BufferSize { width, height, len: data.len() });
        }
        Ok(Self::from_parts(data, width, height, width))
    }

    /// A view whose rows start `stride` pixels apart; the buffer must reach the last pixel of the
    /// last row (`stride * (height - 1) + width` pixels), and may be longer.
    pub fn with_stride(data: &'a [T], width: usize, height: usize, stride: usize) -> Result<Self, Error> {
        if stride < width {
            return Err(Error::Stride { width, stride });
        }
        let needed = match height {
            0 => Some(0),
            h => stride.checked_mul(h - 1).and_then(|n| n.checked_add(width)),
        };
        match needed {
            Some(needed) if needed <= data.len() => Ok(Self::from_parts(data, width, height, stride)),
            _ => Err(Error::StridedBufferSize { width, height, stride, len: data.len() }),
        }
    }

    pub(crate) fn from_parts(data: &'a [T], width: usize, height: usize, stride: usize) -> Self {
        ImageRef { data, width, height, stride }
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

    /// Pixels from the start of one row to the start of the next.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// The pixel at column `x`, row `y`. Panics when out of bounds, like slice indexing.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> T {
        assert!(x < self.width, "column {x} outside a {}-pixel-wide view", self.width);
        self.data[y * self.stride + x]
    }

    /// Row `y` as a slice of `width` pixels, borrowed from the caller's buffer.
    #[inline]
    pub fn row(&self, y: usize) -> &'a [T] {
        let start = y * self.stride;
        &self.data[start..start + self.width]
    }

    /// The view's pixels in one contiguous slice, when its rows are back to back.
    pub fn as_contiguous_slice(&self) -> Option<&'a [T]> {
        (self.stride == self.width || self.height <= 1).then(|| &self.data[..self.width * self.height])
    }

    /// An owned copy of the viewed pixels.
    pub fn to_image(&self) -> Image<T> {
        let mut data = Vec::with_capacity(self.width * self.height);
        for y in 0..self.height {
            data.extend_from_slice(self.row(y));
        }
        Image::from_vec(self.width, self.height, data).expect("one row of width pixels per row")
    }

    /// The image whose pixel `(x, y)` is `f` of this view's pixel `(x, y)`.
    pub fn map<U: Copy>(&self, f: impl Fn(T) -> U) -> Image<U> {
        let mut data = Vec::with_capacity(self.width * self.height);
        for y in 0..self.height {
            data.extend(self.row(y).iter().map(|&p| f(p)));
        }
        Image::from_vec(self.width, self.height, data).expect("one row of width pixels per row")
    }
}

impl<'a, S: bytemuck::Pod, const N: usize> ImageRef<'a, [S; N]> {
    /// A view of an interleaved buffer of `N` samples per pixel (RGB: `N = 3`), `stride`
    /// samples per row (`N * width` for a contiguous buffer), as pixels, without copying.
    pub fn from_interleaved(
        data: &'a [S],
        width: usize,
        height: usize,
        stride: usize,
    ) -> Result<Self, Error> {
        if stride % N != 0 {
            return Err(Error::Interleave { channels: N, stride });
        }
        let whole = data.len() - data.len() % N;
        let pixels: &'a [[S; N]] = bytemuck::cast_slice(&data[..whole]);
        Self::with_stride(pixels, width, height, stride / N)
    }
}

impl<'a, T: Copy> From<&'a Image<T>> for ImageRef<'a, T> {
    fn from(image: &'a Image<T>) -> Self {
        image.view()
    }
}
