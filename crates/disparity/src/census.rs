//! Census transform: each pixel becomes a bit string saying which neighbours in its window are
//! darker than it. Matching costs are then Hamming distances, which are robust to gain and bias
//! differences between the two cameras.

use rayon::prelude::*;

use crate::kernels::layout::{Samples, Window};
use crate::kernels::{census_row, CensusKernel};
use crate::{CensusWindow, GrayImage, Image};

/// Census transform with a dense `window` (at most 64 comparisons, so one `u64` per pixel).
/// Bit order: window positions row by row, skipping the centre; a bit is 1 when that
/// neighbour is darker than the centre. Outside the image the nearest border pixel is used.
pub(crate) fn census_transform(image: &GrayImage, window: CensusWindow, out: &mut Image<u64>) {
    census_transform_tolerant(image, window, 0, out)
}

/// [`census_transform`] where a neighbour counts as darker only when it is darker than the centre
/// by more than `tolerance` (in samples, 257 per 8-bit grey level): on smoothed noisy views,
/// differences this small are mostly what remains of the noise, and in flat areas they would
/// give the two views unrelated bit strings (docs/robustness.md).
pub(crate) fn census_transform_tolerant(
    image: &GrayImage,
    window: CensusWindow,
    tolerance: u16,
    out: &mut Image<u64>,
) {
    let kernel = CensusKernel::for_level(crate::kernels::features().level);
    census_transform_with(image, window, tolerance, out, kernel)
}

fn census_transform_with(
    image: &GrayImage,
    window: CensusWindow,
    tolerance: u16,
    out: &mut Image<u64>,
    kernel: CensusKernel,
) {
    let (width, height) = image.size();
    debug_assert_eq!(out.size(), (width, height));
    if width == 0 || height == 0 {
        return;
    }
    let kernel = match kernel.on_bytes() {
        Some((bytes, min_width))
            if width >= min_width && tolerance.is_multiple_of(257) && is_byte_scaled(image) =>
        {
            bytes
        }
        _ => kernel,
    };
    let on_bytes = kernel.reads_high_bytes();
    let samples = Samples { samples: image.as_slice(), width, height };
    let shape = Window { width: window.width, height: window.height, tolerance };
    let rows_per_task = height.div_ceil(16).max(1);
    out.as_mut_slice().par_chunks_mut(width * rows_per_task).enumerate().for_each(|(task, rows)| {
        // Each window row, extended by the border pixels, so the inner loops need no clamping.
        let len = window.height * (width + window.width - 1);
        // Only the buffer the kernel pads into.
        let mut padded = vec![0u16; if on_bytes { 0 } else { len }];
        let mut high_bytes = vec![0u8; if on_bytes { len } else { 0 }];
        for (i, bits) in rows.chunks_mut(width).enumerate() {
            census_row(kernel, samples, shape, task * rows_per_task + i, &mut padded, &mut high_bytes, bits);
        }
    });
}

/// Whether every sample is a multiple of 257, as in 8-bit images scaled to 16 bits (`b · 257`
/// has both bytes `b`): then the high bytes compare exactly as the samples do, and a 512-bit
/// comparison covers 64 pixels instead of 32 (and a downsampled view can stay byte-scaled).
pub(crate) fn is_byte_scaled(image: &GrayImage) -> bool {
    image.as_slice().chunks(4096).all(|c| c.iter().fold(true, |ok, &v| ok & (v >> 8 == v & 0xff)))
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    /// Every kernel this machine can run.
    fn kernels() -> Vec<CensusKernel> {
        // Only x86 adds a kernel below.
        #[cfg_attr(not(target_arch = "x86_64"), allow(unused_mut))]
        let mut kernels: Vec<CensusKernel> =
            crate::kernels::supported_levels().into_iter().map(CensusKernel::for_level).collect();
        #[cfg(target_arch = "x86_64")]
        if kernels.contains(&CensusKernel::Gfni) {
            kernels.push(CensusKernel::Avx512);
        }
        kernels
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]

        #[test]
        fn every_kernel_matches_the_reference(width in 1usize..300, height in 1usize..20, window in 0usize..9,
                                              levels in 1u32..=65535, scale in 0u8..3, seed in any::<u64>(),
                                              tolerance in prop_oneof![Just(0u16), Just(257), Just(514), any::<u16>()]) {
            let (ww, wh) = [(3, 3), (5, 5), (9, 7), (7, 9), (13, 5), (5, 13), (1, 3), (3, 1), (9, 3)][window];
            // Windows wider or taller than the image are not used by the matcher (as in the
            // fixed-size test below).
            prop_assume!(width >= ww && height >= wh);
            // Few distinct levels make many ties; `scale` 1 spreads them over the whole u16 range.
            let mut s = seed | 1;
            let img = GrayImage::from_fn(width, height, |_, _| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                let v = (s % u64::from(levels)) as u16;
                match scale {
                    0 => v,
                    1 => v.wrapping_mul(40_503),
                    // 8-bit images as loaded (`b · 257`), which the byte kernel takes.
                    _ => (v % 256) * 257,
                }
            });
            let window = CensusWindow { width: ww, height: wh };
            let mut reference = Image::new(width, height, 0u64);
            crate::reference::census_transform(&img, window, tolerance, &mut reference);
            for kernel in kernels() {
                let mut out = Image::new(width, height, 0x5555u64);
                census_transform_with(&img, window, tolerance, &mut out, kernel);
                prop_assert!(out == reference, "{:?}, {}x{} window {}x{} tolerance {}", kernel, width, height, ww, wh, tolerance);
            }
        }
    }

    #[test]
    fn census_marks_darker_neighbours() {
        // 3x3 window around the centre of a 3x3 image: bits in row order, centre skipped.
        let img = GrayImage::from_vec(3, 3, vec![1, 9, 1, 9, 5, 9, 1, 9, 1]).unwrap();
        let mut out = Image::new(3, 3, 0u64);
        census_transform(&img, CensusWindow { width: 3, height: 3 }, &mut out);
        assert_eq!(out.get(1, 1), 0b1010_0101);
    }

    #[test]
    fn the_tolerance_ignores_small_differences() {
        // Neighbours 1, 2 and 3 samples darker than the centre (and one brighter).
        let img = GrayImage::from_vec(5, 1, vec![9, 8, 10, 7, 6]).unwrap();
        let window = CensusWindow { width: 5, height: 1 };
        let bits = |tolerance| {
            let mut out = Image::new(5, 1, 0u64);
            census_transform_tolerant(&img, window, tolerance, &mut out);
            out.get(2, 0)
        };
        // Bits in window order 9, 8, 7, 6 (centre 10 skipped).
        assert_eq!(bits(0), 0b1111);
        assert_eq!(bits(1), 0b0111);
        assert_eq!(bits(2), 0b0011);
        assert_eq!(bits(3), 0b0001);
        assert_eq!(bits(4), 0);
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
                crate::reference::census_transform(&img, window, 0, &mut b);
                assert_eq!(a, b, "{w}x{h} window {ww}x{wh}");
            }
        }
    }
}
