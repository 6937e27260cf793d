//! Colour-mapped previews of depth and disparity maps: the Turbo colour map, invalid pixels
//! black, and a colour bar below the map labelled with the range of the colour scale (the 1st
//! and 99th percentiles of the valid values, with the unit), drawn with a built-in 3×5 pixel
//! font (no system fonts).

use std::path::Path;

use image::{ImageBuffer, Rgb};
use stereo_image::Image;

use crate::{format_err, Error};

/// Google's Turbo colour map (Mikhailov 2019) at `t` in `[0, 1]` (clamped; NaN is 0): dark blue
/// at 0, green-yellow in the middle, dark red at 1. This is the published degree-5 polynomial
/// fit, within about 1 % of the reference table.
pub fn turbo(t: f32) -> [u8; 3] {
    let x = if t.is_nan() { 0.0 } else { f64::from(t.clamp(0.0, 1.0)) };
    let (x2, x3) = (x * x, x * x * x);
    let (x4, x5) = (x2 * x2, x2 * x3);
    let channel = |c: [f64; 6]| {
        let v = c[0] + c[1] * x + c[2] * x2 + c[3] * x3 + c[4] * x4 + c[5] * x5;
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    };
    [
        channel([0.13572138, 4.61539260, -42.66032258, 132.13108234, -152.94239396, 59.28637943]),
        channel([0.09140261, 2.19418839, 4.84296658, -14.18503333, 4.27729857, 2.82956604]),
        channel([0.10667330, 12.64194608, -60.58204836, 110.36276771, -89.90310912, 27.34824973]),
    ]
}

/// Which end of the value range gets the warm (red) colours.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ColourScale {
    /// Small values red, large blue: depth (near is red).
    SmallIsWarm,
    /// Large values red: disparity (near is red too).
    LargeIsWarm,
}

/// A rendered preview.
#[derive(Clone, Debug)]
pub struct Preview {
    /// The map (top, its own size) and the colour bar (below it).
    pub image: Image<[u8; 3]>,
    /// The range of the colour scale: the 1st and 99th percentiles of the finite values (values
    /// beyond take the end colours, and the labels then read `<MIN` / `>MAX`); `None` when no
    /// pixel is valid.
    pub range: Option<(f32, f32)>,
    /// Rows of `image` that hold the map (the colour bar is below).
    pub map_height: usize,
}

/// Where on Turbo the cold end of a preview's scale lies.
const TURBO_START: f32 = 0.07;

const GLYPH_W: usize = 3;
const GLYPH_H: usize = 5;

fn glyph(c: char) -> Option<[&'static str; GLYPH_H]> {
    Some(match c {
        '0' => ["111", "101", "101", "101", "111"],
        '1' => ["010", "110", "010", "010", "111"],
        '2' => ["111", "001", "111", "100", "111"],
        '3' => ["111", "001", "111", "001", "111"],
        '4' => ["101", "101", "111", "001", "001"],
        '5' => ["111", "100", "111", "001", "111"],
        '6' => ["111", "100", "111", "101", "111"],
        '7' => ["111", "001", "001", "001", "001"],
        '8' => ["111", "101", "111", "101", "111"],
        '9' => ["111", "101", "111", "001", "111"],
        '.' => ["000", "000", "000", "000", "010"],
        '-' => ["000", "000", "111", "000", "000"],
        'm' => ["00000", "11110", "10101", "10101", "10101"],
        'p' => ["000", "110", "101", "110", "100"],
        'x' => ["000", "101", "010", "010", "101"],
        '<' => ["001", "010", "100", "010", "001"],
        '>' => ["100", "010", "001", "010", "100"],
        ' ' => ["000", "000", "000", "000", "000"],
        _ => return None,
    })
}

/// Columns of a glyph (most are [`GLYPH_W`], `m` is wider).
fn glyph_width(c: char) -> usize {
    glyph(c).map_or(GLYPH_W, |rows| rows[0].len())
}

/// Width in pixels of `text` at `scale` (one blank column between glyphs).
fn text_width(text: &str, scale: usize) -> usize {
    let columns: usize = text.chars().map(|c| glyph_width(c) + 1).sum();
    columns.saturating_sub(1) * scale
}

fn draw_text(image: &mut Image<[u8; 3]>, text: &str, x0: usize, y0: usize, scale: usize, colour: [u8; 3]) {
    let (w, h) = image.size();
    let mut gx = x0;
    for c in text.chars() {
        let advance = (glyph_width(c) + 1) * scale;
        let Some(rows) = glyph(c) else {
            gx += advance;
            continue;
        };
        for (ry, row) in rows.iter().enumerate() {
            for (rx, bit) in row.bytes().enumerate() {
                if bit != b'1' {
                    continue;
                }
                for dy in 0..scale {
                    for dx in 0..scale {
                        let (x, y) = (gx + rx * scale + dx, y0 + ry * scale + dy);
                        if x < w && y < h {
                            image.set(x, y, colour);
                        }
                    }
                }
            }
        }
        gx += advance;
    }
}

/// A label value with three significant digits (at least), e.g. `5.33`, `24.0`, `128`.
pub fn label(value: f32) -> String {
    let v = f64::from(value);
    let a = v.abs();
    if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 10.0 {
        format!("{v:.1}")
    } else if a >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    }
}

/// Colour-maps `values` (non-finite = invalid, drawn black) with Turbo over their 1st to 99th
/// percentile and adds a colour bar below, labelled `MIN UNIT` at the left end and `MAX UNIT` at
/// the right (`<MIN` / `>MAX` when values lie beyond; `unit` drawn with the built-in font:
/// digits, `.`, `-`, `<`, `>`, `m`, `p`, `x`).
pub fn render_preview(values: &Image<f32>, unit: &str, scale: ColourScale) -> Preview {
    let (w, h) = values.size();
    let mut finite: Vec<f32> = values.as_slice().iter().copied().filter(|v| v.is_finite()).collect();
    finite.sort_unstable_by(f32::total_cmp);
    // The scale spans the 1st to 99th percentile, so a few outliers (a disparity near 0 is
    // hundreds of metres away) do not squeeze every other pixel into one colour.
    let at = |p: f64| finite[((finite.len() - 1) as f64 * p).round() as usize];
    let range = (!finite.is_empty()).then(|| (at(0.01), at(0.99)));
    let clipped = (
        finite.first().zip(range).is_some_and(|(min, (lo, _))| *min < lo),
        finite.last().zip(range).is_some_and(|(max, (_, hi))| *max > hi),
    );
    let t_of = |v: f32| -> f32 {
        let Some((lo, hi)) = range else { return 0.5 };
        let t = if hi > lo { ((v - lo) / (hi - lo)).clamp(0.0, 1.0) } else { 0.5 };
        let t = match scale {
            ColourScale::LargeIsWarm => t,
            ColourScale::SmallIsWarm => 1.0 - t,
        };
        // Turbo's cold end is almost black: start a little above it, so no valid pixel looks
        // like an invalid (black) one.
        TURBO_START + (1.0 - TURBO_START) * t
    };

    let s = (w / 150).clamp(1, 4);
    let pad = 3 * s;
    let bar_h = 6 * s;
    let legend_h = pad + bar_h + pad + GLYPH_H * s + pad;
    let background = [40, 40, 40];
    let mut image = Image::new(w, h + legend_h, background);
    for y in 0..h {
        for x in 0..w {
            let v = values.get(x, y);
            image.set(x, y, if v.is_finite() { turbo(t_of(v)) } else { [0, 0, 0] });
        }
    }
    // The bar: value rising from left to right.
    let bar_w = w.saturating_sub(2 * pad).max(1);
    for i in 0..bar_w.min(w) {
        let colour = match range {
            Some((lo, hi)) => {
                let v = if bar_w > 1 { lo + (hi - lo) * i as f32 / (bar_w - 1) as f32 } else { lo };
                turbo(t_of(v))
            }
            None => [0, 0, 0],
        };
        for y in h + pad..h + pad + bar_h {
            if pad + i < w {
                image.set(pad + i, y, colour);
            }
        }
    }
    if let Some((lo, hi)) = range {
        let text_y = h + pad + bar_h + pad;
        let white = [255, 255, 255];
        let left = format!("{}{} {unit}", if clipped.0 { "<" } else { "" }, label(lo));
        draw_text(&mut image, &left, pad.min(w), text_y, s, white);
        let right = format!("{}{} {unit}", if clipped.1 { ">" } else { "" }, label(hi));
        let rw = text_width(&right, s);
        let lw = text_width(&left, s);
        let rx = w.saturating_sub(pad + rw);
        if rx > pad + lw + 2 * s {
            draw_text(&mut image, &right, rx, text_y, s, white);
        }
    }
    Preview { image, range, map_height: h }
}

/// Writes an 8-bit RGB PNG atomically.
pub fn write_png_rgb8(path: &Path, image: &Image<[u8; 3]>) -> Result<(), Error> {
    let (w, h) = image.size();
    if w == 0 || h == 0 {
        return Err(format_err(path, format!("cannot write a {w}x{h} PNG (empty image)")));
    }
    let raw: Vec<u8> = image.as_slice().iter().flatten().copied().collect();
    let buffer: Option<ImageBuffer<Rgb<u8>, Vec<u8>>> = ImageBuffer::from_raw(w as u32, h as u32, raw);
    crate::png16::write_png_buffer(path, buffer)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn turbo_ends_and_middle() {
        let [r0, g0, b0] = turbo(0.15);
        assert!(b0 > r0 && b0 > g0, "{:?}", turbo(0.15));
        let [r1, g1, b1] = turbo(1.0);
        assert!(r1 > g1 && r1 > b1, "{:?}", turbo(1.0));
        let [_, g, _] = turbo(0.5);
        assert!(g > 200, "{:?}", turbo(0.5));
    }

    #[test]
    fn invalid_is_black_and_near_is_red() {
        let values = Image::from_vec(3, 1, vec![1.0, f32::NAN, 5.0]).unwrap();
        let p = render_preview(&values, "m", ColourScale::SmallIsWarm);
        assert_eq!(p.range, Some((1.0, 5.0)));
        assert_eq!(p.image.get(1, 0), [0, 0, 0]);
        assert_eq!(p.image.get(0, 0), turbo(1.0));
        assert_eq!(p.image.get(2, 0), turbo(TURBO_START));
        assert!(turbo(TURBO_START).iter().any(|&c| c > 80), "{:?}", turbo(TURBO_START));
        assert!(p.image.height() > 1);
        assert_eq!(label(5.333), "5.33");
        assert_eq!(label(24.0), "24.0");
        assert_eq!(label(0.1234), "0.123");
    }
}
