//! Point clouds as binary little-endian PLY (Open3D, CloudCompare, plyfile and ROS read it):
//! `float x, y, z` in metres and `uchar red, green, blue` per vertex; and a header / bounding
//! box reader for `stereo-depth info`.

use std::path::Path;

use crate::{format_err, io_err, write_atomic, Error};

/// One coloured point: camera-frame position in metres and 8-bit RGB colour.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlyVertex {
    pub position: [f32; 3],
    pub colour: [u8; 3],
}

/// The bytes of a binary little-endian PLY file with one `vertex` element (`float x y z`,
/// `uchar red green blue`, 15 bytes per vertex). Each comment becomes a `comment` header line
/// (line breaks are replaced by spaces).
pub fn encode_ply(vertices: &[PlyVertex], comments: &[&str]) -> Vec<u8> {
    let mut header = String::from("ply\nformat binary_little_endian 1.0\n");
    for comment in comments {
        header.push_str("comment ");
        header.push_str(&comment.replace(['\r', '\n'], " "));
        header.push('\n');
    }
    header.push_str(&format!("element vertex {}\n", vertices.len()));
    for axis in ["x", "y", "z"] {
        header.push_str(&format!("property float {axis}\n"));
    }
    for channel in ["red", "green", "blue"] {
        header.push_str(&format!("property uchar {channel}\n"));
    }
    header.push_str("end_header\n");
    let mut bytes = header.into_bytes();
    bytes.reserve(vertices.len() * 15);
    for v in vertices {
        for c in v.position {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
        bytes.extend_from_slice(&v.colour);
    }
    bytes
}

/// Writes [`encode_ply`] atomically.
pub fn write_ply(path: &Path, vertices: &[PlyVertex], comments: &[&str]) -> Result<(), Error> {
    write_atomic(path, &encode_ply(vertices, comments))
}

/// A property of the vertex element.
#[derive(Clone, Debug, PartialEq)]
pub struct PlyProperty {
    pub name: String,
    /// The PLY type, e.g. `float`, or `list uchar int` for list properties.
    pub kind: String,
}

/// What a PLY file holds, for `stereo-depth info`.
#[derive(Clone, Debug, PartialEq)]
pub struct PlyInfo {
    /// `ascii`, `binary_little_endian` or `binary_big_endian`.
    pub format: String,
    pub comments: Vec<String>,
    pub vertex_count: usize,
    pub properties: Vec<PlyProperty>,
    /// `(min, max)` of x, y, z over the vertices (binary files whose first element is `vertex`
    /// with scalar x, y, z properties); `None` otherwise or without vertices.
    pub bounds: Option<([f64; 3], [f64; 3])>,
    /// Vertices whose x, y and z are all finite (when `bounds` could be computed).
    pub finite_vertices: Option<usize>,
}

fn scalar_size(kind: &str) -> Option<usize> {
    Some(match kind {
        "char" | "uchar" | "int8" | "uint8" => 1,
        "short" | "ushort" | "int16" | "uint16" => 2,
        "int" | "uint" | "float" | "int32" | "uint32" | "float32" => 4,
        "double" | "float64" => 8,
        _ => return None,
    })
}

fn read_scalar(kind: &str, bytes: &[u8], little: bool) -> f64 {
    macro_rules! get {
        ($t:ty, $n:expr) => {{
            let mut a = [0u8; $n];
            a.copy_from_slice(&bytes[..$n]);
            if little {
                <$t>::from_le_bytes(a) as f64
            } else {
                <$t>::from_be_bytes(a) as f64
            }
        }};
    }
    match kind {
        "char" | "int8" => get!(i8, 1),
        "uchar" | "uint8" => get!(u8, 1),
        "short" | "int16" => get!(i16, 2),
        "ushort" | "uint16" => get!(u16, 2),
        "int" | "int32" => get!(i32, 4),
        "uint" | "uint32" => get!(u32, 4),
        "float" | "float32" => get!(f32, 4),
        _ => get!(f64, 8),
    }
}

/// Reads a PLY header and, for binary files whose first element is `vertex`, the bounding box.
pub fn read_ply_info(path: &Path) -> Result<PlyInfo, Error> {
    if path.is_dir() {
        return Err(format_err(path, "is a directory, not a PLY file"));
    }
    let bytes = std::fs::read(path).map_err(io_err(path))?;
    let bad = |m: &str| format_err(path, format!("not a valid PLY file: {m}"));
    if !bytes.starts_with(b"ply\n") && !bytes.starts_with(b"ply\r\n") {
        return Err(bad("no 'ply' magic line"));
    }
    let end = bytes
        .windows(b"end_header".len())
        .position(|w| w == b"end_header")
        .ok_or_else(|| bad("no end_header line"))?;
    let mut body_start = end + b"end_header".len();
    if bytes.get(body_start) == Some(&b'\r') {
        body_start += 1;
    }
    if bytes.get(body_start) != Some(&b'\n') {
        return Err(bad("end_header is not followed by a line break"));
    }
    body_start += 1;
    let header = std::str::from_utf8(&bytes[..end]).map_err(|_| bad("header is not text"))?;

    let mut format = None;
    let mut comments = Vec::new();
    // (name, count, properties)
    let mut elements: Vec<(String, usize, Vec<PlyProperty>)> = Vec::new();
    for line in header.lines().skip(1) {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            [] => {}
            ["format", f, _version] => format = Some(f.to_string()),
            ["comment", ..] | ["obj_info", ..] => {
                comments.push(line.trim_start().split_once(' ').map_or("", |c| c.1).to_string())
            }
            ["element", name, count] => {
                let count = count.parse().map_err(|_| bad(&format!("bad element count in {line:?}")))?;
                elements.push((name.to_string(), count, Vec::new()));
            }
            ["property", "list", count, item, name] => {
                let element = elements.last_mut().ok_or_else(|| bad("property before any element"))?;
                element.2.push(PlyProperty { name: name.to_string(), kind: format!("list {count} {item}") });
            }
            ["property", kind, name] => {
                scalar_size(kind).ok_or_else(|| bad(&format!("unknown property type {kind:?}")))?;
                let element = elements.last_mut().ok_or_else(|| bad("property before any element"))?;
                element.2.push(PlyProperty { name: name.to_string(), kind: kind.to_string() });
            }
            _ => return Err(bad(&format!("unexpected header line {line:?}"))),
        }
    }
    let format = format.ok_or_else(|| bad("no format line"))?;
    let little = match format.as_str() {
        "binary_little_endian" => Some(true),
        "binary_big_endian" => Some(false),
        "ascii" => None,
        other => return Err(bad(&format!("unknown format {other:?}"))),
    };
    let vertex = elements.iter().position(|e| e.0 == "vertex");
    let (vertex_count, properties) =
        vertex.map(|i| (elements[i].1, elements[i].2.clone())).unwrap_or((0, Vec::new()));

    let mut bounds = None;
    let mut finite_vertices = None;
    if let (Some(little), Some(0)) = (little, vertex) {
        let scalar = properties.iter().all(|p| scalar_size(&p.kind).is_some());
        if scalar {
            let stride: usize = properties.iter().filter_map(|p| scalar_size(&p.kind)).sum();
            let body = &bytes[body_start..];
            let needed = stride.checked_mul(vertex_count).ok_or_else(|| bad("vertex count overflows"))?;
            if body.len() < needed {
                return Err(bad(&format!(
                    "truncated: {vertex_count} vertices of {stride} bytes need {needed} bytes, the file has {}",
                    body.len()
                )));
            }
            let mut offsets: [Option<(usize, String)>; 3] = [None, None, None];
            let mut offset = 0;
            for p in &properties {
                if let Some(axis) = ["x", "y", "z"].iter().position(|a| *a == p.name) {
                    offsets[axis] = Some((offset, p.kind.clone()));
                }
                offset += scalar_size(&p.kind).unwrap_or(0);
            }
            if let [Some(ox), Some(oy), Some(oz)] = offsets {
                let mut lo = [f64::INFINITY; 3];
                let mut hi = [f64::NEG_INFINITY; 3];
                let mut finite = 0;
                for v in body[..needed].chunks_exact(stride) {
                    let xyz = [&ox, &oy, &oz].map(|(o, kind)| read_scalar(kind, &v[*o..], little));
                    if xyz.iter().all(|c| c.is_finite()) {
                        finite += 1;
                        for a in 0..3 {
                            lo[a] = lo[a].min(xyz[a]);
                            hi[a] = hi[a].max(xyz[a]);
                        }
                    }
                }
                finite_vertices = Some(finite);
                bounds = (finite > 0).then_some((lo, hi));
            }
        }
    }
    Ok(PlyInfo { format, comments, vertex_count, properties, bounds, finite_vertices })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_header_and_bounds() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.ply");
        let vertices = [
            PlyVertex { position: [1.0, -2.0, 3.0], colour: [1, 2, 3] },
            PlyVertex { position: [-1.0, 2.5, 0.5], colour: [255, 0, 9] },
        ];
        write_ply(&path, &vertices, &["metres, x right\ny down"]).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert!(bytes.ends_with(&[0, 0, 0, 0x3f, 255, 0, 9]));
        let info = read_ply_info(&path).unwrap();
        assert_eq!(info.format, "binary_little_endian");
        assert_eq!(info.comments, ["metres, x right y down"]);
        assert_eq!(info.vertex_count, 2);
        let names: Vec<&str> = info.properties.iter().map(|p| p.name.as_str()).collect();
        assert_eq!(names, ["x", "y", "z", "red", "green", "blue"]);
        assert_eq!(info.bounds, Some(([-1.0, -2.0, 0.5], [1.0, 2.5, 3.0])));
        std::fs::write(&path, &bytes[..bytes.len() - 1]).unwrap();
        assert!(read_ply_info(&path).unwrap_err().to_string().contains("truncated"));
    }
}
