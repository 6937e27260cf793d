//! The working-memory plan of [`crate::sgm`]: how many rows each strip of the two-pass
//! aggregation holds, and what the whole call needs, so a caller can bound it
//! ([`crate::SgmParams::max_memory`]) and report it ([`crate::planned_memory_bytes`]).

use crate::aggregate::{pass_state_bytes, StripPlan};
use crate::{Error, SgmParams};

/// Rows below a strip over which the backward pass warms up its paths (and, in single-pass
/// mode, rows above a thread's strip). SGM paths forget their start within a few dozen pixels:
/// on the Middlebury scenes 16 rows instead of 32 changed bad2 by at most 0.02 (default) and
/// 0.05 (`--fill`, reindeer) and saved about 6 % of the 8-path time on wood2.
pub(crate) const OVERLAP_ROWS: usize = 16;

/// The default strip volume (bytes), when [`SgmParams::max_memory`] does not ask for less: small
/// enough that the volume is mostly cache resident and cheap to fault in on a one-shot run, large
/// enough that the warm-up rows cost little.
pub(crate) const DEFAULT_STRIP_BYTES: usize = 16 << 20;

/// Strips are at least this many rows (unless the budget forces fewer), so the warm-up (16 rows,
/// backward pass only) stays a small share of the work.
pub(crate) const MIN_DEFAULT_STRIP_ROWS: usize = 96;

/// Bookkeeping per strip row (its lock and slices).
const ROW_SLOT_BYTES: usize = 64;

/// Rows per strip of the single-pass aggregation beyond which the image gets another strip...
/// (each strip after the first repeats [`OVERLAP_ROWS`] rows: at 4× the Middlebury size, matched
/// at about 550 rows, 128-row strips cost the fast preset 10–15 % on two threads)
const STREAM_STRIP_ROWS: usize = 512;

/// ... up to this many strips (and at least two, for two threads).
const MAX_STREAM_STRIPS: usize = 8;

/// The single-pass aggregation's strips for an image `height` rows high: a function of the image
/// alone, not of the pool's threads. Each strip's paths start from a warm-up over the
/// [`OVERLAP_ROWS`] rows above it, an approximation at its top edge, so strips cut per thread
/// made the map differ between machines (and, through the adaptation's coarse match, the default
/// preset's maps of pairs whose tones are corrected). Each strip beyond the first costs those
/// rows again.
pub(crate) fn stream_strips(height: usize) -> usize {
    (height / STREAM_STRIP_ROWS).clamp(2, MAX_STREAM_STRIPS).min(height.max(1))
}

/// What [`crate::sgm`] will allocate.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct MemoryPlan {
    /// The strips of the two-pass aggregation (unused in single-pass mode).
    pub strips: StripPlan,
    /// Strips of the single-pass aggregation ([`stream_strips`]).
    pub stream_strips: usize,
    /// Peak working memory, bytes.
    pub bytes: usize,
    /// The smallest plan still exceeds [`SgmParams::max_memory`] (then `bytes` is that plan's).
    pub too_large: bool,
}

impl MemoryPlan {
    /// An error if the plan does not fit the caller's bound.
    pub(crate) fn check(&self, width: usize, height: usize, params: &SgmParams) -> Result<(), Error> {
        if !self.too_large {
            return Ok(());
        }
        Err(Error::InvalidParameter {
            name: "max memory",
            message: format!(
                "{} bytes is too small for a {width}x{height} pair with {} disparities: at least {} \
                 bytes are needed",
                params.max_memory.unwrap_or(0),
                params.range.count(),
                self.bytes
            ),
        })
    }
}

/// Plans the memory for a `width × height` pair within `params.max_memory` if possible.
pub(crate) fn plan(width: usize, height: usize, params: &SgmParams) -> MemoryPlan {
    let nd = params.range.count();
    // Saturating throughout: an absurd size plans `usize::MAX` bytes (refused) instead of
    // overflowing.
    let pixels = width.saturating_mul(height);
    let census = pixels.saturating_mul(2 * 8);
    let disparity = pixels.saturating_mul(4 * if params.median { 2 } else { 1 });
    let fixed = census.saturating_add(disparity);
    let row_bytes = width.saturating_mul(nd).saturating_mul(2);
    let (strips, stream_strips, bytes, too_large) = if params.single_pass {
        let strips = stream_strips(height);
        // Two rows of sums and a second cost row: the ← path of each row runs beside the next
        // row's paths (at most the size of the `u16` cost row counted in the pass state).
        let held_cost = width.saturating_mul(crate::kernels::layout::padded_lanes(nd)).saturating_mul(2);
        let per_strip = pass_state_bytes(width, nd, params.paths)
            .saturating_add(row_bytes.saturating_mul(2))
            .saturating_add(held_cost);
        #[cfg(test)]
        let strips = tests::STRIPS.get().map_or(strips, |s| s.rows);
        let bytes = fixed.saturating_add(strips.saturating_mul(per_strip));
        #[cfg(test)]
        let overlap = tests::STRIPS.get().map_or(OVERLAP_ROWS, |s| s.overlap);
        #[cfg(not(test))]
        let overlap = OVERLAP_ROWS;
        let plan = StripPlan { rows: height, overlap, shared_costs: false };
        (plan, strips, bytes, params.max_memory.is_some_and(|m| bytes > m))
    } else {
        let fixed = fixed.saturating_add(pass_state_bytes(width, nd, params.paths).saturating_mul(2));
        let per_row = row_bytes.saturating_add(ROW_SLOT_BYTES);
        let default_rows = (DEFAULT_STRIP_BYTES / row_bytes.max(1)).max(MIN_DEFAULT_STRIP_ROWS);
        let mut rows = tuning("STEREO_DISPARITY_STRIP_ROWS").unwrap_or(default_rows).clamp(1, height.max(1));
        let mut too_large = false;
        if let Some(budget) = params.max_memory {
            let fit = budget.saturating_sub(fixed) / per_row;
            too_large = fit == 0;
            rows = rows.min(fit.max(1));
        }
        // Even strips: the same volume, but no short last strip paying a full warm-up.
        let count = height.div_ceil(rows.max(1)).max(1);
        let rows = height.div_ceil(count).max(1);
        let overlap = tuning("STEREO_DISPARITY_OVERLAP").unwrap_or(OVERLAP_ROWS);
        #[cfg(test)]
        let (rows, overlap) = tests::STRIPS.get().map_or((rows, overlap), |s| (s.rows, s.overlap));
        // The passes keep each strip row's matching costs for the second pass where that fits
        // the budget next to the strips planned above (so the strips, and the result, do not
        // depend on it): the `u16` passes always, 8-bit passes whose level remakes its cost rows
        // (`Level::remakes_u8_cost_rows`) only where the strip buffers are kept between calls.
        let u8_passes = crate::aggregate::u8_passes(worst_cost(params), params.p1, params.p2);
        let cost_row = crate::aggregate::cost_row_bytes(width, nd, u8_passes);
        let strip_bytes = rows.saturating_mul(per_row);
        let shared_bytes = rows.saturating_mul(cost_row);
        let with_costs = fixed.saturating_add(strip_bytes).saturating_add(shared_bytes);
        let recompute = u8_passes && crate::kernels::features().level.remakes_u8_cost_rows();
        let shared_costs = (!recompute || crate::buffer::keeping())
            && !matches!(params.max_memory, Some(m) if with_costs > m);
        #[cfg(test)]
        let shared_costs = tests::STRIPS.get().map_or(shared_costs, |s| s.shared_costs);
        let bytes =
            fixed.saturating_add(strip_bytes).saturating_add(if shared_costs { shared_bytes } else { 0 });
        (StripPlan { rows, overlap, shared_costs }, 1, bytes, too_large)
    };
    MemoryPlan { strips, stream_strips, bytes, too_large }
}

/// The largest matching cost of `params`' cost (the aggregation's `worst`).
pub(crate) fn worst_cost(params: &SgmParams) -> u16 {
    let census_bits = (params.census.width * params.census.height).saturating_sub(1) as u32;
    crate::cost::infeasible_cost(census_bits, params.matching_cost)
}

/// A tuning override from the environment (for measurements only).
fn tuning(name: &str) -> Option<usize> {
    std::env::var(name).ok()?.parse().ok()
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::cell::Cell;

    thread_local! {
        /// Forces the strip plan of [`plan`] on this thread: two-pass strip rows, overlap and
        /// shared costs, or single-pass strip count (`rows`) and overlap.
        pub(crate) static STRIPS: Cell<Option<StripPlan>> = const { Cell::new(None) };
    }

    /// Runs `f` with the strip plan forced to `strips`: on the one thread of a pool of its own,
    /// since the matcher plans on a thread of the current pool (`on_pool_thread`), where a plan
    /// forced on the caller's thread would not be seen.
    pub(crate) fn with_strips<R: Send>(strips: StripPlan, f: impl FnOnce() -> R + Send) -> R {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().expect("a one-thread pool");
        pool.install(|| {
            STRIPS.set(Some(strips));
            let r = f();
            STRIPS.set(None);
            r
        })
    }

    #[test]
    fn a_budget_bounds_the_plan() {
        let params = SgmParams { range: crate::DisparityRange::new(0, 320).unwrap(), ..SgmParams::default() };
        let free = plan(6000, 4000, &params);
        assert!(!free.too_large && free.strips.rows < 4000);
        let bounded = plan(6000, 4000, &SgmParams { max_memory: Some(1 << 30), ..params.clone() });
        assert!(!bounded.too_large && bounded.bytes <= 1 << 30, "{bounded:?}");
        let tiny = plan(6000, 4000, &SgmParams { max_memory: Some(100 << 20), ..params.clone() });
        assert!(tiny.too_large && tiny.check(6000, 4000, &params).is_err());
        let small = plan(64, 48, &SgmParams { range: crate::DisparityRange::new(0, 16).unwrap(), ..params });
        assert_eq!(small.strips.rows, 48, "a small image is one strip: exact SGM");
    }

    #[test]
    fn absurd_sizes_plan_everything_instead_of_overflowing() {
        let params =
            SgmParams { range: crate::DisparityRange::new(0, 4096).unwrap(), ..SgmParams::default() };
        for single_pass in [false, true] {
            let params = SgmParams { single_pass, max_memory: Some(1 << 40), ..params.clone() };
            let p = plan(usize::MAX / 3, usize::MAX / 5, &params);
            assert_eq!(p.bytes, usize::MAX, "single pass {single_pass}");
            assert!(p.too_large && p.check(usize::MAX / 3, usize::MAX / 5, &params).is_err());
        }
    }
}
