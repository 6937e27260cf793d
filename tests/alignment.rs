//! The rectification check of the pair command: a vertically misaligned right view is measured,
//! reported and compensated; a clean pair is matched exactly as loaded.

mod common;

use std::fs;
use std::path::Path;

use common::{occluded, run_in, s, shifted_down, write_pgm16, write_scene};
use serde_json::Value;
use stereo_disparity::DisparityMap;

const WIDTH: usize = 450;
const HEIGHT: usize = 375;

fn stats(path: &Path) -> Value {
    serde_json::from_str(&fs::read_to_string(path).unwrap()).unwrap()
}

/// Percentage of the visible ground-truth pixels whose disparity is missing or off by more than
/// 2 px (Middlebury's bad 2.0, invalid pixels counted as bad).
fn bad2(disparity: &DisparityMap, gt: &DisparityMap) -> f64 {
    let hidden = occluded(gt);
    let (mut bad, mut total) = (0usize, 0usize);
    for y in 0..gt.height() {
        for x in 0..gt.width() {
            if hidden.get(x, y) {
                continue;
            }
            total += 1;
            let d = disparity.get(x, y);
            if !d.is_finite() || (d - gt.get(x, y)).abs() > 2.0 {
                bad += 1;
            }
        }
    }
    100.0 * bad as f64 / total as f64
}

/// Runs the pair command on `right` in `dir`; returns the run, its disparity and statistics.
fn match_pair(dir: &Path, right: &str, extra: &[&str]) -> (common::Run, DisparityMap, Value) {
    let (disparity, json) = (dir.join("disparity.pfm"), dir.join("stats.json"));
    let mut args =
        vec!["left.pgm", right, "--max-disparity", "48", "--disparity", s(&disparity), "--stats", s(&json)];
    args.extend_from_slice(extra);
    let run = run_in(dir, &args);
    run.assert_success();
    let map = stereo_io::read_pfm(&disparity).unwrap();
    (run, map, stats(&json))
}

#[test]
fn a_right_view_one_pixel_lower_is_reported_and_compensated() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), WIDTH, HEIGHT);
    write_pgm16(&dir.path().join("lower.pgm"), &shifted_down(&scene.right, 1));

    let (clean_run, clean, clean_stats) = match_pair(dir.path(), "right.pgm", &[]);
    assert_eq!(clean_run.stderr, "", "a clean pair warns about nothing");
    assert_eq!(clean_stats["rectification"]["verdict"], "aligned");

    let (run, shifted, json) = match_pair(dir.path(), "lower.pgm", &[]);
    let report = &json["rectification"];
    let offset = report["vertical_offset_px"].as_f64().unwrap();
    assert!((offset - 1.0).abs() < 0.1, "{report}");
    assert!(report["rotation_deg"].as_f64().unwrap().abs() < 0.02, "{report}");
    assert_eq!(report["verdict"], "misaligned");
    assert_eq!(report["compensated"], true);
    assert!(json["timings_ms"]["rectification"].as_f64().unwrap() > 0.0);
    assert_eq!(run.stderr.lines().count(), 1, "one warning line: {:?}", run.stderr);
    assert!(
        run.stderr.starts_with("stereo-depth: warning: lower.pgm is 1.0")
            && run.stderr.contains("px lower than left.pgm at the centre")
            && run.stderr.contains("compensated (check the rectification)"),
        "{:?}",
        run.stderr
    );
    assert!(run.stdout.contains("rectification misaligned: offset +1.0"), "{}", run.stdout);

    // Compensated, the shifted pair matches about as well as the clean one; uncompensated, the
    // one-pixel offset costs a lot.
    let (clean_bad, shifted_bad) = (bad2(&clean, &scene.gt_left), bad2(&shifted, &scene.gt_left));
    assert!(
        shifted_bad < clean_bad + 1.0,
        "bad2 {shifted_bad:.2} % shifted and compensated, {clean_bad:.2} % clean"
    );
    let (run, raw, json) = match_pair(dir.path(), "lower.pgm", &["--no-align"]);
    assert_eq!(json["rectification"]["compensated"], false);
    assert!(run.stderr.contains("not compensated (--no-align)"), "{:?}", run.stderr);
    let raw_bad = bad2(&raw, &scene.gt_left);
    assert!(raw_bad > shifted_bad + 2.0, "bad2 {raw_bad:.2} % uncompensated, {shifted_bad:.2} % compensated");
}

#[test]
fn a_clean_pair_is_matched_as_loaded() {
    let dir = tempfile::tempdir().unwrap();
    write_scene(dir.path(), WIDTH, HEIGHT);
    let (_, checked, json) = match_pair(dir.path(), "right.pgm", &[]);
    let checked_bytes = fs::read(dir.path().join("disparity.pfm")).unwrap();
    assert_eq!(json["rectification"]["verdict"], "aligned");
    assert_eq!(json["rectification"]["compensated"], false);
    let (run, unchecked, _) = match_pair(dir.path(), "right.pgm", &["--no-align"]);
    assert_eq!(run.stderr, "");
    assert_eq!(checked_bytes, fs::read(dir.path().join("disparity.pfm")).unwrap());
    assert_eq!(checked.size(), unchecked.size());
}

#[test]
fn swapped_views_are_warned_about() {
    let dir = tempfile::tempdir().unwrap();
    write_scene(dir.path(), WIDTH, HEIGHT);
    let run =
        run_in(dir.path(), &["right.pgm", "left.pgm", "--max-disparity", "48", "--disparity", "d.pfm", "-q"]);
    run.assert_success();
    assert_eq!(run.stderr.lines().count(), 1, "{:?}", run.stderr);
    assert!(
        run.stderr.starts_with("stereo-depth: warning: right.pgm, left.pgm: ")
            && run
                .stderr
                .trim_end()
                .ends_with("of the matches want negative disparity: are LEFT and RIGHT swapped?"),
        "{:?}",
        run.stderr
    );
}
