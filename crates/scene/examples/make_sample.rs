//! Renders the sample scene in `data/slanted/`: 8-bit grey PNGs of both views and the dense
//! left ground truth as a Middlebury PFM.
//!
//! ```text
//! cargo run -p stereo-scene --example make_sample [-- OUTPUT_DIR]
//! ```

use std::io::Write;
use std::path::{Path, PathBuf};

use stereo_scene::{render, to_u8, Foreground, Rect, SceneParams};

/// The parameters of `data/slanted/` (documented in its README).
fn sample_params() -> SceneParams {
    SceneParams {
        width: WIDTH,
        height: HEIGHT,
        seed: 2024,
        // 10 px at the top-left corner to about 29.4 px at the bottom-right.
        plane: (10.0, 0.06, 0.01),
        foreground: Some(Foreground {
            rect: Rect { x0: 119.5, y0: 59.5, x1: 209.5, y1: 149.5 },
            disparity: 45.0,
        }),
        // One 8-bit grey level.
        noise: 257.0,
        supersampling: 4,
    }
}

const WIDTH: usize = 288;
const HEIGHT: usize = 216;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../data/slanted"));
    std::fs::create_dir_all(&dir)?;
    let dir = dir.canonicalize()?;
    let scene = render(&sample_params());
    for (name, view) in [("left.png", &scene.left), ("right.png", &scene.right)] {
        let grey = to_u8(view);
        let (w, h) = grey.size();
        image::GrayImage::from_raw(w as u32, h as u32, grey.into_vec())
            .ok_or("buffer size")?
            .save(dir.join(name))?;
    }
    write_pfm(&dir.join("disp0GT.pfm"), &scene.gt_left)?;
    let occluded = scene.occluded.as_slice().iter().filter(|&&o| o).count();
    let gt = scene.gt_left.as_slice();
    let (min, max) =
        gt.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &d| (lo.min(d), hi.max(d)));
    println!(
        "wrote {} ({}x{}): disparity {min:.2}..{max:.2} px, {:.1}% of left pixels occluded",
        dir.display(),
        scene.left.width(),
        scene.left.height(),
        100.0 * occluded as f64 / gt.len() as f64
    );
    Ok(())
}

/// Middlebury PFM: `Pf` (one channel), size, negative scale = little-endian, rows bottom to top.
fn write_pfm(path: &Path, disparity: &stereo_image::DisparityMap) -> std::io::Result<()> {
    let (w, h) = disparity.size();
    let mut bytes = format!("Pf\n{w} {h}\n-1.0\n").into_bytes();
    for y in (0..h).rev() {
        for &d in disparity.row(y) {
            bytes.extend_from_slice(&d.to_le_bytes());
        }
    }
    std::fs::File::create(path)?.write_all(&bytes)
}
