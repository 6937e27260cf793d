//! The alignment estimate on pairs with a known vertical offset and rotation of the right view.

use std::path::PathBuf;

use stereo_degrade::{degrade, BitDepth, Degradation, Raster};
use stereo_image::{DisparityRange, GrayImage};
use stereo_rectify::{compensate, estimate_alignment, Alignment, AlignmentVerdict};
use stereo_scene::{render, SceneParams, SplitMix64};

const WIDTH: usize = 450;
const HEIGHT: usize = 375;

/// A band-limited random texture (periods 4–40 px), so point samples at sub-pixel positions are
/// exact views of the same continuous scene.
struct Texture(Vec<(f64, f64, f64, f64)>);

impl Texture {
    fn new(seed: u64) -> Self {
        let mut rng = SplitMix64::new(seed);
        Texture(
            (0..24)
                .map(|_| {
                    let period = 4.0 * 10f64.powf(rng.next_f64());
                    let angle = std::f64::consts::PI * rng.next_f64();
                    let k = std::f64::consts::TAU / period;
                    (
                        k * angle.cos(),
                        k * angle.sin(),
                        std::f64::consts::TAU * rng.next_f64(),
                        0.5 + rng.next_f64(),
                    )
                })
                .collect(),
        )
    }

    fn value(&self, x: f64, y: f64) -> f64 {
        let sum: f64 = self.0.iter().map(|&(kx, ky, phase, a)| a * (kx * x + ky * y + phase).sin()).sum();
        32768.0 + 26000.0 * (0.25 * sum).tanh()
    }
}

/// A pair whose right view is `shift` px lower and rotated `rotation_deg` about the centre
/// (positive: its right side lower), with `photometric` applied to the right view's grey values.
fn pair(shift: f64, rotation_deg: f64, photometric: impl Fn(f64) -> f64) -> (GrayImage, GrayImage) {
    let texture = Texture::new(0xA11C_0001);
    let left = GrayImage::from_fn(WIDTH, HEIGHT, |x, y| texture.value(x as f64, y as f64).round() as u16);
    let (cx, cy) = ((WIDTH as f64 - 1.0) / 2.0, (HEIGHT as f64 - 1.0) / 2.0);
    let (sin, cos) = rotation_deg.to_radians().sin_cos();
    let right = GrayImage::from_fn(WIDTH, HEIGHT, |x, y| {
        // Undo the rotation and the shift: the ideal right view's point.
        let (px, py) = (x as f64 - cx, y as f64 - cy);
        let (qx, qy) = (cos * px + sin * py + cx, -sin * px + cos * py + cy - shift);
        // A slanted plane, disparity 10 + 0.05·u (10 to about 32 px): the ideal right pixel qx
        // shows the left point u with u − (10 + 0.05·u) = qx.
        let u = (qx + 10.0) / 0.95;
        photometric(texture.value(u, qy)).round().clamp(0.0, 65535.0) as u16
    });
    (left, right)
}

fn range() -> DisparityRange {
    DisparityRange::new(0, 48).unwrap()
}

#[track_caller]
fn assert_estimate(alignment: &Alignment, shift: f64, rotation_deg: f64) {
    assert!(
        (alignment.vertical_offset_px as f64 - shift).abs() < 0.1
            && (alignment.rotation_deg as f64 - rotation_deg).abs() < 0.02,
        "shift {shift}, rotation {rotation_deg}°: estimated {alignment:?}"
    );
    assert!(alignment.patches_used >= 100, "{alignment:?}");
}

#[test]
fn sub_pixel_vertical_shifts_are_measured() {
    for shift in [-1.5, -1.0, -0.6, -0.4, 0.15, 0.45, 0.8, 1.25, 1.5] {
        let (left, right) = pair(shift, 0.0, |v| v);
        let alignment = estimate_alignment(&left, &right, range());
        assert_estimate(&alignment, shift, 0.0);
        // ±1.5 px is the limit between misaligned and badly misaligned: either verdict is right.
        if shift.abs() < 1.45 {
            let expected =
                if shift.abs() < 0.3 { AlignmentVerdict::Aligned } else { AlignmentVerdict::Misaligned };
            assert_eq!(alignment.verdict, expected, "shift {shift}: {alignment:?}");
        }
    }
}

#[test]
fn rotations_are_measured() {
    for (shift, rotation) in [(0.0, 0.1), (0.0, -0.1), (0.0, 0.2), (0.0, -0.2), (0.5, 0.1), (-0.7, -0.2)] {
        let (left, right) = pair(shift, rotation, |v| v);
        let alignment = estimate_alignment(&left, &right, range());
        assert_estimate(&alignment, shift, rotation);
        // A rotation moves the edges: |shift| + |sin θ|·cx there.
        let edge = shift.abs() + rotation.to_radians().sin().abs() * (WIDTH as f64 - 1.0) / 2.0;
        assert!((alignment.max_abs_offset_px as f64 - edge).abs() < 0.1, "{alignment:?}");
    }
}

#[test]
fn a_large_offset_is_badly_misaligned() {
    let (left, right) = pair(2.5, 0.0, |v| v);
    let alignment = estimate_alignment(&left, &right, range());
    assert_estimate(&alignment, 2.5, 0.0);
    assert_eq!(alignment.verdict, AlignmentVerdict::BadlyMisaligned);
}

#[test]
fn a_clean_pair_is_aligned() {
    let (left, right) = pair(0.0, 0.0, |v| v);
    let alignment = estimate_alignment(&left, &right, range());
    assert_eq!(alignment.verdict, AlignmentVerdict::Aligned, "{alignment:?}");
    assert!(alignment.vertical_offset_px.abs() < 0.1 && alignment.max_abs_offset_px < 0.15, "{alignment:?}");
    assert!(alignment.negative_disparity_share < 0.2, "{alignment:?}");

    // The generated scene with occlusions and a foreground object, with sensor noise.
    let scene = render(&SceneParams { width: WIDTH, height: HEIGHT, noise: 300.0, ..SceneParams::default() });
    let alignment = estimate_alignment(&scene.left, &scene.right, range());
    assert_eq!(alignment.verdict, AlignmentVerdict::Aligned, "{alignment:?}");
    assert!(alignment.vertical_offset_px.abs() < 0.1, "{alignment:?}");
    assert!(alignment.negative_disparity_share < 0.2, "{alignment:?}");
}

#[test]
fn gain_and_gamma_do_not_change_the_estimate() {
    // Gain 1.5 and gamma 0.8 on the right view only (clipped at white, like a sensor).
    let exposure = |v: f64| 1.5 * 65535.0 * (v / 65535.0).powf(1.0 / 0.8);
    for (shift, rotation) in [(0.0, 0.0), (0.7, 0.0), (-0.4, 0.1)] {
        let (left, plain) = pair(shift, rotation, |v| v);
        let (_, exposed) = pair(shift, rotation, exposure);
        let a = estimate_alignment(&left, &plain, range());
        let b = estimate_alignment(&left, &exposed, range());
        assert_estimate(&b, shift, rotation);
        assert!(
            (a.vertical_offset_px - b.vertical_offset_px).abs() < 0.03
                && (a.rotation_deg - b.rotation_deg).abs() < 0.01,
            "plain {a:?}, exposed {b:?}"
        );
        assert_eq!(a.verdict, b.verdict);
    }
}

#[test]
fn compensation_removes_the_misalignment() {
    for (shift, rotation) in [(1.0, 0.0), (-0.6, 0.1), (0.4, -0.2), (1.4, 0.0)] {
        let (left, right) = pair(shift, rotation, |v| v);
        let alignment = estimate_alignment(&left, &right, range());
        let aligned = compensate(&right, &alignment);
        let residual = estimate_alignment(&left, &aligned, range());
        assert!(
            residual.max_abs_offset_px < 0.15,
            "shift {shift}, rotation {rotation}: residual {residual:?}"
        );
        assert_eq!(residual.verdict, AlignmentVerdict::Aligned);
    }
}

#[test]
fn compensating_nothing_keeps_the_image() {
    let (_, right) = pair(0.0, 0.0, |v| v);
    let none = Alignment {
        vertical_offset_px: 0.0,
        rotation_deg: 0.0,
        max_abs_offset_px: 0.0,
        patches_used: 0,
        negative_disparity_share: 0.0,
        verdict: AlignmentVerdict::Unknown,
    };
    assert_eq!(compensate(&right, &none), right);
}

#[test]
fn a_swapped_pair_wants_negative_disparities() {
    let scene = render(&SceneParams { width: WIDTH, height: HEIGHT, ..SceneParams::default() });
    let normal = estimate_alignment(&scene.left, &scene.right, range());
    assert!(normal.negative_disparity_share < 0.2, "{normal:?}");
    let swapped = estimate_alignment(&scene.right, &scene.left, range());
    assert!(swapped.negative_disparity_share > 0.5, "{swapped:?}");
    // Swapping does not invent a misalignment.
    assert_eq!(swapped.verdict, AlignmentVerdict::Aligned, "{swapped:?}");
}

#[test]
fn unrelated_images_are_unknown() {
    let (left, _) = pair(0.0, 0.0, |v| v);
    let other = Texture::new(7);
    let right = GrayImage::from_fn(WIDTH, HEIGHT, |x, y| other.value(x as f64, y as f64) as u16);
    assert_eq!(estimate_alignment(&left, &right, range()).verdict, AlignmentVerdict::Unknown);
    let flat = GrayImage::new(WIDTH, HEIGHT, 30_000);
    assert_eq!(estimate_alignment(&flat, &flat, range()).verdict, AlignmentVerdict::Unknown);
}

/// The Middlebury scenes of the shared development data, when present (`STEREO_DATA` or
/// /work/shared/data): every clean pair is aligned, and a 1 px shift of its right view is found.
#[test]
fn real_scenes_when_available() {
    let root =
        std::env::var_os("STEREO_DATA").map_or_else(|| PathBuf::from("/work/shared/data"), PathBuf::from);
    let Ok(table) = std::fs::read_to_string(root.join("scenes.tsv")) else {
        eprintln!("skipped: no scenes.tsv in {}", root.display());
        return;
    };
    let ndisp_column =
        table.lines().next().unwrap().split('\t').position(|c| c == "suggested_ndisp").unwrap();
    for line in table.lines().skip(1) {
        let fields: Vec<&str> = line.split('\t').collect();
        let folder = root.join(fields[0]);
        let load = |name: &str| stereo_io::load_gray(&folder.join(name)).unwrap();
        let (left, right) = (load(fields[1]), load(fields[2]));
        let range = DisparityRange::new(0, fields[ndisp_column].parse().unwrap()).unwrap();
        let clean = estimate_alignment(&left, &right, range);
        assert_eq!(clean.verdict, AlignmentVerdict::Aligned, "{}: {clean:?}", fields[0]);
        assert!(clean.negative_disparity_share < 0.2, "{}: {clean:?}", fields[0]);
        // One whole pixel lower: the rows move exactly, no interpolation.
        let shifted = compensate(&right, &Alignment { vertical_offset_px: -1.0, ..clean });
        let measured = estimate_alignment(&left, &shifted, range);
        let expected = clean.vertical_offset_px + 1.0;
        assert!((measured.vertical_offset_px - expected).abs() < 0.1, "{}: {measured:?}", fields[0]);
        assert_eq!(measured.verdict, AlignmentVerdict::Misaligned, "{}: {measured:?}", fields[0]);
        unbiased_under_degradations(fields[0], &left, &right, range, &clean);
    }
}

/// The right view degraded (`stereo-degrade`, as `stereo-depth degrade` does) reads the clean
/// pair's offset plus what the degradation adds. The fit once interpolated the right view only,
/// which read 0.25 px as 0.16–0.21, 0.1° as 0.06–0.09°, and added 0.06–0.08 px under noise σ 6
/// and up to 0.28 px under blur σ 1.5 (docs/robustness.md).
fn unbiased_under_degradations(
    scene: &str,
    left: &GrayImage,
    right: &GrayImage,
    range: DisparityRange,
    clean: &Alignment,
) {
    let (w, h) = right.size();
    let raster = Raster::new(w, h, 1, BitDepth::Sixteen, right.as_slice().to_vec()).unwrap();
    let degraded = |spec: &str| {
        let out = degrade(&raster, &spec.parse::<Degradation>().unwrap(), 7).unwrap();
        let image = GrayImage::from_vec(w, h, out.samples().to_vec()).unwrap();
        estimate_alignment(left, &image, range)
    };
    let (offset, rotation) = (clean.vertical_offset_px, clean.rotation_deg);
    // (spec, expected added offset, its tolerance, expected added rotation, its tolerance)
    for (spec, add_offset, offset_tol, add_rotation, rotation_tol) in [
        ("vshift=0.25", 0.25, 0.04, 0.0, 0.01),
        ("rotate=0.1", 0.0, 0.04, 0.1, 0.015),
        ("noise=6", 0.0, 0.04, 0.0, 0.01),
        ("blur=1.5", 0.0, 0.15, 0.0, 0.04),
    ] {
        let m = degraded(spec);
        assert!(
            (m.vertical_offset_px - offset - add_offset).abs() < offset_tol
                && (m.rotation_deg - rotation - add_rotation).abs() < rotation_tol,
            "{scene} {spec}: clean {clean:?}, degraded {m:?}"
        );
    }
}
