//! Census transform: each pixel becomes a bit string saying which neighbours in its window are
//! darker than it. Matching costs are then Hamming distances, which are robust to gain and bias
//! differences between the two cameras.

use rayon::prelude::*;

use crate::{CensusWindow, GrayImage, Image};

/// Census transform with a dense `window` (at most 64 comparisons, so one `u64` per pixel).
/// Bit order: window positions row by row, skipping the centre; a bit is 1 when that
/// neighbour is darker than the centre. Outside the image the nearest border pixel is used.
pub(crate) fn census_transform(image: &GrayImage, window: CensusWindow, out: &mut Image<u64>) {
    census_transform_with(image, window, out, Kernel::for_level(crate::kernels::features().level))
}

/// The row kernels; chosen once per transform (tests run each one the machine supports).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kernel {
    Generic,
    #[cfg(target_arch = "x86_64")]
    Avx2,
    #[cfg(target_arch = "x86_64")]
    Avx512,
    #[cfg(target_arch = "x86_64")]
    Gfni,
    /// [`Kernel::Gfni`] on the high bytes, for 8-bit images (see [`is_byte_scaled`]).
    #[cfg(target_arch = "x86_64")]
    GfniBytes,
}

impl Kernel {
    /// The fastest kernel for `level`: the bit-matrix transpose needs AVX-512VBMI and GFNI on
    /// top of the AVX-512 level (Intel Ice Lake, AMD Zen 4 and later), older AVX-512 CPUs keep the plain kernel.
    fn for_level(level: crate::kernels::Level) -> Kernel {
        #[cfg(target_arch = "x86_64")]
        {
            use crate::kernels::Level;
            match level {
                Level::Avx512 if crate::kernels::Features::capped(level).gfni => return Kernel::Gfni,
                Level::Avx512 => return Kernel::Avx512,
                Level::Avx2 => return Kernel::Avx2,
                Level::Scalar => {}
            }
        }
        let _ = level;
        Kernel::Generic
    }
}

fn census_transform_with(image: &GrayImage, window: CensusWindow, out: &mut Image<u64>, kernel: Kernel) {
    let (width, height) = image.size();
    debug_assert_eq!(out.size(), (width, height));
    if width == 0 || height == 0 {
        return;
    }
    #[cfg(target_arch = "x86_64")]
    let kernel = match kernel {
        Kernel::Gfni if is_byte_scaled(image) => Kernel::GfniBytes,
        k => k,
    };
    let rows_per_task = height.div_ceil(16).max(1);
    out.as_mut_slice().par_chunks_mut(width * rows_per_task).enumerate().for_each(|(task, rows)| {
        // Each window row, extended by the border pixels, so the inner loops need no clamping.
        let len = window.height * (width + window.width - 1);
        let mut padded = vec![0u16; len];
        #[cfg(target_arch = "x86_64")]
        let mut high_bytes = if kernel == Kernel::GfniBytes { vec![0u8; len] } else { Vec::new() };
        #[cfg(not(target_arch = "x86_64"))]
        let mut high_bytes = Vec::new();
        for (i, bits) in rows.chunks_mut(width).enumerate() {
            census_row(kernel, image, window, task * rows_per_task + i, &mut padded, &mut high_bytes, bits);
        }
    });
}

/// Whether every sample is a multiple of 257, as in 8-bit images scaled to 16 bits (`b · 257`
/// has both bytes `b`): then the high bytes compare exactly as the samples do, and a 512-bit
/// comparison covers 64 pixels instead of 32 (and a downsampled view can stay byte-scaled).
pub(crate) fn is_byte_scaled(image: &GrayImage) -> bool {
    image.as_slice().chunks(4096).all(|c| c.iter().fold(true, |ok, &v| ok & (v >> 8 == v & 0xff)))
}

fn census_row(
    kernel: Kernel,
    image: &GrayImage,
    window: CensusWindow,
    y: usize,
    padded: &mut [u16],
    #[allow(unused_variables)] high_bytes: &mut [u8],
    bits: &mut [u64],
) {
    match kernel {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Kernel::Gfni` is only chosen when the CPU has AVX-512F/BW/VL/VBMI and GFNI.
        Kernel::Gfni => unsafe { census_row_gfni(image, window, y, padded, bits) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Kernel::GfniBytes` is only made from `Kernel::Gfni` (so the CPU has what it
        // needs) and then `high_bytes` is as long as `padded`; the image is at least 64 wide.
        Kernel::GfniBytes if image.width() >= 64 => unsafe {
            census_row_gfni_bytes(image, window, y, high_bytes, bits)
        },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above (only the CPU features matter here).
        Kernel::GfniBytes => unsafe { census_row_gfni(image, window, y, padded, bits) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Kernel::Avx512` is only chosen at the AVX-512 level, detected on this CPU.
        Kernel::Avx512 => unsafe { census_row_avx512(image, window, y, padded, bits) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `Kernel::Avx2` is only chosen at the AVX2 level, detected on this CPU.
        Kernel::Avx2 => unsafe { census_row_avx2(image, window, y, padded, bits) },
        Kernel::Generic => census_row_generic(image, window, y, padded, bits),
    }
}

/// 64 masks of 64 bits, the rows of the bit matrix [`census_row_gfni`] transposes; aligned so
/// each group of 8 rows is one aligned 512-bit load.
#[cfg(target_arch = "x86_64")]
#[repr(C, align(64))]
struct BitRows([u64; 64]);

#[cfg(target_arch = "x86_64")]
impl BitRows {
    /// The rows as 32-bit halves, low half first, for masks made of two 32-lane comparisons.
    fn halves_mut(&mut self) -> &mut [u32; 128] {
        // SAFETY: 64 `u64` are 128 `u32` (whose alignment is smaller); x86-64 is little-endian,
        // so half `2i` is the low half of row `i`.
        unsafe { &mut *self.0.as_mut_ptr().cast::<[u32; 128]>() }
    }

    /// Transposes the matrix (see [`transpose_64x64`]) into the 64 census values `out`.
    #[inline]
    #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vbmi,gfni")]
    fn store_transposed(&self, out: &mut [u64]) {
        use std::arch::x86_64::*;
        assert_eq!(out.len(), 64);
        // SAFETY: the matrix is 512 bytes, aligned to 64.
        let rows: [__m512i; 8] =
            std::array::from_fn(|k| unsafe { _mm512_load_si512(self.0.as_ptr().add(8 * k).cast()) });
        for (k, v) in transpose_64x64(rows).into_iter().enumerate() {
            // SAFETY: `8k + 8 <= 64 = out.len()`.
            unsafe { _mm512_storeu_si512(out.as_mut_ptr().add(8 * k).cast(), v) };
        }
    }
}

/// `vpermb` indices that transpose the 8x8 bytes of a 512-bit register (byte `8i + j` takes
/// byte `8j + i`), reversing the byte order within each qword when `reverse` is set (byte
/// `8i + 7 - j` takes byte `8j + i`).
#[cfg(target_arch = "x86_64")]
const fn byte_transpose(reverse: bool) -> [u8; 64] {
    let mut idx = [0u8; 64];
    let mut i = 0;
    while i < 8 {
        let mut j = 0;
        while j < 8 {
            let to = if reverse { 8 * i + 7 - j } else { 8 * i + j };
            idx[to] = (8 * j + i) as u8;
            j += 1;
        }
        i += 1;
    }
    idx
}

#[cfg(target_arch = "x86_64")]
static GATHER_BLOCKS: [u8; 64] = byte_transpose(true);
#[cfg(target_arch = "x86_64")]
static SPREAD_BYTES: [u8; 64] = byte_transpose(false);

/// Transposes the 64x64 bit matrix whose row `8k + q` is qword `q` of `rows[k]`: afterwards
/// bit `i` of row `p` is bit `p` of the old row `i`. The 8x8 bit blocks are transposed by one
/// GF(2) affine transform each, so the whole matrix takes 48 shuffle-class instructions.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vbmi,gfni")]
fn transpose_64x64(rows: [std::arch::x86_64::__m512i; 8]) -> [std::arch::x86_64::__m512i; 8] {
    use std::arch::x86_64::*;
    // SAFETY: both tables are 64 bytes.
    let (gather, spread) = unsafe {
        (_mm512_loadu_si512(GATHER_BLOCKS.as_ptr().cast()), _mm512_loadu_si512(SPREAD_BYTES.as_ptr().cast()))
    };
    // Byte `c` of the constant is `1 << c`: as the "vector" operand of the affine transform,
    // byte `c` of each result qword gets bit `c` of each byte of the matrix operand, the bytes
    // taken last to first (bit `i` from byte `7 - i`).
    let unit = _mm512_set1_epi64(0x8040_2010_0804_0201u64 as i64);
    // 1. Qword `J` of register `I` := bytes `J` of rows `8I + 7 ..= 8I` (the 8x8 bit block
    //    (I, J), rows last to first). 2. Transpose each block: byte `c` bit `i` of that qword is
    //    now bit `8J + c` of row `8I + i`.
    let t = rows.map(|r| _mm512_gf2p8affine_epi64_epi8::<0>(unit, _mm512_permutexvar_epi8(gather, r)));
    // 3. Transpose the 8x8 qwords across the registers: qword `I` of register `J` := qword `J`
    //    of register `I`.
    let lo = |a, b| _mm512_unpacklo_epi64(a, b);
    let hi = |a, b| _mm512_unpackhi_epi64(a, b);
    let (a0, a1, a2, a3) = (lo(t[0], t[1]), hi(t[0], t[1]), lo(t[2], t[3]), hi(t[2], t[3]));
    let (a4, a5, a6, a7) = (lo(t[4], t[5]), hi(t[4], t[5]), lo(t[6], t[7]), hi(t[6], t[7]));
    let even = |a, b| _mm512_shuffle_i64x2::<0b10_00_10_00>(a, b);
    let odd = |a, b| _mm512_shuffle_i64x2::<0b11_01_11_01>(a, b);
    let (b0, b1, b2, b3) = (even(a0, a2), odd(a0, a2), even(a1, a3), odd(a1, a3));
    let (b4, b5, b6, b7) = (even(a4, a6), odd(a4, a6), even(a5, a7), odd(a5, a7));
    let q = [
        even(b0, b4),
        even(b2, b6),
        even(b1, b5),
        even(b3, b7),
        odd(b0, b4),
        odd(b2, b6),
        odd(b1, b5),
        odd(b3, b7),
    ];
    // 4. Byte `c` of qword `I` to byte `I` of qword `c`: register `J` qword `c` is row
    //    `8J + c` of the transpose.
    q.map(|v| _mm512_permutexvar_epi8(spread, v))
}

/// The census of one row, 64 pixels at a time: for each window position one comparison of 64
/// neighbours with their centres gives a 64-bit mask (bit `p`: pixel `p` has that census
/// bit); the masks are the rows of a 64x64 bit matrix whose transpose holds the pixels' census
/// values. About 7 instructions per pixel (mostly the comparisons and mask stores, 2 + 2 per
/// window position and 64 pixels) where [`census_row_generic`] needs about 30.
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL/VBMI and GFNI.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vbmi,gfni,avx2")]
unsafe fn census_row_gfni(
    image: &GrayImage,
    window: CensusWindow,
    y: usize,
    padded: &mut [u16],
    bits: &mut [u64],
) {
    use std::arch::x86_64::*;
    let width = image.size().0;
    if width < 64 {
        // Too narrow for one block.
        return census_row_generic(image, window, y, padded, bits);
    }
    pad_window_rows(image, window, y, padded);
    let rx = window.width / 2;
    let pw = width + 2 * rx;
    let n = window.width * window.height - 1;
    assert!(n <= 64 && padded.len() == window.height * pw && bits.len() == width);
    let centre = image.row(y);
    let offsets = neighbour_offsets(window, pw);
    // Rows `n..64` of the matrix stay zero.
    let mut matrix = BitRows([0; 64]);
    let mut x0 = 0;
    loop {
        // The last block overlaps the one before it when the width is not a multiple of 64.
        let x = x0.min(width - 64);
        // SAFETY: `x + 64 <= width`: the centre reads are inside the row.
        let (c_lo, c_hi) = unsafe {
            (
                _mm512_loadu_si512(centre.as_ptr().add(x).cast()),
                _mm512_loadu_si512(centre.as_ptr().add(x + 32).cast()),
            )
        };
        for (m, &o) in matrix.halves_mut().chunks_exact_mut(2).zip(&offsets[..n]) {
            // SAFETY: `o = dy * pw + dx` with `dy < window.height` and `dx < window.width`, so
            // `o + x + 64 <= dy * pw + (2 * rx + width) = (dy + 1) * pw <= padded.len()`.
            let (lo, hi) = unsafe {
                let src = padded.as_ptr().add(o + x);
                (_mm512_loadu_si512(src.cast()), _mm512_loadu_si512(src.add(32).cast()))
            };
            m[0] = _mm512_cmplt_epu16_mask(lo, c_lo);
            m[1] = _mm512_cmplt_epu16_mask(hi, c_hi);
        }
        matrix.store_transposed(&mut bits[x..x + 64]);
        x0 += 64;
        if x0 >= width {
            break;
        }
    }
}

/// `offsets[i]`: where in the padded window rows (`pw` entries each) the neighbour of census bit
/// `i` of pixel 0 is. Window position `r` (row by row, centre skipped) is bit `n - 1 - r`.
#[cfg(target_arch = "x86_64")]
fn neighbour_offsets(window: CensusWindow, pw: usize) -> [usize; 64] {
    let (rx, ry) = (window.width / 2, window.height / 2);
    let mut offsets = [0usize; 64];
    let mut bit = window.width * window.height - 1;
    for dy in 0..window.height {
        for dx in 0..window.width {
            if (dy, dx) != (ry, rx) {
                bit -= 1;
                offsets[bit] = dy * pw + dx;
            }
        }
    }
    offsets
}

/// [`census_row_gfni`] for images whose samples are all multiples of 257 (see
/// [`is_byte_scaled`]): the window rows are padded as high bytes, and one comparison of 64
/// bytes gives a whole mask.
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL/VBMI and GFNI; the image at least 64 pixels wide.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vbmi,gfni,avx2")]
unsafe fn census_row_gfni_bytes(
    image: &GrayImage,
    window: CensusWindow,
    y: usize,
    padded: &mut [u8],
    bits: &mut [u64],
) {
    use std::arch::x86_64::*;
    let (width, height) = image.size();
    let (rx, ry) = (window.width / 2, window.height / 2);
    let pw = width + 2 * rx;
    let n = window.width * window.height - 1;
    assert!(width >= 64 && n <= 64 && padded.len() == window.height * pw && bits.len() == width);
    let high = |v: u16| (v >> 8) as u8;
    for (dy, p) in padded.chunks_exact_mut(pw).enumerate() {
        let src = image.row((y + dy).saturating_sub(ry).min(height - 1));
        p[..rx].fill(high(src[0]));
        for (d, &s) in p[rx..rx + width].iter_mut().zip(src) {
            *d = high(s);
        }
        p[rx + width..].fill(high(src[width - 1]));
    }
    // As in `census_row_gfni`; the centres are the middle padded row.
    let offsets = neighbour_offsets(window, pw);
    let centre = &padded[ry * pw + rx..ry * pw + rx + width];
    let mut matrix = BitRows([0; 64]);
    let mut x0 = 0;
    loop {
        let x = x0.min(width - 64);
        // SAFETY: `x + 64 <= width`: inside the centre row.
        let c = unsafe { _mm512_loadu_si512(centre.as_ptr().add(x).cast()) };
        for (m, &o) in matrix.0.iter_mut().zip(&offsets[..n]) {
            // SAFETY: `o = dy * pw + dx` with `dy < window.height` and `dx < window.width`, so
            // `o + x + 64 <= dy * pw + (2 * rx + width) = (dy + 1) * pw <= padded.len()`.
            let v = unsafe { _mm512_loadu_si512(padded.as_ptr().add(o + x).cast()) };
            *m = _mm512_cmplt_epu8_mask(v, c);
        }
        matrix.store_transposed(&mut bits[x..x + 64]);
        x0 += 64;
        if x0 >= width {
            break;
        }
    }
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

/// Fills `padded` with the window rows around row `y` (clamped to the image), each extended by
/// `window.width / 2` copies of its border pixels at both ends.
#[inline(always)]
fn pad_window_rows(image: &GrayImage, window: CensusWindow, y: usize, padded: &mut [u16]) {
    let (width, height) = image.size();
    let (rx, ry) = (window.width / 2, window.height / 2);
    let pw = width + 2 * rx;
    for (dy, p) in padded.chunks_exact_mut(pw).enumerate() {
        let src = image.row((y + dy).saturating_sub(ry).min(height - 1));
        p[..rx].fill(src[0]);
        p[rx..rx + width].copy_from_slice(src);
        p[rx + width..].fill(src[width - 1]);
    }
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
    pad_window_rows(image, window, y, padded);
    let width = image.size().0;
    let (rx, ry) = (window.width / 2, window.height / 2);
    let pw = width + 2 * rx;
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
    use proptest::prelude::*;

    use super::*;

    /// Every kernel this machine can run.
    fn kernels() -> Vec<Kernel> {
        // Only x86 adds a kernel below.
        #[cfg_attr(not(target_arch = "x86_64"), allow(unused_mut))]
        let mut kernels: Vec<Kernel> =
            crate::kernels::supported_levels().into_iter().map(Kernel::for_level).collect();
        #[cfg(target_arch = "x86_64")]
        if kernels.contains(&Kernel::Gfni) {
            kernels.push(Kernel::Avx512);
        }
        kernels
    }

    #[cfg(target_arch = "x86_64")]
    #[test]
    fn the_bit_matrix_transpose_transposes() {
        if !crate::kernels::Features::capped(crate::kernels::Level::Avx512).gfni {
            return;
        }
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..20 {
            let rows: [u64; 64] = std::array::from_fn(|_| {
                s ^= s << 13;
                s ^= s >> 7;
                s ^= s << 17;
                s
            });
            let mut out = [0u64; 64];
            // SAFETY: the CPU has AVX-512F/BW/VL/VBMI and GFNI (checked above); `rows` and `out`
            // are 64 qwords each.
            unsafe {
                use std::arch::x86_64::*;
                let v = std::array::from_fn(|k| _mm512_loadu_si512(rows.as_ptr().add(8 * k).cast()));
                for (k, t) in transpose_64x64(v).into_iter().enumerate() {
                    _mm512_storeu_si512(out.as_mut_ptr().add(8 * k).cast(), t);
                }
            }
            for (p, &o) in out.iter().enumerate() {
                let expected = (0..64).fold(0u64, |acc, i| acc | ((rows[i] >> p) & 1) << i);
                assert_eq!(o, expected, "row {p}");
            }
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(200))]

        #[test]
        fn every_kernel_matches_the_reference(width in 1usize..300, height in 1usize..20, window in 0usize..9,
                                              levels in 1u32..=65535, scale in 0u8..3, seed in any::<u64>()) {
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
            crate::reference::census_transform(&img, window, &mut reference);
            for kernel in kernels() {
                let mut out = Image::new(width, height, 0x5555u64);
                census_transform_with(&img, window, &mut out, kernel);
                prop_assert!(out == reference, "{:?}, {}x{} window {}x{}", kernel, width, height, ww, wh);
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
