//! The bad-input catalogue (issue 8): every command (pair, batch, eval, info, calc, batch-merge)
//! is given each kind of bad input. Every case must end with exit status 1 (runtime) or 2 (usage),
//! never a panic (101), exactly one line on stderr naming the file or parameter, nothing on stdout,
//! and no file (nor temporary file) left behind. The cases already in tests/errors.rs,
//! tests/outputs.rs and tests/calc.rs are not repeated here; docs/hardening.md lists them all.
//!
//! Cases that need a read-only folder or a full disk use a small tmpfs mounted for the test when
//! the tests run as root with mount permission, a `chmod 555` folder when not root, and are
//! skipped (with a note on stderr) otherwise.

mod common;

use std::fs;
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::process::Command;

use common::*;

const W: u32 = 64;
const H: u32 = 48;

/// A textured 8-bit grey PNG (a shifted copy is a plausible pair).
fn png8(w: u32, h: u32, shift: u32) -> Vec<u8> {
    let img = image::GrayImage::from_fn(w, h, |x, y| {
        let v = ((x + shift).wrapping_mul(2654435761u32) ^ y.wrapping_mul(40503)) >> 7;
        image::Luma([(v % 251) as u8])
    });
    let mut bytes = Vec::new();
    img.write_to(&mut Cursor::new(&mut bytes), image::ImageFormat::Png).unwrap();
    bytes
}

fn png16(w: u32, h: u32, shift: u32) -> Vec<u8> {
    let img = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(w, h, |x, y| {
        let v = ((x + shift).wrapping_mul(2654435761u32) ^ y.wrapping_mul(40503)) >> 7;
        image::Luma([((v % 251) * 257) as u16])
    });
    let mut bytes = Vec::new();
    img.write_to(&mut Cursor::new(&mut bytes), image::ImageFormat::Png).unwrap();
    bytes
}

fn jpeg(w: u32, h: u32) -> Vec<u8> {
    let img = image::GrayImage::from_fn(w, h, |x, y| image::Luma([((x * 7 + y * 13) % 256) as u8]));
    let mut bytes = Vec::new();
    img.write_to(&mut Cursor::new(&mut bytes), image::ImageFormat::Jpeg).unwrap();
    bytes
}

fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
        }
    }
    !crc
}

/// A PNG whose header claims `w × h` 8-bit grey pixels, with a tiny IDAT: only a decoder that
/// trusts the header allocates `w·h` bytes.
fn png_header_only(w: u32, h: u32) -> Vec<u8> {
    let chunk = |kind: &[u8], data: &[u8]| {
        let mut c = (data.len() as u32).to_be_bytes().to_vec();
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        c.extend_from_slice(&body);
        c.extend_from_slice(&crc32(&body).to_be_bytes());
        c
    };
    let mut ihdr = w.to_be_bytes().to_vec();
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[8, 0, 0, 0, 0]);
    let mut out = b"\x89PNG\r\n\x1a\n".to_vec();
    out.extend(chunk(b"IHDR", &ihdr));
    out.extend(chunk(b"IDAT", &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]));
    out.extend(chunk(b"IEND", &[]));
    out
}

/// A valid PNG whose IHDR CRC is wrong.
fn png_bad_crc() -> Vec<u8> {
    let mut bytes = png8(W, H, 0);
    // Signature (8) + length (4) + "IHDR" (4) + 13 data bytes: the CRC follows.
    bytes[8 + 4 + 4 + 13] ^= 0x5a;
    bytes
}

fn pfm(header: &str, values: usize) -> Vec<u8> {
    let mut bytes = header.as_bytes().to_vec();
    for i in 0..values {
        bytes.extend_from_slice(&(i as f32).to_le_bytes());
    }
    bytes
}

const CALIB: &str = "cam0=[300 0 32; 0 300 24; 0 0 1]\ndoffs=0\nbaseline=80\nwidth=64\nheight=48\nndisp=16\n";

/// Every fixture the cases refer to, in `dir`: good pair `left.png`/`right.png`, bad images,
/// PFMs, calib files and a folder `folder.png`.
fn fixtures(dir: &Path) {
    let files: Vec<(&str, Vec<u8>)> = vec![
        ("left.png", png8(W, H, 0)),
        ("right.png", png8(W, H, 3)),
        ("right16.png", png16(W, H, 3)),
        ("small.png", png8(W / 2, H, 3)),
        ("empty.png", Vec::new()),
        ("text.png", b"this is a text file, not a picture\n".to_vec()),
        ("jpeg.png", jpeg(W, H)),
        ("truncated.png", {
            let b = png8(W, H, 0);
            b[..b.len() / 2].to_vec()
        }),
        ("truncated_jpeg.png", {
            let b = jpeg(W, H);
            b[..b.len() / 3].to_vec()
        }),
        ("badcrc.png", png_bad_crc()),
        ("huge.png", png_header_only(100_000, 100_000)),
        ("wide.png", png_header_only(u32::MAX / 2, 1)),
        ("zero.png", png_header_only(0, 10)),
        ("one.png", png8(1, 1, 0)),
        ("col.png", png8(1, H, 0)),
        ("row.png", png8(W, 1, 0)),
        ("narrow.png", png8(16, H, 0)),
        ("narrow_r.png", png8(16, H, 2)),
        ("good.pfm", pfm(&format!("Pf\n{W} {H}\n-1.0\n"), (W * H) as usize)),
        ("badmagic.pfm", pfm("P7\n4 4\n-1.0\n", 16)),
        ("badsize.pfm", pfm("Pf\n-4 4\n-1.0\n", 16)),
        ("badnumber.pfm", pfm("Pf\nfour 4\n-1.0\n", 16)),
        ("zeroscale.pfm", pfm("Pf\n4 4\n0\n", 16)),
        ("nanscale.pfm", pfm("Pf\n4 4\nnan\n", 16)),
        ("short.pfm", pfm("Pf\n4 4\n-1.0\n", 15)),
        ("hugepfm.pfm", pfm("Pf\n100000 100000\n-1.0\n", 4)),
        ("headeronly.pfm", b"Pf\n4 4".to_vec()),
        ("colour.pfm", pfm("PF\n4 4\n-1.0\n", 48)),
        ("calib.txt", CALIB.as_bytes().to_vec()),
        ("garbage_calib.txt", b"this is not a calibration\n".to_vec()),
        ("nocam0_calib.txt", b"doffs=0\nbaseline=80\n".to_vec()),
        ("badmatrix_calib.txt", b"cam0=[300 0 32; 0 300 24]\nbaseline=80\n".to_vec()),
        ("nanbase_calib.txt", b"cam0=[300 0 32; 0 300 24; 0 0 1]\nbaseline=nan\n".to_vec()),
        ("zerofocal_calib.txt", b"cam0=[0 0 32; 0 0 24; 0 0 1]\nbaseline=80\n".to_vec()),
        ("negbase_calib.txt", b"cam0=[300 0 32; 0 300 24; 0 0 1]\nbaseline=-80\n".to_vec()),
        ("negndisp_calib.txt", b"cam0=[300 0 32; 0 300 24; 0 0 1]\nbaseline=80\nndisp=-16\n".to_vec()),
        ("binary_calib.txt", vec![0xff, 0xfe, 0x00, 0x80]),
        ("notjson.json", b"{ this is not json".to_vec()),
        ("truncated.exr", b"\x76\x2f\x31\x01\x02\x00\x00\x00chan".to_vec()),
        ("truncated.ply", b"ply\nformat binary_little_endian 1.0\nelement vertex 10\n".to_vec()),
    ];
    for (name, bytes) in files {
        fs::write(dir.join(name), bytes).unwrap();
    }
    fs::create_dir(dir.join("folder.png")).unwrap();
    fs::create_dir(dir.join("out")).unwrap();
}

/// Every file under `dir`, recursively, as relative paths (hidden temporaries included), sorted.
fn tree(dir: &Path) -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in fs::read_dir(&d).unwrap() {
            let entry = entry.unwrap();
            let rel = entry.path().strip_prefix(dir).unwrap().to_string_lossy().into_owned();
            if entry.file_type().unwrap().is_dir() {
                stack.push(entry.path());
            }
            out.push(rel);
        }
    }
    out.sort();
    out
}

const RIG_ARGS: &str = "--baseline 80 --focal 12 --pixel 4";
/// Outputs of every pair case: all must be absent after the failure.
const OUTPUTS: &str = "-o out/d.exr --disparity out/d.pfm --stats out/s.json --preview out/p.png";

/// One case: a command line (split on spaces; `{rig}` and `{out}` expand), the exit status and
/// words the one error line must contain.
struct Case {
    args: String,
    code: i32,
    needles: Vec<&'static str>,
}

fn case(args: &str, code: i32, needles: &[&'static str]) -> Case {
    let args = args.replace("{rig}", RIG_ARGS).replace("{out}", OUTPUTS);
    Case { args, code, needles: needles.to_vec() }
}

/// Runs every case in one fixture folder; collects all failures before failing.
fn check(cases: &[Case]) {
    let dir = tempfile::tempdir().unwrap();
    fixtures(dir.path());
    let before = tree(dir.path());
    let mut failures = Vec::new();
    for c in cases {
        let args: Vec<&str> = c.args.split_whitespace().collect();
        let run = run_in(dir.path(), &args);
        let one_line = run.stderr.starts_with("stereo-depth: error: ")
            && run.stderr.ends_with('\n')
            && run.stderr.lines().count() == 1;
        let mut problems = Vec::new();
        if run.code != Some(c.code) {
            problems.push(format!("exit {:?}, want {}", run.code, c.code));
        }
        if !one_line {
            problems.push("stderr is not one error line".to_string());
        }
        for needle in &c.needles {
            if !run.stderr.contains(needle) {
                problems.push(format!("does not name {needle:?}"));
            }
        }
        if !run.stdout.is_empty() {
            problems.push(format!("stdout: {:?}", run.stdout));
        }
        let after = tree(dir.path());
        if after != before {
            let new: Vec<&String> = after.iter().filter(|p| !before.contains(p)).collect();
            problems.push(format!("left files behind: {new:?}"));
            for path in new {
                let _ = fs::remove_file(dir.path().join(path));
            }
        }
        if !problems.is_empty() {
            failures.push(format!(
                "`{}`: {}\n    stderr: {}",
                c.args,
                problems.join("; "),
                run.stderr.trim_end()
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}

#[test]
fn pair_command_bad_images() {
    check(&[
        case("missing.png right.png {rig} {out}", 1, &["missing.png"]),
        case("left.png missing.png {rig} {out}", 1, &["missing.png"]),
        case("folder.png right.png {rig} {out}", 1, &["folder.png", "directory"]),
        case("left.png folder.png {rig} {out}", 1, &["folder.png", "directory"]),
        case("empty.png right.png {rig} {out}", 1, &["empty.png", "empty file"]),
        case("left.png empty.png {rig} {out}", 1, &["empty.png", "empty file"]),
        case("text.png right.png {rig} {out}", 1, &["text.png", "not a PNG"]),
        case("truncated.png right.png {rig} {out}", 1, &["truncated.png"]),
        case("left.png truncated.png {rig} {out}", 1, &["truncated.png"]),
        case("truncated_jpeg.png right.png {rig} {out}", 1, &["truncated_jpeg.png", "JPEG"]),
        case("badcrc.png right.png {rig} {out}", 1, &["badcrc.png"]),
        case("huge.png right.png {rig} {out}", 1, &["huge.png", "100000x100000", "--max-pixels"]),
        case("left.png huge.png {rig} {out}", 1, &["huge.png", "--max-pixels"]),
        case("huge.png huge.png {rig} {out} --max-pixels 20G", 1, &["huge.png", "memory", "--max-memory"]),
        case("wide.png wide.png {rig} {out}", 1, &["wide.png", "--max-pixels"]),
        case("zero.png zero.png {rig} {out}", 1, &["zero.png"]),
        case("one.png one.png {rig} {out}", 1, &["one.png", "1x1", "smaller than"]),
        case("one.png one.png {rig} {out} --matcher bm", 1, &["one.png", "1x1"]),
        case("col.png col.png {rig} {out}", 1, &["col.png", "1x48"]),
        case("row.png row.png {rig} {out}", 1, &["row.png", "64x1"]),
        case("row.png row.png {rig} {out} --matcher bm", 1, &["row.png", "64x1"]),
        case("left.png small.png {rig} {out}", 1, &["small.png", "32x48", "64x48"]),
        case("left.png one.png {rig} {out}", 1, &["one.png", "1x1"]),
    ]);
}

#[test]
fn pair_command_bad_ranges_rigs_and_limits() {
    check(&[
        // Width not larger than the disparity range (the range must fit in the image).
        case(
            "narrow.png narrow_r.png {rig} {out} --max-disparity 17",
            2,
            &["wider than the image", "--max-disparity"],
        ),
        case(
            "narrow.png narrow_r.png {rig} {out} --min-disparity -20 --max-disparity 0",
            2,
            &["wider than the image"],
        ),
        case(
            "left.png right.png {rig} {out} --min-disparity 5 --max-disparity -5",
            2,
            &["--min-disparity", "--max-disparity"],
        ),
        case(
            "left.png right.png {rig} {out} --min-disparity -5 --max-disparity -5",
            2,
            &["empty disparity range"],
        ),
        case("left.png right.png {rig} {out} --max-disparity 99999999999", 2, &["--max-disparity"]),
        case("left.png right.png {rig} {out} --max-disparity", 2, &["--max-disparity"]),
        // Rig parameters not in tests/errors.rs.
        case("left.png right.png --baseline inf --focal 12 --pixel 4 {out}", 2, &["--baseline"]),
        case("left.png right.png --baseline=-inf --focal 12 --pixel 4 {out}", 2, &["--baseline"]),
        case("left.png right.png --baseline 80 --focal inf --pixel 4 {out}", 2, &["--focal"]),
        case("left.png right.png --baseline 80 --focal-px nan {out}", 2, &["--focal-px"]),
        case("left.png right.png --baseline 80 --focal-px 0 {out}", 2, &["--focal-px"]),
        case("left.png right.png --baseline 80 --focal-px -300 {out}", 2, &["--focal-px"]),
        case("left.png right.png --baseline 80 --focal-px inf {out}", 2, &["--focal-px"]),
        case("left.png right.png {rig} {out} --doffs inf", 2, &["--doffs"]),
        case("left.png right.png {rig} {out} --cx nan --cy 1", 2, &["--cx"]),
        case("left.png right.png {rig} {out} --sensor-width 0", 2, &["--sensor-width"]),
        case("left.png right.png {rig} {out} --sensor-width nan", 2, &["--sensor-width"]),
        case("left.png right.png {rig} {out} --lr-max-diff nan", 2, &["--lr-max-diff"]),
        case("left.png right.png {rig} {out} --lr-max-diff -1", 2, &["--lr-max-diff"]),
        case("left.png right.png {rig} {out} --threads 0", 2, &["--threads"]),
        // Limits.
        case("left.png right.png {rig} {out} --max-pixels 3000", 1, &["left.png", "--max-pixels"]),
        case("left.png right.png {rig} {out} --max-pixels 0", 2, &["--max-pixels"]),
        case("left.png right.png {rig} {out} --max-pixels 10Q", 2, &["--max-pixels"]),
        case("left.png right.png {rig} {out} --max-memory 100K", 1, &["left.png", "--max-memory"]),
        case("left.png right.png {rig} {out} --max-memory -1", 2, &["--max-memory"]),
        case("left.png right.png {rig} {out} --max-memory 99999999T", 2, &["--max-memory"]),
    ]);
}

#[test]
fn pair_command_bad_calib_files() {
    check(&[
        case("left.png right.png --calib missing_calib.txt {out}", 1, &["missing_calib.txt"]),
        case("left.png right.png --calib folder.png {out}", 1, &["folder.png", "directory"]),
        case("left.png right.png --calib empty.png {out}", 1, &["empty.png", "cam0"]),
        case("left.png right.png --calib garbage_calib.txt {out}", 1, &["garbage_calib.txt", "key=value"]),
        case("left.png right.png --calib nocam0_calib.txt {out}", 1, &["nocam0_calib.txt", "cam0"]),
        case("left.png right.png --calib badmatrix_calib.txt {out}", 1, &["badmatrix_calib.txt", "cam0"]),
        case("left.png right.png --calib nanbase_calib.txt {out}", 1, &["nanbase_calib.txt", "baseline"]),
        case("left.png right.png --calib negndisp_calib.txt {out}", 1, &["negndisp_calib.txt", "ndisp"]),
        case("left.png right.png --calib binary_calib.txt {out}", 1, &["binary_calib.txt", "UTF-8"]),
        case("left.png right.png --calib zerofocal_calib.txt {out}", 2, &["zerofocal_calib.txt", "focal"]),
        case("left.png right.png --calib negbase_calib.txt {out}", 2, &["negbase_calib.txt", "baseline"]),
        // The calib.txt is for a different image size.
        case("small.png small.png --calib calib.txt {out}", 1, &["small.png", "32x48", "64x48"]),
    ]);
}

#[test]
fn pair_command_bad_outputs() {
    check(&[
        case("left.png right.png {rig} -o folder.png", 1, &["folder.png", "folder"]),
        case("left.png right.png {rig} -o out/d.exr --disparity folder.png", 1, &["folder.png"]),
        case("left.png right.png {rig} -o missing/d.exr", 1, &["missing"]),
        case("left.png right.png {rig} -o out/d.exr --stats missing/s.json", 1, &["missing/s.json"]),
        // A device is never replaced by the atomic rename, and nothing is left beside it.
        case("left.png right.png {rig} -o /dev/full", 1, &["/dev/full", "not a regular file"]),
        case("left.png right.png {rig} -o out/d.exr --stats /dev/full", 1, &["/dev/full"]),
        case("left.png right.png {rig} -o out/d.exr --preview /dev/null", 1, &["/dev/null"]),
        // A folder no one can create files in (procfs), even root.
        case("left.png right.png {rig} -o /proc/depth.exr", 1, &["/proc/depth.exr"]),
        case("left.png right.png {rig} -o out/d.exr --disparity /proc/d.pfm", 1, &["/proc/d.pfm"]),
        // Output over an input through another spelling of the path.
        case("left.png right.png {rig} -o ./out/../left.png", 2, &["left.png", "input"]),
        case("left.png right.png {rig} -o out/x.exr --stats out/x.exr", 2, &["same file"]),
    ]);
}

#[test]
fn eval_command_bad_inputs() {
    check(&[
        case("eval folder.png good.pfm", 1, &["folder.png", "directory"]),
        case("eval good.pfm folder.png", 1, &["folder.png", "directory"]),
        case("eval empty.pfm good.pfm", 1, &["empty.pfm"]),
        case("eval badmagic.pfm good.pfm", 1, &["badmagic.pfm", "not a PFM"]),
        case("eval badsize.pfm good.pfm", 1, &["badsize.pfm", "size"]),
        case("eval badnumber.pfm good.pfm", 1, &["badnumber.pfm", "header"]),
        case("eval zeroscale.pfm good.pfm", 1, &["zeroscale.pfm", "scale"]),
        case("eval nanscale.pfm good.pfm", 1, &["nanscale.pfm", "scale"]),
        case("eval short.pfm good.pfm", 1, &["short.pfm", "truncated"]),
        case("eval hugepfm.pfm good.pfm", 1, &["hugepfm.pfm", "truncated"]),
        case("eval headeronly.pfm good.pfm", 1, &["headeronly.pfm", "truncated"]),
        case("eval colour.pfm good.pfm", 1, &["colour.pfm", "grey"]),
        case("eval good.pfm short.pfm", 1, &["short.pfm"]),
        case("eval good.pfm text.png", 1, &["text.png", "not a PNG"]),
        case("eval good.pfm truncated.png", 1, &["truncated.png"]),
        case("eval good.pfm badcrc.png", 1, &["badcrc.png"]),
        case("eval good.pfm huge.png", 1, &["huge.png", "100000x100000"]),
        case("eval good.pfm empty.png", 1, &["empty.png"]),
        case("eval good.pfm calib.txt", 1, &["calib.txt", "format"]),
        case("eval good.pfm one.png", 1, &["size"]),
        case("eval good.pfm good.pfm --gt-scale nan", 2, &["--gt-scale"]),
        case("eval good.pfm good.pfm --gt-scale -4", 2, &["--gt-scale"]),
        case("eval good.pfm good.pfm --gt-scale inf", 2, &["--gt-scale"]),
    ]);
}

#[test]
fn info_command_bad_inputs() {
    check(&[
        case("info missing.exr", 1, &["missing.exr"]),
        case("info folder.png", 1, &["folder.png", "directory"]),
        case("info empty.png", 1, &["empty.png"]),
        case("info text.png", 1, &["text.png", "unrecognised"]),
        case("info truncated.png", 1, &["truncated.png"]),
        case("info badcrc.png", 1, &["badcrc.png"]),
        case("info huge.png", 1, &["huge.png", "100000x100000"]),
        case("info short.pfm", 1, &["short.pfm", "truncated"]),
        case("info hugepfm.pfm", 1, &["hugepfm.pfm", "truncated"]),
        case("info colour.pfm", 1, &["colour.pfm"]),
        case("info notjson.json", 1, &["notjson.json"]),
        case("info truncated.exr", 1, &["truncated.exr"]),
        case("info truncated.ply", 1, &["truncated.ply"]),
    ]);
}

#[test]
fn calc_command_bad_inputs() {
    check(&[
        case("calc --baseline inf --focal 12 --pixel 4", 2, &["--baseline"]),
        case("calc --baseline 80 --focal=-inf --pixel 4", 2, &["--focal"]),
        case("calc --baseline 80 --focal 12 --pixel 0", 2, &["--pixel"]),
        case("calc --baseline 80 --focal 12 --pixel 4 --distance nan", 2, &["--distance"]),
        case("calc --baseline 80 --focal 12 --pixel 4 --chart folder.png", 1, &["folder.png"]),
        case("calc --baseline 80 --focal 12 --pixel 4 --chart /proc/chart.svg", 1, &["/proc/chart.svg"]),
    ]);
}

#[test]
fn batch_merge_bad_inputs() {
    let dir = tempfile::tempdir().unwrap();
    fixtures(dir.path());
    let shards = dir.path().join("shards");
    fs::create_dir(&shards).unwrap();
    fs::write(shards.join("summary.shard-0-of-2.json"), "{ not json").unwrap();
    fs::write(shards.join("summary.shard-1-of-2.json"), "{}").unwrap();
    check(&[
        case("batch-merge missing", 1, &["missing"]),
        case("batch-merge left.png", 1, &["left.png"]),
        case("batch-merge out", 1, &["out", "no shard summaries"]),
    ]);
    let before = list(&shards);
    let run = run_in(dir.path(), &["batch-merge", "shards"]);
    let message = run.assert_error(1);
    assert!(message.contains("summary.shard-0-of-2.json"), "{message}");
    assert_eq!(list(&shards), before);
}

/// Batch runs: usage errors exit 2 with one line; a bad pair is a failed row (named in the summary
/// and in the one failure line), exit 1, and leaves none of its outputs.
#[test]
fn batch_command_bad_inputs() {
    check(&[
        case("batch missing --out out {rig}", 1, &["missing", "INPUT_DIR"]),
        case("batch left.png --out out {rig}", 1, &["left.png", "not a folder"]),
        case("batch out --out left.png {rig}", 1, &["left.png", "--out"]),
        case("batch out --out out {rig} --max-pixels 0", 2, &["--max-pixels"]),
        case("batch out --out out {rig} --max-memory 1X", 2, &["--max-memory"]),
        case("batch out --out out --baseline nan --focal 12 --pixel 4", 2, &["--baseline"]),
        case("batch out --out out {rig} --min-disparity 9 --max-disparity 3", 2, &["disparity"]),
        case("batch out --out out --baseline 80 --calib garbage_calib.txt", 1, &["garbage_calib.txt"]),
    ]);

    let bad: [(&str, &[u8], &str); 7] = [
        ("empty", b"", "empty file"),
        ("text", b"not a picture", "not a PNG"),
        ("truncated", &png8(W, H, 0)[..200], "truncated.png"),
        ("badcrc", &png_bad_crc(), "badcrc.png"),
        ("huge", &png_header_only(100_000, 100_000), "--max-pixels"),
        ("one", &png8(1, 1, 0), "1x1"),
        ("small", &png8(W / 2, H, 0), "32x48"),
    ];
    for (name, bytes, needle) in bad {
        let dir = tempfile::tempdir().unwrap();
        let input = dir.path().join("in");
        fs::create_dir_all(input.join("left")).unwrap();
        fs::create_dir_all(input.join("right")).unwrap();
        fs::write(input.join(format!("left/{name}.png")), bytes).unwrap();
        fs::write(input.join(format!("right/{name}.png")), png8(W, H, 3)).unwrap();
        // A good pair beside it is processed.
        fs::write(input.join("left/good.png"), png8(W, H, 0)).unwrap();
        fs::write(input.join("right/good.png"), png8(W, H, 3)).unwrap();
        let mut args = vec!["batch", "in", "--out", "out", "--quiet", "--disparity", "--stats", "--preview"];
        args.extend(RIG);
        let run = run_in(dir.path(), &args);
        let line = run.assert_error_line(1);
        assert!(line.contains("1 of 2 pairs failed"), "{name}: {line}");
        let out = dir.path().join("out");
        let summary: serde_json::Value =
            serde_json::from_str(&fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
        let row = summary["rows"].as_array().unwrap().iter().find(|r| r["name"] == name).unwrap();
        assert_eq!(row["status"], "failed", "{name}");
        let error = row["error"].as_str().unwrap();
        assert!(error.contains(needle) && !error.contains('\n'), "{name}: {error}");
        let mut files = tree(&out);
        files.retain(|f| !f.starts_with("summary."));
        assert_eq!(
            files,
            ["good.depth.exr", "good.disparity.pfm", "good.preview.png", "good.stats.json"],
            "{name}: the failed pair left outputs or temporaries"
        );
    }

    // A Middlebury scene with a bad calib.txt is a failed row naming the file.
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("in/scene");
    fs::create_dir_all(&scene).unwrap();
    fs::write(scene.join("im0.png"), png8(W, H, 0)).unwrap();
    fs::write(scene.join("im1.png"), png8(W, H, 3)).unwrap();
    fs::write(scene.join("calib.txt"), "cam0=[300 0 32; 0 300 24]\nbaseline=80\n").unwrap();
    let run = run_in(
        dir.path(),
        &["batch", "in", "--out", "out", "--quiet", "--baseline", "80", "--focal-px", "300"],
    );
    run.assert_error_line(1);
    let summary: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(dir.path().join("out/summary.json")).unwrap()).unwrap();
    let error = summary["rows"][0]["error"].as_str().unwrap();
    assert!(error.contains("calib.txt") && error.contains("cam0"), "{error}");
    let mut files = tree(&dir.path().join("out"));
    files.retain(|f| !f.starts_with("summary."));
    assert!(files.iter().all(|f| !f.contains('.') || f == "scene"), "{files:?}");
}

/// 8 and 16-bit images of the same size pair: the 8-bit samples are widened exactly (× 257), so
/// the two are on one scale. A JPEG named .png is read by its content. Both succeed.
#[test]
fn mixed_bit_depths_and_misnamed_jpeg_are_accepted() {
    let dir = tempfile::tempdir().unwrap();
    fixtures(dir.path());
    let a = run_in(dir.path(), &["left.png", "right.png", "--disparity", "out/a.pfm"]);
    a.assert_success();
    let b = run_in(dir.path(), &["left.png", "right16.png", "--disparity", "out/b.pfm"]);
    b.assert_success();
    assert_eq!(
        fs::read(dir.path().join("out/a.pfm")).unwrap(),
        fs::read(dir.path().join("out/b.pfm")).unwrap(),
        "an 8-bit image and its exact 16-bit copy give the same disparities"
    );
    run_in(dir.path(), &["jpeg.png", "jpeg.png", "--disparity", "out/j.pfm"]).assert_success();
}

/// The root check of the cases below: only root can mount, and root ignores file permissions.
fn is_root() -> bool {
    fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("Uid:")).map(|l| l.split_whitespace().nth(1) == Some("0"))
        })
        .unwrap_or(false)
}

/// A tmpfs mounted on a fresh folder for the test's life (root with mount permission only).
struct Tmpfs {
    _dir: tempfile::TempDir,
    path: PathBuf,
}

impl Tmpfs {
    fn mount(options: &str) -> Option<Tmpfs> {
        if !is_root() {
            return None;
        }
        let dir = tempfile::tempdir().ok()?;
        let ok = Command::new("mount")
            .args(["-t", "tmpfs", "-o", options, "tmpfs"])
            .arg(dir.path())
            .output()
            .is_ok_and(|o| o.status.success());
        ok.then(|| Tmpfs { path: dir.path().to_path_buf(), _dir: dir })
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg(&self.path).output();
    }
}

/// A folder the program cannot create files in: a read-only tmpfs as root, a `chmod 555` folder
/// otherwise; `None` (skip) when root cannot mount.
fn read_only_folder() -> Option<(Option<Tmpfs>, Option<tempfile::TempDir>, PathBuf)> {
    if is_root() {
        let fs = Tmpfs::mount("ro,size=64k")?;
        let path = fs.path.clone();
        Some((Some(fs), None, path))
    } else {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().ok()?;
        fs::set_permissions(dir.path(), fs::Permissions::from_mode(0o555)).ok()?;
        let path = dir.path().to_path_buf();
        Some((None, Some(dir), path))
    }
}

#[test]
fn read_only_output_folder() {
    let Some((_mount, _dir, ro)) = read_only_folder() else {
        eprintln!("note: skipped: running as root without permission to mount a read-only tmpfs");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    fixtures(dir.path());
    let exr = ro.join("d.exr");
    let pfm = ro.join("d.pfm");
    let png = ro.join("chart.png");
    for args in [
        vec!["left.png", "right.png", "-o", s(&exr)],
        vec!["left.png", "right.png", "-o", "out/d.exr", "--disparity", s(&pfm)],
        vec!["calc", "--baseline", "80", "--focal", "12", "--pixel", "4", "--chart", s(&png)],
    ] {
        let mut all = args.clone();
        if all[0] != "calc" {
            all.extend(RIG);
        }
        let run = run_in(dir.path(), &all);
        let message = run.assert_error(1);
        assert!(message.contains(s(&ro)), "{message}");
        assert!(list(&ro).is_empty(), "{:?}", list(&ro));
        assert!(list(&dir.path().join("out")).is_empty());
    }
    fs::create_dir_all(dir.path().join("in/left")).unwrap();
    fs::create_dir_all(dir.path().join("in/right")).unwrap();
    fs::copy(dir.path().join("left.png"), dir.path().join("in/left/a.png")).unwrap();
    fs::copy(dir.path().join("right.png"), dir.path().join("in/right/a.png")).unwrap();
    let run = run_in(dir.path(), &[&["batch", "in", "--out", s(&ro.join("batch"))][..], &RIG].concat());
    let message = run.assert_error(1);
    assert!(message.contains("batch"), "{message}");
}

/// A full disk: a 64 KiB tmpfs. The first output that does not fit fails the run, names the file,
/// and neither it, its temporary, nor the outputs written before it remain.
#[test]
fn disk_full() {
    let Some(tmpfs) = Tmpfs::mount("size=64k") else {
        eprintln!("note: skipped: mounting a small tmpfs needs root with mount permission");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    fixtures(dir.path());
    // 256x192 maps: the PFM alone (192 KiB) cannot fit.
    fs::write(dir.path().join("big_l.png"), png8(256, 192, 0)).unwrap();
    fs::write(dir.path().join("big_r.png"), png8(256, 192, 3)).unwrap();
    let full = &tmpfs.path;
    let exr = full.join("d.exr");
    let pfm = full.join("d.pfm");
    let run = run_in(
        dir.path(),
        &[&["big_l.png", "big_r.png", "-o", s(&exr), "--disparity", s(&pfm)][..], &RIG].concat(),
    );
    let message = run.assert_error(1);
    assert!(message.contains(s(full)) && message.contains("No space left"), "{message}");
    assert!(list(full).is_empty(), "left behind on the full disk: {:?}", list(full));

    // A batch onto the full disk: failed rows, no partial files, the summary error names the file.
    let input = dir.path().join("in");
    fs::create_dir_all(input.join("left")).unwrap();
    fs::create_dir_all(input.join("right")).unwrap();
    fs::copy(dir.path().join("big_l.png"), input.join("left/a.png")).unwrap();
    fs::copy(dir.path().join("big_r.png"), input.join("right/a.png")).unwrap();
    let out = full.join("batch");
    let run = run_in(
        dir.path(),
        &[&["batch", "in", "--out", s(&out), "--quiet", "--disparity"][..], &RIG].concat(),
    );
    assert_ne!(run.code, Some(101), "{}", run.stderr);
    assert_eq!(run.code, Some(1), "{}", run.stderr);
    for f in tree(&out) {
        assert!(!f.starts_with("a.") && !f.starts_with(".a."), "partial output {f}");
    }
}
