use super::*;

fn small() -> SceneParams {
    SceneParams { width: 160, height: 96, ..SceneParams::default() }
}

/// Catmull-Rom interpolation of row `y` of `image` at continuous column `x` (borders clamped).
fn cubic(image: &GrayImage, x: f64, y: usize) -> f64 {
    let row = image.row(y);
    let at = |i: i64| row[i.clamp(0, row.len() as i64 - 1) as usize] as f64;
    let i = x.floor() as i64;
    let t = x - i as f64;
    let (p0, p1, p2, p3) = (at(i - 1), at(i), at(i + 1), at(i + 2));
    p1 + 0.5 * t * (p2 - p0 + t * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + t * (3.0 * (p1 - p2) + p3 - p0)))
}

fn std_dev(values: impl Iterator<Item = f64> + Clone) -> f64 {
    let n = values.clone().count() as f64;
    let mean = values.clone().sum::<f64>() / n;
    (values.map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt()
}

#[test]
fn ground_truth_is_the_exact_surface_disparity() {
    let params = SceneParams::default();
    let scene = render(&params);
    let (a, b, c) = params.plane;
    let fg = params.foreground.unwrap();
    let (mut min, mut max) = (f32::INFINITY, f32::NEG_INFINITY);
    for y in 0..params.height {
        for x in 0..params.width {
            let d = scene.gt_left.get(x, y);
            let expected = if fg.rect.contains(x as f64, y as f64) {
                fg.disparity
            } else {
                a + b * x as f64 + c * y as f64
            };
            assert!((d as f64 - expected).abs() < 1e-5, "({x}, {y}): {d} vs {expected}");
            min = min.min(d);
            max = max.max(d);
        }
    }
    assert_eq!(min, 8.0);
    assert_eq!(max, 36.0);
    // The plane alone spans about 8..24 px.
    let corner = scene.gt_left.get(params.width - 1, params.height - 1);
    assert!((23.0..25.0).contains(&corner), "{corner}");
}

#[test]
fn integer_shift_is_reproduced_exactly() {
    let params = SceneParams { plane: (10.0, 0.0, 0.0), foreground: None, ..small() };
    let scene = render(&params);
    for y in 0..params.height {
        for x in 10..params.width {
            let (l, r) = (scene.left.get(x, y) as i32, scene.right.get(x - 10, y) as i32);
            assert!((l - r).abs() <= 1, "({x}, {y}): {l} vs {r}");
            assert!(!scene.occluded.get(x, y));
        }
        for x in 0..10 {
            assert!(scene.occluded.get(x, y));
        }
    }
}

#[test]
fn right_view_warped_by_ground_truth_matches_left() {
    let params = SceneParams::default();
    let scene = render(&params);
    let (w, h) = scene.left.size();
    let texture_std = std_dev(scene.left.as_slice().iter().map(|&v| v as f64));
    // Mean absolute warping error with the true disparity and with a wrong one.
    let error = |offset: f64| {
        let (mut sum, mut count, mut big) = (0.0, 0usize, 0usize);
        for y in 0..h {
            for x in 0..w {
                if scene.occluded.get(x, y) {
                    continue;
                }
                let xr = x as f64 - scene.gt_left.get(x, y) as f64 - offset;
                if xr < 1.0 || xr > w as f64 - 3.0 {
                    continue;
                }
                let e = (cubic(&scene.right, xr, y) - scene.left.get(x, y) as f64).abs();
                sum += e;
                count += 1;
                big += usize::from(e > 0.1 * texture_std);
            }
        }
        (sum / count as f64 / texture_std, big as f64 / count as f64)
    };
    let (exact, exact_big) = error(0.0);
    let (off, _) = error(0.5);
    // Residuals come from interpolation and the slightly different pixel footprints on the slant,
    // and a few mixed pixels next to the foreground's edges.
    assert!(exact < 0.02, "mean error {exact} of the texture std");
    assert!(exact_big < 0.01, "{exact_big} of pixels off by more than 10% of the texture std");
    assert!(off > 10.0 * exact, "half a pixel off: {off} vs exact {exact}");
}

#[test]
fn right_ground_truth_agrees_with_left() {
    let scene = render(&SceneParams::default());
    let (w, h) = scene.left.size();
    let mut checked = 0;
    for y in 0..h {
        for x in 0..w {
            if scene.occluded.get(x, y) {
                continue;
            }
            let d = scene.gt_left.get(x, y);
            let xr = (x as f32 - d).round() as usize;
            // The right pixel centre is within half a pixel, so its disparity differs by at most
            // half a pixel times the slope.
            assert!((scene.gt_right.get(xr, y) - d).abs() < 0.05, "({x}, {y})");
            checked += 1;
        }
    }
    assert!(checked > w * h * 3 / 4);
}

#[test]
fn occlusions_are_where_the_geometry_puts_them() {
    let params = SceneParams::default();
    let scene = render(&params);
    let fg = params.foreground.unwrap();
    let (a, b, c) = params.plane;
    let y = 100;
    let (x0, x1) = (fg.rect.x0.ceil() as usize, fg.rect.x1.ceil() as usize);
    // Left of the rectangle the background is hidden behind it in the right view over
    // (D - d_plane) pixels; the rectangle itself is fully visible.
    // A background point at x is seen in the right view at x - d(x); the rectangle covers
    // [x0 - D, x1 - D) there, so the hidden band starts at (rect.x0 - D + a + c·y) / (1 - b).
    let start = ((fg.rect.x0 - fg.disparity + a + c * y as f64) / (1.0 - b)).ceil() as usize;
    assert!(x0 - start > 20);
    for x in start..x0 {
        assert!(scene.occluded.get(x, y), "x = {x}");
    }
    for x in start - 3..start {
        assert!(!scene.occluded.get(x, y), "x = {x}");
    }
    for x in x0..x1 {
        assert!(!scene.occluded.get(x, y));
    }
    // Left border: points at x < d leave the right image.
    assert!(scene.occluded.get(7, y) && !scene.occluded.get(10, y));
    // Right view: the background right of the rectangle is hidden in the left view.
    let xr = x1 - fg.disparity as usize + 1;
    assert!(scene.occluded_right.get(xr, y));
}

#[test]
fn rendering_is_deterministic_and_seeded() {
    let params = small();
    let (s1, s2) = (render(&params), render(&params));
    assert_eq!(s1.left, s2.left);
    assert_eq!(s1.right, s2.right);
    let noisy = SceneParams { noise: 100.0, ..small() };
    assert_eq!(render(&noisy).left, render(&noisy).left);
    let other = render(&SceneParams { seed: 7, ..small() });
    assert_ne!(s1.left, other.left);
    assert_eq!(s1.gt_left, other.gt_left);
}

#[test]
fn noise_has_the_requested_std() {
    let clean = render(&small());
    let noisy = render(&SceneParams { noise: 200.0, ..small() });
    let diff = clean.left.as_slice().iter().zip(noisy.left.as_slice()).map(|(&a, &b)| b as f64 - a as f64);
    let s = std_dev(diff);
    assert!((s - 200.0).abs() < 10.0, "{s}");
}

#[test]
fn texture_has_no_flat_areas_and_uses_the_range() {
    let scene = render(&SceneParams::default());
    for image in [&scene.left, &scene.right] {
        let (w, h) = image.size();
        let mut lowest = f64::INFINITY;
        for y in 2..h - 2 {
            for x in 2..w - 2 {
                let window =
                    (y - 2..=y + 2).flat_map(|j| (x - 2..=x + 2).map(move |i| image.get(i, j) as f64));
                lowest = lowest.min(std_dev(window));
            }
        }
        assert!(lowest > 1000.0, "flattest 5x5 window has std {lowest}");
        let mut sorted = image.as_slice().to_vec();
        sorted.sort_unstable();
        let (p1, p99) = (sorted[sorted.len() / 100], sorted[sorted.len() * 99 / 100]);
        assert!(p1 < 12_000 && p99 > 53_000, "1st percentile {p1}, 99th {p99}");
    }
}

#[test]
fn to_u8_rounds() {
    let image = GrayImage::from_vec(4, 1, vec![0, 128, 129, 65535]).unwrap();
    assert_eq!(to_u8(&image).as_slice(), &[0, 0, 1, 255]);
}
