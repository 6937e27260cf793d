//! Measures the vertical misalignment of a stereo pair and how long the measurement takes.
//!
//! `cargo run --release -p stereo-rectify --example check_alignment -- LEFT RIGHT MAX_DISPARITY [RUNS]`
//!
//! Prints the estimate, the best and median time of RUNS calls (default 10), and the estimate's
//! exact bits, so a change to the measurement can be checked for identical results.

use std::path::Path;
use std::time::Instant;

use stereo_image::DisparityRange;
use stereo_rectify::estimate_alignment;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (left, right, max, runs) = match args.as_slice() {
        [left, right, max] => (left, right, max, 10),
        [left, right, max, runs] => (left, right, max, runs.parse::<usize>()?.max(1)),
        _ => return Err("usage: check_alignment LEFT RIGHT MAX_DISPARITY [RUNS]".into()),
    };
    let left = stereo_io::load_gray(Path::new(left))?;
    let right = stereo_io::load_gray(Path::new(right))?;
    let range = DisparityRange::new(0, max.parse()?)?;
    let mut alignment = estimate_alignment(&left, &right, range);
    // The first run pays for the thread pool's start; report the best of a few.
    let mut times = Vec::with_capacity(runs);
    for _ in 0..runs {
        let t = Instant::now();
        alignment = estimate_alignment(&left, &right, range);
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    let (best, median) = (times[0], times[runs / 2]);
    println!(
        "offset {:+.3} px  rotation {:+.4}°  max |offset| {:.3} px  patches {}  negative share {:.2}  {}  {:.2} ms (median {:.2})  \
         bits {:08x} {:08x} {:08x}",
        alignment.vertical_offset_px,
        alignment.rotation_deg,
        alignment.max_abs_offset_px,
        alignment.patches_used,
        alignment.negative_disparity_share,
        alignment.verdict.as_str(),
        best,
        median,
        alignment.vertical_offset_px.to_bits(),
        alignment.rotation_deg.to_bits(),
        alignment.max_abs_offset_px.to_bits()
    );
    Ok(())
}
