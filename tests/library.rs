//! The library pipeline on a caller's in-memory buffers gives the command's disparity, bit for
//! bit: the same `Plan` runs behind both.

mod common;

use common::{run_in, s, slanted};
use stereo_pipeline::{DisparityRange, ImageRef, Matcher, PipelineParams, Plan, Preset, SgmParams};

/// The slanted sample as 8-bit RGB buffers with 2 pixels of padding per row (a camera frame
/// layout), decoded independently of the program.
fn rgb_frame(name: &str) -> (Vec<u8>, usize, usize, usize) {
    let rgb = image::open(slanted(name)).unwrap().to_rgb8();
    let (w, h) = (rgb.width() as usize, rgb.height() as usize);
    let stride = 3 * (w + 2);
    let mut frame = vec![0u8; stride * h];
    for (y, row) in rgb.as_raw().chunks_exact(3 * w).enumerate() {
        frame[y * stride..y * stride + 3 * w].copy_from_slice(row);
    }
    (frame, w, h, stride)
}

#[test]
fn borrowed_colour_frames_match_like_the_command() {
    let dir = tempfile::tempdir().unwrap();
    let (left, w, h, stride) = rgb_frame("left.png");
    let (right, ..) = rgb_frame("right.png");
    for (preset, flag) in [(Preset::Balanced, "balanced"), (Preset::Fast, "fast")] {
        let out = dir.path().join(format!("{flag}.pfm"));
        run_in(
            dir.path(),
            &[
                s(&slanted("left.png")),
                s(&slanted("right.png")),
                "--max-disparity",
                "64",
                "--preset",
                flag,
                "--disparity",
                s(&out),
            ],
        )
        .assert_success();
        let cli = stereo_io::read_pfm(&out).unwrap();

        let range = DisparityRange::new(0, 64).unwrap();
        let params = PipelineParams::new(Matcher::Sgm(SgmParams { range, ..SgmParams::preset(preset) }));
        let plan = Plan::new(&params, (w, h), (w, h)).unwrap();
        let left_view = ImageRef::<[u8; 3]>::from_interleaved(&left, w, h, stride).unwrap();
        let right_view = ImageRef::<[u8; 3]>::from_interleaved(&right, w, h, stride).unwrap();
        let result = plan.run(left_view, right_view).unwrap();

        let bits =
            |m: &stereo_pipeline::DisparityMap| m.as_slice().iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        assert_eq!(result.disparity.size(), cli.size());
        assert!(bits(&result.disparity) == bits(&cli), "{flag}: library and command differ");
    }
}
