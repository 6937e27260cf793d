//! Determinism (the same input gives bit-identical outputs with any thread count and SIMD level)
//! and interruption (a batch killed at a random moment leaves no output that looks complete but
//! is not, and a re-run completes the rest).

mod common;

use std::fs;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::*;

/// Runs the binary in `cwd` with `env` set; asserts success.
fn run_env(cwd: &Path, env: &[(&str, &str)], args: &[&str]) {
    let output = Command::new(env!("CARGO_BIN_EXE_stereo-depth"))
        .args(args)
        .envs(env.iter().copied())
        .current_dir(cwd)
        .stdin(Stdio::null())
        .output()
        .unwrap();
    assert!(output.status.success(), "{args:?} {env:?}: {}", String::from_utf8_lossy(&output.stderr));
}

#[test]
fn outputs_are_bit_identical_across_threads_and_simd_levels() {
    let dir = tempfile::tempdir().unwrap();
    write_scene(dir.path(), 160, 120);
    for matcher in ["sgm", "bm"] {
        let mut reference: Option<Vec<Vec<u8>>> = None;
        // A level this CPU lacks runs its best one (x86-64 or aarch64).
        for simd in ["scalar", "avx2", "avx512", "neon"] {
            for threads in ["1", "2", "5"] {
                let tag = format!("{matcher}-{simd}-{threads}");
                let (exr, pfm, png) = (format!("{tag}.exr"), format!("{tag}.pfm"), format!("{tag}.png"));
                let mut args = vec!["left.pgm", "right.pgm", "--matcher", matcher, "--threads", threads];
                args.extend(["-o", &exr, "--disparity", &pfm, "--depth-png", &png]);
                args.extend(RIG);
                run_env(dir.path(), &[("STEREO_DISPARITY_SIMD", simd)], &args);
                let bytes: Vec<Vec<u8>> =
                    [&exr, &pfm, &png].iter().map(|p| fs::read(dir.path().join(p)).unwrap()).collect();
                match &reference {
                    None => reference = Some(bytes),
                    Some(first) => {
                        for (what, (a, b)) in ["EXR", "PFM", "depth PNG"].iter().zip(first.iter().zip(&bytes))
                        {
                            assert!(
                                a == b,
                                "{matcher}: the {what} with SIMD {simd}, {threads} threads differs"
                            );
                        }
                    }
                }
            }
        }
    }
    // The batch command (2 pairs in flight sharing the pool) writes the same bytes.
    let input = dir.path().join("in");
    for side in ["left", "right"] {
        fs::create_dir_all(input.join(side)).unwrap();
        for name in ["a", "b"] {
            fs::copy(dir.path().join(format!("{side}.pgm")), input.join(format!("{side}/{name}.pgm")))
                .unwrap();
        }
    }
    let mut args =
        vec!["batch", "in", "--out", "out", "--jobs", "2", "--threads", "3", "--disparity", "--quiet"];
    args.extend(RIG);
    run_env(dir.path(), &[], &args);
    for name in ["a", "b"] {
        assert_eq!(
            fs::read(dir.path().join(format!("out/{name}.disparity.pfm"))).unwrap(),
            fs::read(dir.path().join("sgm-avx512-1.pfm")).unwrap(),
            "batch pair {name}"
        );
    }
}

/// Every output present under `out` opens and is whole; returns the visible files.
fn check_whole(out: &Path) -> Vec<String> {
    let mut files = Vec::new();
    let mut stack = vec![out.to_path_buf()];
    while let Some(dir) = stack.pop() {
        for entry in fs::read_dir(&dir).unwrap() {
            let entry = entry.unwrap();
            let path = entry.path();
            let name = entry.file_name().to_string_lossy().into_owned();
            if path.is_dir() {
                stack.push(path);
                continue;
            }
            if name.starts_with('.') {
                // An atomic write's temporary: never mistaken for an output.
                assert!(name.contains(".tmp-"), "unexpected hidden file {name}");
                continue;
            }
            if name.ends_with(".exr") {
                let exr = read_exr(&path);
                assert_eq!((exr.width, exr.height), (96, 64), "{name}");
            } else if name.ends_with(".pfm") {
                let map = stereo_io::read_pfm(&path).unwrap_or_else(|e| panic!("{e}"));
                assert_eq!(map.size(), (96, 64), "{name}");
            } else if name.ends_with(".json") {
                let text = fs::read_to_string(&path).unwrap();
                serde_json::from_str::<serde_json::Value>(&text).unwrap_or_else(|e| panic!("{name}: {e}"));
            } else if name.ends_with(".csv") {
                assert!(fs::read_to_string(&path).unwrap().ends_with('\n'), "{name}");
            } else {
                panic!("unexpected output {name}");
            }
            files.push(name);
        }
    }
    files
}

#[test]
fn a_killed_batch_leaves_only_whole_outputs_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("in");
    for side in ["left", "right"] {
        fs::create_dir_all(input.join(side)).unwrap();
    }
    for i in 0..20 {
        let params = stereo_scene::SceneParams {
            width: 96,
            height: 64,
            seed: i,
            ..stereo_scene::SceneParams::default()
        };
        let scene = stereo_scene::render(&params);
        write_pgm16(&input.join(format!("left/p{i:02}.pgm")), &scene.left);
        write_pgm16(&input.join(format!("right/p{i:02}.pgm")), &scene.right);
    }
    let out = dir.path().join("out");
    let mut args = vec!["batch", "in", "--out", "out", "--disparity", "--stats", "--quiet", "--jobs", "1"];
    args.extend(RIG);

    // Kill at a different moment in each round: after the first, third and sixth depth map.
    for (round, wait_for) in [1usize, 3, 6].into_iter().enumerate() {
        let mut child = Command::new(env!("CARGO_BIN_EXE_stereo-depth"))
            .args(&args)
            .current_dir(dir.path())
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let start = Instant::now();
        let count = || {
            fs::read_dir(&out)
                .map(|d| {
                    d.flatten().filter(|e| e.file_name().to_string_lossy().ends_with(".depth.exr")).count()
                })
                .unwrap_or(0)
        };
        let already = count();
        while count() < already + wait_for && start.elapsed() < Duration::from_secs(60) {
            if child.try_wait().unwrap().is_some() {
                break;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        let _ = child.kill(); // SIGKILL
        let status = child.wait().unwrap();
        let files = check_whole(&out);
        eprintln!("round {round}: killed ({status}) with {} whole outputs", files.len());
    }

    // The re-run completes the rest: every pair has all its outputs, nothing is left over.
    let run = run_in(dir.path(), &args);
    run.assert_success();
    let files = check_whole(&out);
    for i in 0..20 {
        for ext in ["depth.exr", "disparity.pfm", "stats.json"] {
            let name = format!("p{i:02}.{ext}");
            assert!(files.contains(&name), "{name} missing after the re-run");
        }
    }
    let hidden: Vec<String> = fs::read_dir(&out)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with('.'))
        .collect();
    assert!(hidden.is_empty(), "temporaries left after the re-run: {hidden:?}");
    let summary: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["failed"], 0, "{summary}");
}
