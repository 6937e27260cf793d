//! No flying points: a far scene (background at 2–5 px, the left band where the true match has
//! left the right image) gives no valid disparity at or below zero, and no depth farther than
//! twice the scene's farthest point, in the disparity map, the depth map and the point cloud, with
//! either matcher and with `--fill`.

mod common;

use common::*;

/// A scene far from the rig: the plane runs from 2 px (left edge) to about 5 px of disparity,
/// the box at 9 px.
fn far_scene(dir: &std::path::Path) -> stereo_scene::Scene {
    let params = stereo_scene::SceneParams {
        width: 240,
        height: 160,
        plane: (2.0, 0.012, 0.004),
        foreground: Some(stereo_scene::Foreground {
            rect: stereo_scene::Rect { x0: 100.5, y0: 50.5, x1: 160.5, y1: 110.5 },
            disparity: 9.0,
        }),
        ..stereo_scene::SceneParams::default()
    };
    let scene = stereo_scene::render(&params);
    write_pgm16(&dir.join("left.pgm"), &scene.left);
    write_pgm16(&dir.join("right.pgm"), &scene.right);
    scene
}

#[test]
fn no_disparity_at_or_below_zero_and_no_point_far_behind_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let scene = far_scene(dir.path());
    let gt_min = scene.gt_left.as_slice().iter().copied().fold(f32::INFINITY, f32::min);
    let farthest_m = DEPTH_PER_DISPARITY / f64::from(gt_min);
    for extra in [&["--matcher", "sgm"][..], &["--matcher", "sgm", "--fill"], &["--matcher", "bm"]] {
        let mut args = vec!["left.pgm", "right.pgm", "--max-disparity", "32", "--disparity", "d.pfm"];
        args.extend(["-o", "z.exr", "--points", "p.ply"]);
        args.extend(extra);
        args.extend(RIG);
        let run = run_in(dir.path(), &args);
        assert_eq!(run.code, Some(0), "{extra:?}: {}", run.stderr);

        let disparity = stereo_io::read_pfm(&dir.path().join("d.pfm")).unwrap();
        let valid: Vec<f32> = disparity.as_slice().iter().copied().filter(|d| d.is_finite()).collect();
        assert!(valid.len() > disparity.as_slice().len() / 2, "{extra:?}: only {} valid", valid.len());
        assert!(valid.iter().all(|&d| d > 0.0), "{extra:?}: a valid disparity <= 0");

        let depth = read_exr(&dir.path().join("z.exr")).z;
        let far =
            depth.as_slice().iter().filter(|z| z.is_finite() && f64::from(**z) > 2.0 * farthest_m).count();
        // Allowed: a handful of left-band pixels (the bar is 0.02 % of the valid pixels).
        assert!(
            far * 5000 <= valid.len() * 10,
            "{extra:?}: {far} of {} valid pixels beyond 2x the scene",
            valid.len()
        );
        assert!(depth.as_slice().iter().all(|z| z.is_nan() || *z > 0.0), "{extra:?}: a depth <= 0");

        let ply = stereo_io::read_ply_info(&dir.path().join("p.ply")).unwrap();
        assert_eq!(ply.vertex_count, depth.as_slice().iter().filter(|z| z.is_finite()).count(), "{extra:?}");
    }
}

/// Far islands (docs/robustness.md): on a noisy pair the left band (where the true match has left
/// the right image) keeps small islands of interior winners far behind the scene that pass the
/// left-right check. Before they were rejected, 0.04 % of the valid pixels of this pair lay beyond
/// twice the farthest depth; the bar is 0.02 %.
#[test]
fn no_far_islands_on_a_noisy_pair() {
    let dir = tempfile::tempdir().unwrap();
    let (left, right) = (slanted("left.png"), slanted("right.png"));
    let run = run_in(dir.path(), &["degrade", "--out", "noisy", "--both", "noise=12", s(&left), s(&right)]);
    assert_eq!(run.code, Some(0), "{}", run.stderr);
    let gt = stereo_io::read_pfm(&slanted("disp0GT.pfm")).unwrap();
    let gt_min = gt.as_slice().iter().copied().filter(|d| d.is_finite()).fold(f32::INFINITY, f32::min);
    for matcher in ["sgm", "bm"] {
        let args = ["noisy/left.png", "noisy/right.png", "--max-disparity", "64", "--matcher", matcher];
        let run = run_in(dir.path(), &[&args[..], &["--disparity", "d.pfm", "--quiet"]].concat());
        assert_eq!(run.code, Some(0), "{matcher}: {}", run.stderr);
        let disparity = stereo_io::read_pfm(&dir.path().join("d.pfm")).unwrap();
        let valid: Vec<f32> = disparity.as_slice().iter().copied().filter(|d| d.is_finite()).collect();
        assert!(valid.len() > disparity.as_slice().len() / 2, "{matcher}: only {} valid", valid.len());
        let far = valid.iter().filter(|&&d| d < gt_min / 2.0).count();
        assert!(
            far * 5000 <= valid.len(),
            "{matcher}: {far} of {} valid pixels beyond 2x the scene",
            valid.len()
        );
    }
}
