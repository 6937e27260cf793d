//! Measures the vertical misalignment of a stereo pair and how long the measurement takes.
//!
//! `cargo run --release -p stereo-rectify --example check_alignment -- LEFT RIGHT MAX_DISPARITY`

use std::path::Path;
use std::time::Instant;

use stereo_image::DisparityRange;
use stereo_rectify::estimate_alignment;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [left, right, max] = args.as_slice() else {
        return Err("usage: check_alignment LEFT RIGHT MAX_DISPARITY".into());
    };
    let left = stereo_io::load_gray(Path::new(left))?;
    let right = stereo_io::load_gray(Path::new(right))?;
    let range = DisparityRange::new(0, max.parse()?)?;
    let mut alignment = estimate_alignment(&left, &right, range);
    // The first run pays for the thread pool's start; report the best of a few.
    let mut best = f64::INFINITY;
    for _ in 0..10 {
        let t = Instant::now();
        alignment = estimate_alignment(&left, &right, range);
        best = best.min(t.elapsed().as_secs_f64() * 1e3);
    }
    println!(
        "offset {:+.3} px  rotation {:+.4}°  max |offset| {:.3} px  patches {}  negative share {:.2}  {}  {:.2} ms",
        alignment.vertical_offset_px,
        alignment.rotation_deg,
        alignment.max_abs_offset_px,
        alignment.patches_used,
        alignment.negative_disparity_share,
        alignment.verdict.as_str(),
        best
    );
    Ok(())
}
