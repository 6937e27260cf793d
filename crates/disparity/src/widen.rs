//! A map matched on a reduced pair ([`crate::SgmParams::downscale`]) brought back to full size.
//! The disparities are interpolated within a surface, so that a slanted surface comes back as a
//! slope, not as steps the width of a reduced pixel; the statuses and confidences, and the
//! disparities across depth edges and beside holes, are repeated.

use rayon::prelude::*;
use stereo_image::Image;

/// Reduced rows per task: each task widens the reduced rows its full rows lie between once (and
/// the row after its last), keeping two at a time.
const BAND: usize = 8;

/// Where the pixels of a line of `full` pixels lie between the line's `n` reduced pixels:
/// reduced pixel `i` is centred on pixel `f·i + (f − 1)/2` (the box reduction's centre). Pixel
/// `x` lies in interval `k`, between reduced pixels `k − 1` and `k` at the fraction `t` from
/// `k − 1`, for `k` in `1..n`; interval `0` is before the first centre and `n` after the last,
/// where the pixel keeps the nearest reduced pixel's value (`t` 0).
fn intervals(full: usize, n: usize, f: usize) -> Vec<(u32, f32)> {
    (0..full)
        .map(|x| {
            // The first centre's pixel is f / 2 (rounded up for an even f, as the centres are).
            let k = ((x + f - f / 2) / f).min(n);
            let t = if k == 0 || k == n { 0.0 } else { fraction(x + f - f / 2 - k * f, f) };
            (k as u32, t)
        })
        .collect()
}

/// The fraction from the previous centre of the pixel `q` pixels into its interval (both the
/// production path and the reference compute it here, so they agree bit for bit).
fn fraction(q: usize, f: usize) -> f32 {
    (q as f32 + (f / 2) as f32 - (f - 1) as f32 / 2.0) / f as f32
}

/// The larger and smaller of two numbers that are not NaN (`f32::max` and `min` handle NaN, which
/// keeps the per-pixel loops from being vectorised).
#[inline(always)]
fn larger(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

#[inline(always)]
fn smaller(a: f32, b: f32) -> f32 {
    if a < b {
        a
    } else {
        b
    }
}

/// The reduced disparities `small` (already times the columns' factor `f.0`, `small_width` wide;
/// rows reduced by `f.1`) brought to `width × height`. A pixel whose (up to) four nearest reduced
/// pixels are all valid and within `f.0` of each other (one reduced pixel: the same surface)
/// takes their bilinear interpolation at its position ([`intervals`]; along the rows first, then
/// down the columns; with `f.0` 1 a column's own pixels only); any other pixel takes the value,
/// or the tagged hole, of the reduced pixel it lies in, as [`replicate`] does, so depth edges
/// stay sharp and no hole grows or shrinks (docs/performance.md).
pub(crate) fn widen_disparity(
    small: &[f32],
    small_width: usize,
    (f, fy): (usize, usize),
    width: usize,
    height: usize,
) -> Image<f32> {
    let small_height = small.len() / small_width;
    // The reduced pair is the full one divided by the factors, rounded down
    // (`radiometric::downsample_by`).
    assert!(width >= f * small_width && height >= fy * small_height);
    let rows = intervals(height, small_height, fy);
    let same_surface = f as f32;
    let mut out = vec![0f32; width * height];
    // Band b writes the full rows whose interval starts in reduced rows b·BAND..(b + 1)·BAND.
    let first_row = |k: usize| rows.partition_point(|&(r, _)| (r as usize).saturating_sub(1) < k);
    let bands = small_height.div_ceil(BAND);
    let mut pieces = Vec::with_capacity(bands);
    let mut rest = &mut out[..];
    for b in 0..bands {
        let (y0, y1) = (first_row(b * BAND), first_row((b + 1) * BAND));
        let (piece, tail) = std::mem::take(&mut rest).split_at_mut((y1 - y0) * width);
        pieces.push((y0, piece));
        rest = tail;
    }
    debug_assert!(rest.is_empty());
    let fractions: Vec<f32> = (0..f).map(|q| fraction(q, f)).collect();
    pieces.into_par_iter().for_each(|(y0, piece)| {
        // The two reduced rows the current full row lies between, widened once each.
        let mut cache = [(usize::MAX, Widened::new(width)), (usize::MAX, Widened::new(width))];
        for (i, out) in piece.chunks_exact_mut(width).enumerate() {
            let y = y0 + i;
            let (k, t) = rows[y];
            let n = small_height;
            let (above, below) = ((k as usize).saturating_sub(1).min(n - 1), (k as usize).min(n - 1));
            for wanted in [above, below] {
                if cache[0].0 != wanted && cache[1].0 != wanted {
                    // Rows come in order: the slot not holding `above` is free.
                    let slot = usize::from(cache[0].0 == above);
                    fill_row(
                        &mut cache[slot].1,
                        &small[wanted * small_width..(wanted + 1) * small_width],
                        &fractions,
                    );
                    cache[slot].0 = wanted;
                }
            }
            let slot_of = |k: usize| if cache[0].0 == k { &cache[0].1 } else { &cache[1].1 };
            let (a, c) = (slot_of(above), slot_of(below));
            // The reduced pixel a full pixel lies in is one of the two.
            let own = &slot_of((y / fy).min(n - 1)).nearest;
            blend_rows(a, c, own, t, same_surface, out);
        }
    });
    Image::from_vec(width, height, out).expect("width * height samples")
}

/// One full row between the widened reduced rows `a` and `c`, at the fraction `t` from `a`:
/// their interpolation where all four reduced pixels lie on one surface, else `own`.
#[inline(always)]
fn blend_rows_generic(
    a: &Widened,
    c: &Widened,
    own: &[f32],
    t: f32,
    same_surface: f32,
    out: &mut [f32],
    _level: crate::kernels::Level,
) {
    let above = a.value.iter().zip(&a.low).zip(&a.high);
    let below = c.value.iter().zip(&c.low).zip(&c.high);
    for (((out, ((&va, &la), &ha)), ((&vc, &lc), &hc)), &own) in out.iter_mut().zip(above).zip(below).zip(own)
    {
        let spread = larger(ha, hc) - smaller(la, lc);
        *out = if spread <= same_surface { va + t * (vc - va) } else { own };
    }
}

crate::kernels::multiversion! {
    /// [`blend_rows_generic`] compiled for the detected level.
    fn blend_rows(a: &Widened, c: &Widened, own: &[f32], t: f32, same_surface: f32, out: &mut [f32]) => blend_rows_generic;
}

#[inline(always)]
fn fill_row_generic(widened: &mut Widened, row: &[f32], fractions: &[f32], _level: crate::kernels::Level) {
    match fractions.len() {
        1 => widened.fill_own(row),
        2 => widened.fill_by::<2>(row, fractions),
        3 => widened.fill_by::<3>(row, fractions),
        4 => widened.fill_by::<4>(row, fractions),
        _ => widened.fill_by::<0>(row, fractions),
    }
}

crate::kernels::multiversion! {
    /// `row`, reduced by `fractions.len()`, widened into `widened`; `fractions[q]`: [`fraction`]
    /// of `q`. Compiled for the detected level.
    fn fill_row(widened: &mut Widened, row: &[f32], fractions: &[f32]) => fill_row_generic;
}

/// One reduced row widened to full width: per pixel the value interpolated along the row, the
/// extremes of the two reduced pixels it lies between (infinite where either is a hole, so the
/// same-surface test fails), and the value of the reduced pixel it lies in.
struct Widened {
    value: Vec<f32>,
    low: Vec<f32>,
    high: Vec<f32>,
    nearest: Vec<f32>,
}

impl Widened {
    fn new(width: usize) -> Self {
        Widened {
            value: vec![0.0; width],
            low: vec![0.0; width],
            high: vec![0.0; width],
            nearest: vec![0.0; width],
        }
    }

    /// [`fill_row`] for columns that were not reduced: each pixel is its own reduced pixel.
    fn fill_own(&mut self, row: &[f32]) {
        self.value.copy_from_slice(row);
        self.nearest.copy_from_slice(row);
        for ((low, high), &v) in self.low.iter_mut().zip(&mut self.high).zip(row) {
            (*low, *high) = if v.is_finite() { (v, v) } else { (f32::NEG_INFINITY, f32::INFINITY) };
        }
    }

    /// [`fill_row`] for `f == F`, or any `f` (`fractions.len()`) with `F` 0: blocks of a size
    /// known at compile time unroll (a division per pixel or a call per block cost more than
    /// the interpolation).
    #[inline(always)]
    fn fill_by<const F: usize>(&mut self, row: &[f32], fractions: &[f32]) {
        let f = if F == 0 { fractions.len() } else { F };
        let n = row.len();
        // Interval k (k in 1..n) covers pixels f·(k − 1) + f/2 .. f·k + f/2; interval 0 the
        // pixels before, interval n the pixels after (one reduced pixel each). The row is at
        // least f·n wide ([`widen_disparity`]).
        let lead = f / 2;
        let inner = lead + f * (n - 1);
        let single = |v: f32| if v.is_finite() { (v, v) } else { (f32::NEG_INFINITY, f32::INFINITY) };
        let (first, last) = (single(row[0]), single(row[n - 1]));
        self.value[..lead].fill(row[0]);
        self.low[..lead].fill(first.0);
        self.high[..lead].fill(first.1);
        self.value[inner..].fill(row[n - 1]);
        self.low[inner..].fill(last.0);
        self.high[inner..].fill(last.1);
        let blocks = self.value[lead..inner]
            .chunks_exact_mut(f)
            .zip(self.low[lead..inner].chunks_exact_mut(f))
            .zip(self.high[lead..inner].chunks_exact_mut(f))
            .zip(row.windows(2));
        let fractions = &fractions[..f];
        for (((value, low), high), pair) in blocks {
            let (a, b) = (pair[0], pair[1]);
            let valid = a.is_finite() && b.is_finite();
            let step = b - a;
            let (lo, hi) =
                if valid { (smaller(a, b), larger(a, b)) } else { (f32::NEG_INFINITY, f32::INFINITY) };
            for q in 0..f {
                value[q] = a + fractions[q] * step;
                low[q] = lo;
                high[q] = hi;
            }
        }
        for (block, &v) in self.nearest[..f * n].chunks_exact_mut(f).zip(row) {
            for out in block {
                *out = v;
            }
        }
        self.nearest[f * n..].fill(row[n - 1]);
    }
}

/// `small` (`small_width` wide) brought to `width × height`: each pixel covers `f.0 × f.1`
/// pixels, the last row and column repeat where the size is not a multiple of the factors. Each
/// reduced row is widened once into the first of its `f.1` rows, which the others copy.
pub(crate) fn replicate<T: Copy + Send + Sync>(
    small: &[T],
    small_width: usize,
    (f, fy): (usize, usize),
    width: usize,
    height: usize,
) -> Image<T> {
    let small_height = small.len() / small_width;
    let widen = |y: usize, row: &mut [T]| {
        let at = (y / fy).min(small_height - 1) * small_width;
        let small_row = &small[at..at + small_width];
        // Whole blocks of `f` (a loop the compiler unrolls for the usual factors), then the tail.
        let blocks = (small_width - 1) * f;
        match f {
            1 => row[..blocks].copy_from_slice(&small_row[..small_width - 1]),
            2 => widen_by::<T, 2>(small_row, &mut row[..blocks]),
            3 => widen_by::<T, 3>(small_row, &mut row[..blocks]),
            4 => widen_by::<T, 4>(small_row, &mut row[..blocks]),
            _ => {
                for (block, &v) in row[..blocks].chunks_exact_mut(f).zip(small_row) {
                    block.fill(v);
                }
            }
        }
        row[blocks..].fill(small_row[small_width - 1]);
    };
    let mut out = vec![small[0]; width * height];
    let whole = height / fy * fy;
    let (blocks, tail) = out.split_at_mut(whole * width);
    blocks.par_chunks_exact_mut(width * fy).enumerate().for_each(|(block, rows)| {
        let (first, rest) = rows.split_at_mut(width);
        widen(block * fy, first);
        for row in rest.chunks_exact_mut(width) {
            row.copy_from_slice(first);
        }
    });
    for (i, row) in tail.chunks_exact_mut(width).enumerate() {
        widen(whole + i, row);
    }
    Image::from_vec(width, height, out).expect("width * height samples")
}

/// `out` (`F` entries per entry of `small`, as many as fit) with each entry of `small` repeated.
#[inline(always)]
fn widen_by<T: Copy, const F: usize>(small: &[T], out: &mut [T]) {
    for (block, &v) in out.chunks_exact_mut(F).zip(small) {
        *<&mut [T; F]>::try_from(block).expect("F entries") = [v; F];
    }
}

/// [`widen_disparity`] pixel by pixel, as its documentation says: the readable reference the
/// row-wise version is tested against bit for bit.
#[cfg(test)]
pub(crate) fn widen_disparity_reference(
    small: &[f32],
    small_width: usize,
    (f, fy): (usize, usize),
    width: usize,
    height: usize,
) -> Image<f32> {
    let small_height = small.len() / small_width;
    let (columns, rows) = (intervals(width, small_width, f), intervals(height, small_height, fy));
    let at = |x: usize, y: usize| small[y * small_width + x];
    let between = |k: u32, n: usize| ((k as usize).saturating_sub(1).min(n - 1), (k as usize).min(n - 1));
    Image::from_fn(width, height, |x, y| {
        let ((kx, tx), (ky, ty)) = (columns[x], rows[y]);
        // Columns not reduced: a pixel is its own reduced pixel, no neighbour's.
        let (x0, x1) = if f == 1 { (x, x) } else { between(kx, small_width) };
        let (y0, y1) = between(ky, small_height);
        let corners = [at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1)];
        let valid = corners.iter().all(|v| v.is_finite());
        let spread = corners.iter().copied().fold(f32::MIN, f32::max)
            - corners.iter().copied().fold(f32::MAX, f32::min);
        if valid && spread <= f as f32 {
            let [a, b, c, e] = corners;
            let (top, bottom) = (a + tx * (b - a), c + tx * (e - c));
            top + ty * (bottom - top)
        } else {
            at((x / f).min(small_width - 1), (y / fy).min(small_height - 1))
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The reduced map of the full-resolution disparities `d`: each reduced pixel samples `d` at
    /// its centre.
    fn sampled(d: impl Fn(f64, f64) -> f64, small_width: usize, small_height: usize, f: usize) -> Vec<f32> {
        let centre = |i: usize| (f * i) as f64 + (f - 1) as f64 / 2.0;
        (0..small_height)
            .flat_map(|k| (0..small_width).map(move |i| (i, k)))
            .map(|(i, k)| d(centre(i), centre(k)) as f32)
            .collect()
    }

    #[test]
    fn a_slanted_plane_comes_back_as_the_plane() {
        for f in 2..=4 {
            let plane = |x: f64, y: f64| 20.0 + 0.1 * x - 0.05 * y;
            let (sw, sh) = (23, 17);
            let (w, h) = (f * sw + f - 1, f * sh);
            let out = widen_disparity(&sampled(plane, sw, sh, f), sw, (f, f), w, h);
            // Between the first and the last centres the interpolation is the plane itself; the
            // replicated map was off by up to a step of 0.1·(f − 1)/2 px along x.
            let centre = |i: usize| f * i + (f - 1) / 2;
            for y in centre(0) + 1..centre(sh - 1) {
                for x in centre(0) + 1..centre(sw - 1) {
                    let err = (f64::from(out.get(x, y)) - plane(x as f64, y as f64)).abs();
                    assert!(err < 1e-4, "f {f} ({x},{y}) off by {err}");
                }
            }
        }
    }

    #[test]
    fn halved_rows_come_back_as_the_plane_with_columns_untouched() {
        // Rows halved, columns not: between the first and the last row centres a slanted plane
        // comes back exactly; each column keeps its own disparities, and a hole stays one column
        // wide, repeated down the two rows it covers.
        let plane = |x: f64, y: f64| 20.0 + 0.1 * x - 0.05 * y;
        let (sw, sh) = (23, 17);
        let centre = |k: usize| 2.0 * k as f64 + 0.5;
        let mut small: Vec<f32> =
            (0..sw * sh).map(|p| plane((p % sw) as f64, centre(p / sw)) as f32).collect();
        let hole = f32::from_bits(0x7fc0_0005);
        small[5 * sw + 7] = hole;
        let (w, h) = (sw, 2 * sh + 1);
        let out = widen_disparity(&small, sw, (1, 2), w, h);
        let repeated = replicate(&small, sw, (1, 2), w, h);
        for y in 1..2 * sh - 1 {
            for x in 0..w {
                let v = out.get(x, y);
                if repeated.get(x, y).is_nan() {
                    assert_eq!(v.to_bits(), hole.to_bits(), "({x},{y})");
                } else if !(x == 7 && (9..=12).contains(&y)) {
                    let err = (f64::from(v) - plane(x as f64, y as f64)).abs();
                    assert!(err < 1e-4, "({x},{y}) off by {err}");
                }
            }
        }
        assert!(out.get(7, 10).is_nan() && out.get(7, 11).is_nan() && !out.get(6, 10).is_nan());
    }

    #[test]
    fn depth_edges_and_holes_are_repeated_not_blended() {
        // A foreground at 40 px beside a background at 10 (an edge far wider than f), and a tagged
        // hole: no pixel takes a value between the two surfaces, and the holes are exactly the
        // replicated map's.
        let f = 3;
        let (sw, sh) = (12, 9);
        let hole = f32::from_bits(0x7fc0_0005);
        let mut small: Vec<f32> = (0..sw * sh).map(|p| if p % sw < 6 { 10.0 } else { 40.0 }).collect();
        small[4 * sw + 2] = hole;
        let (w, h) = (sw * f + 1, sh * f + 2);
        let out = widen_disparity(&small, sw, (f, f), w, h);
        let repeated = replicate(&small, sw, (f, f), w, h);
        for (&v, &r) in out.as_slice().iter().zip(repeated.as_slice()) {
            assert_eq!(v.is_nan(), r.is_nan());
            if v.is_nan() {
                assert_eq!(v.to_bits(), r.to_bits());
            } else {
                assert!(v == 10.0 || v == 40.0, "{v}");
            }
        }
    }

    fn value() -> impl Strategy<Value = f32> {
        prop_oneof![
            8 => 0.0f32..60.0,
            1 => Just(f32::from_bits(0x7fc0_0003)),
            1 => Just(f32::from_bits(0xffc0_0007)),
        ]
    }

    proptest! {
        #[test]
        fn widen_disparity_matches_the_reference(
            (sw, sh, fx, fy, extra_w, extra_h, small) in (1usize..14, 1usize..10, 1usize..6, 2usize..6)
                .prop_flat_map(|(sw, sh, fx, fy)| {
                    (Just(sw), Just(sh), Just(fx), Just(fy), 0..fx, 0..fy, proptest::collection::vec(
                        // Smooth runs (neighbours within f) and jumps, to exercise both branches.
                        prop_oneof![3 => value(), 1 => (0.0f32..2.0).prop_map(|v| 30.0 + v)], sw * sh))
                }),
        ) {
            // Any column and row factors: square, the rows alone (fx 1), the rows twice the columns'.
            let factors = (fx, fy);
            let (w, h) = (fx * sw + extra_w, fy * sh + extra_h);
            let got = widen_disparity(&small, sw, factors, w, h);
            let want = widen_disparity_reference(&small, sw, factors, w, h);
            for (i, (&a, &b)) in got.as_slice().iter().zip(want.as_slice()).enumerate() {
                prop_assert_eq!(a.to_bits(), b.to_bits(), "pixel {} of {}x{} (factors {:?})", i, w, h, factors);
            }
        }
    }
}
