//! In-process timing of the library pipeline on one pair, the reference for the Python
//! package's overhead (`crates/python/bench/bench.py`): the median wall time of
//! `Plan::run` on the pair's 16-bit grey views (conversion, rectification check, matching),
//! the same work `stereo_depth.Matcher.compute` does on the same arrays.
//!
//! `cargo run --release --example time_pipeline -- LEFT RIGHT MAX_DISPARITY [RUNS]`

use std::time::Instant;

use stereo_pipeline::{DisparityRange, ImageRef, Matcher, PipelineParams, Plan, SgmParams};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        eprintln!("usage: time_pipeline LEFT RIGHT MAX_DISPARITY [RUNS]");
        std::process::exit(2);
    }
    let left = stereo_io::load_gray(args[1].as_ref()).expect("left image");
    let right = stereo_io::load_gray(args[2].as_ref()).expect("right image");
    let max: i32 = args[3].parse().expect("MAX_DISPARITY");
    let runs: usize = args.get(4).and_then(|s| s.parse().ok()).unwrap_or(9);
    let range = DisparityRange::new(0, max).expect("range");
    let params = PipelineParams::new(Matcher::Sgm(SgmParams { range, ..SgmParams::default() }));
    let plan = Plan::new(&params, left.size(), right.size()).expect("plan");
    let (mut total, mut matching) = (Vec::new(), Vec::new());
    for _ in 0..runs {
        let t = Instant::now();
        let result = plan.run(ImageRef::from(&left), ImageRef::from(&right)).expect("run");
        total.push(t.elapsed().as_secs_f64() * 1000.0);
        matching.push(result.timings.matching.as_secs_f64() * 1000.0);
    }
    println!(
        "{{\"width\": {}, \"height\": {}, \"runs\": {runs}, \"total_ms\": {:.3}, \"match_ms\": {:.3}}}",
        left.width(),
        left.height(),
        median(total),
        median(matching)
    );
}
