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
    pub(crate) fn fill(&mut self, row: &[u16], reversed: bool) {
        let width = row.len();
        for v in [&mut self.value, &mut self.lo, &mut self.hi] {
            v.clear();
            v.resize(width + 2 * BT_PAD, 0);
        }
        for x in 0..width {
            let c = u32::from(row[x]);
            let (a, b) = (u32::from(row[x.saturating_sub(1)]), u32::from(row[(x + 1).min(width - 1)]));
            // Twice the centre and twice each half-pixel interpolation.
            let (c2, a2, b2) = (2 * c, c + a, c + b);
            let i = BT_PAD + if reversed { width - 1 - x } else { x };
            self.value[i] = grey_of_pair_sum(c2);
            self.lo[i] = grey_of_pair_sum(c2.min(a2).min(b2));
            self.hi[i] = grey_of_pair_sum(c2.max(a2).max(b2));
        }
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
