//! The similarity `x -> s R x + t` (proper rotation, uniform scale, translation) and its least
//! squares fit to point pairs (Umeyama 1991), shared by the wrap's alignment and piece matching
//! and the performance solve's first pose.

use faer::Mat;

use super::mat3::{add, determinant, dot, mat_vec, scale, sub, transpose, Mat3, Vec3, IDENTITY};

/// `x -> scale * rotation * x + translation`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Similarity {
    pub rotation: Mat3,
    pub scale: f64,
    pub translation: Vec3,
}

impl Similarity {
    pub const IDENTITY: Similarity = Similarity { rotation: IDENTITY, scale: 1.0, translation: [0.0; 3] };

    pub fn apply(&self, p: Vec3) -> Vec3 {
        add(scale(mat_vec(&self.rotation, p), self.scale), self.translation)
    }

    /// The point this similarity takes to `q`: `R^T (q - t) / s`.
    pub fn apply_inverse(&self, q: Vec3) -> Vec3 {
        scale(mat_vec(&transpose(&self.rotation), sub(q, self.translation)), 1.0 / self.scale)
    }
}

/// Weighted Umeyama (1991, Eq. (40)-(42)): the similarity minimising
/// `sum_i a_i |s R p_i + t - q_i|^2` over proper rotations `R` (the reflection of the SVD's
/// smallest direction taken out, Eq. (39)), `s` fixed at 1 unless `with_scale`. `None` when the
/// weights sum to nothing or the scale comes out non-positive (pairs that agree on no
/// orientation). Callers say what a degenerate spread means for them: the fit itself only
/// needs the covariance's SVD.
pub fn fit_similarity(source: &[Vec3], target: &[Vec3], weights: &[f64], with_scale: bool) -> Option<Similarity> {
    let total: f64 = weights.iter().sum();
    if source.is_empty() || source.len() != target.len() || !(total > 0.0) {
        return None;
    }
    let centre = |points: &[Vec3]| {
        let sum = points.iter().zip(weights).fold([0.0; 3], |acc, (p, a)| add(acc, scale(*p, *a)));
        scale(sum, 1.0 / total)
    };
    let (mu_p, mu_q) = (centre(source), centre(target));
    let mut covariance = [[0.0; 3]; 3];
    let mut variance_p = 0.0;
    for ((p, q), a) in source.iter().zip(target).zip(weights) {
        let (dp, dq) = (sub(*p, mu_p), sub(*q, mu_q));
        variance_p += a * dot(dp, dp);
        for r in 0..3 {
            for c in 0..3 {
                covariance[r][c] += a * dq[r] * dp[c];
            }
        }
    }
    let svd = Mat::<f64>::from_fn(3, 3, |r, c| covariance[r][c]).svd().ok()?;
    let (u, v, d) = (svd.U(), svd.V(), svd.S().column_vector());
    let det_u = determinant(&std::array::from_fn(|r| std::array::from_fn(|c| u[(r, c)])));
    let det_v = determinant(&std::array::from_fn(|r| std::array::from_fn(|c| v[(r, c)])));
    let signs = [1.0, 1.0, if det_u * det_v < 0.0 { -1.0 } else { 1.0 }];
    let rotation: Mat3 = std::array::from_fn(|r| std::array::from_fn(|c| (0..3).map(|k| u[(r, k)] * signs[k] * v[(c, k)]).sum()));
    let s = if with_scale { (0..3).map(|k| d[k] * signs[k]).sum::<f64>() / variance_p } else { 1.0 };
    if !(s > 0.0 && s.is_finite()) {
        return None;
    }
    Some(Similarity { rotation, scale: s, translation: sub(mu_q, scale(mat_vec(&rotation, mu_p), s)) })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn turn(a: f64, b: f64) -> Mat3 {
        let (sa, ca) = a.sin_cos();
        let (sb, cb) = b.sin_cos();
        let z = [[ca, -sa, 0.0], [sa, ca, 0.0], [0.0, 0.0, 1.0]];
        let x = [[1.0, 0.0, 0.0], [0.0, cb, -sb], [0.0, sb, cb]];
        super::super::mat3::mat_mul(&z, &x)
    }

    #[test]
    fn weights_pick_which_pairs_the_fit_follows() {
        let truth = Similarity { rotation: turn(0.8, -1.1), scale: 2.5, translation: [1.0, -3.0, 0.5] };
        let source: Vec<Vec3> = (0..7).map(|i| [(i as f64).sin(), (1.7 * i as f64).cos(), 0.2 * i as f64]).collect();
        let mut target: Vec<Vec3> = source.iter().map(|p| truth.apply(*p)).collect();
        // One pair far off, weighted out: the fit is still exact.
        target[3] = [40.0, 40.0, 40.0];
        let mut weights = vec![1.0; 7];
        weights[3] = 0.0;
        let fitted = fit_similarity(&source, &target, &weights, true).unwrap();
        for r in 0..3 {
            for c in 0..3 {
                assert!((fitted.rotation[r][c] - truth.rotation[r][c]).abs() < 1e-10);
            }
            assert!((fitted.translation[r] - truth.translation[r]).abs() < 1e-9);
        }
        assert!((fitted.scale - 2.5).abs() < 1e-10);
        for p in &source {
            let back = fitted.apply_inverse(fitted.apply(*p));
            assert!((0..3).all(|a| (back[a] - p[a]).abs() < 1e-12));
        }
        // Weighted in, it pulls the fit away.
        let pulled = fit_similarity(&source, &target, &[1.0; 7], true).unwrap();
        assert!((pulled.scale - 2.5).abs() > 1e-3);
        // A mirror image is fitted by a proper rotation, never a reflection.
        let mirrored: Vec<Vec3> = source.iter().map(|p| [-p[0], p[1], p[2]]).collect();
        let proper = fit_similarity(&source, &mirrored, &[1.0; 7], false).unwrap();
        assert!((determinant(&proper.rotation) - 1.0).abs() < 1e-10);
        assert!(fit_similarity(&source, &target, &[0.0; 7], true).is_none());
    }
}
