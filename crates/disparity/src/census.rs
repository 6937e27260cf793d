//! Census transform: each pixel becomes a bit string saying which neighbours in its window are
//! darker than it. Matching costs are then Hamming distances, which are robust to gain and bias
//! differences between the two cameras.

use rayon::prelude::*;

use crate::{CensusWindow, GrayImage, Image};

/// Census transform with a dense `window` (at most 64 comparisons, so one `u64` per pixel).
/// Bit order: window positions row by row, skipping the centre; a bit is 1 when that
/// neighbour is darker than the centre. Outside the image the nearest border pixel is used.
pub(crate) fn census_transform(image: &GrayImage, window: CensusWindow, out: &mut Image<u64>) {
    let (width, height) = image.size();
    debug_assert_eq!(out.size(), (width, height));
    if width == 0 || height == 0 {
        return;
    }
    let rows_per_task = height.div_ceil(16).max(1);
    out.as_mut_slice().par_chunks_mut(width * rows_per_task).enumerate().for_each(|(task, rows)| {
        // Each window row, extended by the border pixels, so the inner loops need no clamping.
        let mut padded = vec![0u16; window.height * (width + window.width - 1)];
        for (i, bits) in rows.chunks_mut(width).enumerate() {
            census_row(image, window, task * rows_per_task + i, &mut padded, bits);
        }
    });
}

fn census_row(image: &GrayImage, window: CensusWindow, y: usize, padded: &mut [u16], bits: &mut [u64]) {
    #[cfg(target_arch = "x86_64")]
    {
        use crate::simd::{features, Level};
        match features().level {
            // SAFETY: the level was detected on this CPU.
            Level::Avx512 => return unsafe { census_row_avx512(image, window, y, padded, bits) },
            // SAFETY: as above.
            Level::Avx2 => return unsafe { census_row_avx2(image, window, y, padded, bits) },
            Level::Scalar => {}
        }
    }
    census_row_generic(image, window, y, padded, bits)
}

/// [`census_row_generic`] compiled for AVX-512 (auto-vectorised over pixels).
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2")]
unsafe fn census_row_avx512(
    image: &GrayImage,
    window: CensusWindow,
    y: usize,
    padded: &mut [u16],
    bits: &mut [u64],
) {
    census_row_generic(image, window, y, padded, bits)
}

/// [`census_row_generic`] compiled for AVX2 (auto-vectorised over pixels).
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn census_row_avx2(
    image: &GrayImage,
    window: CensusWindow,
    y: usize,
    padded: &mut [u16],
    bits: &mut [u64],
) {
    census_row_generic(image, window, y, padded, bits)
}

/// One row of the transform: one pass over the row per window position, so the comparisons of
/// many pixels run side by side.
#[inline(always)]
fn census_row_generic(
    image: &GrayImage,
    window: CensusWindow,
    y: usize,
    padded: &mut [u16],
    bits: &mut [u64],
) {
    let (width, height) = image.size();
    let (rx, ry) = (window.width / 2, window.height / 2);
    let pw = width + 2 * rx;
    for (dy, p) in padded.chunks_exact_mut(pw).enumerate() {
        let src = image.row((y + dy).saturating_sub(ry).min(height - 1));
        p[..rx].fill(src[0]);
        p[rx..rx + width].copy_from_slice(src);
        p[rx + width..].fill(src[width - 1]);
    }
    let centre = image.row(y);
    bits.fill(0);
    for (dy, p) in padded.chunks_exact(pw).enumerate() {
        for dx in 0..window.width {
            if dx == rx && dy == ry {
                continue;
            }
            let neighbours = &p[dx..dx + width];
            for ((b, &n), &c) in bits.iter_mut().zip(neighbours).zip(centre) {
                *b = (*b << 1) | u64::from(n < c);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn census_marks_darker_neighbours() {
        // 3x3 window around the centre of a 3x3 image: bits in row order, centre skipped.
        let img = GrayImage::from_vec(3, 3, vec![1, 9, 1, 9, 5, 9, 1, 9, 1]).unwrap();
        let mut out = Image::new(3, 3, 0u64);
        census_transform(&img, CensusWindow { width: 3, height: 3 }, &mut out);
        assert_eq!(out.get(1, 1), 0b1010_0101);
    }

    #[test]
    fn census_is_invariant_to_gain_and_bias() {
        let img = GrayImage::from_fn(20, 10, |x, y| ((x * 37 + y * 101) % 200) as u16);
        let brighter = GrayImage::from_fn(20, 10, |x, y| img.get(x, y) * 3 + 500);
        let window = CensusWindow { width: 9, height: 7 };
        let (mut a, mut b) = (Image::new(20, 10, 0u64), Image::new(20, 10, 0u64));
        census_transform(&img, window, &mut a);
        census_transform(&brighter, window, &mut b);
        assert_eq!(a, b);
    }

    #[test]
    fn census_matches_the_reference_on_random_images() {
        let mut s = 0x2545_f491_4f6c_dd1du64;
        for (w, h) in [(3, 3), (9, 7), (10, 20), (50, 9), (77, 33)] {
            for (ww, wh) in [(3, 3), (5, 5), (9, 7), (7, 9), (13, 5)] {
                if w < ww || h < wh {
                    continue;
                }
                let img = GrayImage::from_fn(w, h, |_, _| {
                    s ^= s << 13;
                    s ^= s >> 7;
                    s ^= s << 17;
                    (s % 7) as u16 * 9000
                });
                let window = CensusWindow { width: ww, height: wh };
                let (mut a, mut b) = (Image::new(w, h, 0u64), Image::new(w, h, 0u64));
                census_transform(&img, window, &mut a);
                crate::reference::census_transform(&img, window, &mut b);
                assert_eq!(a, b, "{w}x{h} window {ww}x{wh}");
            }
        }
    }
}
