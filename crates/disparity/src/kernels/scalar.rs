//! The scalar kernels: the readable reference of every SIMD kernel (each SIMD version is
//! proptested bit-for-bit against its function here) and the code every level falls back to.
//! Imports only [`super::layout`].

use super::layout::{
    feasible, padded_lanes, padded_lanes_u8, AdRows, BandRow, BtRow, PathIn, PathInU8, Samples, Window,
    BT_PAD, JUNK_COST, PAD_U8,
};

/// The readable reference of [`super::path_step`].
pub(crate) fn path_step_scalar<const N: usize>(
    cost: &[u16],
    p1: u16,
    ins: [PathIn<'_>; N],
    outs: [&mut [u16]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u16; N] {
    let mut mins = [u16::MAX; N];
    let nd = sum.len();
    for (i, out) in outs.into_iter().enumerate() {
        let PathIn { prev, prev_min, p2 } = ins[i];
        let jump = prev_min.saturating_add(p2);
        let (prev, out) = (&prev[..cost.len() + 2], &mut out[1..=cost.len()]);
        for (k, (&c, o)) in cost.iter().zip(out.iter_mut()).enumerate() {
            let best =
                prev[k + 1].min(prev[k].saturating_add(p1)).min(prev[k + 2].saturating_add(p1)).min(jump);
            *o = c.saturating_add(best).wrapping_sub(prev_min);
        }
        mins[i] = out.iter().copied().fold(u16::MAX, u16::min);
        for (s, &v) in sum.iter_mut().zip(&out[..nd]) {
            *s = if i == 0 && !accumulate { v } else { s.wrapping_add(v) };
        }
    }
    mins
}

/// The readable reference of [`super::path_step_u8`].
pub(crate) fn path_step_u8_scalar<const N: usize>(
    cost: &[u8],
    p1: u8,
    ins: [PathInU8<'_>; N],
    outs: [&mut [u8]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u8; N] {
    let mut mins = [u8::MAX; N];
    let nd = sum.len();
    for (i, out) in outs.into_iter().enumerate() {
        let PathIn { prev, prev_min, p2 } = ins[i];
        let jump = prev_min.saturating_add(p2);
        let (prev, out) = (&prev[..cost.len() + 2], &mut out[1..=cost.len()]);
        for (k, (&c, o)) in cost.iter().zip(out.iter_mut()).enumerate() {
            let best =
                prev[k + 1].min(prev[k].saturating_add(p1)).min(prev[k + 2].saturating_add(p1)).min(jump);
            *o = c.saturating_add(best.wrapping_sub(prev_min));
        }
        mins[i] = out.iter().copied().fold(u8::MAX, u8::min);
        for (s, &v) in sum.iter_mut().zip(&out[..nd]) {
            *s = if i == 0 && !accumulate { u16::from(v) } else { s.wrapping_add(u16::from(v)) };
        }
    }
    mins
}

/// The readable reference of [`super::cost_row`].
#[inline(always)]
pub(crate) fn cost_row_scalar(
    left: &[u64],
    right: &[u64],
    min_disparity: i32,
    nd: usize,
    worst: u16,
    ad: Option<AdRows<'_>>,
    out: &mut [u16],
) {
    let lanes = padded_lanes(nd);
    for (x, costs) in out.chunks_exact_mut(lanes).enumerate() {
        cost_pixel_scalar(left, right, x, min_disparity, nd, worst, ad, costs);
    }
}

/// The readable reference of [`super::cost_bands`]: [`cost_row_scalar`]'s pixel step over each
/// pixel's own band (`nd` real disparities up to `range_max`, [`JUNK_COST`] past it).
pub(crate) fn cost_bands_scalar(
    left: &[u64],
    right: &[u64],
    bands: BandRow<'_>,
    range_max: i32,
    worst: u16,
    ad: Option<AdRows<'_>>,
    out: &mut [u16],
) {
    for x in 0..left.len() {
        let (o, nd, entries) = bands.band(x, range_max);
        cost_pixel_scalar(left, right, x, o, nd, worst, ad, &mut out[entries]);
    }
}

/// Pixel `x`'s costs from disparity `min_disparity` into `costs`: `nd` real ones (`worst` where
/// the right pixel is outside the row), [`JUNK_COST`] in the lanes past them.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn cost_pixel_scalar(
    left: &[u64],
    right: &[u64],
    x: usize,
    min_disparity: i32,
    nd: usize,
    worst: u16,
    ad: Option<AdRows<'_>>,
    costs: &mut [u16],
) {
    let width = left.len();
    let l = left[x];
    // Disparity index k has its right pixel at x - min - k: inside the row for k in lo..hi.
    let (lo, hi, first) = feasible(x, width, min_disparity, nd);
    costs[..lo].fill(worst);
    for (k, c) in costs[lo..hi].iter_mut().enumerate() {
        let xr = (first - (lo + k) as i64) as usize;
        *c = (l ^ right[xr]).count_ones() as u16;
        if let Some(ad) = ad {
            let il = BT_PAD + x;
            let ir = BT_PAD + width - 1 - xr;
            let at = |r: &BtRow, i: usize| (r.value[i], r.lo[i], r.hi[i]);
            let term = u16::from(bt(at(ad.left, il), at(ad.right, ir))) * ad.weight;
            *c += term.min(ad.cap);
        }
    }
    costs[hi..nd].fill(worst);
    costs[nd..].fill(JUNK_COST);
}

/// A cost row's entry type: the `u16` rows, padded past `nd` with [`JUNK_COST`], and the 8-bit
/// rows of the 8-bit passes, padded with [`PAD_U8`] (every census distance, at most 64, fits).
pub(crate) trait CostEntry: Copy {
    const PAST_ND: Self;
    fn from_distance(bits: u32) -> Self;
}

impl CostEntry for u16 {
    const PAST_ND: u16 = JUNK_COST;
    fn from_distance(bits: u32) -> u16 {
        bits as u16
    }
}

impl CostEntry for u8 {
    const PAST_ND: u8 = PAD_U8;
    fn from_distance(bits: u32) -> u8 {
        bits as u8
    }
}

/// The census part of a SIMD kernel's pixel step (the Hamming distances of
/// [`cost_pixel_scalar`], without the AD term): `block(l, r, dst)` stores the 16 distances of
/// disparities `k..k + 16` at `dst` (`r` the 16 right census strings from the lowest address,
/// the highest disparity's first) wherever all 16 right pixels are inside the row, this loop's
/// step at the ends of the feasible range, `worst` where the right pixel is outside the row,
/// [`CostEntry::PAST_ND`] past `nd`. Returns [`feasible`]'s `(lo, hi, first)` for the AD term.
///
/// # Safety
/// `costs.len()` is a multiple of 16 and at least `nd`; `block` may write the 16 entries at
/// `dst` and read the 16 strings at `r`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub(crate) unsafe fn census_costs_in_blocks<C: CostEntry>(
    left: &[u64],
    right: &[u64],
    x: usize,
    min_disparity: i32,
    nd: usize,
    worst: C,
    costs: &mut [C],
    block: impl Fn(u64, *const u64, *mut C),
) -> (usize, usize, i64) {
    let width = left.len();
    let l = left[x];
    let (lo, hi, first) = feasible(x, width, min_disparity, nd);
    // The fills below are empty for most pixels; the guards keep `u8` rows from calling
    // `memset` for nothing (three calls per pixel otherwise).
    if lo > 0 {
        costs[..lo].fill(worst);
    }
    // Disparity index k has its right pixel at first - k.
    let one = |costs: &mut [C], k: usize| {
        costs[k] = C::from_distance((l ^ right[(first - k as i64) as usize]).count_ones());
    };
    let mut k = lo;
    while k < hi && !k.is_multiple_of(16) {
        one(costs, k);
        k += 1;
    }
    while k + 16 <= hi {
        // SAFETY: k..k + 16 are feasible, so right pixels first - k - 15 ..= first - k are
        // inside the row; entries k..k + 16 are this pixel's (k + 16 <= hi <= costs.len()).
        block(l, right.as_ptr().add((first - k as i64) as usize - 15), costs.as_mut_ptr().add(k));
        k += 16;
    }
    while k < hi {
        one(costs, k);
        k += 1;
    }
    if hi < nd {
        costs[hi..nd].fill(worst);
    }
    if nd < costs.len() {
        costs[nd..].fill(C::PAST_ND);
    }
    (lo, hi, first)
}

/// The readable reference of [`super::cost_row_u8`] (the loop of [`cost_row_scalar`] in 8 bits).
#[inline(always)]
pub(crate) fn cost_row_u8_scalar(
    left: &[u64],
    right: &[u64],
    min_disparity: i32,
    nd: usize,
    worst: u16,
    ad: Option<AdRows<'_>>,
    out: &mut [u8],
) {
    let width = left.len();
    let lanes = padded_lanes_u8(nd);
    for (x, costs) in out.chunks_exact_mut(lanes).enumerate() {
        let l = left[x];
        let (lo, hi, first) = feasible(x, width, min_disparity, nd);
        costs[..lo].fill(worst as u8);
        for (k, c) in costs[lo..hi].iter_mut().enumerate() {
            let xr = (first - (lo + k) as i64) as usize;
            let mut cost = (l ^ right[xr]).count_ones() as u16;
            if let Some(ad) = ad {
                let il = BT_PAD + x;
                let ir = BT_PAD + width - 1 - xr;
                let at = |r: &BtRow, i: usize| (r.value[i], r.lo[i], r.hi[i]);
                cost += (u16::from(bt(at(ad.left, il), at(ad.right, ir))) * ad.weight).min(ad.cap);
            }
            *c = cost as u8;
        }
        costs[hi..nd].fill(worst as u8);
        costs[nd..].fill(PAD_U8);
    }
}

/// The readable reference of [`super::p2_row_u8`].
pub(crate) fn p2_row_u8_scalar(table: &[u8; 256], a: &[u16], b: &[u16], out: &mut [u8]) {
    for ((o, &a), &b) in out.iter_mut().zip(a).zip(b) {
        *o = table[usize::from(a.abs_diff(b) / 257)];
    }
}

/// The readable reference of [`super::argmin`].
pub(crate) fn argmin_scalar<T: Copy + Ord>(values: &[T]) -> (T, usize) {
    let mut best = 0;
    for (k, &v) in values.iter().enumerate() {
        if v < values[best] {
            best = k;
        }
    }
    (values[best], best)
}

/// The readable reference of [`super::keep_smaller`].
pub(crate) fn keep_smaller_scalar(costs: &[u16], first_index: u16, best: &mut [u16], index: &mut [u16]) {
    for (j, ((&c, b), i)) in costs.iter().zip(best.iter_mut()).zip(index.iter_mut()).enumerate() {
        if c < *b {
            *b = c;
            *i = first_index + j as u16;
        }
    }
}

/// The Birchfield–Tomasi dissimilarity of two pixels given as `(value, lo, hi)`.
#[inline(always)]
pub(crate) fn bt(l: (u8, u8, u8), r: (u8, u8, u8)) -> u8 {
    let d_lr = l.0.saturating_sub(r.2).max(r.1.saturating_sub(l.0));
    let d_rl = r.0.saturating_sub(l.2).max(l.1.saturating_sub(r.0));
    d_lr.min(d_rl)
}

/// `s / 514` rounded half up: a sum of two 16-bit samples in 8-bit grey levels.
#[inline]
pub(crate) fn grey_of_pair_sum(s: u32) -> u8 {
    ((s + 257) / 514) as u8
}

/// The BT inputs of `row` in order into `value`, `lo` and `hi` (each `row.len()` entries).
/// The minimum of the doubled centre and the two doubled half-pixel interpolations is
/// `c + min(a, b, c)` (and likewise the maximum), and rounding is monotonic, so each output is
/// one rounding of one sum.
#[inline(always)]
pub(crate) fn bt_fill_in_order(row: &[u16], value: &mut [u8], lo: &mut [u8], hi: &mut [u8]) {
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

/// Fills `padded` with the window rows around row `y` (clamped to the image), each extended by
/// `window.width / 2` copies of its border pixels at both ends.
#[inline(always)]
pub(crate) fn pad_window_rows(image: Samples<'_>, window: Window, y: usize, padded: &mut [u16]) {
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

/// Where each neighbour of the window (centre skipped, in the reference's bit order, most
/// significant first) starts in the padded rows of [`pad_window_rows`] (`pw` samples each),
/// relative to the pixel; entries past the `width · height − 1` neighbours are 0.
#[inline(always)]
pub(crate) fn window_offsets(window: Window, pw: usize) -> [usize; 64] {
    let (rx, ry) = (window.width / 2, window.height / 2);
    let mut offsets = [0usize; 64];
    let mut i = 0;
    for dy in 0..window.height {
        for dx in 0..window.width {
            if dx != rx || dy != ry {
                offsets[i] = dy * pw + dx;
                i += 1;
            }
        }
    }
    offsets
}

/// `window_offsets(9 × 7, pw)[i]` computed (the default window's neighbours in raster order,
/// the centre, raster position 31, skipped): with `i` a constant of an unrolled loop it folds
/// into a constant plus one of seven multiples of `pw`, where the table is read from memory.
/// (The NEON census kernels only: compiled for x86-64, LLVM kept the loops and divided by 9 at
/// every neighbour, 1.6× the AVX2 kernel's time.)
#[cfg(any(test, target_arch = "aarch64"))]
#[inline(always)]
pub(crate) fn offset_in_9x7(i: usize, pw: usize) -> usize {
    let p = i + usize::from(i >= 31);
    p / 9 * pw + p % 9
}

/// The padded rows of a byte census kernel ([`pad_window_rows_high_bytes`]): their width, where
/// the first centre is, the neighbour count and the tolerance in high bytes.
pub(crate) struct HighByteRows {
    pub(crate) pw: usize,
    pub(crate) centre: usize,
    pub(crate) n: usize,
    pub(crate) tolerance: u8,
}

/// [`pad_window_rows`] of the samples' high bytes: for byte-scaled images (`b · 257`, see
/// `census::is_byte_scaled`), whose high bytes compare as the samples do. First checks what the
/// byte kernels' unchecked loads rely on (an image `min_width` or wider, `padded` and `bits`
/// as long as the row needs, at most 64 neighbours) and a tolerance in whole bytes.
#[inline(always)]
pub(crate) fn pad_window_rows_high_bytes(
    image: Samples<'_>,
    window: Window,
    y: usize,
    padded: &mut [u8],
    bits: &[u64],
    min_width: usize,
) -> HighByteRows {
    let (width, height) = image.size();
    let (rx, ry) = (window.width / 2, window.height / 2);
    let pw = width + 2 * rx;
    let n = window.width * window.height - 1;
    assert!(width >= min_width && n <= 64 && padded.len() == window.height * pw && bits.len() == width);
    assert!(window.tolerance.is_multiple_of(257), "a tolerance in whole bytes");
    let high = |v: u16| (v >> 8) as u8;
    for (dy, p) in padded.chunks_exact_mut(pw).enumerate() {
        let src = image.row((y + dy).saturating_sub(ry).min(height - 1));
        p[..rx].fill(high(src[0]));
        for (d, &s) in p[rx..rx + width].iter_mut().zip(src) {
            *d = high(s);
        }
        p[rx + width..].fill(high(src[width - 1]));
    }
    HighByteRows { pw, centre: ry * pw + rx, n, tolerance: (window.tolerance / 257) as u8 }
}

/// One row of the transform: one pass over the row per window position, so the comparisons of
/// many pixels run side by side. A bit is set when the neighbour is darker than the centre by
/// more than the window's tolerance.
#[inline(always)]
pub(crate) fn census_row_scalar(
    image: Samples<'_>,
    window: Window,
    y: usize,
    padded: &mut [u16],
    bits: &mut [u64],
) {
    pad_window_rows(image, window, y, padded);
    census_span_scalar(padded, window, image.row(y), 0, bits);
}

/// The transform of pixels `from..` of a row whose window rows `padded` holds (as
/// [`pad_window_rows`] fills it; `centre` is the row itself, `bits` as long): the loop of
/// [`census_row_scalar`], which the SIMD kernels also run on the pixels past their last step.
#[inline(always)]
pub(crate) fn census_span_scalar(
    padded: &[u16],
    window: Window,
    centre: &[u16],
    from: usize,
    bits: &mut [u64],
) {
    let width = centre.len();
    let (rx, ry) = (window.width / 2, window.height / 2);
    let pw = width + 2 * rx;
    let tolerance = window.tolerance;
    let span = &mut bits[from..width];
    span.fill(0);
    for (dy, p) in padded.chunks_exact(pw).enumerate() {
        for dx in 0..window.width {
            if dx == rx && dy == ry {
                continue;
            }
            let neighbours = &p[dx + from..dx + width];
            for ((b, &n), &c) in span.iter_mut().zip(neighbours).zip(&centre[from..]) {
                *b = (*b << 1) | u64::from(n < c.saturating_sub(tolerance));
            }
        }
    }
}

/// `f32::total_cmp` order as a plain `i32` order (an involution on the bits).
#[inline(always)]
pub(crate) fn median_key(bits: u32) -> i32 {
    (bits ^ (((bits as i32) >> 31) as u32 >> 1)) as i32
}

/// The readable reference of [`super::median3x3_row`]: each pixel `x` of `out` whose centre
/// `rows[1][x + 1]` is valid becomes the median of the valid (non-NaN) values of its 3 × 3
/// window `rows[0..3][x..x + 3]` in `f32::total_cmp` order, the mean of the two middle ones for
/// an even count; a hole (NaN, any payload) is copied.
#[cfg(test)]
pub(crate) fn median3x3_row_scalar(rows: [&[f32]; 3], out: &mut [f32]) {
    for (x, o) in out.iter_mut().enumerate() {
        let centre = rows[1][x + 1];
        if centre.is_nan() {
            *o = centre;
            continue;
        }
        let mut window: Vec<f32> =
            rows.iter().flat_map(|r| &r[x..x + 3]).copied().filter(|v| !v.is_nan()).collect();
        window.sort_unstable_by(f32::total_cmp);
        let n = window.len();
        *o = if n % 2 == 1 { window[n / 2] } else { 0.5 * (window[n / 2 - 1] + window[n / 2]) };
    }
}

/// Runs the exchanges of Paeth's median-of-nine network (as in Devillard's `opt_med9`) on the
/// window entries `$w` (each `$lanes` lanes) with the minimum and maximum `$min`, `$max`:
/// afterwards entry 4 holds the median. In every pair the first entry receives the smaller key.
/// Written out (not a loop over a table) so that the entries stay in registers.
macro_rules! median9_network {
    ($w:ident, $min:expr, $max:expr) => {
        median9_network!(@ $w, $min, $max; (1, 2) (4, 5) (7, 8) (0, 1) (3, 4) (6, 7) (1, 2) (4, 5)
            (7, 8) (0, 3) (5, 8) (4, 7) (3, 6) (1, 4) (2, 5) (4, 7) (2, 4) (4, 6) (2, 4))
    };
    (@ $w:ident, $min:expr, $max:expr; $(($a:literal, $b:literal))*) => {
        $(
            let (p, q) = ($w[$a], $w[$b]);
            $w[$a] = $min(p, q);
            $w[$b] = $max(p, q);
        )*
    };
}
// The AVX-512 and NEON kernels run the same network on their registers.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
pub(crate) use median9_network;

/// Lane-wise minimum and maximum of `B` keys, the network's exchange.
#[inline(always)]
fn lanes_min<const B: usize>(p: [i32; B], q: [i32; B]) -> [i32; B] {
    std::array::from_fn(|l| p[l].min(q[l]))
}

#[inline(always)]
fn lanes_max<const B: usize>(p: [i32; B], q: [i32; B]) -> [i32; B] {
    std::array::from_fn(|l| p[l].max(q[l]))
}

/// Entry 4 of the median network over the window keys `w` whose holes (`hole`, 1 per hole)
/// became `low` lowest keys and the rest highest ones, per lane: with `h` holes and `low =
/// ⌊h/2⌋` it is the median of the valid keys (an odd count) or the upper of the two middle ones
/// (an even count); with `low = ⌈h/2⌉` the lower one. No valid key equals a sentinel:
/// `i32::MIN` and `i32::MAX` are keys of NaNs.
#[inline(always)]
fn median_with_sentinels<const B: usize>(
    w: &[[i32; B]; 9],
    hole: &[[i32; B]; 9],
    low: &[i32; B],
) -> [i32; B] {
    let mut w = *w;
    let mut seen = [0i32; B];
    for (entry, hole) in w.iter_mut().zip(hole) {
        for l in 0..B {
            let sentinel = if seen[l] < low[l] { i32::MIN } else { i32::MAX };
            entry[l] = if hole[l] != 0 { sentinel } else { entry[l] };
            seen[l] += hole[l];
        }
    }
    median9_network!(w, lanes_min, lanes_max);
    w[4]
}

/// [`median3x3_row_scalar`] for the `B` pixels from `x`, written as lanes the compiler
/// vectorises (`i32` throughout): a window without holes runs the median network once; one with
/// holes runs it with the holes as sentinels ([`median_with_sentinels`]), twice where a lane has
/// an even count of valid values (the mean of the two middle ones).
#[inline(always)]
fn median3x3_lanes<const B: usize>(rows: [&[f32]; 3], x: usize, out: &mut [f32]) {
    let mut w = [[0i32; B]; 9];
    let mut hole = [[0i32; B]; 9];
    let mut holes = [0i32; B];
    for (i, (entry, hole)) in w.iter_mut().zip(&mut hole).enumerate() {
        let row = &rows[i / 3][x + i % 3..x + i % 3 + B];
        for l in 0..B {
            let bits = row[l].to_bits();
            entry[l] = median_key(bits);
            hole[l] = i32::from(bits & 0x7fff_ffff > 0x7f80_0000);
            holes[l] += hole[l];
        }
    }
    let from_key = |k: i32| f32::from_bits(median_key(k as u32) as u32);
    let out = &mut out[x..x + B];
    if holes.iter().fold(0, |a, &h| a | h) == 0 {
        median9_network!(w, lanes_min, lanes_max);
        for (o, &k) in out.iter_mut().zip(&w[4]) {
            *o = from_key(k);
        }
        return;
    }
    let upper = median_with_sentinels(&w, &hole, &holes.map(|h| h >> 1));
    let lower = if holes.iter().fold(0, |a, &h| a | (h & 1)) != 0 {
        median_with_sentinels(&w, &hole, &holes.map(|h| (h + 1) >> 1))
    } else {
        upper
    };
    let centre = &rows[1][x + 1..x + 1 + B];
    for l in 0..B {
        let (lo, hi) = (from_key(lower[l]), from_key(upper[l]));
        let median = if holes[l] & 1 == 1 { 0.5 * (lo + hi) } else { hi };
        out[l] = if hole[4][l] != 0 { centre[l] } else { median };
    }
}

/// [`median3x3_row_scalar`] as lanes the compiler can vectorise (8 pixels at a time): the
/// scalar level's kernel, and the SIMD kernels' last pixels.
#[inline(always)]
pub(crate) fn median3x3_row_lanes(rows: [&[f32]; 3], out: &mut [f32]) {
    const B: usize = 8;
    let blocks = out.len() - out.len() % B;
    for x in (0..blocks).step_by(B) {
        median3x3_lanes::<B>(rows, x, out);
    }
    for x in blocks..out.len() {
        median3x3_lanes::<1>(rows, x, out);
    }
}
