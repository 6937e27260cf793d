//! Bad input: every failure exits 1 (runtime) or 2 (usage), never panics, prints exactly one
//! line on stderr, and leaves no output (nor temporary file) behind.

mod common;

use std::fs;
use std::path::Path;

use common::*;

/// Runs the pair command in `dir` (which holds left.pgm/right.pgm from [`write_scene`]) with
/// `-o out.exr --disparity out.pfm --stats out.json` and checks the failure; returns the message.
#[track_caller]
fn fails(dir: &Path, args: &[&str], code: i32) -> String {
    let before = list(dir);
    let mut all: Vec<&str> = args.to_vec();
    all.extend(["-o", "out.exr", "--disparity", "out.pfm", "--stats", "out.json"]);
    let run = run_in(dir, &all);
    let message = run.assert_error(code).to_string();
    assert_eq!(run.stdout, "", "nothing on stdout after an error");
    assert_eq!(list(dir), before, "files appeared: {message}");
    message
}

fn scene() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    write_scene(dir.path(), 64, 48);
    dir
}

fn with_rig<'a>(args: &[&'a str]) -> Vec<&'a str> {
    let mut all = args.to_vec();
    all.extend(RIG);
    all
}

#[test]
fn missing_left_file() {
    let dir = scene();
    let message = fails(dir.path(), &with_rig(&["nothere.png", "right.pgm"]), 1);
    assert!(message.contains("nothere.png"), "{message}");
    assert_eq!(message.matches("nothere.png").count(), 1, "path named twice: {message}");
}

#[test]
fn text_file_renamed_png() {
    let dir = scene();
    fs::write(dir.path().join("notes.png"), "this is not an image\n").unwrap();
    let message = fails(dir.path(), &with_rig(&["notes.png", "right.pgm"]), 1);
    assert!(message.contains("notes.png"), "{message}");
}

#[test]
fn left_right_size_mismatch() {
    let dir = scene();
    let small = tempfile::tempdir().unwrap();
    write_scene(small.path(), 40, 48);
    fs::copy(small.path().join("right.pgm"), dir.path().join("small.pgm")).unwrap();
    let message = fails(dir.path(), &with_rig(&["left.pgm", "small.pgm"]), 1);
    assert!(message.contains("64x48") && message.contains("40x48"), "{message}");
}

#[test]
fn invalid_rig_parameters() {
    let dir = scene();
    for (flag, value) in [
        ("--baseline", "0"),
        ("--baseline", "-80"),
        ("--baseline", "NaN"),
        ("--focal", "0"),
        ("--focal", "-12"),
        ("--focal", "nan"),
        ("--pixel", "0"),
        ("--pixel", "-4"),
        ("--pixel", "NaN"),
        ("--pixel", "inf"),
    ] {
        let mut args = vec!["left.pgm", "right.pgm", "--baseline", "80", "--focal", "12", "--pixel", "4"];
        // The later occurrence is an error for clap, so replace the value in place.
        let at = args.iter().position(|a| *a == flag).unwrap();
        args[at + 1] = value;
        let message = fails(dir.path(), &args, 2);
        assert!(message.contains(flag), "{flag} {value}: {message}");
    }
    let message = fails(dir.path(), &with_rig(&["left.pgm", "right.pgm", "--doffs", "nan"]), 2);
    assert!(message.contains("--doffs"), "{message}");
}

#[test]
fn inverted_disparity_range() {
    let dir = scene();
    let args = with_rig(&["left.pgm", "right.pgm", "--min-disparity", "64", "--max-disparity", "16"]);
    let message = fails(dir.path(), &args, 2);
    assert!(message.contains("disparity"), "{message}");
    let args = with_rig(&["left.pgm", "right.pgm", "--min-disparity", "16", "--max-disparity", "16"]);
    fails(dir.path(), &args, 2);
}

#[test]
fn disparity_range_wider_than_image() {
    let dir = scene();
    let args = with_rig(&["left.pgm", "right.pgm", "--max-disparity", "100"]);
    let message = fails(dir.path(), &args, 2);
    assert!(message.contains("wider than the image"), "{message}");
}

#[test]
fn output_folder_missing() {
    let dir = scene();
    let before = list(dir.path());
    let run = run_in(dir.path(), &with_rig(&["left.pgm", "right.pgm", "-o", "no/such/dir/out.exr"]));
    let message = run.assert_error(1);
    assert!(message.contains("no/such/dir"), "{message}");
    assert_eq!(list(dir.path()), before);

    // Only the disparity map's folder is missing: the depth map is not written either.
    let run = run_in(
        dir.path(),
        &with_rig(&["left.pgm", "right.pgm", "-o", "out.exr", "--disparity", "nodir/d.pfm"]),
    );
    run.assert_error(1);
    assert_eq!(list(dir.path()), before);
}

#[test]
fn output_over_an_input_is_refused() {
    let dir = scene();
    let before = fs::read(dir.path().join("left.pgm")).unwrap();
    let run = run_in(dir.path(), &with_rig(&["left.pgm", "right.pgm", "-o", "left.pgm"]));
    run.assert_error(2);
    assert_eq!(fs::read(dir.path().join("left.pgm")).unwrap(), before);
}

#[test]
fn options_of_the_other_matcher_are_refused() {
    let dir = scene();
    let message = fails(dir.path(), &with_rig(&["left.pgm", "right.pgm", "--block-size", "9"]), 2);
    assert!(message.contains("--block-size"), "{message}");
    let args = with_rig(&["left.pgm", "right.pgm", "--matcher", "bm", "--p1", "9"]);
    let message = fails(dir.path(), &args, 2);
    assert!(message.contains("--p1"), "{message}");
}

#[test]
fn clap_usage_errors_exit_2() {
    let dir = scene();
    // Missing rig flags.
    let run = run_in(dir.path(), &["left.pgm", "right.pgm"]);
    assert_eq!(run.code, Some(2), "{}", run.stderr);
    assert!(run.stderr.contains("--baseline"), "{}", run.stderr);
    let run = run_in(dir.path(), &with_rig(&["left.pgm", "right.pgm", "--paths", "5"]));
    assert_eq!(run.code, Some(2), "{}", run.stderr);
    assert_eq!(list(dir.path()), ["gt.pfm", "left.pgm", "right.pgm"]);
}

#[test]
fn eval_errors() {
    let dir = scene();
    let run = run_in(dir.path(), &["eval", "missing.pfm", "gt.pfm"]);
    let message = run.assert_error(1);
    assert!(message.contains("missing.pfm"), "{message}");

    // Estimate and ground truth of different sizes.
    let small = tempfile::tempdir().unwrap();
    write_scene(small.path(), 40, 30);
    let other = small.path().join("gt.pfm");
    let run = run_in(dir.path(), &["eval", "gt.pfm", s(&other)]);
    let message = run.assert_error(1);
    assert!(message.contains("size"), "{message}");

    let run = run_in(dir.path(), &["eval", "gt.pfm", "gt.pfm", "--gt-scale", "0"]);
    let message = run.assert_error(2);
    assert!(message.contains("--gt-scale"), "{message}");
}

/// A missing required argument is named on the one error line, with the usage of its
/// (sub)command: clap's own message lists the names on lines of their own.
#[test]
fn missing_required_arguments_are_named() {
    let dir = scene();
    // The command line, what must be reported missing, and the start of the usage shown.
    let cases: &[(&[&str], &str, &str)] = &[
        (&[], "<LEFT>, <RIGHT>", "stereo-depth <LEFT> <RIGHT>"),
        (&["left.pgm"], "<RIGHT>", "stereo-depth <LEFT> <RIGHT>"),
        (&["left.pgm", "right.pgm", "--cx", "3"], "--cy <PX>", "stereo-depth "),
        (&["batch"], "--out <OUT_DIR>, <INPUT_DIR>", "stereo-depth batch "),
        (&["batch", "."], "--out <OUT_DIR>", "stereo-depth batch "),
        (&["batch-merge"], "<OUT_DIR>", "stereo-depth batch-merge <OUT_DIR>"),
        (&["calc"], "--baseline <MM>, --focal <MM>, --pixel <UM>", "stereo-depth calc "),
        (&["calc", "--baseline", "80", "--focal", "12"], "--pixel <UM>", "stereo-depth calc "),
        (&["eval"], "<EST>, <GT>", "stereo-depth eval <EST> <GT>"),
        (&["eval", "gt.pfm"], "<GT>", "stereo-depth eval <EST> <GT>"),
        (&["eval-folder"], "<DIR>", "stereo-depth eval-folder <DIR>"),
        (&["info"], "<FILE>", "stereo-depth info <FILE>"),
        (&["degrade"], "--out <DIR>, <LEFT>, <RIGHT>", "stereo-depth degrade "),
        (&["degrade", "left.pgm", "right.pgm"], "--out <DIR>", "stereo-depth degrade "),
    ];
    for &(args, missing, usage) in cases {
        let run = run_in(dir.path(), args);
        let message = run.assert_error(2);
        assert_eq!(run.stdout, "", "{args:?}");
        let expected = format!("stereo-depth: error: missing {missing}; usage: {usage}");
        assert!(message.starts_with(&expected), "{args:?}: {message}\n  want {expected}...");
        assert!(message.ends_with(" (see --help)"), "{args:?}: {message}");
    }
    assert_eq!(list(dir.path()), ["gt.pfm", "left.pgm", "right.pgm"]);

    // A flag without its value is clap's one-line message, naming the flag.
    let message = run_in(dir.path(), &["calc", "--focal", "12", "--pixel", "4", "--baseline"])
        .assert_error(2)
        .to_string();
    assert!(message.contains("--baseline <MM>") && message.contains("a value is required"), "{message}");
}
