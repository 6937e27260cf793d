//! Matching costs: Hamming distances between left and right census strings, optionally plus a
//! capped Birchfield–Tomasi intensity term (AD-census). They are computed row by row inside the
//! aggregation passes ([`crate::kernels::cost_row`]), never stored as a `W·H·D` volume.

use crate::kernels;
pub(crate) use crate::kernels::layout::{AdRows, BtRow, BT_PAD};
use crate::MatchingCost;

// The kernels' bound on the AD cap is the public one.
const _: () = assert!(crate::MAX_AD_CAP == kernels::layout::MAX_AD_CAP);

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
        kernels::bt_fill(kernels::features().level, row, value, lo, hi);
        if reversed {
            value.reverse();
            lo.reverse();
            hi.reverse();
        }
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

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::kernels::scalar::grey_of_pair_sum;

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
