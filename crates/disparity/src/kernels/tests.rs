//! Every SIMD kernel against its scalar reference, bit for bit, on each level this CPU runs.

use proptest::prelude::*;

use super::layout::*;
use super::scalar::*;
use super::*;

pub(super) mod row;

/// The 8-bit costs of one pixel: `narrow[k] = wide[k]` for the `nd` disparities, [`PAD_U8`] for
/// the padding lanes (`narrow.len()` is a multiple of [`LANES_U8`]). The costs must fit in `u8`.
fn narrow_costs(wide: &[u16], nd: usize, narrow: &mut [u8]) {
    for (k, n) in narrow.iter_mut().enumerate() {
        *n = if k < nd { wide[k] as u8 } else { PAD_U8 };
    }
}

/// [`narrow_costs`] for a whole row (`wide` with `wide_lanes` entries per pixel, `narrow` with
/// `narrow_lanes`): the reference of [`cost_row_u8`], which makes the 8-bit row
/// directly.
fn narrow_row(wide: &[u16], wide_lanes: usize, nd: usize, narrow: &mut [u8], narrow_lanes: usize) {
    assert!(nd <= wide_lanes && nd <= narrow_lanes && narrow_lanes.is_multiple_of(LANES_U8));
    assert_eq!(wide.len() / wide_lanes, narrow.len() / narrow_lanes);
    for (w, n) in wide.chunks_exact(wide_lanes).zip(narrow.chunks_exact_mut(narrow_lanes)) {
        narrow_costs(w, nd, n);
    }
}

#[allow(clippy::type_complexity)]
fn path_case() -> impl Strategy<Value = (usize, usize, u16, Vec<(Vec<u16>, u16, u16)>, Vec<u16>, bool)> {
    (1usize..=100, 0usize..4).prop_flat_map(|(nd, extra)| {
        let lanes = padded_lanes(nd);
        let nd_sum = nd.saturating_sub(extra).max(1);
        (
            Just(nd),
            Just(nd_sum),
            1u16..200,
            prop::collection::vec((prop::collection::vec(0u16..9000, lanes + 2), 0u16..4100, 1u16..4000), 4),
            prop::collection::vec(0u16..8000, nd_sum),
            any::<bool>(),
        )
    })
}

/// The BT rows of two grey rows (the right one reversed, as the cost kernels read it).
fn bt_rows(left: &[u16], right: &[u16]) -> (BtRow, BtRow) {
    let (mut bt_left, mut bt_right) = (BtRow::default(), BtRow::default());
    bt_left.fill(left, false);
    bt_right.fill(right, true);
    (bt_left, bt_right)
}

/// A random AD term (weight 0–8, cap 0–127) over `left` and `right`, if `ad` is given.
fn ad_rows<'a>(ad: Option<(u8, u8)>, left: &'a BtRow, right: &'a BtRow) -> Option<AdRows<'a>> {
    ad.map(|(weight, cap)| AdRows { left, right, weight: u16::from(weight % 9), cap: u16::from(cap % 128) })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]

    #[test]
    fn path_step_kernels_match_the_scalar_reference((nd, _nd_sum, p1, paths, sum0, acc) in path_case(),
                                                    costs in prop::collection::vec(0u16..=64, 128)) {
        let lanes = padded_lanes(nd);
        let mut cost = costs[..lanes].to_vec();
        cost[nd..].fill(JUNK_COST);
        let ins: [PathIn; 4] = std::array::from_fn(|i| PathIn { prev: &paths[i].0, prev_min: paths[i].1, p2: paths[i].2 });
        let run = |level: Level| {
            let mut outs = vec![vec![PAD; lanes + 2]; 4];
            let mut sum = sum0.clone();
            let [a, b, c, d] = &mut outs[..] else { unreachable!() };
            let mins = path_step(level, &cost, p1, ins, [&mut a[..], &mut b[..], &mut c[..], &mut d[..]], &mut sum, acc);
            let two = {
                let mut o2 = vec![vec![PAD; lanes + 2]; 2];
                let mut s2 = sum0.clone();
                let [e, f] = &mut o2[..] else { unreachable!() };
                let m = path_step(level, &cost, p1, [ins[0], ins[1]], [&mut e[..], &mut f[..]], &mut s2, acc);
                (o2, s2, m)
            };
            (outs, sum, mins, two)
        };
        let reference = run(Level::Scalar);
        for level in supported_levels() {
            prop_assert_eq!(&run(level), &reference, "{:?}", level);
        }
    }

    #[test]
    fn cost_row_kernels_match_the_scalar_reference(width in 1usize..120, nd_frac in 0.0f64..1.0,
                                                   min in -40i32..40, seed in any::<u64>(), worst in 9u16..=64,
                                                   ad in any::<Option<(u8, u8)>>(), step in 1u64..20000) {
        let nd = ((width as f64 * nd_frac) as usize).max(1);
        let mut s = seed | 1;
        let mut next = || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s };
        let left: Vec<u64> = (0..width).map(|_| next()).collect();
        let right: Vec<u64> = (0..width).map(|_| next()).collect();
        // Grey rows: random walks (small steps give BT values below the cap, large ones above).
        let mut walk = |width: usize| {
            let mut v = next() % 65536;
            let mut row = Vec::with_capacity(width);
            for _ in 0..width {
                let r = next();
                v = (v + r % step + 65536 - step / 2) % 65536;
                row.push(v as u16);
            }
            row
        };
        let (bt_left, bt_right) = bt_rows(&walk(width), &walk(width));
        let ad = ad_rows(ad, &bt_left, &bt_right);
        let worst = worst + ad.map_or(0, |a| a.cap);
        let lanes = padded_lanes(nd);
        let mut reference = vec![0u16; width * lanes];
        cost_row_scalar(&left, &right, min, nd, worst, ad, &mut reference);
        for level in supported_levels() {
            let f = Features::capped(level);
            let mut out = vec![1u16; width * lanes];
            cost_row(f, &left, &right, min, nd, worst, ad, &mut out);
            prop_assert_eq!(&out, &reference, "{:?}", f);
        }
    }

    /// The band cost kernels equal the per-pixel rows of [`cost_row_scalar`] at each pixel's
    /// band (and the scalar band reference), for bands anywhere in the range, wider than what
    /// is left of it, and at the image borders.
    #[test]
    fn cost_band_kernels_match_the_cost_row(width in 1usize..100, nd in 1i32..90, min in -20i32..20,
                                            seed in any::<u64>(), worst in 9u16..=64,
                                            ad in any::<Option<(u8, u8)>>()) {
        let mut s = seed | 1;
        let mut next = || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s };
        let left: Vec<u64> = (0..width).map(|_| next()).collect();
        let right: Vec<u64> = (0..width).map(|_| next()).collect();
        let grey = |next: &mut dyn FnMut() -> u64| (0..width).map(|_| (next() % 65536) as u16).collect::<Vec<u16>>();
        let (grey_left, grey_right) = (grey(&mut next), grey(&mut next));
        let (bt_left, bt_right) = bt_rows(&grey_left, &grey_right);
        let ad = ad_rows(ad, &bt_left, &bt_right);
        let worst = worst + ad.map_or(0, |a| a.cap);
        let max = min + nd;
        let mut offsets = Vec::new();
        let mut lanes = Vec::new();
        let mut starts = Vec::new();
        let mut total = 0;
        for _ in 0..width {
            let o = min + (next() % nd as u64) as i32;
            let n = 16 * (1 + (next() % 4) as u16);
            offsets.push(o);
            lanes.push(n);
            starts.push(total);
            total += usize::from(n);
        }
        let bands = BandRow { offsets: &offsets, lanes: &lanes, starts: &starts };
        let mut reference = vec![0u16; total];
        scalar::cost_bands_scalar(&left, &right, bands, max, worst, ad, &mut reference);
        // Pixel x's band is the row of costs from its offset with as many real disparities.
        for x in 0..width {
            let (o, n) = (offsets[x], usize::from(lanes[x]));
            let nd_x = ((max - o) as usize).min(n);
            let mut row = vec![0u16; width * padded_lanes(nd_x)];
            cost_row_scalar(&left, &right, o, nd_x, worst, ad, &mut row);
            let p = padded_lanes(nd_x);
            prop_assert_eq!(&reference[starts[x]..starts[x] + nd_x], &row[x * p..x * p + nd_x]);
            prop_assert!(reference[starts[x] + nd_x..starts[x] + n].iter().all(|&c| c == JUNK_COST));
        }
        for level in supported_levels() {
            let f = Features::capped(level);
            let mut out = vec![1u16; total];
            cost_bands(f, &left, &right, bands, max, worst, ad, &mut out);
            prop_assert_eq!(&out, &reference, "{:?}", f);
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]

    /// The 8-bit cost row equals the narrowed `u16` row (costs for `k < nd`, [`PAD_U8`]
    /// after) on every level, for widths, disparity counts (multiples of 32 or not, up to
    /// 256) and offsets (negative, past the width) that exercise interior and border pixels
    /// (rows up to 600 wide, so that the lean columns of up to 256 lanes occur),
    /// with and without the AD term (any weight the public `u8` allows).
    #[test]
    fn cost_row_u8_kernels_match_the_narrowed_scalar_reference(
        width in prop_oneof![1usize..200, 200usize..600], nd in prop_oneof![1usize..=64, 1usize..=256],
        min in prop_oneof![-8i32..8, -300i32..300], seed in any::<u64>(), worst in 9u16..=64,
        ad in any::<Option<(u8, u8)>>(), step in 1u64..20000,
    ) {
        let mut s = seed | 1;
        let mut next = || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s };
        let left: Vec<u64> = (0..width).map(|_| next()).collect();
        let right: Vec<u64> = (0..width).map(|_| next()).collect();
        let mut walk = |width: usize| {
            let mut v = next() % 65536;
            let mut row = Vec::with_capacity(width);
            for _ in 0..width {
                let r = next();
                v = (v + r % step + 65536 - step / 2) % 65536;
                row.push(v as u16);
            }
            row
        };
        let (bt_left, bt_right) = bt_rows(&walk(width), &walk(width));
        let ad = ad.map(|(weight, cap)| AdRows {
            left: &bt_left, right: &bt_right, weight: u16::from(weight), cap: u16::from(cap % (MAX_AD_CAP + 1)),
        });
        let worst = worst + ad.map_or(0, |a| a.cap);
        let (lanes, lanes8) = (padded_lanes(nd), padded_lanes_u8(nd));
        let mut wide = vec![0u16; width * lanes];
        cost_row_scalar(&left, &right, min, nd, worst, ad, &mut wide);
        let mut reference = vec![0u8; width * lanes8];
        narrow_row(&wide, lanes, nd, &mut reference, lanes8);
        let mut out = vec![1u8; width * lanes8];
        cost_row_u8_scalar(&left, &right, min, nd, worst, ad, &mut out);
        prop_assert_eq!(&out, &reference, "scalar");
        for level in supported_levels() {
            let f = Features::capped(level);
            // Also at an odd address: the kernel's stores must not depend on alignment.
            for offset in [0, 1] {
                let mut buf = vec![1u8; width * lanes8 + offset];
                let out = &mut buf[offset..];
                cost_row_u8(f, &left, &right, min, nd, worst, ad, out);
                prop_assert_eq!(&out[..], &reference[..], "{:?} offset {}", f, offset);
            }
        }
    }
}

proptest! {
    /// The P2 row equals its scalar reference on every level, for any 16-bit intensities (steps
    /// of every size, so every table entry and both table halves are read) and lengths that
    /// leave a partial last block.
    #[test]
    fn p2_row_kernels_match_the_scalar_reference(
        pairs in prop::collection::vec((any::<u16>(), any::<u16>()), 0..150), seed in any::<u64>(),
    ) {
        let mut s = seed | 1;
        let table: [u8; 256] = std::array::from_fn(|_| { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s as u8 });
        let (a, b): (Vec<u16>, Vec<u16>) = pairs.into_iter().unzip();
        let mut reference = vec![0u8; a.len()];
        p2_row_u8_scalar(&table, &a, &b, &mut reference);
        for level in supported_levels() {
            let mut out = vec![1u8; a.len()];
            p2_row_u8(level, &table, &a, &b, &mut out);
            prop_assert_eq!(&out, &reference, "{:?}", level);
        }
    }
}

proptest! {
    /// Rows of disparities with holes (NaNs of several payloads and signs), equal values, both
    /// zeros and infinities, of lengths that leave partial blocks of 16 and 8: every level's
    /// median equals the sorting reference bit for bit, and so do the lanes the other levels
    /// compile.
    #[test]
    fn median3x3_row_kernels_match_the_scalar_reference(
        values in prop::collection::vec(0u8..40, 3..160), holes in 0u8..10, seed in any::<u64>(),
    ) {
        let width = values.len() / 3;
        let mut s = seed | 1;
        let mut next = move || { s ^= s << 13; s ^= s >> 7; s ^= s << 17; s };
        let special = [f32::NAN, -f32::NAN, f32::from_bits(0x7fc0_0003), -0.0, 0.0, f32::INFINITY];
        let framed: Vec<Vec<f32>> = values.chunks_exact(width).take(3).map(|row| {
            std::iter::once(f32::NAN).chain(row.iter().map(|&v| {
                let r = next();
                if (r % 10) < u64::from(holes) {
                    special[(r >> 8) as usize % 3]
                } else if r % 97 == 11 {
                    special[3 + (r >> 8) as usize % 3]
                } else {
                    f32::from(v) * 0.25 - 2.0
                }
            })).chain(std::iter::once(f32::NAN)).collect()
        }).collect();
        let rows = [&framed[0][..], &framed[1][..], &framed[2][..]];
        let mut reference = vec![1.0f32; width];
        median3x3_row_scalar(rows, &mut reference);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for level in supported_levels() {
            let mut out = vec![1.0f32; width];
            median3x3_row(level, rows, &mut out);
            prop_assert_eq!(bits(&out), bits(&reference), "{:?}", level);
        }
        let mut lanes = vec![1.0f32; width];
        median3x3_row_lanes(rows, &mut lanes);
        prop_assert_eq!(bits(&lanes), bits(&reference));
    }
}

proptest! {
    #[test]
    fn argmin_kernels_match_the_scalar_reference(values in prop::collection::vec(0u16..40, 1..150),
                                                 big in any::<bool>()) {
        let values: Vec<u16> = values.iter().map(|&v| if big { v.wrapping_mul(1700) } else { v }).collect();
        for level in supported_levels() {
            prop_assert_eq!(argmin(level, &values), argmin_scalar(&values), "{:?}", level);
        }
    }

    #[test]
    fn keep_smaller_kernels_match_the_scalar_reference(rows in prop::collection::vec((0u16..30, 0u16..30, 0u16..500), 1..150),
                                                       first in 0u16..1000) {
        let costs: Vec<u16> = rows.iter().map(|r| r.0).collect();
        let best: Vec<u16> = rows.iter().map(|r| r.1).collect();
        let index: Vec<u16> = rows.iter().map(|r| r.2).collect();
        let (mut b0, mut i0) = (best.clone(), index.clone());
        keep_smaller_scalar(&costs, first, &mut b0, &mut i0);
        for level in supported_levels() {
            let (mut b, mut i) = (best.clone(), index.clone());
            keep_smaller(level, &costs, first, &mut b, &mut i);
            prop_assert_eq!((&b, &i), (&b0, &i0), "{:?}", level);
        }
    }
}

#[test]
fn a_start_from_zero_returns_the_cost() {
    let nd = 40;
    let lanes = padded_lanes(nd);
    let mut cost: Vec<u16> = (0..lanes as u16).map(|k| k % 61).collect();
    cost[nd..].fill(JUNK_COST);
    let zero = vec![0u16; lanes + 2];
    for level in supported_levels() {
        let mut out = vec![PAD; lanes + 2];
        let mut sum = vec![0u16; nd];
        let [m] = path_step(
            level,
            &cost,
            10,
            [PathIn { prev: &zero, prev_min: 0, p2: 80 }],
            [&mut out[..]],
            &mut sum,
            false,
        );
        assert_eq!(&out[1..=lanes], &cost[..]);
        assert_eq!(&sum[..], &cost[..nd]);
        assert_eq!(m, 0);
    }
}

/// Random path inputs whose values obey the 8-bit bound: costs up to `max_cost`, previous
/// path costs within `0..=max_cost + p2` (as the recurrence produces), padded as the
/// aggregation pads them.
fn case() -> impl Strategy<Value = (usize, usize, u16, u16, u16, Vec<u64>, bool)> {
    (
        1usize..200,
        0.0f64..1.0,
        1u16..60,
        1u16..120,
        10u16..140,
        prop::collection::vec(any::<u64>(), 4),
        any::<bool>(),
    )
        .prop_map(|(nd, frac, p1, p2, max_cost, seeds, acc)| {
            let nd_sum = ((nd as f64 * frac) as usize).clamp(1, nd);
            (nd, nd_sum, p1, p2, max_cost, seeds, acc)
        })
        .prop_filter("8-bit bound", |&(_, _, p1, p2, max_cost, _, _)| fits(max_cost, p1, p2))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    /// The 8-bit step equals the 16-bit reference step lane for lane (sums, path costs and
    /// minima) whenever the values fit, on every level this CPU runs.
    #[test]
    fn u8_step_equals_the_u16_step((nd, nd_sum, p1, p2, max_cost, seeds, acc) in case()) {
        let mut state = seeds[0] | 1;
        let mut next = move |bound: u16| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state % (u64::from(bound) + 1)) as u16
        };
        let lanes16 = padded_lanes(nd);
        let lanes8 = padded_lanes_u8(nd);
        let cost16: Vec<u16> = (0..lanes16).map(|k| if k < nd { next(max_cost) } else { JUNK_COST }).collect();
        let mut cost8 = vec![0u8; lanes8];
        narrow_costs(&cost16, nd, &mut cost8);
        // Two paths: one continuing (previous costs with their true minimum), one starting.
        let prev_min = next(max_cost);
        let prev16: Vec<u16> = (0..lanes16 + 2)
            .map(|k| match k {
                0 => PAD,
                k if k > nd => if k == lanes16 + 1 { PAD } else { JUNK_COST },
                _ => prev_min + next(max_cost + p2 - prev_min),
            })
            .collect();
        let prev_min = prev16[1..=nd].iter().copied().min().unwrap();
        let prev8: Vec<u8> = (0..lanes8 + 2).map(|k| if (1..=nd).contains(&k) { prev16[k] as u8 } else { PAD_U8 }).collect();
        let zero16 = vec![0u16; lanes16 + 2];
        let zero8 = vec![0u8; lanes8 + 2];
        let sum0: Vec<u16> = (0..nd_sum).map(|_| next(1000)).collect();

        let ins16 = [PathIn { prev: &prev16, prev_min, p2 }, PathIn { prev: &zero16, prev_min: 0, p2: 0 }];
        let (mut a16, mut b16) = (vec![0u16; lanes16 + 2], vec![0u16; lanes16 + 2]);
        let mut sum16 = sum0.clone();
        let mins16 = path_step_scalar(&cost16, p1, ins16, [&mut a16, &mut b16], &mut sum16, acc);

        for level in supported_levels() {
            let ins8 = [
                PathInU8 { prev: &prev8, prev_min: prev_min as u8, p2: p2 as u8 },
                PathInU8 { prev: &zero8, prev_min: 0, p2: 0 },
            ];
            let (mut a8, mut b8) = (vec![0u8; lanes8 + 2], vec![0u8; lanes8 + 2]);
            let mut sum8 = sum0.clone();
            let mins8 = path_step_u8(level, &cost8, p1 as u8, ins8, [&mut a8, &mut b8], &mut sum8, acc);
            prop_assert_eq!(&sum8, &sum16, "{:?} sums", level);
            prop_assert_eq!(mins8.map(u16::from), mins16, "{:?} minima", level);
            for (out8, out16) in [(&a8, &a16), (&b8, &b16)] {
                let real8: Vec<u16> = out8[1..=nd].iter().map(|&v| u16::from(v)).collect();
                prop_assert_eq!(&real8[..], &out16[1..=nd], "{:?} path costs", level);
                prop_assert!(out8[nd + 1..=lanes8].iter().all(|&v| v == PAD_U8), "{:?} padding", level);
            }
        }
    }
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
            for (k, t) in super::x86_avx512::transpose_64x64(v).into_iter().enumerate() {
                _mm512_storeu_si512(out.as_mut_ptr().add(8 * k).cast(), t);
            }
        }
        for (p, &o) in out.iter().enumerate() {
            let expected = (0..64).fold(0u64, |acc, i| acc | ((rows[i] >> p) & 1) << i);
            assert_eq!(o, expected, "row {p}");
        }
    }
}

/// The default window's computed offsets are its table's.
#[test]
fn offset_in_9x7_is_the_window_table() {
    for pw in [16, 393, 1000] {
        let window = Window { width: 9, height: 7, tolerance: 0 };
        let table = window_offsets(window, pw);
        let computed: Vec<usize> = (0..62).map(|i| offset_in_9x7(i, pw)).collect();
        assert_eq!(computed, table[..62]);
    }
}
