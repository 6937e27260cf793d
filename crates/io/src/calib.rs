//! Middlebury `calib.txt` files: the one parser, shared by the pair command (`--calib`) and
//! the batch command (a `calib.txt` beside each Middlebury scene).

use std::collections::BTreeMap;
use std::path::Path;

use crate::{format_err, io_err, Error};

/// What a Middlebury `calib.txt` says about the rig.
#[derive(Clone, Debug, PartialEq)]
pub struct Calib {
    /// `cam0`'s focal length, pixels.
    pub focal_px: f64,
    /// `cam0`'s principal point, pixels.
    pub cx: f64,
    pub cy: f64,
    /// `doffs`, or `cam1.cx - cam0.cx` when only `cam1` is given.
    pub doffs: Option<f64>,
    pub baseline_mm: Option<f64>,
    pub width: Option<usize>,
    pub height: Option<usize>,
    pub ndisp: Option<usize>,
}

/// Parses a Middlebury `calib.txt`: `key=value` lines, `cam0=[f 0 cx; 0 f cy; 0 0 1]`, `doffs=`,
/// `baseline=` (mm), `width=`, `height=`, `ndisp=`; other keys are ignored.
pub fn parse_calib(text: &str) -> Result<Calib, String> {
    let mut values: BTreeMap<&str, &str> = BTreeMap::new();
    for (number, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let (key, value) =
            line.split_once('=').ok_or_else(|| format!("line {}: not key=value: {line:?}", number + 1))?;
        values.insert(key.trim(), value.trim());
    }
    let number = |key: &str| -> Result<Option<f64>, String> {
        values
            .get(key)
            .map(|v| {
                v.parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| format!("{key}={v} is not a number"))
            })
            .transpose()
    };
    let count = |key: &str| -> Result<Option<usize>, String> {
        values
            .get(key)
            .map(|v| v.parse::<usize>().map_err(|_| format!("{key}={v} is not a whole number")))
            .transpose()
    };
    let matrix = |key: &str| -> Result<Option<[[f64; 3]; 3]>, String> {
        let Some(text) = values.get(key) else { return Ok(None) };
        let bad = || format!("{key}={text} is not a 3x3 matrix [a b c; d e f; g h i]");
        let inner = text.strip_prefix('[').and_then(|t| t.strip_suffix(']')).ok_or_else(bad)?;
        let mut m = [[0.0; 3]; 3];
        let rows: Vec<&str> = inner.split(';').collect();
        if rows.len() != 3 {
            return Err(bad());
        }
        for (r, row) in rows.iter().enumerate() {
            let cells: Vec<f64> = row
                .split_whitespace()
                .map(|c| c.parse::<f64>().ok().filter(|v| v.is_finite()))
                .collect::<Option<_>>()
                .ok_or_else(bad)?;
            if cells.len() != 3 {
                return Err(bad());
            }
            m[r].copy_from_slice(&cells);
        }
        Ok(Some(m))
    };
    let cam0 = matrix("cam0")?.ok_or("no cam0=[f 0 cx; 0 f cy; 0 0 1]")?;
    let cam1 = matrix("cam1")?;
    let doffs = match number("doffs")? {
        Some(d) => Some(d),
        None => cam1.map(|c1| c1[0][2] - cam0[0][2]),
    };
    Ok(Calib {
        focal_px: cam0[0][0],
        cx: cam0[0][2],
        cy: cam0[1][2],
        doffs,
        baseline_mm: number("baseline")?,
        width: count("width")?,
        height: count("height")?,
        ndisp: count("ndisp")?,
    })
}

/// Reads and parses a Middlebury `calib.txt` (see [`parse_calib`]); errors name the file.
pub fn read_calib(path: &Path) -> Result<Calib, Error> {
    if path.is_dir() {
        return Err(format_err(path, "is a directory, not a calib.txt file"));
    }
    let bytes = std::fs::read(path).map_err(io_err(path))?;
    let text = String::from_utf8(bytes)
        .map_err(|_| format_err(path, "not a Middlebury calib.txt (not UTF-8 text)"))?;
    parse_calib(&text).map_err(|message| format_err(path, format!("invalid Middlebury calib.txt: {message}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn middlebury_calib() {
        let text = "cam0=[3997.684 0 1176.728; 0 3997.684 1011.728; 0 0 1]\n\
                    cam1=[3997.684 0 1307.839; 0 3997.684 1011.728; 0 0 1]\n\
                    doffs=131.111\nbaseline=193.001\nwidth=2964\nheight=1988\nndisp=280\nisint=0\nvmin=31\n";
        let c = parse_calib(text).unwrap();
        assert_eq!((c.focal_px, c.cx, c.cy), (3997.684, 1176.728, 1011.728));
        assert_eq!((c.doffs, c.baseline_mm), (Some(131.111), Some(193.001)));
        assert_eq!((c.width, c.height, c.ndisp), (Some(2964), Some(1988), Some(280)));

        // doffs from the principal points when absent; CRLF line ends.
        let c =
            parse_calib("cam0=[100 0 10; 0 100 20; 0 0 1]\r\ncam1=[100 0 15; 0 100 20; 0 0 1]\r\n").unwrap();
        assert_eq!((c.doffs, c.baseline_mm, c.ndisp), (Some(5.0), None, None));

        for bad in [
            "",
            "doffs=1",
            "cam0=[1 0 0; 0 1 0]",
            "cam0=[1 0 0; 0 1 0; 0 0 x]",
            "cam0=[1 0 0; 0 1 0; 0 0 1]\nndisp=-3",
            "garbage",
        ] {
            assert!(parse_calib(bad).is_err(), "{bad:?}");
        }
    }
}
