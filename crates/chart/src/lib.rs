//! Charts of a stereo rig's design: disparity (px, left axis) and depth resolution (right axis)
//! against distance (m), as PNG or SVG.
//!
//! Rendered with `plotters` in pure Rust; text uses DejaVu Sans, bundled in the binary (the
//! `dejavu` crate), so nothing depends on the system's fonts or graphics libraries. An SVG names
//! the font family `sans-serif` and leaves the glyphs to the viewer.
//!
//! ```
//! use stereo_chart::{render, DepthChart, Format, Sample};
//!
//! // 80 mm baseline, 3000 px focal length: Z = 240 / d.
//! let samples = (0..=50)
//!     .map(|i| {
//!         let z = 2.0 + i as f64 * 0.44;
//!         Sample { distance_m: z, disparity_px: 240.0 / z, resolution_mm: z * z / 0.24 }
//!     })
//!     .collect();
//! let chart = DepthChart {
//!     title: "B = 80 mm, f = 3000 px".into(),
//!     step_px: 1.0,
//!     samples,
//!     near_m: 2.0,
//!     x_max_m: 24.0,
//!     markers: vec![],
//! };
//! let svg = render(&chart, Format::Svg, (800, 500))?;
//! assert!(String::from_utf8(svg)?.starts_with("<svg"));
//! let png = render(&chart, Format::Png, (800, 500))?;
//! assert_eq!(&png[1..4], b"PNG");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, FontStyle};

/// The size of a chart when none is asked for, pixels (SVG: user units).
pub const DEFAULT_SIZE: (u32, u32) = (1000, 600);

/// PNGs are drawn this many times larger, then scaled down (anti-aliasing).
const SUPERSAMPLE: u32 = 2;

/// Why a chart could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// Nothing to draw, or a size or range that is not drawable.
    #[error("cannot draw the chart: {0}")]
    Invalid(String),
    /// The drawing itself failed.
    #[error("cannot render the chart: {0}")]
    Render(String),
}

/// One point of the curves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    pub distance_m: f64,
    pub disparity_px: f64,
    /// Depth resolution for one disparity step, mm; shown in mm, cm or m, whichever keeps the
    /// axis numbers readable.
    pub resolution_mm: f64,
}

/// A vertical dashed line at a distance, labelled (e.g. the distance asked about).
#[derive(Clone, Debug, PartialEq)]
pub struct Marker {
    pub distance_m: f64,
    pub label: String,
}

/// What to draw.
#[derive(Clone, Debug, PartialEq)]
pub struct DepthChart {
    /// The caption, e.g. the rig.
    pub title: String,
    /// The disparity step of the depth resolution, px (named on the right axis).
    pub step_px: f64,
    /// The curves, by ascending distance (at least two points).
    pub samples: Vec<Sample>,
    /// Distances below this are out of the disparity search: shaded.
    pub near_m: f64,
    /// The x axis spans `0..x_max_m`.
    pub x_max_m: f64,
    pub markers: Vec<Marker>,
}

/// The image format.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    Png,
    Svg,
}

impl Format {
    /// By the file extension, `.png` or `.svg` (any case); `None` for anything else.
    pub fn from_path(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "png" => Some(Format::Png),
            "svg" => Some(Format::Svg),
            _ => None,
        }
    }
}

/// The family name the bundled font is registered under.
const FONT: &str = "sans-serif";

fn register_fonts() -> Result<(), Error> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| {
        register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).is_ok()
            && register_font(FONT, FontStyle::Bold, dejavu::sans::bold()).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err(Error::Render("the bundled font cannot be loaded".into()))
    }
}

const DISPARITY: RGBColor = RGBColor(31, 97, 180);
const RESOLUTION: RGBColor = RGBColor(200, 60, 20);
const MARKER: RGBColor = RGBColor(70, 70, 70);

/// The unit of the right axis for resolutions up to `max_mm`, and the factor from mm.
fn resolution_unit(max_mm: f64) -> (&'static str, f64) {
    if max_mm <= 100.0 {
        ("mm", 1.0)
    } else if max_mm <= 1000.0 {
        ("cm", 0.1)
    } else {
        ("m", 0.001)
    }
}

/// `step` px without trailing zeros: `"1"`, `"0.25"`.
fn step_text(step: f64) -> String {
    let text = format!("{step:.4}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// Renders `chart` at `size` (pixels; at least 300 × 200) as PNG or SVG bytes.
pub fn render(chart: &DepthChart, format: Format, size: (u32, u32)) -> Result<Vec<u8>, Error> {
    check(chart, size)?;
    register_fonts()?;
    match format {
        Format::Png => {
            // Drawn at twice the size and scaled down: the bitmap backend draws lines without
            // anti-aliasing.
            let (w, h) = (size.0 * SUPERSAMPLE, size.1 * SUPERSAMPLE);
            let mut rgb = vec![0u8; w as usize * h as usize * 3];
            {
                let root = BitMapBackend::with_buffer(&mut rgb, (w, h)).into_drawing_area();
                draw(chart, &root, SUPERSAMPLE)?;
                root.present().map_err(|e| Error::Render(e.to_string()))?;
            }
            let large = image::RgbImage::from_raw(w, h, rgb)
                .ok_or_else(|| Error::Render("the bitmap has the wrong size".into()))?;
            let image =
                image::imageops::resize(&large, size.0, size.1, image::imageops::FilterType::Triangle);
            let mut png = Vec::new();
            let encoder = image::codecs::png::PngEncoder::new_with_quality(
                &mut png,
                image::codecs::png::CompressionType::Best,
                image::codecs::png::FilterType::Adaptive,
            );
            image.write_with_encoder(encoder).map_err(|e| Error::Render(e.to_string()))?;
            Ok(png)
        }
        Format::Svg => {
            let mut svg = String::new();
            {
                let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
                draw(chart, &root, 1)?;
                root.present().map_err(|e| Error::Render(e.to_string()))?;
            }
            Ok(svg.into_bytes())
        }
    }
}

fn check(chart: &DepthChart, size: (u32, u32)) -> Result<(), Error> {
    let invalid = |what: &str| Err(Error::Invalid(what.to_string()));
    if size.0 < 300 || size.1 < 200 || size.0 > 10_000 || size.1 > 10_000 {
        return invalid("the size must be from 300 × 200 to 10000 × 10000 pixels");
    }
    if chart.samples.len() < 2 {
        return invalid("fewer than two samples");
    }
    let finite = |s: &Sample| {
        s.distance_m.is_finite()
            && s.disparity_px.is_finite()
            && s.resolution_mm.is_finite()
            && s.distance_m >= 0.0
            && s.resolution_mm >= 0.0
    };
    if !chart.samples.iter().all(finite) {
        return invalid("a sample is not finite or negative");
    }
    if !(chart.x_max_m.is_finite() && chart.x_max_m > 0.0) {
        return invalid("the distance axis is empty");
    }
    if !(chart.step_px.is_finite() && chart.step_px > 0.0) {
        return invalid("the disparity step is not > 0");
    }
    Ok(())
}

/// Axis numbers: enough decimals for an axis up to `max`, trailing zeros trimmed (`400`, `2.5`).
fn tick(value: f64, max: f64) -> String {
    let decimals = (3 - max.abs().log10().floor() as i32).clamp(0, 12) as usize;
    let text = format!("{value:.decimals$}");
    let text = if text.contains('.') { text.trim_end_matches('0').trim_end_matches('.') } else { &text };
    if text == "-0" {
        "0".to_string()
    } else {
        text.to_string()
    }
}

/// Draws `chart` on `root`, every length in pixels multiplied by `k` (for supersampling).
fn draw<DB: DrawingBackend>(chart: &DepthChart, root: &DrawingArea<DB, Shift>, k: u32) -> Result<(), Error> {
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| Error::Render(e.to_string());
    let px = |v: u32| v * k;
    let font = |size: u32| (FONT, f64::from(size * k)).into_font();
    root.fill(&WHITE).map_err(err)?;

    let max = |f: fn(&Sample) -> f64| chart.samples.iter().map(f).fold(0.0, f64::max);
    let d_max = (max(|s| s.disparity_px) * 1.08).max(1e-9);
    let (unit, per_mm) = resolution_unit(max(|s| s.resolution_mm));
    let r_max = (max(|s| s.resolution_mm) * per_mm * 1.08).max(1e-9);
    let x_max = chart.x_max_m;

    let mut plot = ChartBuilder::on(root)
        .caption(&chart.title, font(22))
        .margin(px(18))
        .x_label_area_size(px(56))
        .y_label_area_size(px(78))
        .right_y_label_area_size(px(86))
        .build_cartesian_2d(0.0..x_max, 0.0..d_max)
        .map_err(err)?
        .set_secondary_coord(0.0..x_max, 0.0..r_max);

    let x_tick = |v: &f64| tick(*v, x_max);
    let d_tick = |v: &f64| tick(*v, d_max);
    let r_tick = |v: &f64| tick(*v, r_max);
    plot.configure_mesh()
        .y_desc("Disparity (px)")
        .x_labels(12)
        .y_labels(10)
        .x_label_formatter(&x_tick)
        .y_label_formatter(&d_tick)
        .label_style(font(15))
        .axis_desc_style(font(18).color(&DISPARITY))
        .light_line_style(RGBColor(238, 238, 238))
        .bold_line_style(RGBColor(210, 210, 210))
        .set_all_tick_mark_size(px(5))
        .draw()
        .map_err(err)?;
    // Again for the x axis title alone, in black: the axis title style is shared by both axes.
    plot.configure_mesh()
        .disable_mesh()
        .disable_y_axis()
        .x_desc("Distance (m)")
        .x_labels(12)
        .x_label_formatter(&x_tick)
        .label_style(font(15).color(&TRANSPARENT))
        .axis_style(TRANSPARENT)
        .set_all_tick_mark_size(0)
        .axis_desc_style(font(18))
        .draw()
        .map_err(err)?;
    let step = step_text(chart.step_px);
    plot.configure_secondary_axes()
        .y_desc(format!("Depth resolution ({unit} per {step} px step)"))
        .y_labels(10)
        .y_label_formatter(&r_tick)
        .label_style(font(15))
        .axis_desc_style(font(18).color(&RESOLUTION))
        .set_all_tick_mark_size(px(5))
        .draw()
        .map_err(err)?;

    // Closer than the nearest measurable distance: the disparity is beyond the search.
    let near = chart.near_m.clamp(0.0, x_max);
    if near > 0.0 {
        plot.draw_series(std::iter::once(Rectangle::new(
            [(0.0, 0.0), (near, d_max)],
            RGBColor(120, 120, 120).mix(0.15).filled(),
        )))
        .map_err(err)?;
        // The label only where the band is wide enough to hold it.
        let (x0, _) = plot.backend_coord(&(0.0, 0.0));
        let (x1, _) = plot.backend_coord(&(near, 0.0));
        if x1 - x0 >= px(22) as i32 {
            let style = font(15)
                .transform(FontTransform::Rotate270)
                .color(&RGBColor(90, 90, 90))
                .pos(Pos::new(HPos::Center, VPos::Center));
            plot.draw_series(std::iter::once(Text::new(
                "too close: disparity beyond the search",
                (near / 2.0, d_max / 2.0),
                style,
            )))
            .map_err(err)?;
        }
    }

    let line = move |color: RGBColor| color.stroke_width(px(3));
    let legend = move |color: RGBColor| {
        move |(x, y): (i32, i32)| PathElement::new(vec![(x, y), (x + px(24) as i32, y)], line(color))
    };
    plot.draw_series(LineSeries::new(
        chart.samples.iter().map(|s| (s.distance_m, s.disparity_px)),
        line(DISPARITY),
    ))
    .map_err(err)?
    .label("Disparity (px), left axis")
    .legend(legend(DISPARITY));
    plot.draw_secondary_series(LineSeries::new(
        chart.samples.iter().map(|s| (s.distance_m, s.resolution_mm * per_mm)),
        line(RESOLUTION),
    ))
    .map_err(err)?
    .label(format!("Depth resolution ({unit}), right axis"))
    .legend(legend(RESOLUTION));

    for marker in chart.markers.iter().filter(|m| m.distance_m.is_finite() && m.distance_m <= x_max) {
        let z = marker.distance_m.max(0.0);
        plot.draw_series(DashedLineSeries::new(
            [(z, 0.0), (z, d_max)],
            px(8),
            px(6),
            MARKER.stroke_width(px(2)),
        ))
        .map_err(err)?;
        // Left of the line when it is in the right half of the chart.
        let (hpos, dx) =
            if z > x_max / 2.0 { (HPos::Right, -x_max * 0.006) } else { (HPos::Left, x_max * 0.006) };
        let style = font(15).color(&MARKER).pos(Pos::new(hpos, VPos::Top));
        plot.draw_series(std::iter::once(Text::new(marker.label.clone(), (z + dx, d_max * 0.985), style)))
            .map_err(err)?;
    }

    plot.configure_series_labels()
        .position(SeriesLabelPosition::UpperMiddle)
        .margin(px(14))
        .legend_area_size(px(30))
        .label_font(font(15))
        .background_style(WHITE.mix(0.9))
        .border_style(RGBColor(160, 160, 160))
        .draw()
        .map_err(err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chart() -> DepthChart {
        let samples = (0..=100)
            .map(|i| {
                let z = 240.0 / 127.0 + i as f64 * (24.0 - 240.0 / 127.0) / 100.0;
                Sample { distance_m: z, disparity_px: 240.0 / z, resolution_mm: z * z / 0.24 }
            })
            .collect();
        DepthChart {
            title: "Rig: B = 80 mm, f = 12 mm (3000 px), pixel 4 µm".into(),
            step_px: 1.0,
            samples,
            near_m: 240.0 / 127.0,
            x_max_m: 24.0,
            markers: vec![Marker { distance_m: 5.0, label: "5 m: 48 px".into() }],
        }
    }

    #[test]
    fn png_decodes_at_its_size() {
        let png = render(&chart(), Format::Png, (640, 400)).unwrap();
        let image = image::load_from_memory_with_format(&png, image::ImageFormat::Png).unwrap();
        assert_eq!((image.width(), image.height()), (640, 400));
        let rgb = image.to_rgb8();
        // Both curve colours are drawn, and text (dark grey/black pixels) too.
        let has = |c: [u8; 3]| rgb.pixels().any(|p| p.0 == c);
        assert!(has([31, 97, 180]) && has([200, 60, 20]));
        assert!(rgb.pixels().filter(|p| p.0.iter().all(|&v| v < 60)).count() > 500);
    }

    #[test]
    fn svg_has_the_axis_titles() {
        let svg = String::from_utf8(render(&chart(), Format::Svg, DEFAULT_SIZE).unwrap()).unwrap();
        assert!(svg.starts_with("<svg"));
        for text in ["Distance (m)", "Disparity (px)", "Depth resolution (m per 1 px step)", "5 m: 48 px"] {
            assert!(svg.contains(text), "{text} missing");
        }
    }

    #[test]
    fn units_follow_the_largest_resolution() {
        assert_eq!(resolution_unit(40.0), ("mm", 1.0));
        assert_eq!(resolution_unit(400.0), ("cm", 0.1));
        assert_eq!(resolution_unit(2400.0), ("m", 0.001));
        assert_eq!(step_text(0.25), "0.25");
        assert_eq!(step_text(1.0), "1");
        assert_eq!(tick(400.0, 432.0), "400");
        assert_eq!(tick(2.5, 2.6), "2.5");
        assert_eq!(tick(0.30000000000000004, 2.6), "0.3");
        assert_eq!(tick(0.0125, 0.02), "0.0125");
    }

    #[test]
    fn formats_by_extension() {
        assert_eq!(Format::from_path(Path::new("a/chart.PNG")), Some(Format::Png));
        assert_eq!(Format::from_path(Path::new("chart.svg")), Some(Format::Svg));
        assert_eq!(Format::from_path(Path::new("chart.jpg")), None);
        assert_eq!(Format::from_path(Path::new("chart")), None);
    }

    #[test]
    fn bad_charts_are_errors() {
        let mut c = chart();
        c.samples.truncate(1);
        assert!(matches!(render(&c, Format::Png, DEFAULT_SIZE), Err(Error::Invalid(_))));
        let mut c = chart();
        c.samples[3].disparity_px = f64::NAN;
        assert!(render(&c, Format::Svg, DEFAULT_SIZE).is_err());
        let mut c = chart();
        c.x_max_m = 0.0;
        assert!(render(&c, Format::Svg, DEFAULT_SIZE).is_err());
        assert!(render(&chart(), Format::Png, (10, 10)).is_err());
    }
}
