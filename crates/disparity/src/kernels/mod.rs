//! The SIMD kernels, grouped by instruction set, and the one place that picks among them.
//!
//! - [`layout`]: lane counts, paddings, sentinels and the kernels' plain input types; every
//!   kernel file imports it, it imports nothing from the crate.
//! - [`scalar`]: the readable reference of every kernel, and the fallback on every CPU.
//! - `x86_avx2`, `x86_avx512`, `aarch64_neon`: the `std::arch` versions, one file per instruction
//!   set.
//! - this module: [`Level`] and the cached CPU-feature check ([`features`]), and one dispatching
//!   entry point per kernel (the only `match` on [`Level`] in the crate, together with
//!   [`multiversion!`], which compiles a generic body once per level).
//!
//! Every SIMD kernel computes exactly what its scalar reference computes (tested on random inputs
//! with proptest on each level the machine supports, in `tests.rs`), so the disparity maps do not
//! depend on the CPU. See `SIMD.md` in the crate for where new kernels and instruction sets go.

use std::sync::OnceLock;

use layout::{
    padded_lanes, padded_lanes_u8, AdRows, BandRow, FromRow, PathIn, PathInU8, Samples, Trailing, Window,
    BT_PAD, LANES, LANES_U8, MAX_AD_CAP,
};

/// One register of the SGM recurrence (Hirschmüller 2008, eq. 13) for one path, written once for
/// every register width and lane type: loads the previous pixel's path costs at `prev` (lanes
/// `d - 1`, `d`, `d + 1` at offsets 0, 1, 2), forms `best = min(prev[d], min(prev[d - 1],
/// prev[d + 1]) + P1, prev_min + P2)` with saturating adds, combines it with the matching costs
/// `c`, stores the new path costs at `out` and evaluates to them.
///
/// `u16` lanes add the cost first (`(c + best) - prev_min`, saturating then wrapping: the padding
/// lanes hold large values), `u8` lanes subtract first (`c + (best - prev_min)`, exact because
/// the bracket lies in `0..=P2`); both are what the scalar references compute.
/// `U8_512_REGISTERS` is the step alone on registers (`c, prev[d], prev[d - 1], prev[d + 1], P1,
/// jump, prev_min`), for the row kernels that keep a path in registers (`U8_NEON_REGISTERS` its
/// NEON twin). `U16_NEON` and `U8_NEON` are the steps on 128-bit NEON registers.
#[cfg(any(target_arch = "x86_64", target_arch = "aarch64"))]
macro_rules! path_vector {
    (U16_512, $($rest:tt)*) => {
        path_vector!(@ [_mm512_loadu_si512, _mm512_storeu_si512, _mm512_min_epu16, _mm512_adds_epu16, _mm512_sub_epi16], cost_first, $($rest)*)
    };
    (U16_256, $($rest:tt)*) => {
        path_vector!(@ [_mm256_loadu_si256, _mm256_storeu_si256, _mm256_min_epu16, _mm256_adds_epu16, _mm256_sub_epi16], cost_first, $($rest)*)
    };
    (U8_512, $($rest:tt)*) => {
        path_vector!(@ [_mm512_loadu_si512, _mm512_storeu_si512, _mm512_min_epu8, _mm512_adds_epu8, _mm512_sub_epi8], bracket_first, $($rest)*)
    };
    (U8_256, $($rest:tt)*) => {
        path_vector!(@ [_mm256_loadu_si256, _mm256_storeu_si256, _mm256_min_epu8, _mm256_adds_epu8, _mm256_sub_epi8], bracket_first, $($rest)*)
    };
    (U16_NEON, $($rest:tt)*) => {
        path_vector!(@ [vld1q_u16, vst1q_u16, vminq_u16, vqaddq_u16, vsubq_u16], cost_first, $($rest)*)
    };
    (U8_NEON, $($rest:tt)*) => {
        path_vector!(@ [vld1q_u8, vst1q_u8, vminq_u8, vqaddq_u8, vsubq_u8], bracket_first, $($rest)*)
    };
    (U8_512_REGISTERS, $($rest:tt)*) => {
        path_vector!(@step [_mm512_min_epu8, _mm512_adds_epu8, _mm512_sub_epi8], bracket_first, $($rest)*)
    };
    (U8_256_REGISTERS, $($rest:tt)*) => {
        path_vector!(@step [_mm256_min_epu8, _mm256_adds_epu8, _mm256_sub_epi8], bracket_first, $($rest)*)
    };
    (U8_NEON_REGISTERS, $($rest:tt)*) => {
        path_vector!(@step [vminq_u8, vqaddq_u8, vsubq_u8], bracket_first, $($rest)*)
    };
    (@ [$load:ident, $store:ident, $min:ident, $adds:ident, $sub:ident], $order:ident,
     $c:expr, $prev:expr, $out:expr, $p1:expr, $jump:expr, $pmin:expr) => {{
        let prev = $prev;
        let l = $load(prev.cast());
        let m = $load(prev.add(1).cast());
        let r = $load(prev.add(2).cast());
        let v = path_vector!(@step [$min, $adds, $sub], $order, $c, m, l, r, $p1, $jump, $pmin);
        $store($out.cast(), v);
        v
    }};
    (@step [$min:ident, $adds:ident, $sub:ident], $order:ident,
     $c:expr, $m:expr, $l:expr, $r:expr, $p1:expr, $jump:expr, $pmin:expr) => {{
        let near = $adds($min($l, $r), $p1);
        let best = $min($min($m, near), $jump);
        path_vector!(@combine $order, $adds, $sub, $c, best, $pmin)
    }};
    (@combine cost_first, $adds:ident, $sub:ident, $c:expr, $best:expr, $pmin:expr) => {
        $sub($adds($c, $best), $pmin)
    };
    (@combine bracket_first, $adds:ident, $sub:ident, $c:expr, $best:expr, $pmin:expr) => {
        $adds($c, $sub($best, $pmin))
    };
}

#[cfg(target_arch = "aarch64")]
mod aarch64_neon;
pub(crate) mod layout;
pub(crate) mod scalar;
#[cfg(test)]
mod tests;
#[cfg(target_arch = "x86_64")]
mod x86_avx2;
#[cfg(target_arch = "x86_64")]
mod x86_avx512;

#[cfg(target_arch = "aarch64")]
use aarch64_neon as neon;
#[cfg(target_arch = "x86_64")]
use x86_avx2 as avx2;
/// Shared with `wta::fused_avx2`'s sweep.
#[cfg(target_arch = "x86_64")]
pub(crate) use x86_avx2::hmin_epu16_256;
#[cfg(target_arch = "x86_64")]
use x86_avx512 as avx512;

/// The instruction set the kernels use. Ordered: a level implies every lower one of its
/// architecture. Another architecture adds its variants under its own `cfg` (e.g. `Neon` on
/// `aarch64`), so each target's `match` lists only what it can run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Level {
    Scalar,
    #[cfg(target_arch = "x86_64")]
    Avx2,
    /// AVX-512F/BW/VL.
    #[cfg(target_arch = "x86_64")]
    Avx512,
    /// Advanced SIMD (128-bit), on every aarch64 CPU that runs Linux.
    #[cfg(target_arch = "aarch64")]
    Neon,
}

impl Level {
    /// Every level this crate has, lowest first.
    const ALL: &'static [Level] = &[
        Level::Scalar,
        #[cfg(target_arch = "x86_64")]
        Level::Avx2,
        #[cfg(target_arch = "x86_64")]
        Level::Avx512,
        #[cfg(target_arch = "aarch64")]
        Level::Neon,
    ];

    /// The name `STEREO_DISPARITY_SIMD` takes and the benchmarks report.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Level::Scalar => "scalar",
            #[cfg(target_arch = "x86_64")]
            Level::Avx2 => "avx2",
            #[cfg(target_arch = "x86_64")]
            Level::Avx512 => "avx512",
            #[cfg(target_arch = "aarch64")]
            Level::Neon => "neon",
        }
    }

    /// Whether this is the AVX-512 level (its own kernels: VPOPCNTDQ cost rows, GFNI census,
    /// the 64-lane row kernels, the 32-lane fused winner-takes-all). False on every other
    /// architecture.
    pub(crate) fn avx512(self) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self == Level::Avx512 {
            return true;
        }
        false
    }

    /// Whether the aggregation runs 8-bit path costs where they fit ([`layout::fits`]): at the
    /// levels with register row kernels for them (AVX2, AVX-512, NEON), whose 8-bit step holds
    /// twice the `u16` step's lanes per instruction and keeps the horizontal path in registers.
    pub(crate) fn u8_passes(self) -> bool {
        self != Level::Scalar
    }

    /// Whether this level's 8-bit passes make each strip row's matching costs again in the
    /// second pass of a one-shot call instead of keeping the first pass's: AVX-512's VPOPCNTDQ
    /// cost rows take less time than a fresh buffer's page faults; AVX2's and NEON's are
    /// dearer, and their passes keep them (`memory::plan`).
    pub(crate) fn remakes_u8_cost_rows(self) -> bool {
        self.avx512()
    }
}

/// What the CPU supports, detected once.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Features {
    pub level: Level,
    /// AVX-512 VPOPCNTQ (for the Hamming costs); only with [`Level::Avx512`].
    pub vpopcnt: bool,
    /// AVX-512 VBMI (byte permutations: the 8-bit cost row, the register row kernel); only with
    /// [`Level::Avx512`].
    pub vbmi: bool,
    /// AVX-512 VBMI and GFNI (the census bit-matrix transpose); only with [`Level::Avx512`].
    pub gfni: bool,
}

impl Features {
    /// This CPU's features with the level capped at `level` (the extensions only with AVX-512),
    /// for tests and benchmarks of a lower level.
    pub(crate) fn capped(level: Level) -> Features {
        let detected = detect();
        let level = detected.level.min(level);
        #[cfg(target_arch = "x86_64")]
        let wide = level == Level::Avx512;
        #[cfg(not(target_arch = "x86_64"))]
        let wide = false;
        Features {
            level,
            vpopcnt: detected.vpopcnt && wide,
            vbmi: detected.vbmi && wide,
            gfni: detected.gfni && wide,
        }
    }
}

/// The cached feature check. `STEREO_DISPARITY_SIMD=scalar|avx2|avx512|neon` caps the level (for
/// benchmarks and debugging); it never enables what the CPU lacks.
pub(crate) fn features() -> Features {
    static FEATURES: OnceLock<Features> = OnceLock::new();
    *FEATURES.get_or_init(|| {
        let top = *Level::ALL.last().expect("Scalar is always there");
        let cap = match std::env::var("STEREO_DISPARITY_SIMD") {
            Ok(name) => Level::ALL.iter().copied().find(|l| l.name() == name).unwrap_or(top),
            Err(_) => top,
        };
        Features::capped(cap)
    })
}

/// All levels this machine can run, lowest first (for tests and benchmarks).
#[allow(dead_code)]
pub(crate) fn supported_levels() -> Vec<Level> {
    let top = detect().level;
    Level::ALL.iter().copied().filter(|&l| l <= top).collect()
}

/// What the CPU has, uncapped; detected once.
fn detect() -> Features {
    static DETECTED: OnceLock<Features> = OnceLock::new();
    *DETECTED.get_or_init(|| {
        #[cfg(target_arch = "x86_64")]
        {
            let avx2 = is_x86_feature_detected!("avx2");
            let avx512 = is_x86_feature_detected!("avx512f")
                && is_x86_feature_detected!("avx512bw")
                && is_x86_feature_detected!("avx512vl");
            let vpopcnt = avx512 && is_x86_feature_detected!("avx512vpopcntdq");
            let vbmi = avx512 && is_x86_feature_detected!("avx512vbmi");
            let gfni = vbmi && is_x86_feature_detected!("gfni");
            let level = if avx512 {
                Level::Avx512
            } else if avx2 {
                Level::Avx2
            } else {
                Level::Scalar
            };
            Features { level, vpopcnt, vbmi, gfni }
        }
        #[cfg(target_arch = "aarch64")]
        {
            let level =
                if std::arch::is_aarch64_feature_detected!("neon") { Level::Neon } else { Level::Scalar };
            Features { level, vpopcnt: false, vbmi: false, gfni: false }
        }
        #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
        {
            Features { level: Level::Scalar, vpopcnt: false, vbmi: false, gfni: false }
        }
    })
}

/// Defines `fn $name(args) [-> ret]` that runs the `#[inline(always)]` generic body `$generic(args,
/// level)` compiled for the detected level: one `#[target_feature]` copy per SIMD level, so the
/// kernels called with that `level` inline into it.
macro_rules! multiversion {
    ($(#[$attr:meta])* $vis:vis fn $name:ident $(<$($g:ident: $bound:path),*>)?
     ($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? => $generic:path;) => {
        $(#[$attr])*
        #[allow(clippy::too_many_arguments)]
        $vis fn $name $(<$($g: $bound),*>)? ($($arg: $ty),*) $(-> $ret)? {
            /// # Safety
            /// The CPU must have AVX-512F/BW/VL.
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx2,popcnt")]
            #[allow(clippy::too_many_arguments)]
            unsafe fn avx512 $(<$($g: $bound),*>)? ($($arg: $ty),*) $(-> $ret)? {
                $generic($($arg),*, $crate::kernels::Level::Avx512)
            }
            /// # Safety
            /// The CPU must have AVX2.
            #[cfg(target_arch = "x86_64")]
            #[target_feature(enable = "avx2,popcnt")]
            #[allow(clippy::too_many_arguments)]
            unsafe fn avx2 $(<$($g: $bound),*>)? ($($arg: $ty),*) $(-> $ret)? {
                $generic($($arg),*, $crate::kernels::Level::Avx2)
            }
            /// # Safety
            /// The CPU must have NEON.
            #[cfg(target_arch = "aarch64")]
            #[target_feature(enable = "neon")]
            #[allow(clippy::too_many_arguments)]
            unsafe fn neon $(<$($g: $bound),*>)? ($($arg: $ty),*) $(-> $ret)? {
                $generic($($arg),*, $crate::kernels::Level::Neon)
            }
            match $crate::kernels::features().level {
                // SAFETY: the level was detected on this CPU.
                #[cfg(target_arch = "aarch64")]
                $crate::kernels::Level::Neon => unsafe { neon($($arg),*) },
                // SAFETY: the level was detected on this CPU.
                #[cfg(target_arch = "x86_64")]
                $crate::kernels::Level::Avx512 => unsafe { avx512($($arg),*) },
                // SAFETY: as above.
                #[cfg(target_arch = "x86_64")]
                $crate::kernels::Level::Avx2 => unsafe { avx2($($arg),*) },
                $crate::kernels::Level::Scalar => $generic($($arg),*, $crate::kernels::Level::Scalar),
            }
        }
    };
}
pub(crate) use multiversion;

/// One SGM step for `N` paths at one pixel (Hirschmüller 2008, eq. 13):
/// `out[k] = cost[k] + min(prev[k], prev[k±1] + P1, prev_min + P2) - prev_min` for each path;
/// writes the padded `out` vectors (entries `1..=lanes`), adds the `N` path costs of the first
/// `sum.len()` disparities into `sum` (or stores them when `accumulate` is false) and returns
/// each path's minimum.
///
/// `cost.len()` is the padded lane count (a multiple of [`LANES`]); `prev` and `out` have
/// `cost.len() + 2` entries; `sum.len() <= cost.len()`.
#[inline(always)]
pub(crate) fn path_step<const N: usize>(
    level: Level,
    cost: &[u16],
    p1: u16,
    ins: [PathIn<'_>; N],
    outs: [&mut [u16]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u16; N] {
    check_step_lengths(cost, &ins, &outs, sum);
    match level {
        // SAFETY: `Level::Avx512` is only chosen when the CPU has AVX-512F/BW/VL, and the lengths
        // the kernel reads and writes were checked above.
        #[cfg(target_arch = "x86_64")]
        Level::Avx512 => unsafe { avx512::path_step_avx512(cost, p1, ins, outs, sum, accumulate) },
        // SAFETY: `Level::Avx2` is only chosen when the CPU has AVX2; lengths checked above.
        #[cfg(target_arch = "x86_64")]
        Level::Avx2 => unsafe { avx2::path_step_avx2(cost, p1, ins, outs, sum, accumulate) },
        // SAFETY: `Level::Neon` is only chosen when the CPU has NEON; lengths checked above.
        #[cfg(target_arch = "aarch64")]
        Level::Neon => unsafe { neon::path_step_neon(cost, p1, ins, outs, sum, accumulate) },
        Level::Scalar => scalar::path_step_scalar(cost, p1, ins, outs, sum, accumulate),
    }
}

/// The lengths [`path_step`]'s kernels rely on: `cost` a whole number of [`LANES`] blocks, at
/// most that many sums, `prev` and `out` padded by one entry at each end.
#[inline(always)]
fn check_step_lengths<const N: usize>(
    cost: &[u16],
    ins: &[PathIn<'_>; N],
    outs: &[&mut [u16]; N],
    sum: &[u16],
) {
    let lanes = cost.len();
    assert!(lanes.is_multiple_of(LANES) && sum.len() <= lanes);
    for i in 0..N {
        assert!(ins[i].prev.len() == lanes + 2 && outs[i].len() == lanes + 2);
    }
}

/// [`path_step`] for callers compiled once per level (the `multiversion!` loops, which pass their
/// own level): the AVX2 step is inlined into them instead of called per pixel. Elsewhere use
/// [`path_step`] (the step's intrinsics would not be inlined into code compiled without AVX2).
#[inline(always)]
pub(crate) fn path_step_inlined<const N: usize>(
    level: Level,
    cost: &[u16],
    p1: u16,
    ins: [PathIn<'_>; N],
    outs: [&mut [u16]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u16; N] {
    #[cfg(target_arch = "x86_64")]
    if level == Level::Avx2 {
        check_step_lengths(cost, &ins, &outs, sum);
        // SAFETY: `Level::Avx2` is only chosen when the CPU has AVX2; lengths checked above.
        return unsafe { avx2::path_step_avx2_body(cost, p1, ins, outs, sum, accumulate) };
    }
    #[cfg(target_arch = "aarch64")]
    if level == Level::Neon {
        check_step_lengths(cost, &ins, &outs, sum);
        // SAFETY: `Level::Neon` is only chosen when the CPU has NEON; lengths checked above.
        return unsafe { neon::path_step_neon_body(cost, p1, ins, outs, sum, accumulate) };
    }
    path_step(level, cost, p1, ins, outs, sum, accumulate)
}

/// [`path_step`] on 8-bit path costs (exact when [`layout::fits`] holds for the costs and
/// penalties: a path cost is `C + (bracket in 0..=P2)`, so it stays within `0..=C_max + P2`, the
/// bracket is formed before the cost is added and nothing saturates; lanes past the last
/// disparity hold 255, above every real path cost). `cost.len()` is a multiple of [`LANES_U8`],
/// `prev` and `out` have `cost.len() + 2` entries, `sum.len() <= cost.len()`.
#[inline(always)]
pub(crate) fn path_step_u8<const N: usize>(
    level: Level,
    cost: &[u8],
    p1: u8,
    ins: [PathInU8<'_>; N],
    outs: [&mut [u8]; N],
    sum: &mut [u16],
    accumulate: bool,
) -> [u8; N] {
    let lanes = cost.len();
    assert!(lanes.is_multiple_of(LANES_U8) && sum.len() <= lanes);
    for i in 0..N {
        assert!(ins[i].prev.len() == lanes + 2 && outs[i].len() == lanes + 2);
    }
    match level {
        // SAFETY: `Level::Avx512` is only chosen when the CPU has AVX-512F/BW/VL, and the lengths
        // the kernel reads and writes were checked above.
        #[cfg(target_arch = "x86_64")]
        Level::Avx512 => unsafe { avx512::path_step_u8_avx512(cost, p1, ins, outs, sum, accumulate) },
        // SAFETY: `Level::Avx2` is only chosen when the CPU has AVX2; lengths checked above.
        #[cfg(target_arch = "x86_64")]
        Level::Avx2 => unsafe { avx2::path_step_u8_avx2(cost, p1, ins, outs, sum, accumulate) },
        // SAFETY: `Level::Neon` is only chosen when the CPU has NEON; lengths checked above.
        #[cfg(target_arch = "aarch64")]
        Level::Neon => unsafe { neon::path_step_u8_neon(cost, p1, ins, outs, sum, accumulate) },
        _ => scalar::path_step_u8_scalar(cost, p1, ins, outs, sum, accumulate),
    }
}

/// Checks the AD rows' lengths against a row of `width` census strings.
fn check_ad(ad: &Option<AdRows<'_>>, width: usize) {
    if let Some(ad) = ad {
        for row in [ad.left, ad.right] {
            assert!(row.value.len() == width + 2 * BT_PAD);
            assert!(row.lo.len() == row.value.len() && row.hi.len() == row.value.len());
        }
    }
}

/// Matching costs of one row, `lanes` entries per pixel (`out.len() == width * lanes`):
/// `out[x][k] = popcount(left[x] ^ right[x - min_disparity - k])` (plus, with `ad`,
/// `min(weight · BT(x, x - min_disparity - k), cap)`, see [`scalar::bt`]) for the disparities
/// `k < nd` whose right pixel is inside the row, `worst` for the other disparities below `nd`,
/// and [`layout::JUNK_COST`] for `nd <= k < lanes`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn cost_row(
    features: Features,
    left: &[u64],
    right: &[u64],
    min_disparity: i32,
    nd: usize,
    worst: u16,
    ad: Option<AdRows<'_>>,
    out: &mut [u16],
) {
    assert_eq!(left.len(), right.len());
    assert!(nd > 0 && out.len() == left.len() * padded_lanes(nd));
    check_ad(&ad, left.len());
    match features.level {
        // SAFETY: `vpopcnt` is only set when the CPU has AVX-512F/BW/VL and VPOPCNTDQ; lengths
        // were checked above.
        #[cfg(target_arch = "x86_64")]
        Level::Avx512 if features.vpopcnt => unsafe {
            avx512::cost_row_avx512(left, right, min_disparity, nd, worst, ad, out)
        },
        // SAFETY: AVX2 (which implies POPCNT on every CPU that has it) was detected; lengths were
        // checked above.
        #[cfg(target_arch = "x86_64")]
        Level::Avx512 | Level::Avx2 => unsafe {
            avx2::cost_row_avx2(left, right, min_disparity, nd, worst, ad, out)
        },
        // SAFETY: `Level::Neon` is only chosen when the CPU has NEON; lengths were checked above.
        #[cfg(target_arch = "aarch64")]
        Level::Neon => unsafe { neon::cost_row_neon(left, right, min_disparity, nd, worst, ad, out) },
        Level::Scalar => scalar::cost_row_scalar(left, right, min_disparity, nd, worst, ad, out),
    }
}

/// [`cost_row`] over per-pixel bands: pixel `x`'s `bands.lanes[x]` costs from disparity
/// `bands.offsets[x]` into `out[bands.starts[x]..]`, [`layout::JUNK_COST`] at and past
/// `range_max`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn cost_bands(
    features: Features,
    left: &[u64],
    right: &[u64],
    bands: BandRow<'_>,
    range_max: i32,
    worst: u16,
    ad: Option<AdRows<'_>>,
    out: &mut [u16],
) {
    let width = left.len();
    assert!(right.len() == width && bands.offsets.len() == width && bands.lanes.len() == width);
    assert!(bands.starts.len() >= width);
    for x in 0..width {
        let n = usize::from(bands.lanes[x]);
        assert!(n > 0 && n.is_multiple_of(LANES) && bands.starts[x] + n <= out.len());
        assert!(bands.offsets[x] < range_max);
    }
    check_ad(&ad, width);
    match features.level {
        // SAFETY: `vpopcnt` is only set when the CPU has AVX-512F/BW/VL and VPOPCNTDQ; lengths
        // and offsets were checked above.
        #[cfg(target_arch = "x86_64")]
        Level::Avx512 if features.vpopcnt => unsafe {
            avx512::cost_bands_avx512(left, right, bands, range_max, worst, ad, out)
        },
        // SAFETY: AVX2 (which implies POPCNT on every CPU that has it) was detected; lengths and
        // offsets were checked above.
        #[cfg(target_arch = "x86_64")]
        Level::Avx512 | Level::Avx2 => unsafe {
            avx2::cost_bands_avx2(left, right, bands, range_max, worst, ad, out)
        },
        // SAFETY: `Level::Neon` is only chosen when the CPU has NEON; lengths and offsets were
        // checked above.
        #[cfg(target_arch = "aarch64")]
        Level::Neon => unsafe { neon::cost_bands_neon(left, right, bands, range_max, worst, ad, out) },
        Level::Scalar => scalar::cost_bands_scalar(left, right, bands, range_max, worst, ad, out),
    }
}

/// [`cost_row`] straight to 8 bits, for the 8-bit passes: `out[x][k]` (`out.len() ==
/// width * padded_lanes_u8(nd)`) is the same cost for `k < nd` and [`layout::PAD_U8`] for the
/// padding lanes, i.e. [`cost_row`]'s output narrowed, without the `u16` row in between. Every
/// cost fits: census ≤ 64, the AD cap ≤ [`MAX_AD_CAP`] and `worst <= 255` (asserted).
#[allow(clippy::too_many_arguments)]
pub(crate) fn cost_row_u8(
    features: Features,
    left: &[u64],
    right: &[u64],
    min_disparity: i32,
    nd: usize,
    worst: u16,
    ad: Option<AdRows<'_>>,
    out: &mut [u8],
) {
    assert_eq!(left.len(), right.len());
    assert!(nd > 0 && out.len() == left.len() * padded_lanes_u8(nd));
    assert!(worst <= 255);
    if let Some(ad) = ad {
        assert!(ad.cap <= u16::from(MAX_AD_CAP));
    }
    check_ad(&ad, left.len());
    match features.level {
        // SAFETY: `vpopcnt` and `vbmi` are only set when the CPU has AVX-512F/BW/VL, VPOPCNTDQ and
        // VBMI; lengths and value bounds were checked above.
        #[cfg(target_arch = "x86_64")]
        Level::Avx512 if features.vpopcnt && features.vbmi => unsafe {
            avx512::cost_row_u8_avx512(left, right, min_disparity, nd, worst, ad, out)
        },
        // SAFETY: AVX2 (which implies POPCNT on every CPU that has it) was detected; lengths were
        // checked above.
        #[cfg(target_arch = "x86_64")]
        Level::Avx512 | Level::Avx2 => unsafe {
            avx2::cost_row_u8_avx2(left, right, min_disparity, nd, worst, ad, out)
        },
        // SAFETY: `Level::Neon` is only chosen when the CPU has NEON; lengths and bounds were
        // checked above.
        #[cfg(target_arch = "aarch64")]
        Level::Neon => unsafe { neon::cost_row_u8_neon(left, right, min_disparity, nd, worst, ad, out) },
        Level::Scalar => scalar::cost_row_u8_scalar(left, right, min_disparity, nd, worst, ad, out),
    }
}

/// The smallest value of a non-empty `values` and the index of its first occurrence.
#[inline(always)]
pub(crate) fn argmin(level: Level, values: &[u16]) -> (u16, usize) {
    assert!(!values.is_empty());
    match level {
        // SAFETY: `Level::Avx512` is only chosen when the CPU has AVX-512F/BW/VL.
        #[cfg(target_arch = "x86_64")]
        Level::Avx512 => unsafe { avx512::argmin_avx512(values) },
        // SAFETY: `Level::Avx2` is only chosen when the CPU has AVX2.
        #[cfg(target_arch = "x86_64")]
        Level::Avx2 => unsafe { avx2::argmin_avx2(values) },
        // SAFETY: `Level::Neon` is only chosen when the CPU has NEON.
        #[cfg(target_arch = "aarch64")]
        Level::Neon => unsafe { neon::argmin_neon(values) },
        Level::Scalar => scalar::argmin_scalar(values),
    }
}

/// Right-view winner-takes-all update: for each `j`, if `costs[j] < best[j]` then
/// `best[j] = costs[j]` and `index[j] = first_index + j` (so among equal costs the earliest
/// update stays). All three slices have the same length.
#[inline(always)]
pub(crate) fn keep_smaller(
    level: Level,
    costs: &[u16],
    first_index: u16,
    best: &mut [u16],
    index: &mut [u16],
) {
    assert!(best.len() == costs.len() && index.len() == costs.len());
    assert!(costs.len() + usize::from(first_index) <= usize::from(u16::MAX));
    match level {
        // SAFETY: `Level::Avx512` is only chosen when the CPU has AVX-512F/BW/VL; lengths checked.
        #[cfg(target_arch = "x86_64")]
        Level::Avx512 => unsafe { avx512::keep_smaller_avx512(costs, first_index, best, index) },
        // SAFETY: `Level::Avx2` is only chosen when the CPU has AVX2; lengths checked above.
        #[cfg(target_arch = "x86_64")]
        Level::Avx2 => unsafe { avx2::keep_smaller_avx2(costs, first_index, best, index) },
        // SAFETY: `Level::Neon` is only chosen when the CPU has NEON; lengths checked above.
        #[cfg(target_arch = "aarch64")]
        Level::Neon => unsafe { neon::keep_smaller_neon(costs, first_index, best, index) },
        Level::Scalar => scalar::keep_smaller_scalar(costs, first_index, best, index),
    }
}

/// The Birchfield–Tomasi inputs of `row` in order into `value`, `lo` and `hi` (each `row.len()`
/// entries), see [`scalar::bt_fill_in_order`].
pub(crate) fn bt_fill(level: Level, row: &[u16], value: &mut [u8], lo: &mut [u8], hi: &mut [u8]) {
    match level {
        // SAFETY: the level was detected on this CPU (AVX-512F/BW/VL implies AVX2).
        #[cfg(target_arch = "x86_64")]
        Level::Avx512 | Level::Avx2 => unsafe { avx2::bt_fill_avx2(row, value, lo, hi) },
        _ => scalar::bt_fill_in_order(row, value, lo, hi),
    }
}

/// The 8-bit P2 of each step between pixels of 16-bit intensities `a[i]` and `b[i]`:
/// `out[i] = table[|a[i] - b[i]| / 257]` (the step in 8-bit grey levels). 32 pixels per
/// instruction with AVX-512 VBMI (the table in four registers), else [`scalar::p2_row_u8_scalar`].
// Elsewhere there is only the scalar loop.
#[cfg_attr(not(target_arch = "x86_64"), allow(unused_variables))]
pub(crate) fn p2_row_u8(level: Level, table: &[u8; 256], a: &[u16], b: &[u16], out: &mut [u8]) {
    assert!(a.len() == out.len() && b.len() == out.len());
    #[cfg(target_arch = "x86_64")]
    if level.avx512() && Features::capped(level).vbmi {
        // SAFETY: AVX-512F/BW/VL (the level is only chosen when present) and VBMI (detected);
        // the lengths were checked above.
        unsafe { avx512::p2_row_u8_avx512(table, a, b, out) };
        return;
    }
    scalar::p2_row_u8_scalar(table, a, b, out)
}

/// The 3 × 3 median of one row of a disparity map over the valid values of each window
/// ([`scalar::median3x3_row_scalar`]): `rows` are the row above, the row and the row below,
/// each framed by one value on either side (NaN beyond the map), `out` the row's pixels. 16
/// pixels per step with AVX-512, 8 with AVX2, 4 with NEON; the last few (and the scalar level)
/// by the portable lanes ([`scalar::median3x3_row_lanes`]).
pub(crate) fn median3x3_row(level: Level, rows: [&[f32]; 3], out: &mut [f32]) {
    assert!(rows.iter().all(|r| r.len() == out.len() + 2));
    // Each SIMD kernel returns how many pixels it wrote; the next narrower one continues.
    #[allow(unused_mut)]
    let mut done = 0;
    // SAFETY (all three): the level is only chosen when the CPU has it (AVX-512F/BW/VL, AVX2,
    // NEON); lengths checked above.
    #[cfg(target_arch = "x86_64")]
    if level.avx512() {
        done = unsafe { avx512::median3x3_row_avx512(rows, out) };
    }
    #[cfg(target_arch = "x86_64")]
    if level >= Level::Avx2 {
        done += unsafe { avx2::median3x3_row_avx2(rows.map(|r| &r[done..]), &mut out[done..]) };
    }
    #[cfg(target_arch = "aarch64")]
    if level == Level::Neon {
        done = unsafe { neon::median3x3_row_neon(rows, out) };
    }
    let _ = level;
    scalar::median3x3_row_lanes(rows.map(|r| &r[done..]), &mut out[done..]);
}

/// The most lanes the AVX-512 register kernel keeps (four 64-lane registers); longer vectors
/// take the per-pixel kernel.
#[cfg(target_arch = "x86_64")]
const MAX_REGISTER_LANES: usize = 256;

/// The most lanes the NEON register kernel keeps (eight 16-lane registers of the 32; more would
/// spill the horizontal path to the stack).
#[cfg(target_arch = "aarch64")]
const MAX_REGISTER_LANES_NEON: usize = 128;

/// The most lanes the AVX2 register kernel keeps (four 32-lane registers of the 16).
#[cfg(target_arch = "x86_64")]
const MAX_REGISTER_LANES_AVX2: usize = 128;

/// Whether [`row_u8`] has a kernel for this level and lane count.
pub(crate) fn row_u8_available(level: Level, lanes: usize) -> bool {
    match level {
        Level::Scalar => false,
        #[cfg(target_arch = "x86_64")]
        Level::Avx2 => lanes <= MAX_REGISTER_LANES_AVX2,
        #[cfg(target_arch = "x86_64")]
        Level::Avx512 => lanes <= MAX_REGISTER_LANES,
        #[cfg(target_arch = "aarch64")]
        Level::Neon => lanes <= MAX_REGISTER_LANES_NEON,
    }
}

/// Runs one row of a pass: the horizontal path (right to left when `reverse`, else left to
/// right; entering pixel `x` from its predecessor costs `p2[x]`, the first pixel's entry is not
/// read) and the `K` paths from the previous row, storing (or, with `accumulate`, adding) the sum
/// of their path costs into `sum` (`nd` per pixel).
///
/// `cost` holds `lanes` 8-bit matching costs per pixel ([`crate::kernels::layout::padded_lanes_u8`]
/// lanes, 255 past the last disparity). With `trailing`, that row's ← path runs in the same loop.
/// Returns `false`, touching nothing, when this CPU or this lane count has no register kernel;
/// the caller then steps pixel by pixel.
#[allow(clippy::too_many_arguments)]
// Elsewhere there is no register kernel: only the lengths are checked before returning `false`.
#[cfg_attr(not(any(target_arch = "x86_64", target_arch = "aarch64")), allow(unused_variables))]
pub(crate) fn row_u8<const K: usize>(
    level: Level,
    cost: &[u8],
    lanes: usize,
    nd: usize,
    p1: u8,
    p2: &[u8],
    from_row: [FromRow<'_>; K],
    sum: &mut [u16],
    reverse: bool,
    accumulate: bool,
    trailing: Option<Trailing<'_>>,
) -> bool {
    assert!(lanes.is_multiple_of(LANES_U8) && nd <= lanes && lanes > 0);
    let width = cost.len() / lanes;
    assert!(cost.len() == width * lanes && p2.len() == width && sum.len() == width * nd);
    let stride = lanes + 2;
    for path in &from_row {
        assert!(path.prev.is_empty() || (path.prev.len() == width * stride && path.prev_mins.len() == width));
        assert!(path.dx.abs() <= 1 && path.p2.len() == width);
        assert!(path.out.len() == width * stride && path.out_mins.len() == width);
    }
    if let Some(t) = &trailing {
        assert!(t.cost.len() == cost.len() && t.p2.len() == width && t.sum.len() == sum.len());
    }
    if width == 0 || !row_u8_available(level, lanes) {
        return false;
    }
    // AVX-512 CPUs run rows of 32 lanes (up to 32 disparities) on the AVX2 kernel too: in one
    // 64-lane register half the lanes would be padding (tsukuba's row kernel: 0.68x the profile
    // samples). At 64 lanes two AVX2 registers take as long as one AVX-512 register, at 96 the
    // AVX2 kernel's three registers spill (docs/perf-notes.md, stop 48).
    #[cfg(target_arch = "x86_64")]
    if level == Level::Avx2 || (level == Level::Avx512 && lanes == 32) {
        macro_rules! run {
            ($nv:literal) => {
                // SAFETY: `row_u8_available` chose AVX2 or AVX-512 (only when the CPU has it,
                // and AVX-512 CPUs have AVX2); the lengths were checked above and
                // `lanes == 32 * $nv`.
                unsafe {
                    avx2::row_avx2::<$nv, K>(
                        cost, lanes, nd, p1, p2, from_row, sum, reverse, accumulate, trailing,
                    )
                }
            };
        }
        // `lanes` is a multiple of 32, at most MAX_REGISTER_LANES_AVX2.
        match lanes / 32 {
            1 => run!(1),
            2 => run!(2),
            3 => run!(3),
            _ => run!(4),
        }
        return true;
    }
    #[cfg(target_arch = "x86_64")]
    {
        // Tests turn the VBMI kernel off to cover the other one on CPUs that have both.
        #[cfg(test)]
        let allowed = !tests::row::NO_VBMI.with(|n| n.get());
        #[cfg(not(test))]
        let allowed = true;
        let vbmi = allowed && Features::capped(level).vbmi;
        macro_rules! run {
            ($nv:literal) => {
                // SAFETY: AVX-512 F/BW/VL is present (the level is only chosen when it is), VBMI
                // was detected for the VBMI kernel; the lengths were checked above and
                // `64 * ($nv - 1) < lanes <= 64 * $nv`.
                unsafe {
                    if vbmi {
                        avx512::row_avx512_vbmi::<$nv, K>(
                            cost, lanes, nd, p1, p2, from_row, sum, reverse, accumulate, trailing,
                        )
                    } else {
                        avx512::row_avx512::<$nv, K>(
                            cost, lanes, nd, p1, p2, from_row, sum, reverse, accumulate, trailing,
                        )
                    }
                }
            };
        }
        match lanes.div_ceil(64) {
            1 => run!(1),
            2 => run!(2),
            3 => run!(3),
            _ => run!(4),
        }
        true
    }
    #[cfg(target_arch = "aarch64")]
    {
        macro_rules! run {
            ($nv:literal) => {
                // SAFETY: `row_u8_available` chose NEON (only when the CPU has it); the lengths
                // were checked above and `nd <= 16 * $nv <= lanes <= 16 * $nv + 16`.
                unsafe {
                    neon::row_neon::<$nv, K>(
                        cost, lanes, nd, p1, p2, from_row, sum, reverse, accumulate, trailing,
                    )
                }
            };
        }
        // Only the registers holding disparities are stepped: `lanes` (a multiple of 32, at most
        // MAX_REGISTER_LANES_NEON) may end in a register of padding, whose path costs stay 255.
        // Seven registers took more instructions than eight (teddy with 100 disparities under
        // qemu: 610.4 against 590.8 M), so 97–112 disparities keep the eighth.
        match nd.div_ceil(16) {
            0 | 1 => run!(1),
            2 => run!(2),
            3 => run!(3),
            4 => run!(4),
            5 => run!(5),
            6 => run!(6),
            _ => run!(8),
        }
        true
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    false
}

/// The row kernels; chosen once per transform (tests run each one the machine supports).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum CensusKernel {
    Generic,
    #[cfg(target_arch = "x86_64")]
    Avx2,
    #[cfg(target_arch = "x86_64")]
    Avx512,
    #[cfg(target_arch = "x86_64")]
    Gfni,
    /// [`CensusKernel::Gfni`] on the high bytes, for 8-bit images (see `census::is_byte_scaled`).
    #[cfg(target_arch = "x86_64")]
    GfniBytes,
    #[cfg(target_arch = "aarch64")]
    Neon,
    /// [`CensusKernel::Neon`] on the high bytes, for 8-bit images (see `census::is_byte_scaled`).
    #[cfg(target_arch = "aarch64")]
    NeonBytes,
}

impl CensusKernel {
    /// The fastest kernel for `level`: the bit-matrix transpose needs AVX-512VBMI and GFNI on
    /// top of the AVX-512 level (Intel Ice Lake, AMD Zen 4 and later), older AVX-512 CPUs keep the plain kernel.
    pub(crate) fn for_level(level: Level) -> CensusKernel {
        #[cfg(target_arch = "x86_64")]
        {
            match level {
                Level::Avx512 if Features::capped(level).gfni => return CensusKernel::Gfni,
                Level::Avx512 => return CensusKernel::Avx512,
                Level::Avx2 => return CensusKernel::Avx2,
                Level::Scalar => {}
            }
        }
        #[cfg(target_arch = "aarch64")]
        if level == Level::Neon {
            return CensusKernel::Neon;
        }
        let _ = level;
        CensusKernel::Generic
    }

    /// The variant of this kernel on the high bytes of 8-bit images (see
    /// `census::is_byte_scaled`), if it has one, and the narrowest image that variant takes.
    pub(crate) fn on_bytes(self) -> Option<(CensusKernel, usize)> {
        match self {
            #[cfg(target_arch = "x86_64")]
            CensusKernel::Gfni => Some((CensusKernel::GfniBytes, 64)),
            #[cfg(target_arch = "aarch64")]
            CensusKernel::Neon => Some((CensusKernel::NeonBytes, 16)),
            _ => None,
        }
    }

    /// Whether the kernel pads the window rows as bytes (`census_row`'s `high_bytes`) rather
    /// than as samples (`padded`).
    pub(crate) fn reads_high_bytes(self) -> bool {
        match self {
            #[cfg(target_arch = "x86_64")]
            CensusKernel::GfniBytes => true,
            #[cfg(target_arch = "aarch64")]
            CensusKernel::NeonBytes => true,
            _ => false,
        }
    }
}

pub(crate) fn census_row(
    kernel: CensusKernel,
    image: Samples<'_>,
    window: Window,
    y: usize,
    padded: &mut [u16],
    #[allow(unused_variables)] high_bytes: &mut [u8],
    bits: &mut [u64],
) {
    match kernel {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `CensusKernel::Gfni` is only chosen when the CPU has AVX-512F/BW/VL/VBMI and GFNI.
        CensusKernel::Gfni => unsafe { avx512::census_row_gfni(image, window, y, padded, bits) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `CensusKernel::GfniBytes` is only made from `CensusKernel::Gfni`, so the CPU has
        // what it needs; the kernel checks the lengths and the width.
        CensusKernel::GfniBytes => unsafe {
            avx512::census_row_gfni_bytes(image, window, y, high_bytes, bits)
        },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `CensusKernel::Avx512` is only chosen at the AVX-512 level, detected on this CPU.
        CensusKernel::Avx512 => unsafe { avx512::census_row_avx512(image, window, y, padded, bits) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `CensusKernel::Avx2` is only chosen at the AVX2 level, detected on this CPU.
        CensusKernel::Avx2 => unsafe { avx2::census_row_avx2(image, window, y, padded, bits) },
        #[cfg(target_arch = "aarch64")]
        // SAFETY: `CensusKernel::Neon` is only chosen at the NEON level, detected on this CPU.
        CensusKernel::Neon => unsafe { neon::census_row_neon(image, window, y, padded, bits) },
        #[cfg(target_arch = "aarch64")]
        // SAFETY: `CensusKernel::NeonBytes` is only made from `CensusKernel::Neon`; the kernel
        // checks the lengths and the width.
        CensusKernel::NeonBytes => unsafe { neon::census_row_neon_bytes(image, window, y, high_bytes, bits) },
        CensusKernel::Generic => scalar::census_row_scalar(image, window, y, padded, bits),
    }
}
