//! Middlebury PFM (portable float map) reading and writing.

use std::path::Path;

use stereo_image::Image;

use crate::{format_err, io_err, write_atomic, Error};

/// Python's `bytes.isspace` set, as used by the reference reader.
fn is_space(c: u8) -> bool {
    matches!(c, b' ' | b'\t' | b'\n' | b'\r' | 0x0b | 0x0c)
}

/// Reads whitespace-separated header tokens like `stereo_eval.py::_read_header_tokens`:
/// `#` at the start of a token skips to the end of the line, and exactly one whitespace byte
/// after the last token ends the header.
struct HeaderReader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl HeaderReader<'_> {
    fn token(&mut self) -> Result<String, String> {
        let mut cur: Vec<u8> = Vec::new();
        loop {
            let Some(&c) = self.bytes.get(self.pos) else {
                return Err("truncated PFM header".into());
            };
            self.pos += 1;
            if c == b'#' && cur.is_empty() {
                while let Some(&c) = self.bytes.get(self.pos) {
                    self.pos += 1;
                    if c == b'\n' {
                        break;
                    }
                }
                continue;
            }
            if is_space(c) {
                if !cur.is_empty() {
                    return Ok(String::from_utf8_lossy(&cur).into_owned());
                }
            } else {
                cur.push(c);
                if cur.len() > 64 {
                    return Err("PFM header token too long (not a PFM file?)".into());
                }
            }
        }
    }
}

/// Reads a grey PFM (`Pf`) disparity map, top row first; values as stored (bit-exact, so NaN
/// and inf are preserved). Either endianness is accepted.
pub fn read_pfm(path: &Path) -> Result<Image<f32>, Error> {
    if path.is_dir() {
        return Err(format_err(path, "is a directory, not a PFM file"));
    }
    let bytes = std::fs::read(path).map_err(io_err(path))?;
    decode_pfm(&bytes, path)
}

/// [`read_pfm`] of bytes already in memory; errors name `path`. Nothing is allocated for the
/// pixels before the data is known to hold them all.
pub fn decode_pfm(bytes: &[u8], path: &Path) -> Result<Image<f32>, Error> {
    if bytes.is_empty() {
        return Err(format_err(path, "empty file, not a PFM image"));
    }
    let mut header = HeaderReader { bytes, pos: 0 };
    let fail = |m: String| format_err(path, m);
    let magic = header.token().map_err(fail)?;
    match magic.as_str() {
        "Pf" => {}
        "PF" => return Err(fail("colour PFM ('PF'); a disparity map must be a grey 'Pf' PFM".into())),
        _ => return Err(fail(format!("not a PFM file (magic {magic:?}, want 'Pf')"))),
    }
    let w_tok = header.token().map_err(fail)?;
    let h_tok = header.token().map_err(fail)?;
    let s_tok = header.token().map_err(fail)?;
    let bad_header = || fail(format!("bad PFM header: Pf {w_tok} {h_tok} {s_tok}"));
    let width: i64 = w_tok.parse().map_err(|_| bad_header())?;
    let height: i64 = h_tok.parse().map_err(|_| bad_header())?;
    let scale: f64 = s_tok.parse().map_err(|_| bad_header())?;
    if width <= 0 || height <= 0 {
        return Err(fail(format!("bad PFM size {width}x{height} (must be positive)")));
    }
    if scale == 0.0 || scale.is_nan() {
        return Err(fail(format!("bad PFM scale {s_tok} (must be non-zero)")));
    }
    let little_endian = scale < 0.0;
    let data = &bytes[header.pos..];
    let (width, height) = (width as u64, height as u64);
    let expected = width.checked_mul(height).and_then(|n| n.checked_mul(4));
    let expected = match expected {
        Some(n) if n <= data.len() as u64 => n as usize,
        _ => {
            let want = expected.map_or_else(|| "more than 2^64".to_string(), |n| n.to_string());
            return Err(fail(format!(
                "truncated PFM data: expected {want} bytes for {width}x{height}, found {}",
                data.len()
            )));
        }
    };
    // Both fit in usize now: their product (times 4) is at most the data length.
    let (width, height) = (width as usize, height as usize);
    let mut values = Vec::with_capacity(width * height);
    // Rows are stored bottom to top.
    for y in (0..height).rev() {
        let row = &data[y * width * 4..(y + 1) * width * 4];
        values.extend(row.chunks_exact(4).map(|b| {
            let b = [b[0], b[1], b[2], b[3]];
            if little_endian {
                f32::from_le_bytes(b)
            } else {
                f32::from_be_bytes(b)
            }
        }));
    }
    debug_assert_eq!(values.len() * 4, expected);
    Image::from_vec(width, height, values).map_err(|e| fail(e.to_string()))
}

/// Encodes `map` as a little-endian Middlebury PFM (`Pf`, scale -1, rows bottom to top).
pub fn encode_pfm(map: &Image<f32>) -> Vec<u8> {
    let (width, height) = map.size();
    let mut out = format!("Pf\n{width} {height}\n-1.0\n").into_bytes();
    let header = out.len();
    out.resize(header + width * height * 4, 0);
    // Whole rows at a time into the sized buffer (a loop the compiler turns into wide moves; an
    // `extend` per sample cost more than the file's write).
    for (y, bytes) in (0..height).rev().zip(out[header..].chunks_exact_mut((width * 4).max(1))) {
        for (b, v) in bytes.chunks_exact_mut(4).zip(map.row(y)) {
            b.copy_from_slice(&v.to_le_bytes());
        }
    }
    out
}

/// Writes a Middlebury PFM: `Pf`, little-endian (scale -1), rows bottom to top, atomically.
/// Values are written bit-exact (NaN stays NaN).
pub fn write_pfm(path: &Path, map: &Image<f32>) -> Result<(), Error> {
    let (width, height) = map.size();
    if width == 0 || height == 0 {
        return Err(format_err(path, format!("cannot write a {width}x{height} PFM (empty image)")));
    }
    write_atomic(path, &encode_pfm(map))
}
