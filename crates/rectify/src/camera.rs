//! The camera model the calibration files describe and rectification uses: intrinsics, the
//! plumb-bob / rational and equidistant (fisheye) distortion, and rotation vectors.

use nalgebra::{Matrix3, Vector3};

/// A lens model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LensModel {
    /// Plumb bob / radial-tangential, and the rational model: `k1 k2 p1 p2 k3 k4 k5 k6`.
    PlumbBob,
    /// Equidistant (OpenCV's `fisheye`, ROS `equidistant`): `θd = θ(1 + k1θ² + k2θ⁴ + k3θ⁶ +
    /// k4θ⁸)`, the coefficients in `dist[0..4]`.
    Equidistant,
}

/// One camera: intrinsics and distortion.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// `[fx s cx; 0 fy cy; 0 0 1]` (the skew `s` is ignored, as OpenCV's undistortion does).
    pub k: Matrix3<f64>,
    /// `k1 k2 p1 p2 k3 k4 k5 k6` (missing ones are 0), or `k1 k2 k3 k4` of the equidistant model.
    pub dist: [f64; 8],
    /// Whether any coefficient was given (OpenCV skips the iterative undistortion without).
    pub has_dist: bool,
    pub model: LensModel,
}

impl Camera {
    /// A plumb-bob camera from its matrix and 0, 4, 5 or 8 distortion coefficients.
    pub fn new(k: Matrix3<f64>, coefficients: Vec<f64>) -> Self {
        let mut dist = [0.0; 8];
        for (d, c) in dist.iter_mut().zip(&coefficients) {
            *d = *c;
        }
        Camera { k, dist, has_dist: !coefficients.is_empty(), model: LensModel::PlumbBob }
    }

    /// An equidistant (fisheye) camera from its matrix and 4 coefficients `k1 k2 k3 k4`.
    pub fn equidistant(k: Matrix3<f64>, coefficients: [f64; 4]) -> Self {
        let mut dist = [0.0; 8];
        dist[..4].copy_from_slice(&coefficients);
        Camera { k, dist, has_dist: true, model: LensModel::Equidistant }
    }

    pub(crate) fn fx(&self) -> f64 {
        self.k[(0, 0)]
    }
    pub(crate) fn fy(&self) -> f64 {
        self.k[(1, 1)]
    }
    pub(crate) fn cx(&self) -> f64 {
        self.k[(0, 2)]
    }
    pub(crate) fn cy(&self) -> f64 {
        self.k[(1, 2)]
    }

    /// Applies the distortion to a normalised point.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        if self.model == LensModel::Equidistant {
            let [k1, k2, k3, k4, ..] = self.dist;
            let r = (x * x + y * y).sqrt();
            let theta = r.atan();
            let (t2, t4, t6, t8) = {
                let t2 = theta * theta;
                (t2, t2 * t2, t2 * t2 * t2, t2 * t2 * t2 * t2)
            };
            let theta_d = theta * (1.0 + k1 * t2 + k2 * t4 + k3 * t6 + k4 * t8);
            let scale = if r == 0.0 { 1.0 } else { theta_d / r };
            return (x * scale, y * scale);
        }
        let [k1, k2, p1, p2, k3, k4, k5, k6] = self.dist;
        let (x2, y2) = (x * x, y * y);
        let r2 = x2 + y2;
        let xy2 = 2.0 * x * y;
        let kr = (1.0 + ((k3 * r2 + k2) * r2 + k1) * r2) / (1.0 + ((k6 * r2 + k5) * r2 + k4) * r2);
        (x * kr + p1 * xy2 + p2 * (r2 + 2.0 * x2), y * kr + p1 * (r2 + 2.0 * y2) + p2 * xy2)
    }

    /// The normalised undistorted point of pixel `(u, v)`: OpenCV's fixed-point iteration
    /// (5 steps, as `undistortPoints` by default).
    pub fn undistort_normalized(&self, u: f64, v: f64) -> (f64, f64) {
        // OpenCV multiplies by the reciprocals.
        let (x0, y0) = ((u - self.cx()) * (1.0 / self.fx()), (v - self.cy()) * (1.0 / self.fy()));
        if !self.has_dist {
            return (x0, y0);
        }
        if self.model == LensModel::Equidistant {
            // Newton on θ (as cv::fisheye::undistortPoints).
            let [k1, k2, k3, k4, ..] = self.dist;
            let theta_d =
                (x0 * x0 + y0 * y0).sqrt().clamp(-std::f64::consts::FRAC_PI_2, std::f64::consts::FRAC_PI_2);
            if theta_d <= 1e-8 {
                return (x0, y0);
            }
            let mut theta = theta_d;
            for _ in 0..10 {
                let t2 = theta * theta;
                let (t4, t6, t8) = (t2 * t2, t2 * t2 * t2, t2 * t2 * t2 * t2);
                let f = theta * (1.0 + k1 * t2 + k2 * t4 + k3 * t6 + k4 * t8) - theta_d;
                let df = 1.0 + 3.0 * k1 * t2 + 5.0 * k2 * t4 + 7.0 * k3 * t6 + 9.0 * k4 * t8;
                let step = f / df;
                theta -= step;
                if step.abs() < 1e-10 {
                    break;
                }
            }
            let scale = theta.tan() / theta_d;
            return (x0 * scale, y0 * scale);
        }
        let [k1, k2, p1, p2, k3, k4, k5, k6] = self.dist;
        let (mut x, mut y) = (x0, y0);
        for _ in 0..5 {
            let r2 = x * x + y * y;
            let icdist = (1.0 + ((k6 * r2 + k5) * r2 + k4) * r2) / (1.0 + ((k3 * r2 + k2) * r2 + k1) * r2);
            if icdist < 0.0 {
                return (x0, y0);
            }
            let dx = 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x);
            let dy = p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y;
            x = (x0 - dx) * icdist;
            y = (y0 - dy) * icdist;
        }
        (x, y)
    }

    /// `undistortPoints(pt, K, D, R, P)`: the undistorted point, rotated by `r` and projected
    /// with `p` (`p = P[:, :3]`).
    pub fn undistort_point(&self, u: f64, v: f64, rr: &Matrix3<f64>) -> (f64, f64) {
        let (x, y) = self.undistort_normalized(u, v);
        let xx = rr[(0, 0)] * x + rr[(0, 1)] * y + rr[(0, 2)];
        let yy = rr[(1, 0)] * x + rr[(1, 1)] * y + rr[(1, 2)];
        let ww = 1.0 / (rr[(2, 0)] * x + rr[(2, 1)] * y + rr[(2, 2)]);
        (xx * ww, yy * ww)
    }
}

/// Rotation vector → matrix.
pub fn rodrigues(r: &Vector3<f64>) -> Matrix3<f64> {
    let theta = r.norm();
    if theta < f64::EPSILON {
        return Matrix3::identity();
    }
    let (c, s) = (theta.cos(), theta.sin());
    let n = r / theta;
    let rrt = n * n.transpose();
    let rx = Matrix3::new(0.0, -n.z, n.y, n.z, 0.0, -n.x, -n.y, n.x, 0.0);
    Matrix3::identity() * c + rrt * (1.0 - c) + rx * s
}

/// Rotation matrix → vector (the matrix is first made orthonormal, as OpenCV does).
pub fn rotation_vector(m: &Matrix3<f64>) -> Vector3<f64> {
    let svd = m.svd(true, true);
    let r = svd.u.unwrap() * svd.v_t.unwrap();
    let v = Vector3::new(r[(2, 1)] - r[(1, 2)], r[(0, 2)] - r[(2, 0)], r[(1, 0)] - r[(0, 1)]);
    let s = (v.norm_squared() * 0.25).sqrt();
    let c = ((r.trace() - 1.0) * 0.5).clamp(-1.0, 1.0);
    let theta = c.acos();
    if s < 1e-5 {
        if c > 0.0 {
            return Vector3::zeros();
        }
        let mut v = Vector3::new(
            ((r[(0, 0)] + 1.0) * 0.5).max(0.0).sqrt(),
            ((r[(1, 1)] + 1.0) * 0.5).max(0.0).sqrt() * if r[(0, 1)] < 0.0 { -1.0 } else { 1.0 },
            ((r[(2, 2)] + 1.0) * 0.5).max(0.0).sqrt() * if r[(0, 2)] < 0.0 { -1.0 } else { 1.0 },
        );
        if v.x.abs() < v.y.abs() && v.x.abs() < v.z.abs() && (r[(1, 2)] > 0.0) != (v.y * v.z > 0.0) {
            v.z = -v.z;
        }
        let n = v.norm();
        return v * (theta / n);
    }
    v * (theta / (2.0 * s))
}
