//! Refusing work that cannot fit before anything large is allocated: the images' declared sizes
//! against `--max-pixels`, and the memory a pair will need against `--max-memory` or, without
//! it, the memory the system has available.

use std::path::Path;

use anyhow::{bail, Result};
use stereo_io::ImageHeader;

use crate::config::{Limits, Matcher};

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

/// The matcher's working memory for a `width × height` pair (its parameters hold the range).
pub fn matcher_bytes(matcher: &Matcher, width: usize, height: usize) -> u64 {
    match matcher {
        Matcher::Sgm(params) => sgm_plan(width, height, params),
        Matcher::Bm(params) => {
            // Two prefiltered/census images and two disparity maps, plus per-thread cost rows.
            let pixels = (width * height) as u64;
            let threads = rayon::current_num_threads() as u64;
            let rows = 3 * 4 * (width * params.range.count()) as u64;
            pixels * (16 + 16 + 4 + 4) + threads * rows
        }
    }
}

/// Checks the pair's planned memory against `--max-memory` (or the available memory) and, for
/// SGM, bounds the matcher to what is left, so it aggregates in strips that fit. Errors name the
/// limit and how to change it.
pub fn fit_memory(
    matcher: &mut Matcher,
    left: &Path,
    (width, height): (usize, usize),
    other: u64,
    limits: &Limits,
) -> Result<()> {
    let (limit, source) = match limits.max_memory {
        Some(limit) => (limit, Source::Flag),
        None => match available_memory() {
            Some(available) => (available, Source::Available),
            None => return Ok(()),
        },
    };
    let planned = matcher_bytes(matcher, width, height);
    if planned.saturating_add(other) <= limit {
        return Ok(());
    }
    // SGM can trade speed for memory: bound it to what the rest leaves.
    if let Matcher::Sgm(params) = matcher {
        if let Some(budget) = limit.checked_sub(other) {
            let mut bounded = params.clone();
            bounded.max_memory = Some(usize::try_from(budget).unwrap_or(usize::MAX));
            let bytes = sgm_plan(width, height, &bounded);
            if bytes <= budget {
                *params = bounded;
                return Ok(());
            }
        }
    }
    let count = match matcher {
        Matcher::Sgm(p) => p.range.count(),
        Matcher::Bm(p) => p.range.count(),
    };
    let needed = minimum_bytes(matcher, width, height).saturating_add(other);
    let what = format!(
        "{}: a {width}x{height} pair with {count} disparities needs about {} ({} matcher)",
        left.display(),
        human(needed),
        matcher.name()
    );
    match source {
        Source::Flag => bail!(
            "{what}, more than the --max-memory limit of {}; raise it (e.g. --max-memory {}) or lower \
             --max-disparity",
            human(limit),
            suggestion(needed)
        ),
        Source::Available => bail!(
            "{what}, more than the {} of memory available (MemAvailable in /proc/meminfo); free memory, \
             lower --max-disparity, or set --max-memory {} to try anyway",
            human(limit),
            suggestion(needed)
        ),
    }
}

enum Source {
    Flag,
    Available,
}

/// [`stereo_disparity::planned_memory_bytes`], for sizes its `usize` arithmetic can hold: an
/// absurd header (e.g. 2147483647 x 1 with the default range of a quarter of the width) would
/// overflow it, so beyond a sure bound a lower estimate (path state rows and per-pixel maps)
/// stands in, which is far over any real limit anyway.
fn sgm_plan(width: usize, height: usize, params: &stereo_disparity::SgmParams) -> u64 {
    let nd = params.range.count() as u128;
    let rough = (width as u128) * (nd + 2) * 64 + (width as u128) * (height as u128) * 64;
    if rough > (usize::MAX >> 8) as u128 {
        return u64::try_from(rough).unwrap_or(u64::MAX);
    }
    stereo_disparity::planned_memory_bytes(width, height, params) as u64
}

/// The least the matcher can run in (SGM: one-row strips).
fn minimum_bytes(matcher: &Matcher, width: usize, height: usize) -> u64 {
    match matcher {
        Matcher::Sgm(params) => {
            let smallest = stereo_disparity::SgmParams { max_memory: Some(1), ..params.clone() };
            sgm_plan(width, height, &smallest)
        }
        Matcher::Bm(_) => matcher_bytes(matcher, width, height),
    }
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
