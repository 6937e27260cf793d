//! In-process timing of the library pipeline on one pair, the way OpenCV's matchers are timed by
//! the shared comparison tool (`stereo_eval.py`: one warm-up call, then the median of RUNS
//! calls in the same process): the median wall time of `Plan::run` on the pair's 16-bit grey
//! views (conversion, rectification check, matching) and of its `timings.matching`. Also the
//! reference for the Python package's overhead (`crates/python/bench/bench.py`), which does the
//! same work through `stereo_depth.Matcher.compute`. The command line's `timings_ms.match` is the
//! first call of a fresh process instead: it pays the first touch of every buffer (page faults)
//! and cold caches, which a long-running caller pays once (docs/performance.md).
//!
//! `cargo run --release --example time_pipeline -- LEFT RIGHT MAX_DISPARITY [RUNS]
//!  [--preset fast|balanced|accurate] [--fill] [--threads N] [--warmup N]`

use std::time::Instant;

use stereo_pipeline::{DisparityRange, ImageRef, MatcherOptions, PipelineParams, Plan, Preset};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn usage() -> ! {
    eprintln!(
        "usage: time_pipeline LEFT RIGHT MAX_DISPARITY [RUNS] [--preset fast|balanced|accurate] [--fill] \
         [--threads N] [--warmup N]"
    );
    std::process::exit(2);
}

/// The command line's allocator settings, so the calls after the warm-up reuse freed buffers as
/// the CLI's later allocations do.
#[path = "../src/allocator.rs"]
mod allocator;

fn main() {
    allocator::reuse_freed_memory();
    // Calls after the warm-up reuse the matcher's strip buffers, as a long-lived process does
    // (the batch, the Python package) and as OpenCV's matchers keep theirs.
    stereo_disparity::keep_strip_buffers(true);
    let mut positional = Vec::new();
    let (mut options, mut threads, mut warmup) = (MatcherOptions::default(), None, 1usize);
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        let mut value = || args.next().unwrap_or_else(|| usage());
        match arg.as_str() {
            "--preset" => {
                options.preset = match value().as_str() {
                    "fast" => Preset::Fast,
                    "balanced" => Preset::Balanced,
                    "accurate" => Preset::Accurate,
                    _ => usage(),
                }
            }
            "--fill" => options.fill = true,
            "--threads" => threads = Some(value().parse::<usize>().unwrap_or_else(|_| usage())),
            "--warmup" => warmup = value().parse().unwrap_or_else(|_| usage()),
            _ if arg.starts_with("--") => usage(),
            _ => positional.push(arg),
        }
    }
    if positional.len() < 3 {
        usage();
    }
    if let Some(n) = threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global().expect("thread pool");
    }
    let left = stereo_io::load_gray(positional[0].as_ref()).expect("left image");
    let right = stereo_io::load_gray(positional[1].as_ref()).expect("right image");
    let max: i32 = positional[2].parse().unwrap_or_else(|_| usage());
    let runs: usize = positional.get(3).map(|s| s.parse().unwrap_or_else(|_| usage())).unwrap_or(9);
    // The matcher parameters exactly as the command line resolves them.
    let mut matcher = options.resolve().expect("options");
    matcher.set_range(DisparityRange::new(0, max).expect("range"));
    let params = PipelineParams::new(matcher);
    let plan = Plan::new(&params, left.size(), right.size()).expect("plan");
    let (mut total, mut matching) = (Vec::new(), Vec::new());
    for run in 0..warmup + runs.max(1) {
        let t = Instant::now();
        let result = plan.run(ImageRef::from(&left), ImageRef::from(&right)).expect("run");
        if run >= warmup {
            total.push(t.elapsed().as_secs_f64() * 1000.0);
            matching.push(result.timings.matching.as_secs_f64() * 1000.0);
        }
    }
    println!(
        "{{\"width\": {}, \"height\": {}, \"runs\": {}, \"warmup\": {warmup}, \"total_ms\": {:.3}, \"match_ms\": {:.3}}}",
        left.width(),
        left.height(),
        runs.max(1),
        median(total),
        median(matching)
    );
}
