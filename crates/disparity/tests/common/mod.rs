//! Generated scenes shared by the integration tests.

use stereo_disparity::GrayImage;
use stereo_scene::{Scene, SceneParams};

/// A 480×360 scene in 8-bit levels (stored ×257, as the loader stores 8-bit images) with
/// independent Gaussian noise of `noise` 16-bit levels in each view.
pub fn scene_8bit(noise: f32) -> Scene {
    let mut scene =
        stereo_scene::render(&SceneParams { width: 480, height: 360, noise, ..SceneParams::default() });
    let to_8bit = |image: &GrayImage| {
        GrayImage::from_fn(image.width(), image.height(), |x, y| {
            ((f32::from(image.get(x, y)) / 257.0).round() as u16) * 257
        })
    };
    scene.left = to_8bit(&scene.left);
    scene.right = to_8bit(&scene.right);
    scene
}
