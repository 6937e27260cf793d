//! Matcher throughput: one group per SGM stage (the post-processing as one) and end to end (SGM 8 and 4 paths in two passes,
//! 5 and 3 paths in one pass, each with the full search; 8 paths and 3 paths in one pass also
//! coarse to fine, `-hierarchical`; block matching), at 640×480, 1280×720 and 1920×1080 with 64,
//! 128 and 256 disparities. Throughput is W·H·D elements (disparity evaluations) per second.
//! `cargo bench --bench matchers` (add a filter such as `-- sgm_end_to_end/3path` to run a part).
//! `STEREO_DISPARITY_SIMD=scalar|avx2` caps the kernels.

use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use stereo_disparity::{stages, BmParams, DisparityRange, GrayImage, PathCount, Search, SgmParams};

const SIZES: [(usize, usize); 3] = [(640, 480), (1280, 720), (1920, 1080)];
const RANGES: [i32; 3] = [64, 128, 256];

/// A textured pair: a smooth hash texture, the right view shifted by a disparity that varies
/// slowly across the image (a slanted plane plus a nearer block), so the matchers do real work.
fn pair(width: usize, height: usize, max_disparity: i32) -> (GrayImage, GrayImage) {
    let hash = |x: i64, y: i64| {
        let h = (x.wrapping_mul(0x9E37_79B9) ^ y.wrapping_mul(0x85EB_CA6B)).wrapping_mul(0xC2B2_AE35);
        ((h >> 16) & 0xffff) as u16
    };
    // Blur the hash a little so neighbouring pixels correlate like a real image.
    let texture = |x: i64, y: i64| {
        let s: u32 = (0..2)
            .flat_map(|dy| (0..2).map(move |dx| (dx, dy)))
            .map(|(dx, dy)| u32::from(hash(x + dx, y + dy)))
            .sum();
        (s / 4) as u16
    };
    let disparity = |x: usize, y: usize| {
        let base = (max_disparity as f64) * (0.2 + 0.4 * y as f64 / height as f64);
        let near = x > width / 3 && x < width / 2 && y > height / 3 && y < 2 * height / 3;
        (if near { base * 1.5 } else { base }).min(max_disparity as f64 - 1.0) as i64
    };
    let left = GrayImage::from_fn(width, height, |x, y| texture(x as i64, y as i64));
    let right = GrayImage::from_fn(width, height, |x, y| texture(x as i64 + disparity(x, y), y as i64));
    (left, right)
}

fn cases() -> impl Iterator<Item = (usize, usize, i32, String)> {
    SIZES
        .into_iter()
        .flat_map(|(w, h)| RANGES.into_iter().map(move |nd| (w, h, nd, format!("{w}x{h}/d{nd}"))))
}

fn sgm_params(nd: i32, paths: PathCount) -> SgmParams {
    SgmParams {
        range: DisparityRange::new(0, nd).unwrap(),
        paths,
        search: Search::Full,
        ..SgmParams::default()
    }
}

fn stage_benches(c: &mut Criterion) {
    eprintln!("SGM kernels: {}", stages::simd_level());
    for (stage, run) in [
        ("sgm_stage_census", 0),
        ("sgm_stage_matching_cost", 1),
        ("sgm_stage_aggregate_wta", 2),
        ("sgm_stage_median", 3),
        ("sgm_stage_post", 4),
    ] {
        let mut group = c.benchmark_group(stage);
        group
            .sample_size(10)
            .warm_up_time(Duration::from_millis(300))
            .measurement_time(Duration::from_secs(2));
        for (w, h, nd, id) in cases() {
            let (left, right) = pair(w, h, nd);
            let params = sgm_params(nd, PathCount::Eight);
            let (cl, cr) = (stages::census(&left, &params), stages::census(&right, &params));
            group.throughput(Throughput::Elements((w * h * nd as usize) as u64));
            match run {
                0 => group.bench_function(BenchmarkId::from_parameter(&id), |b| {
                    b.iter(|| stages::census(&left, &params))
                }),
                1 => group.bench_function(BenchmarkId::from_parameter(&id), |b| {
                    b.iter(|| stages::matching_costs(&left, &right, &cl, &cr, &params))
                }),
                2 => group.bench_function(BenchmarkId::from_parameter(&id), |b| {
                    b.iter(|| stages::aggregate_and_select_disparities(&left, &cl, &cr, &params))
                }),
                3 => {
                    let d = stages::aggregate_and_select_disparities(&left, &cl, &cr, &params);
                    group.bench_function(BenchmarkId::from_parameter(&id), |b| b.iter(|| stages::median(&d)))
                }
                _ => {
                    let d = stages::aggregate_and_select_disparities(&left, &cl, &cr, &params);
                    group.bench_function(BenchmarkId::from_parameter(&id), |b| {
                        b.iter(|| stages::post_process(&d, &left, &params))
                    })
                }
            };
        }
        group.finish();
    }
}

fn end_to_end(c: &mut Criterion) {
    let mut group = c.benchmark_group("sgm_end_to_end");
    group.sample_size(10).warm_up_time(Duration::from_millis(300)).measurement_time(Duration::from_secs(3));
    for (w, h, nd, id) in cases() {
        let (left, right) = pair(w, h, nd);
        group.throughput(Throughput::Elements((w * h * nd as usize) as u64));
        // The two-pass modes and the single-pass ones (`--preset fast` is "3path-1pass", run on
        // the pair halved by `Downscale::Coarse` where its range allows; these time full resolution).
        for (name, paths, single_pass, search) in [
            ("8path", PathCount::Eight, false, Search::Full),
            ("8path-hierarchical", PathCount::Eight, false, Search::Hierarchical),
            ("4path", PathCount::Four, false, Search::Full),
            ("5path-1pass", PathCount::Eight, true, Search::Full),
            ("3path-1pass", PathCount::Four, true, Search::Full),
            ("3path-1pass-hierarchical", PathCount::Four, true, Search::Hierarchical),
        ] {
            let params = SgmParams { single_pass, search, ..sgm_params(nd, paths) };
            group.bench_function(BenchmarkId::new(name, &id), |b| {
                b.iter(|| stereo_disparity::sgm(&left, &right, &params).unwrap())
            });
        }
    }
    group.finish();

    let mut group = c.benchmark_group("bm_end_to_end");
    group.sample_size(10).warm_up_time(Duration::from_millis(300)).measurement_time(Duration::from_secs(3));
    for (w, h, nd, id) in cases() {
        let (left, right) = pair(w, h, nd);
        group.throughput(Throughput::Elements((w * h * nd as usize) as u64));
        let params = BmParams { range: DisparityRange::new(0, nd).unwrap(), ..BmParams::default() };
        group.bench_function(BenchmarkId::from_parameter(&id), |b| {
            b.iter(|| stereo_disparity::block_match(&left, &right, &params).unwrap())
        });
    }
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default();
    targets = stage_benches, end_to_end
}
criterion_main!(benches);
