//! `stereo-depth info FILE`: what a file stereo-depth writes contains, recognised by its content
//! (not its name): OpenEXR, PFM, PNG, PLY or JSON.

use std::io::{Read, Write};
use std::path::Path;

use anyhow::{bail, Context, Result};
use stereo_disparity::Image;

pub fn run(path: &Path, out: &mut impl Write) -> Result<()> {
    if path.is_dir() {
        bail!("{}: is a directory, not a file", path.display());
    }
    let mut head = [0u8; 16];
    let n = std::fs::File::open(path)
        .and_then(|mut f| f.read(&mut head))
        .with_context(|| format!("cannot read {}", path.display()))?;
    let head = &head[..n];
    if head.starts_with(&[0x76, 0x2f, 0x31, 0x01]) {
        exr(path, out)
    } else if head.starts_with(b"PF") || head.starts_with(b"Pf") {
        pfm(path, out)
    } else if head.starts_with(b"\x89PNG") {
        png(path, out)
    } else if head.starts_with(b"ply") {
        ply(path, out)
    } else if head.iter().find(|b| !b.is_ascii_whitespace()) == Some(&b'{') {
        json(path, out)
    } else {
        bail!(
            "{}: not a file stereo-depth writes (unrecognised content; want OpenEXR, PFM, PNG, PLY or JSON)",
            path.display()
        )
    }
}

/// `valid N of M px (P %)`, `min .. max`, `mean`, of the finite samples.
fn describe(image: &Image<f32>, unit: &str, valid: impl Fn(f32) -> bool) -> String {
    let total = image.width() * image.height();
    let values: Vec<f64> = image.as_slice().iter().copied().filter(|&v| valid(v)).map(f64::from).collect();
    let percent = if total == 0 { 0.0 } else { 100.0 * values.len() as f64 / total as f64 };
    let mut text = format!("valid {} of {total} px ({percent:.1} %)", values.len());
    if !values.is_empty() {
        let min = values.iter().copied().fold(f64::INFINITY, f64::min);
        let max = values.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let mean = values.iter().sum::<f64>() / values.len() as f64;
        text.push_str(&format!(", range {min:.6} .. {max:.6} {unit}, mean {mean:.6} {unit}"));
    }
    text
}

fn exr(path: &Path, out: &mut impl Write) -> Result<()> {
    let names = stereo_io::exr_channel_names(path)?;
    let mut lines = Vec::new();
    let mut size = (0, 0);
    for name in &names {
        let channel = stereo_io::read_exr_channel(path, name)?;
        size = channel.size();
        let (unit, what) = match name.as_str() {
            "Z" => ("m", " (depth)"),
            "disparity" => ("px", ""),
            _ => ("", ""),
        };
        lines.push(format!("  {name}{what}: {}", describe(&channel, unit, |v| v.is_finite())));
    }
    writeln!(
        out,
        "{}: OpenEXR, {}x{} px, {} channel{} ({}); invalid = NaN",
        path.display(),
        size.0,
        size.1,
        names.len(),
        if names.len() == 1 { "" } else { "s" },
        names.join(", ")
    )?;
    for line in lines {
        writeln!(out, "{line}")?;
    }
    Ok(())
}

fn pfm(path: &Path, out: &mut impl Write) -> Result<()> {
    let map = stereo_io::read_pfm(path)?;
    writeln!(
        out,
        "{}: PFM (32-bit float), {}x{} px; invalid = NaN/inf",
        path.display(),
        map.width(),
        map.height()
    )?;
    writeln!(out, "  {}", describe(&map, "px", |v| v.is_finite()))?;
    Ok(())
}

fn png(path: &Path, out: &mut impl Write) -> Result<()> {
    let info = stereo_io::read_png_info(path)?;
    let colour = match info.channels {
        1 => "grey",
        2 => "grey + alpha",
        3 => "RGB",
        _ => "RGBA",
    };
    writeln!(
        out,
        "{}: PNG, {}x{} px, {}-bit {colour}",
        path.display(),
        info.width,
        info.height,
        info.bit_depth
    )?;
    let total = info.width * info.height;
    let percent = if total == 0 { 0.0 } else { 100.0 * info.nonzero as f64 / total as f64 };
    if info.channels >= 3 {
        writeln!(out, "  a colour image (a --preview is one: Turbo colour map, colour bar below)")?;
        return Ok(());
    }
    write!(out, "  nonzero {} of {total} px ({percent:.1} %)", info.nonzero)?;
    match info.min_nonzero {
        Some(lo) => writeln!(out, ", values {lo} .. {} (0 = invalid?)", info.max)?,
        None => writeln!(out)?,
    }
    if info.bit_depth == 16 {
        if let Some(lo) = info.min_nonzero {
            writeln!(
                out,
                "  as --depth-png (mm): {:.3} .. {:.3} m?  as --disparity-png (KITTI, value / 256): {:.3} .. {:.3} px?",
                lo / 1000.0,
                info.max / 1000.0,
                lo / 256.0,
                info.max / 256.0
            )?;
        }
    }
    Ok(())
}

fn ply(path: &Path, out: &mut impl Write) -> Result<()> {
    let info = stereo_io::read_ply_info(path)?;
    writeln!(out, "{}: PLY ({}), {} vertices", path.display(), info.format, info.vertex_count)?;
    let properties: Vec<String> = info.properties.iter().map(|p| format!("{} {}", p.kind, p.name)).collect();
    writeln!(out, "  properties: {}", properties.join(", "))?;
    for comment in &info.comments {
        writeln!(out, "  comment: {comment}")?;
    }
    if let Some((lo, hi)) = info.bounds {
        writeln!(
            out,
            "  bounds: x {:.4} .. {:.4}, y {:.4} .. {:.4}, z {:.4} .. {:.4}",
            lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]
        )?;
    }
    if let Some(finite) = info.finite_vertices {
        if finite != info.vertex_count {
            writeln!(out, "  {} vertices have a non-finite coordinate", info.vertex_count - finite)?;
        }
    }
    Ok(())
}

fn json(path: &Path, out: &mut impl Write) -> Result<()> {
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    let value: serde_json::Value = serde_json::from_str(&text)
        .map_err(|err| anyhow::anyhow!("{}: not valid JSON: {err}", path.display()))?;
    let number = |v: &serde_json::Value| v.as_f64().map_or("null".to_string(), |n| format!("{n:.4}"));
    let summary = |v: &serde_json::Value| {
        if v.is_null() {
            "null".to_string()
        } else {
            format!(
                "min {}  median {}  max {}  (p5 {}, p95 {})",
                number(&v["min"]),
                number(&v["median"]),
                number(&v["max"]),
                number(&v["p5"]),
                number(&v["p95"])
            )
        }
    };
    if value.get("valid_pixels").is_some() && value.get("matcher").is_some() {
        writeln!(out, "{}: stereo-depth statistics (--stats)", path.display())?;
        writeln!(
            out,
            "  pair: {} + {}",
            value["left"].as_str().unwrap_or("?"),
            value["right"].as_str().unwrap_or("?")
        )?;
        writeln!(
            out,
            "  size {}x{} px, valid {} px ({} %)",
            value["width"],
            value["height"],
            value["valid_pixels"],
            number(&value["density_percent"])
        )?;
        writeln!(out, "  depth m:      {}", summary(&value["depth_m"]))?;
        writeln!(out, "  disparity px: {}", summary(&value["disparity_px"]))?;
        if let Some(r) = value["depth_resolution_mm"].as_object() {
            writeln!(
                out,
                "  depth resolution (1 px): {} mm at the median, {} mm at p95",
                number(&r["at_median"]),
                number(&r["at_p95"])
            )?;
        }
        writeln!(out, "  matcher: {}", value["matcher"]["name"].as_str().unwrap_or("?"))?;
        match value["rig"].as_object() {
            Some(rig) => writeln!(
                out,
                "  rig: baseline {} mm, focal {} px, doffs {}",
                number(&rig["baseline_mm"]),
                number(&rig["focal_px"]),
                number(&rig["doffs"])
            )?,
            None => writeln!(out, "  rig: none (disparity only)")?,
        }
        if let Some(outputs) = value["outputs"].as_object() {
            for (what, path) in outputs.iter().filter(|(_, p)| !p.is_null()) {
                writeln!(out, "  output {what}: {}", path.as_str().unwrap_or("?"))?;
            }
        }
    } else if value.get("pairs").is_some() && value.get("ok").is_some() {
        writeln!(
            out,
            "{}: stereo-depth batch summary: {} pairs, {} ok, {} skipped, {} failed",
            path.display(),
            value["pairs"],
            value["ok"],
            value["skipped"],
            value["failed"]
        )?;
    } else {
        let keys: Vec<&str> =
            value.as_object().map(|o| o.keys().map(String::as_str).collect()).unwrap_or_default();
        writeln!(
            out,
            "{}: JSON object, not a stereo-depth stats file; keys: {}",
            path.display(),
            keys.join(", ")
        )?;
    }
    Ok(())
}
