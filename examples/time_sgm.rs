//! In-process matcher timing on a folder of scenes laid out like `../shared/data` (scenes.tsv):
//! median wall time of `sgm()` per scene and MDE/s (W·H·ndisp / time). For profiling and A/B
//! runs while tuning kernels; the published comparison uses the CLI's `timings_ms.match`.
//!
//! `cargo run --release --example time_sgm -- DATA_DIR [RUNS] [fast|balanced|accurate] [fill]`
//! (`TIME_COST_ROWS=1` times the cost rows alone, `TIME_AGGREGATION=1` the aggregation and
//! selection alone, `TIME_POST=1` the post-processing of the selected map alone, `TIME_POST=median`
//! its 3×3 median alone)

use std::path::Path;
use std::time::Instant;

use stereo_disparity::{sgm, DisparityRange, Preset, SgmParams};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = Path::new(args.get(1).map(String::as_str).unwrap_or("../shared/data"));
    let runs: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(9);
    let preset = match args.get(3).map(String::as_str) {
        Some("fast") => Preset::Fast,
        Some("accurate") => Preset::Accurate,
        _ => Preset::Balanced,
    };
    let fill = args.get(4).is_some_and(|s| s == "fill");
    let table = std::fs::read_to_string(dir.join("scenes.tsv")).expect("scenes.tsv");
    for line in table.lines().skip(1) {
        let f: Vec<&str> = line.split('\t').collect();
        let scene = dir.join(f[0]);
        let left = stereo_io::load_gray(&scene.join(f[1])).expect("left image");
        let right = stereo_io::load_gray(&scene.join(f[2])).expect("right image");
        let nd: i32 = f[11].parse().expect("ndisp");
        let mut params = SgmParams::preset(preset);
        if fill {
            params = params.with_fill();
        }
        params.range = DisparityRange::new(0, nd).expect("range");
        let cost_rows = std::env::var("TIME_COST_ROWS").ok();
        if cost_rows.as_deref() == Some("census") {
            params.matching_cost = stereo_disparity::MatchingCost::Census;
        }
        let post = std::env::var("TIME_POST").ok();
        let stage = if cost_rows.is_some() {
            "cost rows"
        } else if std::env::var_os("TIME_AGGREGATION").is_some() {
            "aggregation"
        } else if post.as_deref() == Some("median") {
            "median"
        } else if post.is_some() {
            "post"
        } else {
            ""
        };
        if !stage.is_empty() {
            // One stage alone, for tuning its kernel: the cost rows (census + AD term), the path
            // aggregation and selection (census cost, costs computed on the fly), or the
            // post-processing of the map they select (or its median).
            let census_left = stereo_disparity::stages::census(&left, &params);
            let census_right = stereo_disparity::stages::census(&right, &params);
            let selected = post.is_some().then(|| {
                stereo_disparity::stages::aggregate_and_select_disparities(
                    &left,
                    &census_left,
                    &census_right,
                    &params,
                )
            });
            let (med, min) = median_and_min_ms(runs, || {
                if let Some(selected) = &selected {
                    let d = if stage == "median" {
                        stereo_disparity::stages::median(selected)
                    } else {
                        stereo_disparity::stages::post_process(selected, &left, &params)
                    };
                    std::hint::black_box(d);
                } else if cost_rows.is_some() {
                    let c = stereo_disparity::stages::matching_costs(
                        &left,
                        &right,
                        &census_left,
                        &census_right,
                        &params,
                    );
                    std::hint::black_box(c);
                } else {
                    let d = stereo_disparity::stages::aggregate_and_select_disparities(
                        &left,
                        &census_left,
                        &census_right,
                        &params,
                    );
                    std::hint::black_box(d);
                }
            });
            println!("{:<9} {stage} {med:8.3} ms (min {min:.3})", f[0]);
            continue;
        }
        let (med, min) = median_and_min_ms(runs, || {
            std::hint::black_box(sgm(&left, &right, &params).expect("sgm"));
        });
        let (w, h) = left.size();
        let mde = |ms: f64| (w * h) as f64 * f64::from(nd) / (ms * 1e3);
        println!(
            "{:<9} {:8.2} ms {:7.0} MDE/s (min {:.2} ms, {:.0} MDE/s)",
            f[0],
            med,
            mde(med),
            min,
            mde(min)
        );
    }
}

/// The median and the minimum wall time (ms) of `runs` calls of `f`.
fn median_and_min_ms(runs: usize, mut f: impl FnMut()) -> (f64, f64) {
    let mut ms: Vec<f64> = (0..runs.max(1))
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    ms.sort_by(f64::total_cmp);
    (ms[ms.len() / 2], ms[0])
}
