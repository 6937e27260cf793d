use stereo_scene::{render, SceneParams};

use super::*;

fn sgm(max: i32) -> PipelineParams {
    PipelineParams::new(Matcher::Sgm(SgmParams {
        range: DisparityRange::new(0, max).unwrap(),
        ..SgmParams::default()
    }))
}

/// Share of non-occluded ground-truth pixels where the estimate is within 1 px.
fn good_share(result: &DisparityMap, scene: &stereo_scene::Scene) -> f64 {
    let (mut good, mut all) = (0, 0);
    for y in 0..result.height() {
        for x in 0..result.width() {
            if scene.occluded.get(x, y) {
                continue;
            }
            all += 1;
            good += usize::from((result.get(x, y) - scene.gt_left.get(x, y)).abs() <= 1.0);
        }
    }
    good as f64 / all as f64
}

#[test]
fn depth_of_a_generated_scene_matches_its_ground_truth() {
    let scene = render(&SceneParams::default());
    let mut params = sgm(64);
    let rig = Rig::from_focal_px(100.0, 500.0).unwrap();
    params.rig = Some(rig.clone());
    let plan = Plan::new(&params, scene.left.size(), scene.right.size()).unwrap();
    let result = plan.run_gray(&scene.left, scene.right.clone()).unwrap();
    assert!(good_share(&result.disparity, &scene) > 0.9);
    assert!(!result.rectification.compensated, "a perfectly rectified pair is matched as loaded");
    // Depth is the rig's triangulation of the disparity, valid exactly where the disparity is.
    let depth = result.depth.unwrap();
    for (d, z) in result.disparity.as_slice().iter().zip(depth.as_slice()) {
        assert_eq!(d.is_finite(), z.is_finite());
        if d.is_finite() {
            let expected = rig.depth(*d as f64).unwrap();
            assert!((*z as f64 - expected).abs() <= 1e-5 * expected);
        }
    }
}

#[test]
fn borrowed_views_give_the_same_result_as_owned_images() {
    let scene = render(&SceneParams { width: 160, height: 96, foreground: None, ..SceneParams::default() });
    let plan = Plan::new(&sgm(32), scene.left.size(), scene.right.size()).unwrap();
    let owned = plan.run_gray(&scene.left, scene.right.clone()).unwrap();
    // The same pixels inside larger buffers (a crop: rows 7 samples apart beyond the width).
    let pad = |img: &GrayImage| -> Vec<u16> {
        (0..img.height()).flat_map(|y| img.row(y).iter().copied().chain([9u16; 7])).collect()
    };
    let (l, r) = (pad(&scene.left), pad(&scene.right));
    let (w, h) = scene.left.size();
    let left = ImageRef::with_stride(&l, w, h, w + 7).unwrap();
    let right = ImageRef::with_stride(&r, w, h, w + 7).unwrap();
    let viewed = plan.run(left, right).unwrap();
    let bits = |m: &DisparityMap| m.as_slice().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&owned.disparity), bits(&viewed.disparity));
}

#[test]
fn plans_refuse_what_cannot_be_matched_before_any_pixel_is_read() {
    let params = sgm(64);
    assert!(matches!(
        Plan::new(&params, (100, 50), (101, 50)),
        Err(Error::Matcher(stereo_disparity::Error::SizeMismatch { .. }))
    ));
    assert!(matches!(
        Plan::new(&params, (40, 50), (40, 50)),
        Err(Error::Matcher(stereo_disparity::Error::RangeWiderThanImage { count: 64, width: 40, .. }))
    ));
    assert!(matches!(Plan::new(&params, (0, 50), (0, 50)), Err(Error::EmptyImage { .. })));
    let mut limited = params.clone();
    limited.depth_limits = DepthLimits::new(Some(1.0), None).unwrap();
    assert!(matches!(Plan::new(&limited, (100, 50), (100, 50)), Err(Error::InvalidParameter { .. })));
    let plan = Plan::new(&params, (100, 50), (100, 50)).unwrap();
    let small = GrayImage::new(90, 50, 0);
    assert!(matches!(plan.run_gray(&small, small.clone()), Err(Error::PlannedFor { .. })));
}

#[test]
fn a_memory_limit_bounds_sgm_or_fails_with_what_it_needs() {
    let params = sgm(128);
    let size = (2000, 1500);
    let unbounded = Plan::new(&params, size, size).unwrap();
    let least = params.matcher.minimum_bytes(size.0, size.1);
    assert!(least < unbounded.planned_matcher_bytes(), "strips need less than the whole pair at once");
    let limit =
        MemoryLimit { bytes: least + (unbounded.planned_matcher_bytes() - least) / 2, other_bytes: 0 };
    let bounded = Plan::with_memory_limit(&params, size, size, Some(limit)).unwrap();
    assert!(bounded.planned_matcher_bytes() <= limit.bytes);
    let tiny = MemoryLimit { bytes: 1000, other_bytes: 0 };
    match Plan::with_memory_limit(&params, size, size, Some(tiny)) {
        Err(Error::TooLarge { needed, limit }) => assert!(needed > limit && limit == 1000),
        other => panic!("expected TooLarge, got {other:?}"),
    }
}

#[test]
fn depth_limits_cut_every_output_alike() {
    let scene = render(&SceneParams::default());
    let mut params = sgm(64);
    let rig = Rig::from_focal_px(100.0, 500.0).unwrap();
    // The foreground box is at disparity 36, the plane at 8..~25: keep only the box.
    let near = rig.depth(30.0).unwrap();
    params.depth_limits = DepthLimits::new(None, Some(near)).unwrap();
    params.rig = Some(rig);
    let plan = Plan::new(&params, scene.left.size(), scene.right.size()).unwrap();
    let result = plan.run_gray(&scene.left, scene.right.clone()).unwrap();
    assert!(result.depth_limits_cut.unwrap() > 10_000);
    assert!(result.disparity.as_slice().iter().filter(|d| d.is_finite()).all(|&d| d >= 30.0));
    assert!(result.depth.unwrap().as_slice().iter().filter(|z| z.is_finite()).all(|&z| z as f64 <= near));
}

#[test]
fn matcher_options_resolve_like_the_presets_and_reject_the_other_matchers_options() {
    assert_eq!(MatcherOptions::default().resolve().unwrap(), Matcher::Sgm(SgmParams::default()));
    let fast = MatcherOptions { preset: Preset::Fast, fill: true, p1: Some(9), ..MatcherOptions::default() };
    let expected = SgmParams { p1: 9, ..SgmParams::preset(Preset::Fast).with_fill() };
    assert_eq!(fast.resolve().unwrap(), Matcher::Sgm(expected));
    let no_lr = MatcherOptions { lr_check: false, lr_max_diff: Some(-1.0), ..MatcherOptions::default() };
    assert!(matches!(no_lr.resolve().unwrap(), Matcher::Sgm(p) if p.lr_max_diff.is_none()));

    let bm = MatcherOptions { matcher: MatcherKind::Bm, ..MatcherOptions::default() };
    assert_eq!(bm.resolve().unwrap(), Matcher::Bm(BmParams::default()));
    let halved = MatcherOptions { downscale: Some(Downscale::By(2)), ..MatcherOptions::default() };
    assert!(matches!(halved.resolve().unwrap(), Matcher::Sgm(p) if p.downscale == Downscale::By(2)));
    let zero = MatcherOptions { downscale: Some(Downscale::By(0)), ..MatcherOptions::default() };
    assert_eq!(
        zero.resolve().unwrap_err().to_string(),
        "downscale must be auto, coarse or between 1 and 8, got 0"
    );
    let bm_halved = MatcherOptions { downscale: Some(Downscale::By(2)), ..bm.clone() };
    assert_eq!(bm_halved.resolve().unwrap_err().to_string(), "downscale applies only to matcher sgm");
    let bm_fill = MatcherOptions { fill: true, ..bm.clone() };
    assert_eq!(bm_fill.resolve().unwrap_err().to_string(), "fill applies only to matcher sgm");
    let even = MatcherOptions { block_size: Some(8), ..bm };
    assert_eq!(even.resolve().unwrap_err().to_string(), "block_size must be odd and at least 3, got 8");
    let sgm_block = MatcherOptions { block_size: Some(9), ..MatcherOptions::default() };
    assert_eq!(
        sgm_block.resolve().unwrap_err(),
        OptionError::OtherMatcher { option: "block_size", matcher: MatcherKind::Bm }
    );
}

/// A stream's later pairs can take the alignment measured on its first one: the same map as
/// measuring again, misaligned pairs still resampled, and the result says it was not measured.
#[test]
fn a_known_alignment_replaces_the_measurement() {
    let scene = render(&SceneParams { width: 320, height: 240, ..SceneParams::default() });
    // The right view 0.8 px lower: what a drifted rectification leaves.
    let lowered = stereo_rectify::Alignment {
        vertical_offset_px: -0.8,
        rotation_deg: 0.0,
        max_abs_offset_px: 0.8,
        patches_used: 0,
        negative_disparity_share: 0.0,
        verdict: stereo_rectify::AlignmentVerdict::Misaligned,
    };
    let right = stereo_rectify::compensate(&scene.right, &lowered);
    let params = sgm(64);
    let plan = Plan::new(&params, scene.left.size(), right.size()).unwrap();
    let first = plan.run_gray(&scene.left, right.clone()).unwrap();
    assert!(first.rectification.measured);
    assert!(first.rectification.compensated, "{:?}", first.rectification);
    let offset = first.rectification.alignment.vertical_offset_px;
    assert!((offset - 0.8).abs() < 0.1, "measured {offset} px, shifted by 0.8");

    let mut known = params.clone();
    known.known_alignment = Some(first.rectification.alignment);
    let plan = Plan::new(&known, scene.left.size(), right.size()).unwrap();
    let later = plan.run_gray(&scene.left, right.clone()).unwrap();
    assert!(!later.rectification.measured);
    assert_eq!(later.rectification.alignment, first.rectification.alignment);
    assert!(later.rectification.compensated);
    let bits = |m: &DisparityMap| m.as_slice().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&later.disparity), bits(&first.disparity));

    // A known alignment is taken as given: told the rows line up, the pair is matched as loaded.
    let mut aligned = params.clone();
    aligned.known_alignment =
        Some(stereo_rectify::Alignment { verdict: stereo_rectify::AlignmentVerdict::Aligned, ..lowered });
    let plan = Plan::new(&aligned, scene.left.size(), right.size()).unwrap();
    let trusted = plan.run_gray(&scene.left, right).unwrap();
    assert!(!trusted.rectification.compensated && !trusted.rectification.measured);
    assert_ne!(bits(&trusted.disparity), bits(&first.disparity));
}
