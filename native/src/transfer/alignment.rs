//! The rotation that best aligns the source neutral to the target neutral (Kabsch 1976).
//!
//! Deformation transfer copies world-space gradients, so it is equivariant under translation
//! and uniform scale but not under rotation: a target modelled tilted would get untilted
//! shapes. Solving in the source's orientation and rotating the deltas back makes the
//! transfer follow any rigid motion of the target.

use faer::Mat;

use super::gradients::{Mat3, Vec3, IDENTITY};
use crate::error::{ShapesmithError, ShapesmithResult};

/// The proper rotation `R` minimising `sum_n |R (s_n - s_bar) - (t_n - t_bar)|^2`.
pub fn best_rotation(source: &[Vec3], target: &[Vec3]) -> ShapesmithResult<Mat3> {
    let cs = centroid(source);
    let ct = centroid(target);
    let mut covariance = Mat::<f64>::zeros(3, 3);
    for (s, t) in source.iter().zip(target) {
        for r in 0..3 {
            for c in 0..3 {
                covariance[(r, c)] += (t[r] - ct[r]) * (s[c] - cs[c]);
            }
        }
    }
    if (0..3).all(|r| (0..3).all(|c| covariance[(r, c)] == 0.0)) {
        return Ok(IDENTITY);
    }
    let svd = covariance
        .svd()
        .map_err(|e| ShapesmithError::Solver(format!("aligning the neutrals failed: {e:?}")))?;
    let (u, v) = (svd.U(), svd.V());
    let det = |m: faer::MatRef<'_, f64>| {
        m[(0, 0)] * (m[(1, 1)] * m[(2, 2)] - m[(1, 2)] * m[(2, 1)])
            - m[(0, 1)] * (m[(1, 0)] * m[(2, 2)] - m[(1, 2)] * m[(2, 0)])
            + m[(0, 2)] * (m[(1, 0)] * m[(2, 1)] - m[(1, 1)] * m[(2, 0)])
    };
    // Flip the weakest axis when U V^T is a reflection.
    let sign = if det(u) * det(v) < 0.0 { -1.0 } else { 1.0 };
    let mut rotation = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            rotation[r][c] = u[(r, 0)] * v[(c, 0)] + u[(r, 1)] * v[(c, 1)] + sign * u[(r, 2)] * v[(c, 2)];
        }
    }
    Ok(rotation)
}

pub fn centroid(points: &[Vec3]) -> Vec3 {
    let mut sum = [0.0; 3];
    for p in points {
        for a in 0..3 {
            sum[a] += p[a];
        }
    }
    let n = points.len().max(1) as f64;
    sum.map(|s| s / n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transfer::gradients::{mat_mul, mat_vec, transpose};

    #[test]
    fn recovers_a_known_rotation_and_never_a_reflection() {
        let source: Vec<Vec3> = (0..20)
            .map(|i| {
                let t = i as f64;
                [t.sin() * 2.0, (1.7 * t).cos(), 0.3 * t - 1.0]
            })
            .collect();
        let (a, b) = (0.7f64, -0.4f64);
        let rz: Mat3 = [[a.cos(), -a.sin(), 0.0], [a.sin(), a.cos(), 0.0], [0.0, 0.0, 1.0]];
        let rx: Mat3 = [[1.0, 0.0, 0.0], [0.0, b.cos(), -b.sin()], [0.0, b.sin(), b.cos()]];
        let truth = mat_mul(&rz, &rx);
        let target: Vec<Vec3> = source.iter().map(|p| mat_vec(&truth, *p).map(|x| 3.0 * x + 1.5)).collect();
        let found = best_rotation(&source, &target).unwrap();
        for r in 0..3 {
            for c in 0..3 {
                assert!((found[r][c] - truth[r][c]).abs() < 1e-10);
            }
        }
        // A mirrored target still gets a proper rotation (determinant +1).
        let mirrored: Vec<Vec3> = source.iter().map(|p| [-p[0], p[1], p[2]]).collect();
        let r = best_rotation(&source, &mirrored).unwrap();
        let rt_r = mat_mul(&transpose(&r), &r);
        let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1]) - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        assert!((det - 1.0).abs() < 1e-10);
        assert!((0..3).all(|i| (rt_r[i][i] - 1.0).abs() < 1e-10));
    }
}
