//! The pinhole camera of 2D tracks, with the polynomial radial distortion of a tracking
//! camera (libmv's polynomial model, radial terms only):
//! `x_n = X_c / -Z_c`, `y_n = Y_c / -Z_c` (the camera looks down its -Z axis, +Y up),
//! `r^2 = x_n^2 + y_n^2`, `(x_d, y_d) = (1 + k1 r^2 + k2 r^4 + k3 r^6) (x_n, y_n)`,
//! `u = f_x x_d + c_x`, `v = f_y y_d + c_y` in pixels from the image's bottom-left corner.

use crate::geometry::mat3::{add, mat_vec, Mat3, Vec3};
use crate::invalid;
use crate::error::ShapesmithResult;

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Focal lengths in pixels, `(f, f * pixel aspect)`.
    pub focal: [f64; 2],
    /// Principal point in pixels from the bottom-left corner.
    pub principal: [f64; 2],
    /// Radial distortion `k1, k2, k3`.
    pub distortion: [f64; 3],
    /// World to camera: `X_c = rotation x + translation`.
    pub rotation: Mat3,
    pub translation: Vec3,
}

/// A point closer to the camera plane than this (in the camera's units, relative to its
/// distance) counts as behind the camera: its projection is undefined.
const MIN_DEPTH: f64 = 1e-9;

impl Camera {
    pub fn validate(&self) -> ShapesmithResult<()> {
        let values = self.focal.iter().chain(&self.principal).chain(&self.distortion).chain(self.rotation.iter().flatten()).chain(&self.translation);
        if values.clone().any(|v| !v.is_finite()) {
            return Err(invalid!("the camera has a non-finite focal length, principal point, distortion or pose"));
        }
        if !(self.focal[0] > 0.0 && self.focal[1] > 0.0) {
            return Err(invalid!("the camera's focal length must be positive, got {:?} pixels", self.focal));
        }
        Ok(())
    }

    /// The pixel of world point `x` and its Jacobian `d(u, v) / dx` (2 x 3); `None` when the
    /// point is not in front of the camera.
    pub fn project(&self, x: Vec3) -> Option<([f64; 2], [[f64; 3]; 2])> {
        let p = add(mat_vec(&self.rotation, x), self.translation);
        let depth = -p[2];
        if !(depth > MIN_DEPTH * (p[0].abs() + p[1].abs() + depth.abs()).max(1e-300)) {
            return None;
        }
        let (xn, yn) = (p[0] / depth, p[1] / depth);
        let r2 = xn * xn + yn * yn;
        let [k1, k2, k3] = self.distortion;
        let factor = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
        let slope = k1 + r2 * (2.0 * k2 + 3.0 * r2 * k3);
        let pixel = [self.focal[0] * xn * factor + self.principal[0], self.focal[1] * yn * factor + self.principal[1]];
        // d(x_d, y_d) / d(x_n, y_n), then d(x_n, y_n) / dp, then dp / dx = rotation.
        let distort = [[factor + 2.0 * xn * xn * slope, 2.0 * xn * yn * slope], [2.0 * xn * yn * slope, factor + 2.0 * yn * yn * slope]];
        let normalise = [[1.0 / depth, 0.0, xn / depth], [0.0, 1.0 / depth, yn / depth]];
        let mut jacobian = [[0.0; 3]; 2];
        for r in 0..2 {
            let d_normal: [f64; 3] = std::array::from_fn(|c| distort[r][0] * normalise[0][c] + distort[r][1] * normalise[1][c]);
            for c in 0..3 {
                jacobian[r][c] = self.focal[r] * (0..3).map(|m| d_normal[m] * self.rotation[m][c]).sum::<f64>();
            }
        }
        Some((pixel, jacobian))
    }

    /// The undistorted normalised coordinates `(x_n, y_n)` of a pixel (fixed-point inversion
    /// of the radial polynomial; exact enough for a first guess of the pose).
    pub fn normalised(&self, pixel: [f64; 2]) -> [f64; 2] {
        let xd = (pixel[0] - self.principal[0]) / self.focal[0];
        let yd = (pixel[1] - self.principal[1]) / self.focal[1];
        let [k1, k2, k3] = self.distortion;
        let (mut x, mut y) = (xd, yd);
        for _ in 0..20 {
            let r2 = x * x + y * y;
            let factor = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
            if !(factor > 0.0) {
                break;
            }
            (x, y) = (xd / factor, yd / factor);
        }
        [x, y]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::performance::pose::rotation_from_vector;

    fn camera() -> Camera {
        Camera {
            focal: [1200.0, 1260.0],
            principal: [960.0, 540.0],
            distortion: [-0.12, 0.03, 0.004],
            rotation: rotation_from_vector([0.1, 0.2, -0.05]),
            translation: [0.02, -0.1, -1.5],
        }
    }

    #[test]
    fn projects_by_the_polynomial_model() {
        let identity = Camera { rotation: crate::geometry::mat3::IDENTITY, translation: [0.0; 3], ..camera() };
        // On the optical axis: the principal point.
        let (pixel, _) = identity.project([0.0, 0.0, -2.0]).unwrap();
        assert!((pixel[0] - 960.0).abs() < 1e-9 && (pixel[1] - 540.0).abs() < 1e-9);
        // x_n = 0.2, y_n = -0.1: r^2 = 0.05.
        let (pixel, _) = identity.project([0.4, -0.2, -2.0]).unwrap();
        let factor = 1.0 - 0.12 * 0.05 + 0.03 * 0.0025 + 0.004 * 0.000125;
        assert!((pixel[0] - (960.0 + 1200.0 * 0.2 * factor)).abs() < 1e-9);
        assert!((pixel[1] - (540.0 - 1260.0 * 0.1 * factor)).abs() < 1e-9);
        // Behind the camera: nothing.
        assert!(identity.project([0.0, 0.0, 1.0]).is_none());
        // The inverse finds the normalised point back.
        let back = identity.normalised(pixel);
        assert!((back[0] - 0.2).abs() < 1e-9 && (back[1] + 0.1).abs() < 1e-9, "{back:?}");
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let camera = camera();
        let x = [0.1, 0.05, 0.2];
        let (_, jacobian) = camera.project(x).unwrap();
        let h = 1e-6;
        for c in 0..3 {
            let mut plus = x;
            plus[c] += h;
            let mut minus = x;
            minus[c] -= h;
            let (a, _) = camera.project(plus).unwrap();
            let (b, _) = camera.project(minus).unwrap();
            for r in 0..2 {
                let numeric = (a[r] - b[r]) / (2.0 * h);
                assert!((numeric - jacobian[r][c]).abs() < 1e-4 * (1.0 + numeric.abs()), "{r} {c}: {numeric} vs {}", jacobian[r][c]);
            }
        }
    }
}
