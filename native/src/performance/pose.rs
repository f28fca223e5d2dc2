//! The head's rigid pose `x = s R X + t` (X in the rig's own space), its update by a
//! rotation vector, and its first guess from point pairs (weighted Umeyama 1991, shared with
//! the wrap in `geometry::similarity`).

use faer::Mat;
use serde::Serialize;

use crate::geometry::mat3::{add, cross, dot, mat_mul, mat_vec, scale, sub, Mat3, Vec3, IDENTITY};
use crate::geometry::similarity::fit_similarity;

#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Pose {
    /// Proper rotation, row-major.
    pub rotation: Mat3,
    pub translation: Vec3,
    /// Uniform scale; 1 unless [`super::PerformanceParams::solve_scale`].
    pub scale: f64,
}

impl Default for Pose {
    fn default() -> Self {
        Self { rotation: IDENTITY, translation: [0.0; 3], scale: 1.0 }
    }
}

impl Pose {
    pub fn apply(&self, p: Vec3) -> Vec3 {
        add(scale(mat_vec(&self.rotation, p), self.scale), self.translation)
    }

    /// The pose after the step: rotation `exp([theta]_x) R` (a left perturbation, so the
    /// Jacobian of `x` in `theta` is `-[s R X]_x`), translation `t + dt`, scale `s e^ds`.
    pub fn stepped(&self, theta: Vec3, dt: Vec3, log_scale: f64) -> Pose {
        Pose {
            rotation: orthonormalised(&mat_mul(&rotation_from_vector(theta), &self.rotation)),
            translation: add(self.translation, dt),
            scale: self.scale * log_scale.exp(),
        }
    }

    /// The rotation as a unit quaternion `(w, x, y, z)` with `w >= 0` (Shepperd's method).
    pub fn quaternion(&self) -> [f64; 4] {
        let m = &self.rotation;
        let trace = m[0][0] + m[1][1] + m[2][2];
        let q = if trace > 0.0 {
            let s = 2.0 * (1.0 + trace).sqrt();
            [0.25 * s, (m[2][1] - m[1][2]) / s, (m[0][2] - m[2][0]) / s, (m[1][0] - m[0][1]) / s]
        } else if m[0][0] > m[1][1] && m[0][0] > m[2][2] {
            let s = 2.0 * (1.0 + m[0][0] - m[1][1] - m[2][2]).sqrt();
            [(m[2][1] - m[1][2]) / s, 0.25 * s, (m[0][1] + m[1][0]) / s, (m[0][2] + m[2][0]) / s]
        } else if m[1][1] > m[2][2] {
            let s = 2.0 * (1.0 + m[1][1] - m[0][0] - m[2][2]).sqrt();
            [(m[0][2] - m[2][0]) / s, (m[0][1] + m[1][0]) / s, 0.25 * s, (m[1][2] + m[2][1]) / s]
        } else {
            let s = 2.0 * (1.0 + m[2][2] - m[0][0] - m[1][1]).sqrt();
            [(m[1][0] - m[0][1]) / s, (m[0][2] + m[2][0]) / s, (m[1][2] + m[2][1]) / s, 0.25 * s]
        };
        let sign = if q[0] < 0.0 { -1.0 } else { 1.0 };
        let n = (q.iter().map(|c| c * c).sum::<f64>()).sqrt();
        q.map(|c| sign * c / n)
    }
}

/// Rodrigues' formula: the rotation by `|v|` about `v / |v|`.
pub fn rotation_from_vector(v: Vec3) -> Mat3 {
    let angle = dot(v, v).sqrt();
    if angle < 1e-12 {
        // First order: I + [v]_x.
        return [[1.0, -v[2], v[1]], [v[2], 1.0, -v[0]], [-v[1], v[0], 1.0]];
    }
    let a = scale(v, 1.0 / angle);
    let (s, c) = angle.sin_cos();
    let t = 1.0 - c;
    [
        [c + t * a[0] * a[0], t * a[0] * a[1] - s * a[2], t * a[0] * a[2] + s * a[1]],
        [t * a[1] * a[0] + s * a[2], c + t * a[1] * a[1], t * a[1] * a[2] - s * a[0]],
        [t * a[2] * a[0] - s * a[1], t * a[2] * a[1] + s * a[0], c + t * a[2] * a[2]],
    ]
}

/// Gram-Schmidt on the rows, so that rounding never accumulates over a long take.
fn orthonormalised(m: &Mat3) -> Mat3 {
    let unit = |v: Vec3| scale(v, 1.0 / dot(v, v).sqrt());
    let x = unit(m[0]);
    let y = unit(sub(m[1], scale(x, dot(x, m[1]))));
    [x, y, cross(x, y)]
}

/// The pose minimising `sum_i a_i |s R p_i + t - q_i|^2` (weighted Umeyama,
/// [`fit_similarity`]), `s` fixed at 1 unless `with_scale`. `None` when the weighted points
/// span less than a plane (the rotation about their line is then free).
pub fn fit_pose(source: &[Vec3], target: &[Vec3], weights: &[f64], with_scale: bool) -> Option<Pose> {
    let total: f64 = weights.iter().sum();
    if source.len() < 3 || total <= 0.0 {
        return None;
    }
    let mu_p = scale(source.iter().zip(weights).fold([0.0; 3], |acc, (p, a)| add(acc, scale(*p, *a))), 1.0 / total);
    let mut spread = [[0.0; 3]; 3];
    for (p, a) in source.iter().zip(weights) {
        let dp = sub(*p, mu_p);
        for r in 0..3 {
            for c in 0..3 {
                spread[r][c] += a * dp[r] * dp[c];
            }
        }
    }
    let spread_values = Mat::<f64>::from_fn(3, 3, |r, c| spread[r][c]).singular_values().ok()?;
    if !(spread_values[1] > 1e-12 * spread_values[0].max(f64::MIN_POSITIVE)) {
        return None;
    }
    let fitted = fit_similarity(source, target, weights, with_scale)?;
    Some(Pose { rotation: fitted.rotation, translation: fitted.translation, scale: fitted.scale })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fit_pose_recovers_a_known_pose_and_quaternion_matches_the_rotation() {
        let rotation = rotation_from_vector([0.3, -0.5, 0.8]);
        let truth = Pose { rotation, translation: [0.1, -2.0, 0.5], scale: 1.3 };
        let source: Vec<Vec3> = (0..6).map(|i| [(i as f64).sin(), (2.0 * i as f64).cos(), 0.3 * i as f64]).collect();
        let target: Vec<Vec3> = source.iter().map(|p| truth.apply(*p)).collect();
        let fitted = fit_pose(&source, &target, &[1.0; 6], true).unwrap();
        for r in 0..3 {
            for c in 0..3 {
                assert!((fitted.rotation[r][c] - rotation[r][c]).abs() < 1e-10);
            }
            assert!((fitted.translation[r] - truth.translation[r]).abs() < 1e-10);
        }
        assert!((fitted.scale - 1.3).abs() < 1e-10);
        // Without scale the rotation is still exact (the points are scaled about their centre).
        let rigid = fit_pose(&source, &target, &[1.0; 6], false).unwrap();
        assert!((rigid.rotation[0][1] - rotation[0][1]).abs() < 1e-10 && rigid.scale == 1.0);
        // q = (cos a/2, sin a/2 * axis) with a = |v|.
        let v = [0.3, -0.5, 0.8];
        let angle = dot(v, v).sqrt();
        let q = truth.quaternion();
        assert!((q[0] - (angle / 2.0).cos()).abs() < 1e-12);
        for a in 0..3 {
            assert!((q[a + 1] - (angle / 2.0).sin() * v[a] / angle).abs() < 1e-12);
        }
        // Collinear points fix no rotation.
        let line: Vec<Vec3> = (0..4).map(|i| [i as f64, 0.0, 0.0]).collect();
        assert!(fit_pose(&line, &line, &[1.0; 4], false).is_none());
    }
}
