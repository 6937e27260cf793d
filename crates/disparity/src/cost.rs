//! Matching costs: Hamming distances between left and right census strings, optionally plus a
//! capped Birchfield–Tomasi intensity term (AD-census). They are computed row by row inside the
//! aggregation passes ([`crate::simd::cost_row`]), never stored as a `W·H·D` volume.

use crate::MatchingCost;

/// Cost of a disparity that points outside the right image: as bad as the worst match (all
/// census bits differ and the intensity term at its cap), so path aggregation can cross the
/// border but winner-takes-all never picks it.
pub(crate) fn infeasible_cost(census_bits: u32, cost: MatchingCost) -> u16 {
    let cap = match cost {
        MatchingCost::Census => 0,
        MatchingCost::AdCensus { cap, .. } => u32::from(cap),
    };
    (census_bits + cap).min(255) as u16
}

/// Entries of padding at both ends of a [`BtRow`]: the SIMD kernels read whole 16- or 32-lane
/// blocks that may start up to 15 entries before the first and end up to 31 after the last
/// feasible one.
pub(crate) const BT_PAD: usize = 32;

/// The Birchfield–Tomasi inputs of one image row in 8-bit grey levels: per pixel its value and
/// the minimum and maximum of it and its two half-pixel interpolations with the neighbours
/// (clamped at the row ends), each rounded from the 16-bit samples (`v / 257`). The right row is
/// stored reversed (pixel `x` at `BT_PAD + width - 1 - x`), so that ascending disparities read
/// ascending addresses; the left row in order (pixel `x` at `BT_PAD + x`). Pads hold 0.
#[derive(Clone, Debug, Default)]
pub(crate) struct BtRow {
    pub value: Vec<u8>,
    pub lo: Vec<u8>,
    pub hi: Vec<u8>,
}

/// `s / 514` rounded half up: a sum of two 16-bit samples in 8-bit grey levels.
#[inline]
fn grey_of_pair_sum(s: u32) -> u8 {
    ((s + 257) / 514) as u8
}

impl BtRow {
    /// Fills the row from the 16-bit samples `row`, reversed or in order.
    ///
    /// Computed in order with a branch-free interior loop (which vectorises: it runs once per row
    /// and pass, so a scalar loop showed in profiles), then reversed in place for the right row.
    /// The buffers are sized (and their pads zeroed) only when the width changes: only the
    /// entries `BT_PAD..BT_PAD + width` are written afterwards, so the pads stay 0.
    pub(crate) fn fill(&mut self, row: &[u16], reversed: bool) {
        let width = row.len();
        let len = width + 2 * BT_PAD;
        for v in [&mut self.value, &mut self.lo, &mut self.hi] {
            if v.len() != len {
                v.clear();
                v.resize(len, 0);
            }
        }
        let span = BT_PAD..BT_PAD + width;
        let (value, lo, hi) = (&mut self.value[span.clone()], &mut self.lo[span.clone()], &mut self.hi[span]);
        match crate::simd::features().level {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: the level was detected on this CPU (AVX-512F/BW/VL implies AVX2).
            crate::simd::Level::Avx512 | crate::simd::Level::Avx2 => unsafe { fill_avx2(row, value, lo, hi) },
            _ => fill_in_order(row, value, lo, hi),
        }
        if reversed {
            value.reverse();
            lo.reverse();
            hi.reverse();
        }
    }
}

/// [`fill_in_order`] compiled for AVX2 (eight 32-bit lanes for the divisions by 514).
///
/// # Safety
/// The CPU must have AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn fill_avx2(row: &[u16], value: &mut [u8], lo: &mut [u8], hi: &mut [u8]) {
    fill_in_order(row, value, lo, hi)
}

/// The BT inputs of `row` in order into `value`, `lo` and `hi` (each `row.len()` entries).
/// The minimum of the doubled centre and the two doubled half-pixel interpolations is
/// `c + min(a, b, c)` (and likewise the maximum), and rounding is monotonic, so each output is
/// one rounding of one sum.
#[inline(always)]
fn fill_in_order(row: &[u16], value: &mut [u8], lo: &mut [u8], hi: &mut [u8]) {
    let width = row.len();
    assert!(value.len() == width && lo.len() == width && hi.len() == width);
    let pixel = |a: u16, c: u16, b: u16| {
        let (min, max) = (c.min(a).min(b), c.max(a).max(b));
        let c32 = u32::from(c);
        (
            grey_of_pair_sum(2 * c32),
            grey_of_pair_sum(c32 + u32::from(min)),
            grey_of_pair_sum(c32 + u32::from(max)),
        )
    };
    let mut put = |x: usize, (v, l, h): (u8, u8, u8)| {
        value[x] = v;
        lo[x] = l;
        hi[x] = h;
    };
    match width {
        0 => return,
        1 => return put(0, pixel(row[0], row[0], row[0])),
        _ => {
            put(0, pixel(row[0], row[0], row[1]));
            put(width - 1, pixel(row[width - 2], row[width - 1], row[width - 1]));
        }
    }
    let inner = 1..width - 1;
    let (value, lo, hi) = (&mut value[inner.clone()], &mut lo[inner.clone()], &mut hi[inner]);
    let (a, c, b) = (&row[..width - 2], &row[1..width - 1], &row[2..]);
    for i in 0..width - 2 {
        let (v, l, h) = pixel(a[i], c[i], b[i]);
        value[i] = v;
        lo[i] = l;
        hi[i] = h;
    }
}

/// A zero-initialised `[T]` of plain integers whose first entry is 64-byte aligned (a `Vec` with
/// up to 64 bytes of slack in front): the 8-bit cost row, so that neither the cost kernel's
/// stores nor the path step's 512-bit loads of it split cache lines (`malloc` only aligns to 16).
#[derive(Default)]
pub(crate) struct AlignedRow<T> {
    buf: Vec<T>,
    start: usize,
    len: usize,
}

impl<T: Copy + Default> AlignedRow<T> {
    pub(crate) fn new(len: usize) -> Self {
        if len == 0 {
            return AlignedRow { buf: Vec::new(), start: 0, len: 0 };
        }
        let size = std::mem::size_of::<T>().max(1);
        let buf = vec![T::default(); len + 64 / size];
        // The `Vec` never grows, so its address (and the alignment found here) stays.
        let start = (64 - buf.as_ptr() as usize % 64) % 64 / size;
        AlignedRow { buf, start, len }
    }
}

impl<T> std::ops::Deref for AlignedRow<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        &self.buf[self.start..self.start + self.len]
    }
}

impl<T> std::ops::DerefMut for AlignedRow<T> {
    fn deref_mut(&mut self) -> &mut [T] {
        &mut self.buf[self.start..self.start + self.len]
    }
}

/// The AD part of the cost kernel's input: the left row in order, the right row reversed, and
/// the term `min(weight · BT, cap)`.
#[derive(Clone, Copy)]
pub(crate) struct AdRows<'a> {
    pub left: &'a BtRow,
    pub right: &'a BtRow,
    pub weight: u16,
    pub cap: u16,
}

/// The Birchfield–Tomasi dissimilarity of two pixels given as `(value, lo, hi)`.
#[inline(always)]
pub(crate) fn bt(l: (u8, u8, u8), r: (u8, u8, u8)) -> u8 {
    let d_lr = l.0.saturating_sub(r.2).max(r.1.saturating_sub(l.0));
    let d_rl = r.0.saturating_sub(l.2).max(l.1.saturating_sub(r.0));
    d_lr.min(d_rl)
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    /// The original per-pixel loop of [`BtRow::fill`] (fresh zero-filled buffers every call).
    fn fill_reference(row: &[u16], reversed: bool) -> BtRow {
        let width = row.len();
        let mut r = BtRow::default();
        for v in [&mut r.value, &mut r.lo, &mut r.hi] {
            v.resize(width + 2 * BT_PAD, 0);
        }
        for x in 0..width {
            let c = u32::from(row[x]);
            let (a, b) = (u32::from(row[x.saturating_sub(1)]), u32::from(row[(x + 1).min(width - 1)]));
            let (c2, a2, b2) = (2 * c, c + a, c + b);
            let i = BT_PAD + if reversed { width - 1 - x } else { x };
            r.value[i] = grey_of_pair_sum(c2);
            r.lo[i] = grey_of_pair_sum(c2.min(a2).min(b2));
            r.hi[i] = grey_of_pair_sum(c2.max(a2).max(b2));
        }
        r
    }

    proptest! {
        /// The vectorised fill equals the original loop, also when one `BtRow` is reused for rows
        /// of other widths and directions (the pads must stay 0).
        #[test]
        fn bt_fill_equals_the_original_loop(rows in prop::collection::vec((prop::collection::vec(any::<u16>(), 0..300), any::<bool>(), any::<bool>()), 1..5)) {
            let mut reused = BtRow::default();
            for (row, reversed, extremes) in rows {
                // Some rows of only the extreme samples (largest sums and rounding edges).
                let row: Vec<u16> = if extremes { row.iter().map(|&v| if v & 1 == 0 { 0 } else { u16::MAX - (v >> 15) }).collect() } else { row };
                let expected = fill_reference(&row, reversed);
                reused.fill(&row, reversed);
                prop_assert_eq!(&reused.value, &expected.value);
                prop_assert_eq!(&reused.lo, &expected.lo);
                prop_assert_eq!(&reused.hi, &expected.hi);
            }
        }
    }
}
