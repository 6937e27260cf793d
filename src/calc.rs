//! `stereo-depth calc`: the rig design calculator. What a baseline, a lens and a sensor can
//! measure — distance, disparity on the sensor, depth resolution, field of view, working range —
//! as text, a table, JSON and a chart. The formulas live in `stereo_triangulation::design`.

use std::fmt::Write as _;
use std::io::Write;

use anyhow::{Context, Result};
use serde::Serialize;
use stereo_chart::{DepthChart, Marker, Sample};
use stereo_triangulation::design::{sig, Design, MaxDisparitySource, Point};

use crate::config::CalcConfig;

/// Runs `calc`: prints the rig warnings, writes the chart if asked (atomically), then prints
/// the text or JSON report on `out`.
pub fn run(config: &CalcConfig, out: &mut impl Write) -> Result<()> {
    crate::checks::print_warnings(&config.warnings);
    let design = &config.design;
    if let Some((path, format)) = &config.chart {
        let bytes = stereo_chart::render(&chart(design), *format, stereo_chart::DEFAULT_SIZE)
            .context("cannot draw the chart")?;
        stereo_io::write_atomic(path, &bytes).context("cannot write the chart")?;
    }

    let chart = config.chart.as_ref().map(|(p, _)| p.display().to_string());
    let text = if config.json {
        let report = Report { design, depth_resolution: RESOLUTION_FORMULA, chart };
        let mut json = serde_json::to_string_pretty(&report).context("cannot serialise the design")?;
        json.push('\n');
        json
    } else {
        let mut text = report(design);
        if let Some(path) = chart {
            let _ = writeln!(text, "\nchart: {path}");
        }
        text
    };
    out.write_all(text.as_bytes())?;
    out.flush()?;
    Ok(())
}

const RESOLUTION_FORMULA: &str = "first order: Z^2 * pixel * step / (baseline * focal)";

/// The JSON report: the design, how the depth resolution is computed, and the chart written.
#[derive(Serialize)]
struct Report<'a> {
    #[serde(flatten)]
    design: &'a Design,
    depth_resolution: &'static str,
    chart: Option<String>,
}

/// Four significant digits.
fn num(x: f64) -> String {
    sig(x, 4)
}

/// A length given in mm, in m from 1 m up.
fn length_mm(mm: f64) -> String {
    if mm.abs() >= 1000.0 {
        format!("{} m", num(mm / 1000.0))
    } else {
        format!("{} mm", num(mm))
    }
}

/// The text report.
fn report(d: &Design) -> String {
    let mut s = String::new();
    let step = d.subpixel_step_px;
    let per_step = format!("per {step} px step");
    let _ = writeln!(
        s,
        "rig                 baseline {} mm, focal length {} mm, pixel {} µm",
        d.baseline_mm, d.focal_mm, d.pixel_um
    );
    let _ = writeln!(s, "focal length        {} px", num(d.focal_px));
    if d.doffs_px != 0.0 {
        let _ = writeln!(s, "disparity offset    {} px (added to every disparity)", d.doffs_px);
    }
    let _ = writeln!(
        s,
        "disparity step      {step} px ({})",
        if step == 1.0 {
            "integer matching; --subpixel 0.25 for quarter-pixel matching"
        } else {
            "subpixel matching"
        }
    );
    match (d.horizontal_fov_deg, d.sensor_width_mm, d.image_width_px) {
        (Some(fov), Some(w), Some(px)) => {
            let _ =
                writeln!(s, "field of view       {}° horizontal (sensor {} mm, {px} px)", num(fov), num(w));
        }
        _ => {
            let _ = writeln!(s, "field of view       unknown: give --sensor-width MM or --width-px N");
        }
    }

    if let Some(p) = d.disparity {
        let _ = writeln!(s, "\nat disparity {} px", p.disparity_px);
        let _ = writeln!(s, "  distance          {} m", num(p.distance_m));
        let _ = writeln!(s, "  disparity         {} mm on the sensor", num(p.disparity_mm));
        let _ = writeln!(s, "  depth resolution  {} {per_step}", length_mm(p.depth_resolution_mm));
    }
    if let Some(p) = d.distance {
        let _ = writeln!(s, "\nat distance {} m", p.distance_m);
        let _ = writeln!(
            s,
            "  disparity         {} px = {} mm on the sensor",
            num(p.disparity_px),
            num(p.disparity_mm)
        );
        let _ = writeln!(s, "  depth resolution  {} {per_step}", length_mm(p.depth_resolution_mm));
    }

    let r = &d.working_range;
    let source = match (r.max_disparity_source, d.image_width_px) {
        (MaxDisparitySource::Given, _) => String::new(),
        (MaxDisparitySource::ImageWidth, Some(w)) => format!(", the default for {w} px wide images"),
        _ => ", the default without an image width".to_string(),
    };
    let _ = writeln!(
        s,
        "\nworking range       disparities {} to {} px (--max-disparity {}{source})",
        r.far.disparity_px, r.near.disparity_px, r.max_disparity_px
    );
    let _ = writeln!(
        s,
        "  nearest           {} m at {} px, depth resolution {}",
        num(r.near.distance_m),
        r.near.disparity_px,
        length_mm(r.near.depth_resolution_mm)
    );
    let _ = writeln!(
        s,
        "  farthest          {} m at {} px, depth resolution {}",
        num(r.far.distance_m),
        r.far.disparity_px,
        length_mm(r.far.depth_resolution_mm)
    );
    if let Some(w) = d.image_width_px {
        let _ = writeln!(
            s,
            "  disparities must stay below the image width, {w} px (--max-disparity at most {w})"
        );
    }
    for (what, p) in [("disparity", d.disparity), ("distance", d.distance)] {
        let Some(p) = p else { continue };
        if p.disparity_px > r.near.disparity_px {
            let _ = writeln!(
                s,
                "  note: the {what} asked about needs {} px, beyond the search ({} to {} px): \
                 set --max-disparity {} or more to measure it",
                num(p.disparity_px),
                r.far.disparity_px,
                r.near.disparity_px,
                p.disparity_px.floor() + 1.0
            );
        } else if p.disparity_px < r.far.disparity_px {
            let _ =
                writeln!(s, "  note: the {what} asked about is below one disparity step: too far to measure");
        }
    }

    if let Some(rows) = &d.table {
        let _ = writeln!(s);
        let _ = writeln!(s, "{}", table(rows));
    }
    let _ = writeln!(
        s,
        "\ndepth resolution: ΔZ ≈ Z²·p·step / (B·f), the first-order change of Z for one disparity step"
    );
    s
}

/// The table, right-aligned under its headers, without a final newline.
fn table(rows: &[Point]) -> String {
    let headers = ["disparity (px)", "disparity (mm)", "distance (m)", "depth resolution (mm)"];
    let cells: Vec<[String; 4]> = rows
        .iter()
        .map(|p| [num(p.disparity_px), num(p.disparity_mm), num(p.distance_m), num(p.depth_resolution_mm)])
        .collect();
    let widths: Vec<usize> = (0..4)
        .map(|i| cells.iter().map(|c| c[i].chars().count()).chain([headers[i].len()]).max().unwrap_or(0))
        .collect();
    let line = |cols: [&str; 4]| {
        cols.iter()
            .zip(&widths)
            .map(|(c, w)| format!("{c:>w$}"))
            .collect::<Vec<_>>()
            .join("  ")
            .trim_end()
            .to_string()
    };
    let mut lines = vec![line(headers)];
    lines.extend(cells.iter().map(|c| line([&c[0], &c[1], &c[2], &c[3]])));
    lines.join("\n")
}

/// The chart of the working range, from the nearest distance to where the depth resolution is a
/// tenth of the distance (extended to the distances asked about, when measurable).
fn chart(d: &Design) -> DepthChart {
    let (near, mut far) = d.chart_range();
    let mut markers = Vec::new();
    if let Some(p) = d.disparity {
        markers.push(Marker {
            distance_m: p.distance_m,
            label: format!("{} px: {} m", num(p.disparity_px), num(p.distance_m)),
        });
    }
    if let Some(p) = d.distance {
        markers.push(Marker {
            distance_m: p.distance_m,
            label: format!("{} m: {} px", num(p.distance_m), num(p.disparity_px)),
        });
    }
    for m in &markers {
        if m.distance_m > far && m.distance_m <= d.working_range.far.distance_m {
            far = (m.distance_m * 1.1).min(d.working_range.far.distance_m);
        }
    }
    let samples = d
        .curve(near, far, 400)
        .iter()
        .map(|p| Sample {
            distance_m: p.distance_m,
            disparity_px: p.disparity_px,
            resolution_mm: p.depth_resolution_mm,
        })
        .collect();
    let doffs = if d.doffs_px != 0.0 { format!(", doffs {} px", d.doffs_px) } else { String::new() };
    DepthChart {
        title: format!(
            "Stereo rig: baseline {} mm, focal length {} mm ({} px), pixel {} µm{doffs}",
            d.baseline_mm,
            d.focal_mm,
            num(d.focal_px),
            d.pixel_um
        ),
        step_px: d.subpixel_step_px,
        samples,
        near_m: near,
        x_max_m: far,
        markers,
    }
}
