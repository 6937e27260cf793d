//! Post-filters on a finished disparity map.

use rayon::prelude::*;

use crate::DisparityMap;

/// 3×3 median over the valid (non-NaN) disparities around each valid pixel; invalid pixels stay
/// invalid. Removes isolated wrong matches and smooths subpixel noise without blurring edges.
/// Equal to [`median_3x3_reference`]: the values are ordered by `f32::total_cmp` through their
/// integer keys, and every window, holes and the map's border included, goes through a
/// 19-exchange median network instead of a sort ([`crate::kernels::median3x3_row`]).
pub(crate) fn median_3x3(disparity: &DisparityMap) -> DisparityMap {
    let (width, height) = disparity.size();
    let mut out = disparity.clone();
    let level = crate::kernels::features().level;
    let rows_per_task = height.div_ceil(16).max(1);
    out.as_mut_slice().par_chunks_mut(width.max(1) * rows_per_task).enumerate().for_each(|(task, rows)| {
        // The rows above, at and below each row, framed by holes (the windows of border pixels
        // reach beyond the map).
        let mut framed: [Vec<f32>; 3] = std::array::from_fn(|_| vec![f32::NAN; width + 2]);
        let load = |line: &mut Vec<f32>, r: usize| {
            if r < height {
                line[1..=width].copy_from_slice(&disparity.as_slice()[r * width..(r + 1) * width]);
            } else {
                line.fill(f32::NAN);
            }
        };
        let y0 = task * rows_per_task;
        load(&mut framed[0], y0.wrapping_sub(1));
        load(&mut framed[1], y0);
        for (i, row) in rows.chunks_mut(width.max(1)).enumerate() {
            // The rows move up by one: only the row below is read anew.
            if i > 0 {
                framed.rotate_left(1);
            }
            load(&mut framed[2], y0 + i + 1);
            let [above, at, below] = &framed;
            crate::kernels::median3x3_row(level, [above, at, below], row);
        }
    });
    out
}

/// The original median, the readable reference of [`median_3x3`].
#[cfg(test)]
pub(crate) fn median_3x3_reference(disparity: &DisparityMap) -> DisparityMap {
    let (width, height) = disparity.size();
    let mut out = disparity.clone();
    out.as_mut_slice().par_chunks_mut(width.max(1)).enumerate().for_each(|(y, row)| {
        let mut window = [0f32; 9];
        for (x, o) in row.iter_mut().enumerate() {
            if o.is_nan() {
                continue;
            }
            let mut n = 0;
            for yy in y.saturating_sub(1)..(y + 2).min(height) {
                for xx in x.saturating_sub(1)..(x + 2).min(width) {
                    let v = disparity.get(xx, yy);
                    if !v.is_nan() {
                        window[n] = v;
                        n += 1;
                    }
                }
            }
            let w = &mut window[..n];
            w.sort_unstable_by(f32::total_cmp);
            *o = if n % 2 == 1 { w[n / 2] } else { 0.5 * (w[n / 2 - 1] + w[n / 2]) };
        }
    });
    out
}

/// Edge-aware weighted median: each pixel becomes the weighted median of the valid disparities
/// in its `(2·radius + 1)²` window, a neighbour weighing
/// `exp(-ΔI² / (2·σc²) - r² / (2·σs²))` for its grey-level difference `ΔI` to the centre in
/// `guide` (8-bit levels) and its distance `r` (`σs = radius`). Disparity edges move onto the
/// image edges, which undoes most of the edge fattening of window costs. Invalid pixels stay
/// invalid unless `fill_holes`, where they take the weighted median of their valid neighbours.
pub fn weighted_median(
    disparity: &DisparityMap,
    guide: &crate::GrayImage,
    radius: usize,
    sigma_color: f32,
    fill_holes: bool,
) -> DisparityMap {
    weighted_median_masked(disparity, guide, radius, sigma_color, fill_holes, None)
}

/// [`weighted_median`] at the depth edges only: pixels whose `(2·radius + 1)²` window holds
/// valid disparities more than `jump` px apart. Elsewhere the window's disparities agree, so the
/// median would change them by at most `jump`; skipping them makes the filter several times
/// cheaper on typical maps, where depth edges cover a small share of the pixels.
pub(crate) fn weighted_median_at_edges(
    disparity: &DisparityMap,
    guide: &crate::GrayImage,
    radius: usize,
    sigma_color: f32,
    jump: f32,
) -> DisparityMap {
    let edges = depth_edges(disparity, radius, jump);
    weighted_median_masked(disparity, guide, radius, sigma_color, false, Some(&edges))
}

/// 1 where the valid disparities of the `(2·radius + 1)²` window around a pixel span more than
/// `jump`, else 0 (separable running minimum and maximum).
fn depth_edges(disparity: &DisparityMap, radius: usize, jump: f32) -> crate::Image<u8> {
    let (w, h) = disparity.size();
    let (mut lo, mut hi) = (vec![f32::INFINITY; w * h], vec![f32::NEG_INFINITY; w * h]);
    for y in 0..h {
        let row = disparity.row(y);
        for x in 0..w {
            for &v in &row[x.saturating_sub(radius)..(x + radius + 1).min(w)] {
                if !v.is_nan() {
                    lo[y * w + x] = lo[y * w + x].min(v);
                    hi[y * w + x] = hi[y * w + x].max(v);
                }
            }
        }
    }
    crate::Image::from_fn(w, h, |x, y| {
        let (mut a, mut b) = (f32::INFINITY, f32::NEG_INFINITY);
        for yy in y.saturating_sub(radius)..(y + radius + 1).min(h) {
            a = a.min(lo[yy * w + x]);
            b = b.max(hi[yy * w + x]);
        }
        u8::from(b - a > jump)
    })
}

fn weighted_median_masked(
    disparity: &DisparityMap,
    guide: &crate::GrayImage,
    radius: usize,
    sigma_color: f32,
    fill_holes: bool,
    only_at: Option<&crate::Image<u8>>,
) -> DisparityMap {
    let (width, height) = disparity.size();
    assert_eq!(guide.size(), (width, height), "guide image size");
    if radius == 0 || width == 0 {
        return disparity.clone();
    }
    let colour: Vec<f32> =
        (0..256).map(|d| (-((d * d) as f32) / (2.0 * sigma_color * sigma_color)).exp()).collect();
    let side = 2 * radius + 1;
    let sigma_space = radius as f32;
    let space: Vec<f32> = (0..side * side)
        .map(|i| {
            let (dx, dy) = ((i % side) as f32 - radius as f32, (i / side) as f32 - radius as f32);
            (-(dx * dx + dy * dy) / (2.0 * sigma_space * sigma_space)).exp()
        })
        .collect();
    let mut out = disparity.clone();
    out.as_mut_slice().par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        // (disparity, weight) packed in one u64, the disparity's total-order bits above the
        // weight's (positive: its bits order as it does): sorting integers is about twice as
        // fast as sorting pairs with a float comparison, and orders the disparities alike
        // (equal ones by weight: their weights are summed in a fixed order).
        let mut window: Vec<u64> = Vec::with_capacity(side * side);
        let ys = y.saturating_sub(radius)..(y + radius + 1).min(height);
        for (x, o) in row.iter_mut().enumerate() {
            if o.is_nan() && !fill_holes {
                continue;
            }
            if let Some(edges) = only_at {
                if edges.row(y)[x] == 0 {
                    continue;
                }
            }
            let centre = guide.get(x, y) / 257;
            let xs = x.saturating_sub(radius)..(x + radius + 1).min(width);
            window.clear();
            let mut total = 0.0;
            for yy in ys.clone() {
                let drow = disparity.row(yy);
                let grow = guide.row(yy);
                let srow = &space[(yy + radius - y) * side..];
                for xx in xs.clone() {
                    let d = drow[xx];
                    if d.is_nan() {
                        continue;
                    }
                    let w = colour[usize::from((grow[xx] / 257).abs_diff(centre))] * srow[xx + radius - x];
                    window.push(u64::from(order_key(d)) << 32 | u64::from(w.to_bits()));
                    total += w;
                }
            }
            if window.is_empty() {
                continue;
            }
            window.sort_unstable();
            let mut acc = 0.0;
            for &key in &window {
                acc += f32::from_bits(key as u32);
                if acc >= 0.5 * total {
                    *o = from_order_key((key >> 32) as u32);
                    break;
                }
            }
        }
    });
    out
}

/// `d`'s bits mapped so that unsigned order is [`f32::total_cmp`]'s order.
fn order_key(d: f32) -> u32 {
    let bits = d.to_bits();
    if bits & 0x8000_0000 != 0 {
        !bits
    } else {
        bits | 0x8000_0000
    }
}

/// The inverse of [`order_key`].
fn from_order_key(key: u32) -> f32 {
    f32::from_bits(if key & 0x8000_0000 != 0 { key & 0x7fff_ffff } else { !key })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn order_keys_sort_as_total_cmp_and_invert() {
        let values = [-3.5f32, -0.25, -0.0, 0.0, 1e-30, 0.25, 7.0, 64.125, f32::MAX, f32::NEG_INFINITY];
        for &a in &values {
            assert_eq!(from_order_key(order_key(a)).to_bits(), a.to_bits());
            for &b in &values {
                assert_eq!(order_key(a).cmp(&order_key(b)), a.total_cmp(&b), "{a} vs {b}");
            }
        }
    }

    #[test]
    fn median_matches_the_reference_on_random_maps() {
        let mut s = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        for (w, h) in [(1, 1), (2, 3), (7, 5), (40, 31), (75, 9)] {
            for holes in [0, 3, 10] {
                let d = DisparityMap::from_fn(w, h, |_, _| {
                    let r = next();
                    if r % 10 < holes {
                        f32::NAN
                    } else {
                        [0.0, -0.0, 1.5, -2.25, 3.0][(r >> 8) as usize % 5] + ((r >> 20) % 64) as f32 * 0.25
                    }
                });
                let (a, b) = (median_3x3(&d), median_3x3_reference(&d));
                let same = a
                    .as_slice()
                    .iter()
                    .zip(b.as_slice())
                    .all(|(p, q)| p.to_bits() == q.to_bits() || (p.is_nan() && q.is_nan()));
                assert!(same, "{w}x{h} holes {holes}");
            }
        }
    }

    #[test]
    fn median_removes_an_outlier_and_keeps_holes() {
        let mut d = DisparityMap::new(5, 5, 10.0);
        d.set(2, 2, 40.0);
        d.set(0, 0, f32::NAN);
        let m = median_3x3(&d);
        assert_eq!(m.get(2, 2), 10.0);
        assert!(m.get(0, 0).is_nan());
        assert_eq!(m.get(4, 4), 10.0);
    }
}
