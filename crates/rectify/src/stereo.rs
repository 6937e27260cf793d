//! Calibrated rectification: the Bouguet construction of OpenCV's `stereoRectify`
//! (`CALIB_ZERO_DISPARITY`, free scaling `alpha`), the plumb-bob / rational distortion model of
//! `undistortPoints` and `initUndistortRectifyMap`, and the maps that take a raw pair to a
//! rectified one ([`Rectifier`]).
//!
//! The numbers follow OpenCV's (5.x) so that results can be compared with it, including the
//! single-precision rounding of the corner points that decides the principal points.

use nalgebra::{Matrix3, Matrix3x4, Matrix4, Vector3};
use rayon::prelude::*;

use crate::calib_file::StereoCalibration;
use crate::camera::{rodrigues, rotation_vector, Camera, LensModel};
use crate::remap::RectifyMap;

/// The inscribed and bounding rectangles `(x, y, w, h)` of the undistorted, rectified image
/// (OpenCV's `getUndistortRectangles`, a 9×9 grid of points).
fn undistort_rectangles(
    camera: &Camera,
    r: &Matrix3<f64>,
    p: &Matrix3x4<f64>,
    size: (usize, usize),
) -> ([f64; 4], [f64; 4]) {
    const N: usize = 9;
    let rr = p.fixed_view::<3, 3>(0, 0) * r;
    let (mut ix0, mut ix1, mut iy0, mut iy1) =
        (-f64::from(f32::MAX), f64::from(f32::MAX), -f64::from(f32::MAX), f64::from(f32::MAX));
    let (mut ox0, mut ox1, mut oy0, mut oy1) =
        (f64::from(f32::MAX), -f64::from(f32::MAX), f64::from(f32::MAX), -f64::from(f32::MAX));
    for y in 0..N {
        for x in 0..N {
            let u = x as f64 * (size.0 as f64 - 1.0) / (N - 1) as f64;
            let v = y as f64 * (size.1 as f64 - 1.0) / (N - 1) as f64;
            let (px, py) = camera.undistort_point(u, v, &rr);
            ox0 = ox0.min(px);
            ox1 = ox1.max(px);
            oy0 = oy0.min(py);
            oy1 = oy1.max(py);
            if x == 0 {
                ix0 = ix0.max(px);
            }
            if x == N - 1 {
                ix1 = ix1.min(px);
            }
            if y == 0 {
                iy0 = iy0.max(py);
            }
            if y == N - 1 {
                iy1 = iy1.min(py);
            }
        }
    }
    ([ix0, iy0, ix1 - ix0, iy1 - iy0], [ox0, oy0, ox1 - ox0, oy1 - oy0])
}

/// What `cv::stereoRectify` returns.
#[derive(Clone, Debug, PartialEq)]
pub struct StereoRectification {
    pub r1: Matrix3<f64>,
    pub r2: Matrix3<f64>,
    pub p1: Matrix3x4<f64>,
    pub p2: Matrix3x4<f64>,
    pub q: Matrix4<f64>,
    /// Whether the cameras sit side by side (`false`: one above the other).
    pub horizontal: bool,
}

/// `cv::stereoRectify(K1, D1, K2, D2, size, R, T, flags = CALIB_ZERO_DISPARITY, alpha)`.
/// `alpha` in `[0, 1]` (0: only valid pixels, 1: every source pixel kept); `None` is OpenCV's
/// `-1` (no scaling).
pub fn stereo_rectify(
    left: &Camera,
    right: &Camera,
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    size: (usize, usize),
    alpha: Option<f64>,
) -> StereoRectification {
    let (nx, ny) = (size.0 as f64, size.1 as f64);
    let om = rotation_vector(r) * -0.5;
    let r_r = rodrigues(&om);
    let tt = r_r * t;
    let idx = if tt.x.abs() > tt.y.abs() { 0 } else { 1 };
    let c = tt[idx];
    let nt = tt.norm();
    let mut uu = Vector3::zeros();
    uu[idx] = if c > 0.0 { 1.0 } else { -1.0 };
    let mut ww = tt.cross(&uu);
    let nw = ww.norm();
    if nw > 0.0 {
        ww *= (c.abs() / nt).acos() / nw;
    }
    let wr = rodrigues(&ww);
    let r1 = wr * r_r.transpose();
    let r2 = wr * r_r;
    let t2 = r2 * t;

    let other = idx ^ 1;
    let mut fc_new = (left.k[(other, other)] + right.k[(other, other)]) * 0.5;
    let mut cc = [(0.0, 0.0); 2];
    for (k, (camera, rk)) in [(left, &r1), (right, &r2)].into_iter().enumerate() {
        let mut sum = (0.0, 0.0);
        for i in 0..4 {
            let u = ((i % 2) as f64 * (nx - 1.0)) as f32 as f64;
            let v = ((i / 2) as f64 * (ny - 1.0)) as f32 as f64;
            // undistortPoints into single-precision points, made homogeneous, then projected
            // (projectPoints) into single-precision points again.
            let (x, y) = camera.undistort_normalized(u, v);
            let p = Vector3::new(x as f32 as f64, y as f32 as f64, 1.0);
            let q = rk * p;
            let z = 1.0 / q.z;
            sum.0 += (fc_new * q.x * z) as f32 as f64;
            sum.1 += (fc_new * q.y * z) as f32 as f64;
        }
        cc[k] = ((nx - 1.0) / 2.0 - sum.0 / 4.0, (ny - 1.0) / 2.0 - sum.1 / 4.0);
    }
    // CALIB_ZERO_DISPARITY: one principal point for both views.
    let mean = ((cc[0].0 + cc[1].0) * 0.5, (cc[0].1 + cc[1].1) * 0.5);
    cc = [mean, mean];
    let t_idx = t2[idx];

    let projection = |fc: f64, (cx, cy): (f64, f64), tx: f64| {
        let mut p = Matrix3x4::zeros();
        p[(0, 0)] = fc;
        p[(1, 1)] = fc;
        p[(0, 2)] = cx;
        p[(1, 2)] = cy;
        p[(2, 2)] = 1.0;
        p[(idx, 3)] = tx;
        p
    };
    let mut p1 = projection(fc_new, cc[0], 0.0);
    let mut p2 = projection(fc_new, cc[1], t_idx * fc_new);

    let (inner1, outer1) = undistort_rectangles(left, &r1, &p1, size);
    let (inner2, outer2) = undistort_rectangles(right, &r2, &p2, size);
    let mut s = 1.0;
    if let Some(alpha) = alpha {
        let alpha = alpha.min(1.0);
        let scales = |(cx, cy): (f64, f64), rect: [f64; 4]| {
            [
                cx / (cx - rect[0]),
                cy / (cy - rect[1]),
                (nx - 1.0 - cx) / (rect[0] + rect[2] - cx),
                (ny - 1.0 - cy) / (rect[1] + rect[3] - cy),
            ]
        };
        let s0 = scales(cc[0], inner1).into_iter().chain(scales(cc[1], inner2)).fold(f64::MIN, f64::max);
        let s1 = scales(cc[0], outer1).into_iter().chain(scales(cc[1], outer2)).fold(f64::MAX, f64::min);
        s = s0 * (1.0 - alpha) + s1 * alpha;
    }
    fc_new *= s;
    p1 = projection(fc_new, cc[0], 0.0);
    p2 = projection(fc_new, cc[1], p2[(idx, 3)] * s);
    let d = if idx == 0 { cc[0].0 - cc[1].0 } else { cc[0].1 - cc[1].1 };
    #[rustfmt::skip]
    let q = Matrix4::new(
        1.0, 0.0, 0.0, -cc[0].0,
        0.0, 1.0, 0.0, -cc[0].1,
        0.0, 0.0, 0.0, fc_new,
        0.0, 0.0, -1.0 / t_idx, d / t_idx,
    );
    StereoRectification { r1, r2, p1, p2, q, horizontal: idx == 0 }
}

/// `cv::fisheye::estimateNewCameraMatrixForUndistortRectify(K, D, size, R, balance)`: the
/// camera matrix that fits the undistorted, rotated image (`balance` 0: the narrower of the
/// fits, 1: the wider).
fn fisheye_new_camera_matrix(
    camera: &Camera,
    r: &Matrix3<f64>,
    size: (usize, usize),
    balance: f64,
) -> Matrix3<f64> {
    let (w, h) = (size.0 as f64, size.1 as f64);
    let balance = balance.clamp(0.0, 1.0);
    // OpenCV takes w/2 and h/2 in integers.
    let (hw, hh) = ((size.0 / 2) as f64, (size.1 / 2) as f64);
    let mut points: Vec<(f64, f64)> = [(hw, 0.0), (w, hh), (hw, h), (0.0, hh)]
        .iter()
        .map(|&(u, v)| camera.undistort_point(u, v, r))
        .collect();
    let aspect = camera.fx() / camera.fy();
    let mut cn = points.iter().fold((0.0, 0.0), |a, p| (a.0 + p.0, a.1 + p.1));
    cn = (cn.0 / 4.0, cn.1 / 4.0 * aspect);
    for p in &mut points {
        p.1 *= aspect;
    }
    let (minx, maxx) = points.iter().fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.0), a.1.max(p.0)));
    let (miny, maxy) = points.iter().fold((f64::MAX, f64::MIN), |a, p| (a.0.min(p.1), a.1.max(p.1)));
    let f = [
        w * 0.5 / (cn.0 - minx),
        w * 0.5 / (maxx - cn.0),
        h * 0.5 * aspect / (cn.1 - miny),
        h * 0.5 * aspect / (maxy - cn.1),
    ];
    let fmin = f.iter().copied().fold(f64::MAX, f64::min);
    let fmax = f.iter().copied().fold(f64::MIN, f64::max);
    let f = balance * fmin + (1.0 - balance) * fmax;
    let (cx, cy) = (-cn.0 * f + w * 0.5, (-cn.1 * f + h * aspect * 0.5) / aspect);
    Matrix3::new(f, 0.0, cx, 0.0, f / aspect, cy, 0.0, 0.0, 1.0)
}

/// `cv::fisheye::stereoRectify(K1, D1, K2, D2, size, R, T, CALIB_ZERO_DISPARITY, balance)` for
/// equidistant cameras (horizontal rigs).
pub fn fisheye_stereo_rectify(
    left: &Camera,
    right: &Camera,
    r: &Matrix3<f64>,
    t: &Vector3<f64>,
    size: (usize, usize),
    balance: f64,
) -> StereoRectification {
    let r_r = rodrigues(&(rotation_vector(r) * -0.5));
    let tt = r_r * t;
    let uu = Vector3::new(if tt.x > 0.0 { 1.0 } else { -1.0 }, 0.0, 0.0);
    let mut ww = tt.cross(&uu);
    let nw = ww.norm();
    if nw > 0.0 {
        ww *= (tt.x.abs() / tt.norm()).acos() / nw;
    }
    let wr = rodrigues(&ww);
    let r1 = wr * r_r.transpose();
    let r2 = wr * r_r;
    let tnew = r2 * t;
    let k1 = fisheye_new_camera_matrix(left, &r1, size, balance);
    let k2 = fisheye_new_camera_matrix(right, &r2, size, balance);
    let fc = k1[(1, 1)].min(k2[(1, 1)]);
    let cc = ((k1[(0, 2)] + k2[(0, 2)]) * 0.5, (k1[(1, 2)] + k2[(1, 2)]) * 0.5);
    let mut p1 = Matrix3x4::zeros();
    p1[(0, 0)] = fc;
    p1[(1, 1)] = fc;
    p1[(0, 2)] = cc.0;
    p1[(1, 2)] = cc.1;
    p1[(2, 2)] = 1.0;
    let mut p2 = p1;
    p2[(0, 3)] = tnew.x * fc;
    #[rustfmt::skip]
    let q = Matrix4::new(
        1.0, 0.0, 0.0, -cc.0,
        0.0, 1.0, 0.0, -cc.1,
        0.0, 0.0, 0.0, fc,
        0.0, 0.0, -1.0 / tnew.x, 0.0,
    );
    StereoRectification { r1, r2, p1, p2, q, horizontal: tnew.x.abs() >= tnew.y.abs() }
}

/// `cv::initUndistortRectifyMap(K, D, R, P, size, CV_32FC1)`: for every rectified pixel, where
/// to sample the raw image.
pub fn undistort_rectify_map(
    camera: &Camera,
    r: &Matrix3<f64>,
    p: &Matrix3x4<f64>,
    size: (usize, usize),
) -> RectifyMap {
    let (w, h) = size;
    let m = p.fixed_view::<3, 3>(0, 0) * r;
    let ir = m.try_inverse().unwrap_or_else(Matrix3::identity);
    let (fx, fy, u0, v0) = (camera.fx(), camera.fy(), camera.cx(), camera.cy());
    let mut map_x = vec![0f32; w * h];
    let mut map_y = vec![0f32; w * h];
    map_x.par_chunks_mut(w.max(1)).zip(map_y.par_chunks_mut(w.max(1))).enumerate().for_each(
        |(i, (row_x, row_y))| {
            let i = i as f64;
            let (bx, by, bw) =
                (i * ir[(0, 1)] + ir[(0, 2)], i * ir[(1, 1)] + ir[(1, 2)], i * ir[(2, 1)] + ir[(2, 2)]);
            for j in 0..w {
                let jf = j as f64;
                let (xh, yh, wh) = (bx + jf * ir[(0, 0)], by + jf * ir[(1, 0)], bw + jf * ir[(2, 0)]);
                if camera.model == LensModel::Equidistant && wh <= 0.0 {
                    // Behind the camera: nothing to sample.
                    row_x[j] = -f32::MAX;
                    row_y[j] = -f32::MAX;
                    continue;
                }
                let iw = 1.0 / wh;
                let (xd, yd) = camera.distort(xh * iw, yh * iw);
                row_x[j] = (fx * xd + u0) as f32;
                row_y[j] = (fy * yd + v0) as f32;
            }
        },
    );
    RectifyMap::new(w, h, map_x, map_y)
}

/// The rectified rig, as triangulation wants it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RectifiedRig {
    /// Focal length of both rectified views, px.
    pub focal_px: f64,
    /// The left view's principal point, px.
    pub cx: f64,
    pub cy: f64,
    /// `cx_right - cx_left` (0 with `CALIB_ZERO_DISPARITY`).
    pub doffs: f64,
    pub baseline_mm: f64,
}

/// Maps for both views of one calibration at one image size, and the rectified rig: made once,
/// applied to every pair of that size.
#[derive(Clone, Debug)]
pub struct Rectifier {
    pub size: (usize, usize),
    pub left: RectifyMap,
    pub right: RectifyMap,
    pub r1: Matrix3<f64>,
    pub r2: Matrix3<f64>,
    pub p1: Matrix3x4<f64>,
    pub p2: Matrix3x4<f64>,
    pub rig: RectifiedRig,
    /// `true`: computed from `R`/`T` (Bouguet); `false`: the file's own `R1 R2 P1 P2`.
    pub computed: bool,
}

impl Rectifier {
    /// The rectification of `calibration` for images of `size`. `alpha`: see [`stereo_rectify`]
    /// (used when the rectification is computed from `R` and `T`). Errors are messages about the
    /// calibration (the caller names the file).
    pub fn new(calibration: &StereoCalibration, size: (usize, usize), alpha: f64) -> Result<Self, String> {
        if size.0 < 2 || size.1 < 2 {
            return Err(format!("{}x{} images are too small to rectify", size.0, size.1));
        }
        if let Some((w, h)) = calibration.image_size {
            if (w, h) != size {
                return Err(format!(
                    "calibrated for {w}x{h} images, not {}x{}: the camera matrices would not apply",
                    size.0, size.1
                ));
            }
        }
        if !(0.0..=1.0).contains(&alpha) {
            return Err(format!("alpha {alpha} is not in [0, 1]"));
        }
        let (r1, r2, p1, p2, computed) = match (&calibration.extrinsics, &calibration.given) {
            (Some(_), _)
                if [&calibration.left, &calibration.right]
                    .iter()
                    .any(|c| c.model == LensModel::Equidistant) =>
            {
                if calibration.left.model != calibration.right.model {
                    return Err("one equidistant (fisheye) and one plumb-bob camera: not supported".into());
                }
                let (r, t) = calibration.extrinsics.as_ref().expect("matched Some");
                // alpha is fisheye's balance (0: only valid pixels).
                let rect = fisheye_stereo_rectify(&calibration.left, &calibration.right, r, t, size, alpha);
                if !rect.horizontal {
                    return Err(
                        "the cameras are one above the other (|Ty| > |Tx|): vertical rigs are not supported"
                            .into(),
                    );
                }
                (rect.r1, rect.r2, rect.p1, rect.p2, true)
            }
            (Some((r, t)), _) => {
                let rect = stereo_rectify(&calibration.left, &calibration.right, r, t, size, Some(alpha));
                if !rect.horizontal {
                    return Err(
                        "the cameras are one above the other (|Ty| > |Tx|): vertical rigs are not supported"
                            .into(),
                    );
                }
                (rect.r1, rect.r2, rect.p1, rect.p2, true)
            }
            (None, Some(g)) => (g.r1, g.r2, g.p1, g.p2, false),
            (None, None) => return Err("no R and T, nor R1 R2 P1 P2".into()),
        };
        let focal_px = p1[(0, 0)];
        let baseline = -p2[(0, 3)] / p2[(0, 0)];
        if baseline <= 0.0 {
            return Err(
                "the right camera is left of the left one (T[0] > 0 / P2[0][3] > 0): are the cameras swapped?"
                    .into(),
            );
        }
        let rig = RectifiedRig {
            focal_px,
            cx: p1[(0, 2)],
            cy: p1[(1, 2)],
            doffs: p2[(0, 2)] - p1[(0, 2)],
            baseline_mm: baseline * calibration.mm_per_unit,
        };
        let (left, right) = rayon::join(
            || undistort_rectify_map(&calibration.left, &r1, &p1, size),
            || undistort_rectify_map(&calibration.right, &r2, &p2, size),
        );
        Ok(Rectifier { size, left, right, r1, r2, p1, p2, rig, computed })
    }

    /// The rectified rig as a Middlebury `calib.txt` (focal length and principal points in px,
    /// baseline in mm).
    pub fn middlebury_calib(&self) -> String {
        let r = &self.rig;
        let cx2 = r.cx + r.doffs;
        format!(
            "cam0=[{f:.9} 0 {cx:.9}; 0 {f:.9} {cy:.9}; 0 0 1]\ncam1=[{f:.9} 0 {cx2:.9}; 0 {f:.9} {cy:.9}; 0 0 1]\n\
             doffs={d:.9}\nbaseline={b:.9}\nwidth={w}\nheight={h}\n",
            f = r.focal_px,
            cx = r.cx,
            cy = r.cy,
            d = r.doffs,
            b = r.baseline_mm,
            w = self.size.0,
            h = self.size.1
        )
    }

    /// The rectification as an OpenCV `FileStorage` YAML file (`R1 R2 P1 P2`, full precision).
    pub fn opencv_yaml(&self) -> String {
        let mat = |name: &str, rows: usize, cols: usize, data: Vec<f64>| {
            let values: Vec<String> = data.iter().map(|v| format!("{v:.17e}")).collect();
            format!(
                "{name}: !!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ {} ]\n",
                values.join(", ")
            )
        };
        let rows3 =
            |m: &Matrix3<f64>| (0..3).flat_map(|r| (0..3).map(move |c| m[(r, c)])).collect::<Vec<_>>();
        let rows34 =
            |m: &Matrix3x4<f64>| (0..3).flat_map(|r| (0..4).map(move |c| m[(r, c)])).collect::<Vec<_>>();
        format!(
            "%YAML:1.0\n---\nimageSize: [ {}, {} ]\n{}{}{}{}",
            self.size.0,
            self.size.1,
            mat("R1", 3, 3, rows3(&self.r1)),
            mat("R2", 3, 3, rows3(&self.r2)),
            mat("P1", 3, 4, rows34(&self.p1)),
            mat("P2", 3, 4, rows34(&self.p2)),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rodrigues_round_trip() {
        let v = Vector3::new(0.01, -0.02, 0.005);
        let m = rodrigues(&v);
        assert!((rotation_vector(&m) - v).norm() < 1e-12);
        assert!((m * m.transpose() - Matrix3::identity()).norm() < 1e-12);
    }

    #[test]
    fn equidistant_undistort_inverts_distort() {
        let k = Matrix3::new(300.0, 0.0, 320.0, 0.0, 300.0, 240.0, 0.0, 0.0, 1.0);
        let cam = Camera::equidistant(k, [0.05, -0.01, 0.003, -0.0005]);
        for (x, y) in [(0.0, 0.0), (0.4, -0.3), (-1.2, 0.8)] {
            let (xd, yd) = cam.distort(x, y);
            let (ux, uy) = cam.undistort_normalized(300.0 * xd + 320.0, 300.0 * yd + 240.0);
            assert!((ux - x).abs() < 1e-9 && (uy - y).abs() < 1e-9, "{x} {y}: {ux} {uy}");
        }
    }

    #[test]
    fn undistort_inverts_distort() {
        let k = Matrix3::new(500.0, 0.0, 320.0, 0.0, 500.0, 240.0, 0.0, 0.0, 1.0);
        let cam = Camera::new(k, vec![-0.1, 0.02, 0.001, -0.0005, 0.0]);
        let (x, y) = (0.2, -0.15);
        let (xd, yd) = cam.distort(x, y);
        let (u, v) = (500.0 * xd + 320.0, 500.0 * yd + 240.0);
        let (ux, uy) = cam.undistort_normalized(u, v);
        assert!((ux - x).abs() < 1e-4 && (uy - y).abs() < 1e-4, "{ux} {uy}");
    }
}
