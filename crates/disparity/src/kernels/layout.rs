//! The data layout every kernel shares: lane counts, paddings and sentinel values, and the plain
//! input types the kernels read. Imported by every kernel file and by the modules that build
//! their buffers; imports nothing from the crate (so no module can form a circle through it).
//!
//! A pixel's `u16` path-cost vector is `lanes + 2` entries, the disparities `0..lanes` at
//! `1..=lanes` and a pad at each end; `lanes` is the disparity count rounded up to [`LANES`].
//! Lanes at or past the disparity count hold [`JUNK_COST`]-sized values that never win a
//! minimum, so the kernels need no remainder loops. The 8-bit vectors are laid out the same way
//! with [`LANES_U8`] and [`PAD_U8`].

/// Disparities are padded to whole blocks of this many `u16` lanes (one AVX2 register, half an
/// AVX-512 one: the AVX-512 kernels finish an odd block with a 256-bit step).
pub(crate) const LANES: usize = 16;

/// Pad at both ends of a path-cost vector: never the minimum, and `+ P1` cannot overflow.
pub(crate) const PAD: u16 = 0x7fff;

/// Matching cost of the lanes past the last disparity. Path costs in those lanes stay within
/// `JUNK_COST ..= JUNK_COST + P2`, above any real path cost (at most 191 + P2: 64 census bits
/// plus the AD cap) and, plus P1, above any real candidate, so they never change a real lane or
/// a path minimum.
pub(crate) const JUNK_COST: u16 = 0x4000;

/// Disparity count rounded up to whole blocks of [`LANES`].
pub(crate) fn padded_lanes(nd: usize) -> usize {
    nd.div_ceil(LANES).max(1) * LANES
}

/// The largest path cost the 8-bit step represents exactly (255 marks the padding lanes).
pub(crate) const MAX_PATH_COST: u16 = 254;

/// Disparities are padded to whole blocks of this many `u8` lanes (one AVX2 register, half an
/// AVX-512 one).
pub(crate) const LANES_U8: usize = 32;

/// Pad at both ends of an 8-bit path-cost vector and value of the lanes past the last disparity.
pub(crate) const PAD_U8: u8 = u8::MAX;

/// Disparity count rounded up to whole blocks of [`LANES_U8`].
pub(crate) fn padded_lanes_u8(nd: usize) -> usize {
    nd.div_ceil(LANES_U8).max(1) * LANES_U8
}

/// Whether the 8-bit step is exact for matching costs up to `max_cost` and penalties `p1`,
/// `max_p2` (the largest P2 of the edge-adaptive table).
pub(crate) fn fits(max_cost: u16, p1: u16, max_p2: u16) -> bool {
    u32::from(max_cost) + u32::from(max_p2.max(p1)) <= u32::from(MAX_PATH_COST)
}

/// The largest AD-census intensity cap the kernels accept: it keeps every matching cost within
/// 8 bits and lets the 8-bit cost kernel look the term up in a 128-entry table. Equal to the
/// public `MAX_AD_CAP` of the crate (checked at compile time in `cost.rs`).
pub(crate) const MAX_AD_CAP: u8 = 127;

/// Entries of padding at both ends of a [`BtRow`]: the SIMD kernels read whole 16- or 32-lane
/// blocks that may start up to 15 entries before the first and end up to 31 after the last
/// feasible one.
pub(crate) const BT_PAD: usize = 32;

/// Lane masks for the SIMD kernels' AD term over a pixel's feasible disparities: 16 entries read
/// from `AD_LANE_MASKS[16 - n..]` are set from lane `n` on; from `AD_LANE_MASKS[32 - n..]` below
/// lane `n`.
pub(crate) static AD_LANE_MASKS: [u16; 48] = {
    let mut m = [0u16; 48];
    let mut i = 16;
    while i < 32 {
        m[i] = u16::MAX;
        i += 1;
    }
    m
};

/// The Birchfield–Tomasi inputs of one image row in 8-bit grey levels: per pixel its value and
/// the minimum and maximum of it and its two half-pixel interpolations with the neighbours
/// (clamped at the row ends), each rounded from the 16-bit samples (`v / 257`). The right row is
/// stored reversed (pixel `x` at `BT_PAD + width - 1 - x`), so that ascending disparities read
/// ascending addresses; the left row in order (pixel `x` at `BT_PAD + x`). Pads hold 0.
/// Filled by [`BtRow::fill`](crate::cost).
#[derive(Clone, Debug, Default)]
pub(crate) struct BtRow {
    pub value: Vec<u8>,
    pub lo: Vec<u8>,
    pub hi: Vec<u8>,
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

/// A row's per-pixel disparity bands (the coarse-to-fine search): pixel `x` searches
/// `offsets[x] .. offsets[x] + lanes[x]` (`lanes[x]` a multiple of [`LANES`]), its entries
/// starting at `starts[x]` of the row's band-after-band layout.
#[derive(Clone, Copy)]
pub(crate) struct BandRow<'a> {
    pub offsets: &'a [i32],
    pub lanes: &'a [u16],
    pub starts: &'a [usize],
}

impl BandRow<'_> {
    /// Pixel `x`'s band: its first disparity, how many of its lanes are disparities below
    /// `range_max` (the rest are padding), and its entries in the row's band-after-band layout.
    #[inline(always)]
    pub(crate) fn band(&self, x: usize, range_max: i32) -> (i32, usize, std::ops::Range<usize>) {
        let (offset, lanes) = (self.offsets[x], usize::from(self.lanes[x]));
        let real = ((range_max - offset) as usize).min(lanes);
        (offset, real, self.starts[x]..self.starts[x] + lanes)
    }
}

/// One path's input for a step: the previous pixel's padded path-cost vector and its minimum,
/// and the large-jump penalty for this step. A path that starts here uses an all-zero `prev`
/// with minimum 0, which makes the step return the matching cost itself.
/// (`T` is the path-cost type: `u16`, or `u8` for the 8-bit step.)
#[derive(Clone, Copy)]
pub(crate) struct PathIn<'a, T = u16> {
    pub prev: &'a [T],
    pub prev_min: T,
    pub p2: T,
}

/// One path's input for an 8-bit step.
pub(crate) type PathInU8<'a> = PathIn<'a, u8>;

/// The disparity indices `lo..hi` of pixel `x` whose right pixel `x - min_disparity - k` is
/// inside a row of `width` pixels (`lo <= hi <= nd`), and `first = x - min_disparity`.
#[inline(always)]
pub(crate) fn feasible(x: usize, width: usize, min_disparity: i32, nd: usize) -> (usize, usize, i64) {
    let first = x as i64 - min_disparity as i64;
    let hi = (first + 1).clamp(0, nd as i64) as usize;
    let lo = (first - (width as i64 - 1)).clamp(0, hi as i64) as usize;
    (lo, hi, first)
}

/// Word indices that interleave the even-lane and odd-lane words of a 2×32-word pair back into
/// lane order (for `_mm512_permutex2var_epi16`): result word `m` is disparity `base + m`, taken
/// from the even words (indices 0..32) or the odd words (32..64) at position `(base + m) / 2`.
#[cfg(target_arch = "x86_64")]
pub(crate) fn interleave(base: usize) -> [i16; 32] {
    std::array::from_fn(|m| {
        let d = base + m;
        (if d.is_multiple_of(2) { d / 2 } else { 32 + d / 2 }) as i16
    })
}

/// A path continuing from the previous row of the pass: from pixel `x + dx` of that row into
/// pixel `x`.
pub(crate) struct FromRow<'a, T = u8> {
    /// The previous row's path costs (`lanes + 2` per pixel, the disparities at `1..=lanes`) and
    /// minima; both empty when the path enters the image on this row.
    pub prev: &'a [T],
    pub prev_mins: &'a [T],
    /// Column of the source pixel relative to `x` (−1, 0 or 1); outside the row the path enters
    /// the image at `x`.
    pub dx: isize,
    /// P2 for entering each pixel along this path.
    pub p2: &'a [T],
    /// This row's path costs and minima, laid out as `prev`.
    pub out: &'a mut [T],
    pub out_mins: &'a mut [T],
}

/// A second, independent row run in the same loop as a [`super::row_u8`] row: the horizontal path
/// alone, right to left, added into `sum`. Its dependency chain overlaps the first row's, so
/// each fills the other's latency (the single-pass aggregation runs the ← path of one row beside
/// the →, ↓ paths of the next).
pub(crate) struct Trailing<'a, T = u8> {
    pub cost: &'a [T],
    pub p2: &'a [T],
    pub sum: &'a mut [u16],
}

/// A grey image as the census kernels read it: `samples` row-major, `width × height`.
#[derive(Clone, Copy)]
pub(crate) struct Samples<'a> {
    pub samples: &'a [u16],
    pub width: usize,
    pub height: usize,
}

impl<'a> Samples<'a> {
    /// Row `y`.
    #[inline(always)]
    pub(crate) fn row(&self, y: usize) -> &'a [u16] {
        &self.samples[y * self.width..(y + 1) * self.width]
    }

    /// `(width, height)`.
    #[inline(always)]
    pub(crate) fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }
}

/// A census window: odd `width × height`, at most 65 pixels (64 census bits), and how much darker
/// than the centre a neighbour must be to set its bit (more than `tolerance`, in samples).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Window {
    pub width: usize,
    pub height: usize,
    pub tolerance: u16,
}
