//! `stereo-depth calc`, the rig design calculator, end to end: the datasheet examples in text and
//! JSON, the inverse question, the table, the field of view, the chart files, and bad input.

mod common;

use std::fs;
use std::path::Path;

use common::*;

/// Runs `stereo-depth calc ARGS` in `dir`.
fn calc_in(dir: &Path, args: &[&str]) -> Run {
    let mut all = vec!["calc"];
    all.extend(args);
    run_in(dir, &all)
}

fn calc(args: &[&str]) -> Run {
    calc_in(&std::env::temp_dir(), args)
}

fn json(args: &[&str]) -> serde_json::Value {
    let mut all = args.to_vec();
    all.push("--json");
    let run = calc(&all);
    run.assert_success();
    serde_json::from_str(&run.stdout).unwrap_or_else(|e| panic!("not JSON ({e}):\n{}", run.stdout))
}

/// The first line of `text` that starts (after indentation) with `key`, with the key and the
/// spaces after it removed. Keys end in two spaces where a shorter key would also match, as in
/// `"disparity  "` (not `disparity step`).
#[track_caller]
fn value<'a>(text: &'a str, key: &str) -> &'a str {
    text.lines()
        .find_map(|line| line.trim_start().strip_prefix(key))
        .map(str::trim)
        .unwrap_or_else(|| panic!("no line {key:?} in:\n{text}"))
}

const EXAMPLE_1: [&str; 8] = ["--baseline", "200", "--focal", "6", "--pixel", "2.5", "--disparity", "150"];
const EXAMPLE_2: [&str; 8] = ["--baseline", "80", "--focal", "12", "--pixel", "4", "--disparity", "400"];

#[test]
fn datasheet_example_200mm_6mm_text() {
    // Z = 200 mm · 6 mm / (150 px · 2.5 µm) = 3.2 m.
    let run = calc(&EXAMPLE_1);
    run.assert_success();
    let out = &run.stdout;
    assert_eq!(value(out, "focal length "), "2400 px");
    assert_eq!(value(out, "distance "), "3.2 m");
    assert_eq!(value(out, "disparity  "), "0.375 mm on the sensor");
    // 3.2² · 2.5 / (200 · 6) m = 21.33 mm.
    assert_eq!(value(out, "depth resolution "), "21.33 mm per 1 px step");
    assert!(run.stderr.is_empty(), "{}", run.stderr);
}

#[test]
fn datasheet_example_80mm_12mm_text() {
    // Z = 80 mm · 12 mm / (400 px · 4 µm) = 0.6 m.
    let run = calc(&EXAMPLE_2);
    run.assert_success();
    let out = &run.stdout;
    assert_eq!(value(out, "focal length "), "3000 px");
    assert_eq!(value(out, "distance "), "0.6 m");
    assert_eq!(value(out, "disparity  "), "1.6 mm on the sensor");
    assert_eq!(value(out, "depth resolution "), "1.5 mm per 1 px step");
    // The default search (0..128) cannot see 400 px: the report says so.
    assert!(out.contains("set --max-disparity 401 or more"), "{out}");
}

#[test]
fn datasheet_examples_json() {
    let j = json(&EXAMPLE_1);
    assert_eq!(j["focal_px"], 2400.0);
    assert_eq!(j["disparity"]["distance_m"], 3.2);
    assert_eq!(j["disparity"]["disparity_mm"], 0.375);
    assert!((j["disparity"]["depth_resolution_mm"].as_f64().unwrap() - 64.0 / 3.0).abs() < 1e-9);

    let j = json(&EXAMPLE_2);
    assert_eq!(j["focal_px"], 3000.0);
    assert_eq!(j["disparity"]["disparity_px"], 400.0);
    assert_eq!(j["disparity"]["distance_m"], 0.6);
    assert_eq!(j["disparity"]["disparity_mm"], 1.6);
    assert_eq!(j["disparity"]["depth_resolution_mm"], 1.5);
    assert!(j["distance"].is_null() && j["table"].is_null() && j["horizontal_fov_deg"].is_null());
    // Working range of the default search 0..128: 127 px and 1 px.
    assert_eq!(j["working_range"]["max_disparity_px"], 128);
    assert_eq!(j["working_range"]["max_disparity_source"], "default");
    assert_eq!(j["working_range"]["far"]["distance_m"], 240.0);
    assert_eq!(j["working_range"]["near"]["disparity_px"], 127.0);
}

#[test]
fn subpixel_step_scales_the_resolution() {
    let mut args = EXAMPLE_2.to_vec();
    args.extend(["--subpixel", "0.25"]);
    let run = calc(&args);
    run.assert_success();
    assert_eq!(value(&run.stdout, "depth resolution "), "0.375 mm per 0.25 px step");
    assert_eq!(json(&args)["working_range"]["far"]["distance_m"], 960.0);
}

#[test]
fn distance_gives_disparity_and_field_of_view() {
    // 80 mm · 3000 px / 5 m = 48 px = 0.192 mm; ΔZ = 25 m² / 240 m = 104.2 mm.
    // A 6.4 mm sensor behind 12 mm: 2·atan(3.2 / 12) = 29.86°.
    let args =
        ["--baseline", "80", "--focal", "12", "--pixel", "4", "--sensor-width", "6.4", "--distance", "5"];
    let run = calc(&args);
    run.assert_success();
    let out = &run.stdout;
    assert_eq!(value(out, "disparity  "), "48 px = 0.192 mm on the sensor");
    assert_eq!(value(out, "depth resolution "), "104.2 mm per 1 px step");
    assert_eq!(value(out, "field of view "), "29.86° horizontal (sensor 6.4 mm, 1600 px)");
    // The matchers' default search for a 1600 px image: 0..400.
    assert!(out.contains("disparities 1 to 399 px (--max-disparity 400"), "{out}");
    let j = json(&args);
    assert!((j["distance"]["disparity_px"].as_f64().unwrap() - 48.0).abs() < 1e-9);
    assert!((j["horizontal_fov_deg"].as_f64().unwrap() - 29.8628).abs() < 1e-4);
    assert_eq!(j["image_width_px"], 1600);
    // The same from the width in pixels.
    let j = json(&["--baseline", "80", "--focal", "12", "--pixel", "4", "--width-px", "1600"]);
    assert!((j["sensor_width_mm"].as_f64().unwrap() - 6.4).abs() < 1e-12);
}

#[test]
fn table_rows() {
    let args = ["--baseline", "80", "--focal", "12", "--pixel", "4", "--table", "--max-disparity", "64"];
    let run = calc(&args);
    run.assert_success();
    let lines: Vec<&str> = run.stdout.lines().collect();
    let header = lines.iter().position(|l| l.contains("disparity (px)")).expect("table header");
    let first: Vec<&str> = lines[header + 1].split_whitespace().collect();
    assert_eq!(first, ["1", "0.004", "240", "240000"]);
    let j = json(&args);
    let rows = j["table"].as_array().unwrap();
    let d: Vec<f64> = rows.iter().map(|r| r["disparity_px"].as_f64().unwrap()).collect();
    assert_eq!(d, [1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 12.0, 16.0, 24.0, 32.0, 48.0, 63.0]);

    // An explicit range and step (implies --table).
    let j = json(&[
        "--baseline",
        "80",
        "--focal",
        "12",
        "--pixel",
        "4",
        "--table-min",
        "100",
        "--table-max",
        "400",
        "--table-step",
        "100",
    ]);
    let z: Vec<f64> =
        j["table"].as_array().unwrap().iter().map(|r| r["distance_m"].as_f64().unwrap()).collect();
    assert_eq!(z, [2.4, 1.2, 0.8, 0.6]);
}

#[test]
fn png_chart_is_written_and_decodes() {
    let dir = tempfile::tempdir().unwrap();
    let run = calc_in(
        dir.path(),
        &["--baseline", "80", "--focal", "12", "--pixel", "4", "--distance", "5", "--chart", "range.png"],
    );
    run.assert_success();
    assert_eq!(run.printed_path("chart").as_deref(), Some(Path::new("range.png")));
    let image = stereo_io::load_rgb8(&dir.path().join("range.png")).expect("a decodable PNG");
    assert_eq!(image.size(), (1000, 600));
    // Not blank: white background, dark text, coloured curves.
    let pixels = image.as_slice();
    assert!(pixels.iter().filter(|p| **p == [255, 255, 255]).count() > pixels.len() / 2);
    assert!(pixels.iter().any(|p| p[2] > 150 && p[0] < 80), "no blue disparity curve");
    assert!(pixels.iter().any(|p| p[0] > 150 && p[2] < 80), "no red resolution curve");
    assert_eq!(list(dir.path()), ["range.png"], "temporary files left");

    // JSON names the chart too.
    let run = calc_in(
        dir.path(),
        &["--baseline", "80", "--focal", "12", "--pixel", "4", "--chart", "range.png", "--json"],
    );
    run.assert_success();
    let j: serde_json::Value = serde_json::from_str(&run.stdout).unwrap();
    assert_eq!(j["chart"], "range.png");
}

#[test]
fn svg_chart_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let run =
        calc_in(dir.path(), &["--baseline", "200", "--focal", "6", "--pixel", "2.5", "--chart", "range.SVG"]);
    run.assert_success();
    let svg = fs::read_to_string(dir.path().join("range.SVG")).unwrap();
    assert!(svg.starts_with("<svg"), "{}", &svg[..svg.len().min(100)]);
    for text in ["Distance (m)", "Disparity (px)", "Depth resolution", "baseline 200 mm"] {
        assert!(svg.contains(text), "{text} missing from the SVG");
    }
}

/// `calc ARGS` fails with exit status 2 and one stderr line naming `flag`; nothing is written.
#[track_caller]
fn rejects(args: &[&str], flag: &str) -> String {
    let dir = tempfile::tempdir().unwrap();
    let mut all = args.to_vec();
    all.extend(["--chart", "out.png"]);
    let run = calc_in(dir.path(), &all);
    let message = run.assert_error(2).to_string();
    assert!(message.contains(flag), "{flag} not named: {message}");
    assert!(message.contains("must be"), "no accepted range: {message}");
    assert_eq!(run.stdout, "");
    assert!(list(dir.path()).is_empty(), "files written: {:?}", list(dir.path()));
    message
}

#[test]
fn bad_rig_parameters_exit_2() {
    let rig =
        |b: &'static str, f: &'static str, p: &'static str| ["--baseline", b, "--focal", f, "--pixel", p];
    let m = rejects(&rig("0", "12", "4"), "--baseline");
    assert_eq!(m, "stereo-depth: error: invalid --baseline 0 mm (must be a finite number > 0 mm)");
    rejects(&rig("-80", "12", "4"), "--baseline");
    rejects(&rig("80", "0", "4"), "--focal");
    rejects(&rig("80", "-12", "4"), "--focal");
    rejects(&rig("80", "12", "NaN"), "--pixel");
    rejects(&rig("80", "12", "inf"), "--pixel");
    let mut args = rig("80", "12", "4").to_vec();
    args.extend(["--doffs", "nan"]);
    rejects(&args, "--doffs");
}

#[test]
fn absurd_values_exit_2() {
    let base = ["--baseline", "80", "--focal", "12", "--pixel", "4"];
    let with = |extra: &[&'static str]| {
        let mut all = base.to_vec();
        all.extend(extra);
        all
    };
    // A pixel larger than the sensor.
    let m =
        rejects(&["--baseline", "80", "--focal", "12", "--pixel", "4000", "--sensor-width", "3"], "--pixel");
    assert!(m.contains("at most 1500 µm"), "{m}");
    // A disparity wider than the sensor in pixels (6.4 mm / 4 µm = 1600 px).
    let m = rejects(&with(&["--sensor-width", "6.4", "--disparity", "2000"]), "--disparity");
    assert!(m.contains("< the image width 1600 px"), "{m}");
    rejects(&with(&["--disparity", "0"]), "--disparity");
    rejects(&with(&["--disparity", "-3"]), "--disparity");
    rejects(&with(&["--distance", "0"]), "--distance");
    rejects(&with(&["--distance", "-5"]), "--distance");
    let m = rejects(&with(&["--width-px", "1600", "--distance", "0.1"]), "--distance");
    assert!(m.contains("> 0.15 m"), "{m}");
    rejects(&with(&["--sensor-width", "0"]), "--sensor-width");
    rejects(&with(&["--width-px", "1"]), "--width-px");
    rejects(&with(&["--width-px", "12.5"]), "--width-px");
    rejects(&with(&["--subpixel", "0"]), "--subpixel");
    rejects(&with(&["--subpixel", "2"]), "--subpixel");
    rejects(&with(&["--max-disparity", "1"]), "--max-disparity");
    rejects(&with(&["--width-px", "640", "--max-disparity", "1000"]), "--max-disparity");
    rejects(&with(&["--table-step", "0"]), "--table-step");
    rejects(&with(&["--table-min", "10", "--table-max", "5"]), "--table-max");
    rejects(&with(&["--table-min", "1", "--table-max", "100", "--table-step", "0.0001"]), "--table-step");
}

#[test]
fn bad_chart_paths() {
    let dir = tempfile::tempdir().unwrap();
    let base = ["--baseline", "80", "--focal", "12", "--pixel", "4", "--chart"];
    let with = |path: &'static str| {
        let mut all = base.to_vec();
        all.push(path);
        all
    };
    let m = calc_in(dir.path(), &with("chart.jpg")).assert_error(2).to_string();
    assert!(m.contains("--chart") && m.contains(".png or .svg"), "{m}");
    // A folder that does not exist: a runtime error, exit 1.
    let m = calc_in(dir.path(), &with("missing/chart.png")).assert_error(1).to_string();
    assert!(m.contains("missing/chart.png"), "{m}");
    assert!(list(dir.path()).is_empty());
}
