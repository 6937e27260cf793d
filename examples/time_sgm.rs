//! In-process matcher timing on a folder of scenes laid out like `../shared/data` (scenes.tsv):
//! median wall time of `sgm()` per scene and MDE/s (W·H·ndisp / time). For profiling and A/B
//! runs while tuning kernels; the published comparison uses the CLI's `timings_ms.match`.
//!
//! `cargo run --release --example time_sgm -- DATA_DIR [RUNS] [fast|balanced|accurate] [fill]`

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
        let mut ms: Vec<f64> = (0..runs)
            .map(|_| {
                let t = Instant::now();
                let d = sgm(&left, &right, &params).expect("sgm");
                std::hint::black_box(d);
                t.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        ms.sort_by(f64::total_cmp);
        let med = ms[ms.len() / 2];
        let (w, h) = left.size();
        println!("{:<9} {:8.2} ms {:7.0} MDE/s", f[0], med, (w * h) as f64 * f64::from(nd) / (med * 1e3));
    }
}
