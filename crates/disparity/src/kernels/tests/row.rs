//! The register row kernels (AVX2, AVX-512, NEON) against the per-pixel scalar step.

use crate::kernels::layout::{padded_lanes_u8, FromRow, PathIn, PAD_U8};
use crate::kernels::scalar::path_step_u8_scalar;
use crate::kernels::{row_u8, row_u8_available, supported_levels, Level};
use proptest::prelude::*;
use std::cell::Cell;

thread_local! {
    /// Turns the VBMI kernel off (to test the other one on CPUs that have both).
    pub(in crate::kernels) static NO_VBMI: Cell<bool> = const { Cell::new(false) };
}

/// The readable reference of [`row_u8`]: the per-pixel scalar step along the row, returning
/// the paths' new costs and minima.
#[allow(clippy::too_many_arguments)]
fn row_u8_scalar<const K: usize>(
    cost: &[u8],
    lanes: usize,
    nd: usize,
    p1: u8,
    p2: &[u8],
    from_row: &mut [FromRow<'_>; K],
    sum: &mut [u16],
    reverse: bool,
    accumulate: bool,
) {
    let width = cost.len() / lanes;
    let stride = lanes + 2;
    let zero = vec![0u8; stride];
    let (mut prev, mut cur) = (vec![PAD_U8; stride], vec![PAD_U8; stride]);
    let mut prev_min = 0;
    for i in 0..width {
        let x = if reverse { width - 1 - i } else { i };
        let c = &cost[x * lanes..(x + 1) * lanes];
        let s = &mut sum[x * nd..(x + 1) * nd];
        let input = if i == 0 {
            PathIn { prev: &zero[..], prev_min: 0, p2: 0 }
        } else {
            PathIn { prev: &prev[..], prev_min, p2: p2[x] }
        };
        [prev_min] = path_step_u8_scalar(c, p1, [input], [&mut cur[..]], s, accumulate);
        std::mem::swap(&mut prev, &mut cur);
        for from in from_row.iter_mut() {
            let f = x as isize + from.dx;
            let input = if from.prev.is_empty() || f < 0 || f >= width as isize {
                PathIn { prev: &zero[..], prev_min: 0, p2: 0 }
            } else {
                let f = f as usize;
                PathIn {
                    prev: &from.prev[f * stride..(f + 1) * stride],
                    prev_min: from.prev_mins[f],
                    p2: from.p2[x],
                }
            };
            let out = &mut from.out[x * stride..(x + 1) * stride];
            [from.out_mins[x]] = path_step_u8_scalar(c, p1, [input], [out], s, true);
        }
    }
}

fn xorshift(seed: u64) -> impl FnMut() -> u64 {
    let mut s = seed | 1;
    move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        s
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn register_rows_match_the_scalar_steps(
        width in 1usize..50, nd in 1usize..=256, max_cost in 1u8..200, p1 in 1u8..30,
        p2_extra in 1u8..60, reverse in any::<bool>(), accumulate in any::<bool>(), paths in 0usize..4,
        first_row in any::<bool>(), seed in any::<u64>(),
    ) {
        let lanes = padded_lanes_u8(nd);
        let stride = lanes + 2;
        // Within the 8-bit bound: cost + P2 <= 254.
        let max_p2 = (u16::from(p1) + u16::from(p2_extra)).min(254 - u16::from(max_cost)) as u8;
        prop_assume!(max_p2 > p1);
        let mut next = xorshift(seed);
        let cost: Vec<u8> = (0..width * lanes)
            .map(|i| if i % lanes < nd { (next() % (u64::from(max_cost) + 1)) as u8 } else { PAD_U8 })
            .collect();
        let penalties = |next: &mut dyn FnMut() -> u64| -> Vec<u8> {
            (0..width).map(|_| p1 + 1 + (next() % u64::from(max_p2 - p1)) as u8).collect()
        };
        let p2 = penalties(&mut next);
        // Previous rows as the recurrence leaves them: path costs up to cost + P2, pads 255.
        let prev: Vec<Vec<u8>> = (0..3)
            .map(|_| {
                (0..width * stride)
                    .map(|i| {
                        let k = i % stride;
                        if k == 0 || k > nd { PAD_U8 } else { (next() % (u64::from(max_cost) + u64::from(max_p2) + 1)) as u8 }
                    })
                    .collect()
            })
            .collect();
        let mins: Vec<Vec<u8>> = prev.iter().map(|p| p.chunks(stride).map(|c| *c.iter().min().unwrap()).collect()).collect();
        let from_p2: Vec<Vec<u8>> = (0..3).map(|_| penalties(&mut next)).collect();
        let start: Vec<u16> = (0..width * nd).map(|_| (next() % 600) as u16).collect();
        let run = |level: Option<Level>| {
            let mut outs = vec![vec![7u8; width * stride]; 3];
            let mut out_mins = vec![vec![0u8; width]; 3];
            let mut s = start.clone();
            let mut o = outs.iter_mut();
            let mut om = out_mins.iter_mut();
            let mut from = |k: usize| FromRow {
                prev: if first_row { &[] } else { &prev[k][..] },
                prev_mins: if first_row { &[] } else { &mins[k][..] },
                dx: [0, -1, 1][k],
                p2: &from_p2[k],
                out: o.next().unwrap(),
                out_mins: om.next().unwrap(),
            };
            let ran = match (paths, level) {
                (0, None) => { row_u8_scalar::<0>(&cost, lanes, nd, p1, &p2, &mut [], &mut s, reverse, accumulate); true }
                (0, Some(l)) => row_u8::<0>(l, &cost, lanes, nd, p1, &p2, [], &mut s, reverse, accumulate, None),
                (1, None) => { row_u8_scalar(&cost, lanes, nd, p1, &p2, &mut [from(0)], &mut s, reverse, accumulate); true }
                (1, Some(l)) => row_u8(l, &cost, lanes, nd, p1, &p2, [from(0)], &mut s, reverse, accumulate, None),
                (_, None) => { row_u8_scalar(&cost, lanes, nd, p1, &p2, &mut [from(0), from(1), from(2)], &mut s, reverse, accumulate); true }
                (_, Some(l)) => row_u8(l, &cost, lanes, nd, p1, &p2, [from(0), from(1), from(2)], &mut s, reverse, accumulate, None),
            };
            (ran, s, outs, out_mins)
        };
        let (_, expected, expected_outs, expected_mins) = run(None);
        for (level, no_vbmi) in supported_levels().into_iter().flat_map(|l| [(l, false), (l, true)]) {
            NO_VBMI.with(|n| n.set(no_vbmi));
            let (ran, got, outs, out_mins) = run(Some(level));
            NO_VBMI.with(|n| n.set(false));
            if row_u8_available(level, lanes) {
                prop_assert!(ran, "the register kernel did not run");
            }
            if ran {
                prop_assert_eq!(&got, &expected, "{:?} sums", level);
                let k = if paths == 0 { 0 } else if paths == 1 { 1 } else { 3 };
                for p in 0..k {
                    for x in 0..width {
                        // Only the disparity lanes are written (the pads keep what was there).
                        let (a, b) = (&outs[p][x * stride + 1..x * stride + 1 + lanes], &expected_outs[p][x * stride + 1..x * stride + 1 + lanes]);
                        prop_assert_eq!(a, b, "{:?} path {} pixel {}", level, p, x);
                    }
                    prop_assert_eq!(&out_mins[p], &expected_mins[p], "{:?} path {} minima", level, p);
                }
            } else {
                prop_assert_eq!(&got, &start);
            }
        }
    }
}
