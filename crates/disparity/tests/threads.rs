//! The same maps on any number of threads: the single-pass aggregation (the fast preset, and the
//! coarse match the default preset's adaptation reads) works in strips cut by the image's height,
//! not by the pool's threads.

mod common;

use stereo_disparity::{sgm, DisparityRange, GrayImage, Preset, SgmParams};

/// The map's bits, matched on a pool of `threads` threads.
fn on(threads: usize, left: &GrayImage, right: &GrayImage, params: &SgmParams) -> Vec<u32> {
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let map = pool.install(|| sgm(left, right, params).unwrap());
    map.as_slice().iter().map(|d| d.to_bits()).collect()
}

#[test]
fn maps_do_not_depend_on_the_thread_count() {
    let scene = common::scene_8bit(1000.0);
    let (w, h) = scene.right.size();
    // A right view exposed 0.6 times as long: the default preset fits a tone mapping to the
    // coarse match's pairs.
    let darker =
        GrayImage::from_fn(w, h, |x, y| (f32::from(scene.right.get(x, y) / 257) * 0.6).round() as u16 * 257);
    let range = DisparityRange::new(0, 48).unwrap();
    let fast = SgmParams { range, ..SgmParams::preset(Preset::Fast) };
    let default = SgmParams { range, ..SgmParams::default() };
    for (name, right, params) in
        [("fast", &scene.right, &fast), ("default, right view darker", &darker, &default)]
    {
        let one = on(1, &scene.left, right, params);
        for threads in [2, 3, 5] {
            assert!(one == on(threads, &scene.left, right, params), "{name}: 1 and {threads} threads differ");
        }
    }
}
