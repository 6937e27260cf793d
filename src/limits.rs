//! Refusing work that cannot fit before anything large is allocated: the images' declared sizes
//! against `--max-pixels`, and the memory a pair will need against `--max-memory` or, without
//! it, the memory the system has available.

use std::path::Path;

use anyhow::{anyhow, bail, Result};
use stereo_io::ImageHeader;

use stereo_pipeline::{Matcher, MemoryLimit};

use crate::config::Limits;
use crate::error::UsageError;

/// The header of one input image, checked against `--max-pixels`.
pub fn probe(path: &Path, limits: &Limits) -> Result<ImageHeader> {
    let header = stereo_io::probe_image(path)?;
    let (w, h) = (header.width, header.height);
    if w == 0 || h == 0 {
        bail!("{}: image is {w}x{h}", path.display());
    }
    if header.pixels() > limits.max_pixels {
        bail!(
            "{}: {w}x{h} image ({:.1} MP) is over the --max-pixels limit of {} ({:.1} MP); raise it with \
             --max-pixels {} to process this image",
            path.display(),
            header.pixels() as f64 / 1e6,
            limits.max_pixels,
            limits.max_pixels as f64 / 1e6,
            header.pixels().div_ceil(1_000_000).max(1).to_string() + "M"
        );
    }
    Ok(header)
}

/// Bytes the pair needs besides the matcher: both grey images, one decoded image at a time, and
/// the maps and encoded outputs written at the end (disparity, depth, EXR buffer, preview,
/// points).
pub fn other_bytes(left: &ImageHeader, right: &ImageHeader, points: bool) -> u64 {
    let pixels = left.pixels();
    let decode = left.decoded_bytes().max(right.decoded_bytes());
    let per_pixel = 2 * 2 + 4 + 4 + 8 + 3 + if points { 15 + 3 } else { 0 };
    decode.saturating_add(pixels.saturating_mul(per_pixel))
}

/// The memory limit of one pair (`--max-memory`, or else what the system has available), with
/// the bytes `other` the command needs besides the matcher; `None` where neither is known.
pub fn memory_limit(limits: &Limits, other: u64) -> (Option<MemoryLimit>, Source) {
    match limits.max_memory {
        Some(bytes) => (Some(MemoryLimit { bytes, other_bytes: other }), Source::Flag),
        None => {
            (available_memory().map(|bytes| MemoryLimit { bytes, other_bytes: other }), Source::Available)
        }
    }
}

/// A planning error as the user should read it: memory errors name the limit and how to change
/// it; the rest are the pipeline's own.
pub fn explain(
    err: stereo_pipeline::Error,
    left: &Path,
    matcher: &Matcher,
    (width, height): (usize, usize),
    source: Source,
) -> anyhow::Error {
    let stereo_pipeline::Error::TooLarge { needed, limit } = err else {
        // Parameters the config could not check before the sizes were known.
        return UsageError(err.to_string()).into();
    };
    let what = format!(
        "{}: a {width}x{height} pair with {} disparities needs about {} ({} matcher)",
        left.display(),
        matcher.range().count(),
        human(needed),
        matcher.name()
    );
    match source {
        Source::Flag => anyhow!(
            "{what}, more than the --max-memory limit of {}; raise it (e.g. --max-memory {}) or lower \
             --max-disparity",
            human(limit),
            suggestion(needed)
        ),
        Source::Available => anyhow!(
            "{what}, more than the {} of memory available (MemAvailable in /proc/meminfo); free memory, \
             lower --max-disparity, or set --max-memory {} to try anyway",
            human(limit),
            suggestion(needed)
        ),
    }
}

/// Where the memory limit comes from.
pub enum Source {
    Flag,
    Available,
}

/// `MemAvailable` of /proc/meminfo, bytes (`None` where there is no such file).
pub fn available_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib.saturating_mul(1024))
}

/// Bytes with a binary unit: `512 B`, `1.5 KiB` ... `3.2 GiB`.
pub fn human(bytes: u64) -> String {
    let units = ["B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"];
    let mut value = bytes as f64;
    let mut unit = 0;
    while value >= 1024.0 && unit + 1 < units.len() {
        value /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{bytes} B")
    } else {
        format!("{value:.1} {}", units[unit])
    }
}

/// A `--max-memory` value of at least `bytes`, rounded up to whole MiB or GiB.
fn suggestion(bytes: u64) -> String {
    const MIB: u64 = 1 << 20;
    const GIB: u64 = 1 << 30;
    if bytes >= GIB {
        format!("{}G", bytes.div_ceil(GIB))
    } else {
        format!("{}M", bytes.div_ceil(MIB).max(1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_are_human() {
        assert_eq!(human(512), "512 B");
        assert_eq!(human(1536), "1.5 KiB");
        assert_eq!(human(3 << 30), "3.0 GiB");
        assert_eq!(suggestion(1), "1M");
        assert_eq!(suggestion((1 << 30) + 1), "2G");
    }
}
