//! The coarse-to-fine search on generated scenes with known disparities: as accurate as the full
//! search over a wide range, far fewer disparities per pixel, the automatic choice, the memory
//! fallback and determinism across thread counts.

use stereo_disparity::{sgm_detailed, DisparityRange, Downscale, PathCount, Search, SgmOutput, SgmParams};
use stereo_scene::{Foreground, Rect, Scene, SceneParams};

/// A 640×200 scene over a wide range: a plane slanting from 60 to about 120 px, a rectangle in
/// front at 200 px.
fn wide_scene() -> Scene {
    stereo_scene::render(&SceneParams {
        width: 640,
        height: 200,
        plane: (60.0, 0.09, 0.02),
        foreground: Some(Foreground {
            rect: Rect { x0: 380.5, y0: 50.5, x1: 520.5, y1: 150.5 },
            disparity: 200.0,
        }),
        supersampling: 2,
        ..SceneParams::default()
    })
}

/// Share (%) of the non-occluded pixels right of the search's reach whose disparity is within
/// 1 px of the truth (invalid pixels count as wrong), and the density (%).
fn good_share(scene: &Scene, out: &SgmOutput, range: DisparityRange) -> (f64, f64) {
    let d = &out.disparity;
    let (w, h) = d.size();
    let (mut good, mut total, mut valid) = (0usize, 0usize, 0usize);
    for y in 0..h {
        for x in range.max as usize..w {
            if scene.occluded.get(x, y) {
                continue;
            }
            total += 1;
            let v = d.get(x, y);
            valid += usize::from(v.is_finite());
            good += usize::from((v - scene.gt_left.get(x, y)).abs() <= 1.0);
        }
    }
    (100.0 * good as f64 / total as f64, 100.0 * valid as f64 / total as f64)
}

/// The search asked for, on the pair at full resolution: the rendered scenes are smooth enough
/// for [`Downscale::Auto`] to halve them, and these tests are about the search itself.
fn params(range: DisparityRange, search: Search) -> SgmParams {
    SgmParams { range, search, downscale: Downscale::By(1), ..SgmParams::default() }
}

#[test]
fn coarse_to_fine_is_as_accurate_as_the_full_search_with_far_fewer_disparities() {
    let scene = wide_scene();
    let range = DisparityRange::new(0, 256).unwrap();
    for (paths, single_pass) in [(PathCount::Eight, false), (PathCount::Four, true)] {
        let full = SgmParams { paths, single_pass, ..params(range, Search::Full) };
        let hierarchical = SgmParams { search: Search::Hierarchical, ..full.clone() };
        let full = sgm_detailed(&scene.left, &scene.right, &full).unwrap();
        let coarse_to_fine = sgm_detailed(&scene.left, &scene.right, &hierarchical).unwrap();
        assert!(!full.search.hierarchical && full.search.mean_range == 256.0);
        let report = coarse_to_fine.search;
        assert!(report.hierarchical && report.levels >= 1, "{report:?}");
        // A quarter of the range (the left 256 columns, which mostly cannot match, keep wide bands).
        assert!(report.mean_range < 64.0, "{report:?}");
        let (good_full, _) = good_share(&scene, &full, range);
        let (good, density) = good_share(&scene, &coarse_to_fine, range);
        assert!(good > 95.0 && density > 95.0, "{paths:?}: {good:.2} % good, {density:.2} % dense");
        assert!(good >= good_full - 0.5, "{paths:?}: {good:.2} % against the full search's {good_full:.2} %");
        // No pixel outside the range.
        assert!(coarse_to_fine
            .disparity
            .as_slice()
            .iter()
            .all(|d| !d.is_finite() || (0.0..256.0).contains(d)));
    }
}

#[test]
fn auto_searches_coarse_to_fine_from_256_disparities() {
    let scene = wide_scene();
    for (max, hierarchical) in [(255, false), (256, true)] {
        let range = DisparityRange::new(0, max).unwrap();
        let out = sgm_detailed(&scene.left, &scene.right, &params(range, Search::Auto)).unwrap();
        assert_eq!(out.search.hierarchical, hierarchical, "range {max}");
    }
}

#[test]
fn too_little_memory_for_the_bands_falls_back_to_the_full_search() {
    let scene = wide_scene();
    let range = DisparityRange::new(0, 256).unwrap();
    let (w, h) = scene.left.size();
    // The full search's smallest plan (one-row strips): too little for the band volume.
    let smallest = SgmParams { max_memory: Some(1), ..params(range, Search::Full) };
    let limit = stereo_disparity::planned_memory_bytes(w, h, &smallest);
    let tight = SgmParams { max_memory: Some(limit), ..params(range, Search::Hierarchical) };
    let out = sgm_detailed(&scene.left, &scene.right, &tight).unwrap();
    assert!(!out.search.hierarchical);
}

#[test]
fn coarse_to_fine_does_not_depend_on_the_thread_count() {
    let scene = wide_scene();
    let p = params(DisparityRange::new(0, 256).unwrap(), Search::Hierarchical);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| sgm_detailed(&scene.left, &scene.right, &p).unwrap().disparity)
    };
    let one = run(1);
    for threads in [2, 3] {
        let other = run(threads);
        assert!(
            one.as_slice().iter().zip(other.as_slice()).all(|(a, b)| a.to_bits() == b.to_bits()),
            "{threads} threads"
        );
    }
}

#[test]
fn auto_searches_coarse_to_fine_from_128_disparities_on_large_images() {
    // 1600×1250 (2 megapixels): a flat textured plane is enough to see the choice.
    let scene = stereo_scene::render(&SceneParams {
        width: 1600,
        height: 1250,
        plane: (20.0, 0.0, 0.0),
        foreground: None,
        supersampling: 1,
        ..SceneParams::default()
    });
    for (max, hierarchical) in [(127, false), (128, true)] {
        let range = DisparityRange::new(0, max).unwrap();
        let out = sgm_detailed(&scene.left, &scene.right, &params(range, Search::Auto)).unwrap();
        assert_eq!(out.search.hierarchical, hierarchical, "range {max}");
    }
}
