//! The AVX-512 census row kernels of [`crate::kernels::census_row`]: a GFNI bit-matrix transpose
//! (with VBMI) and the scalar loop compiled for AVX-512.

use std::arch::x86_64::*;

use crate::kernels::layout::{Samples, Window};
use crate::kernels::scalar::{
    census_row_scalar, pad_window_rows, pad_window_rows_high_bytes, window_offsets, HighByteRows,
};

/// 64 masks of 64 bits, the rows of the bit matrix [`census_row_gfni`] transposes; aligned so
/// each group of 8 rows is one aligned 512-bit load.
#[repr(C, align(64))]
struct BitRows([u64; 64]);

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

static GATHER_BLOCKS: [u8; 64] = byte_transpose(true);
static SPREAD_BYTES: [u8; 64] = byte_transpose(false);

/// Transposes the 64x64 bit matrix whose row `8k + q` is qword `q` of `rows[k]`: afterwards
/// bit `i` of row `p` is bit `p` of the old row `i`. The 8x8 bit blocks are transposed by one
/// GF(2) affine transform each, so the whole matrix takes 48 shuffle-class instructions.
#[inline]
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vbmi,gfni")]
pub(in crate::kernels) fn transpose_64x64(rows: [__m512i; 8]) -> [__m512i; 8] {
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
/// window position and 64 pixels) where [`census_row_scalar`] needs about 30.
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL/VBMI and GFNI.
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vbmi,gfni,avx2")]
pub(in crate::kernels) unsafe fn census_row_gfni(
    image: Samples<'_>,
    window: Window,
    y: usize,
    padded: &mut [u16],
    bits: &mut [u64],
) {
    let width = image.size().0;
    if width < 64 {
        // Too narrow for one block.
        return census_row_scalar(image, window, y, padded, bits);
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
    let tolerance = _mm512_set1_epi16(window.tolerance as i16);
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
        // `n < c - tolerance` (saturating) is `n + tolerance < c`.
        let (c_lo, c_hi) = (_mm512_subs_epu16(c_lo, tolerance), _mm512_subs_epu16(c_hi, tolerance));
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
fn neighbour_offsets(window: Window, pw: usize) -> [usize; 64] {
    // `window_offsets` lists the positions in that order, so bit i's is entry n - 1 - i.
    let mut offsets = window_offsets(window, pw);
    offsets[..window.width * window.height - 1].reverse();
    offsets
}

/// [`census_row_gfni`] for images whose samples are all multiples of 257 (see
/// `census::is_byte_scaled`): the window rows are padded as high bytes, and one comparison of 64
/// bytes gives a whole mask. The window's tolerance must be a multiple of 257.
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL/VBMI and GFNI; the image at least 64 pixels wide.
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vbmi,gfni,avx2")]
pub(in crate::kernels) unsafe fn census_row_gfni_bytes(
    image: Samples<'_>,
    window: Window,
    y: usize,
    padded: &mut [u8],
    bits: &mut [u64],
) {
    let width = image.size().0;
    let HighByteRows { pw, centre, n, tolerance } =
        pad_window_rows_high_bytes(image, window, y, padded, bits, 64);
    // As in `census_row_gfni`; the centres are the middle padded row.
    let offsets = neighbour_offsets(window, pw);
    let centre = &padded[centre..centre + width];
    let mut matrix = BitRows([0; 64]);
    let tolerance = _mm512_set1_epi8(tolerance as i8);
    let mut x0 = 0;
    loop {
        let x = x0.min(width - 64);
        // SAFETY: `x + 64 <= width`: inside the centre row.
        let c = unsafe { _mm512_subs_epu8(_mm512_loadu_si512(centre.as_ptr().add(x).cast()), tolerance) };
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

/// [`census_row_scalar`] compiled for AVX-512 (auto-vectorised over pixels).
///
/// # Safety
/// The CPU must have AVX-512F/BW/VL.
#[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2")]
pub(in crate::kernels) unsafe fn census_row_avx512(
    image: Samples<'_>,
    window: Window,
    y: usize,
    padded: &mut [u16],
    bits: &mut [u64],
) {
    census_row_scalar(image, window, y, padded, bits)
}
