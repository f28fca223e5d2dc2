//! The similarity (rotation, uniform scale, translation) that puts the template where the
//! character is: from point pairs (Umeyama 1991), or, without pairs, from the two meshes'
//! centroids and principal axes (the sign ambiguity of the axes settled by the candidate
//! whose template lands closest to the character's surface).

use faer::{Mat, Side};

use crate::error::{ShapesmithError, ShapesmithResult};
use crate::geometry::bvh::TriangleBvh;
use crate::geometry::mat3::{add, determinant, mat_vec, scale, sub, Mat3, Vec3};
pub use crate::geometry::similarity::Similarity;
use crate::geometry::similarity::fit_similarity;
use crate::invalid;

/// The fewest pairs the alignment takes (method, section 5: a similarity has 7 degrees of
/// freedom; 3 non-collinear pairs fix it, a fourth catches a misplaced one).
pub const MIN_PAIRS: usize = 4;

/// Umeyama (1991), Eq. (40)-(42): the similarity minimising `sum |s R p_i + t - q_i|^2` over
/// proper rotations `R`, `s > 0`. Refuses fewer than [`MIN_PAIRS`] pairs and pairs whose
/// template or character points lie on one line (the rotation about it is then free).
pub fn similarity_from_pairs(template: &[Vec3], character: &[Vec3]) -> ShapesmithResult<Similarity> {
    if template.len() != character.len() {
        return Err(invalid!("{} template points but {} character points: give them in pairs", template.len(), character.len()));
    }
    if template.len() < MIN_PAIRS {
        return Err(invalid!(
            "{} point pair(s) given; the alignment needs at least {MIN_PAIRS} (e.g. both eye corners, the nose tip and the chin)",
            template.len()
        ));
    }
    for (what, points) in [("template", template), ("character", character)] {
        let (_, spread) = centred_covariance(points, points);
        let values = symmetric_eigen(&spread)?.0;
        if values[1] <= 1e-9 * values[2].max(f64::MIN_POSITIVE) {
            return Err(invalid!(
                "the {what} points of the pairs lie on one line (or on one point): spread the pairs over the face"
            ));
        }
    }
    fit_similarity(template, character, &vec![1.0; template.len()], true).ok_or_else(|| {
        invalid!("the point pairs do not agree on any orientation: check that each pair marks the same feature")
    })
}

/// Without pairs: centroids matched, scale from the RMS radii, the template's principal axes
/// turned onto the character's (largest to largest); of the four proper rotations that do
/// this, the one whose template lands closest to the character's surface (mean distance of
/// up to `samples` template vertices).
pub fn similarity_from_principal_axes(
    template: &[Vec3],
    character: &[Vec3],
    character_surface: &TriangleBvh,
    samples: usize,
) -> ShapesmithResult<Similarity> {
    let ((mu_t, _), cov_t) = centred_covariance(template, template);
    let ((mu_c, _), cov_c) = centred_covariance(character, character);
    let (values_t, axes_t) = symmetric_eigen(&cov_t)?;
    let (values_c, axes_c) = symmetric_eigen(&cov_c)?;
    let trace_t: f64 = values_t.iter().sum();
    let trace_c: f64 = values_c.iter().sum();
    if !(trace_t > 0.0 && trace_c > 0.0) {
        return Err(invalid!("the template or the character has all its vertices at one point"));
    }
    let s = (trace_c / trace_t).sqrt();
    let stride = (template.len() / samples.max(1)).max(1);
    let mut best: Option<(f64, Similarity)> = None;
    for signs in [[1.0, 1.0, 1.0], [-1.0, -1.0, 1.0], [-1.0, 1.0, -1.0], [1.0, -1.0, -1.0]] {
        // R = E_c diag(signs) E_t^T maps template axis k onto character axis k.
        let rotation: Mat3 = std::array::from_fn(|r| {
            std::array::from_fn(|c| (0..3).map(|k| axes_c[r][k] * signs[k] * axes_t[c][k]).sum())
        });
        let rotation = if determinant(&rotation) < 0.0 { rotation.map(|row| row.map(|x| -x)) } else { rotation };
        let candidate = Similarity { rotation, scale: s, translation: sub(mu_c, scale(mat_vec(&rotation, mu_t), s)) };
        let distance: f64 = template
            .iter()
            .step_by(stride)
            .map(|p| character_surface.closest_point(&candidate.apply(*p), f64::INFINITY).map_or(0.0, |hit| hit.distance_squared.sqrt()))
            .sum();
        if best.as_ref().is_none_or(|(d, _)| distance < *d) {
            best = Some((distance, candidate));
        }
    }
    best.map(|(_, similarity)| similarity).ok_or_else(|| invalid!("the template has no vertices"))
}

/// ((mean of a, mean of b), (1/n) sum (a - mean a)(b - mean b)^T).
fn centred_covariance(a: &[Vec3], b: &[Vec3]) -> ((Vec3, Vec3), Mat3) {
    let n = a.len().max(1) as f64;
    let mean = |points: &[Vec3]| scale(points.iter().fold([0.0; 3], |acc, p| add(acc, *p)), 1.0 / n);
    let (mu_a, mu_b) = (mean(a), mean(b));
    let mut covariance = [[0.0; 3]; 3];
    for (p, q) in a.iter().zip(b) {
        let (da, db) = (sub(*p, mu_a), sub(*q, mu_b));
        for r in 0..3 {
            for c in 0..3 {
                covariance[r][c] += da[r] * db[c] / n;
            }
        }
    }
    ((mu_a, mu_b), covariance)
}

/// Eigenvalues (ascending) and eigenvectors (columns) of a symmetric 3x3 matrix.
pub(super) fn symmetric_eigen(m: &Mat3) -> ShapesmithResult<(Vec3, Mat3)> {
    let matrix = Mat::<f64>::from_fn(3, 3, |r, c| m[r][c]);
    let eigen = matrix
        .self_adjoint_eigen(Side::Lower)
        .map_err(|e| ShapesmithError::Solver(format!("the principal axes could not be computed: {e:?}")))?;
    let (u, s) = (eigen.U(), eigen.S().column_vector());
    Ok(([s[0], s[1], s[2]], std::array::from_fn(|r| std::array::from_fn(|c| u[(r, c)]))))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mat3::mat_mul;

    fn rotation(a: f64, b: f64) -> Mat3 {
        let rz: Mat3 = [[a.cos(), -a.sin(), 0.0], [a.sin(), a.cos(), 0.0], [0.0, 0.0, 1.0]];
        let rx: Mat3 = [[1.0, 0.0, 0.0], [0.0, b.cos(), -b.sin()], [0.0, b.sin(), b.cos()]];
        mat_mul(&rz, &rx)
    }

    #[test]
    fn recovers_a_known_similarity_exactly_from_pairs() {
        let truth = Similarity { rotation: rotation(2.1, -0.7), scale: 100.0, translation: [3.0, -40.0, 7.5] };
        let template: Vec<Vec3> = (0..6).map(|i| [(i as f64).sin(), (1.3 * i as f64).cos(), 0.2 * i as f64]).collect();
        let character: Vec<Vec3> = template.iter().map(|p| truth.apply(*p)).collect();
        let found = similarity_from_pairs(&template, &character).unwrap();
        assert!((found.scale - truth.scale).abs() < 1e-9 * truth.scale, "{}", found.scale);
        for r in 0..3 {
            assert!((found.translation[r] - truth.translation[r]).abs() < 1e-8);
            for c in 0..3 {
                assert!((found.rotation[r][c] - truth.rotation[r][c]).abs() < 1e-10);
            }
        }
        // A mirrored character still gets a proper rotation.
        let mirrored: Vec<Vec3> = character.iter().map(|p| [-p[0], p[1], p[2]]).collect();
        assert!((determinant(&similarity_from_pairs(&template, &mirrored).unwrap().rotation) - 1.0).abs() < 1e-10);
    }

    #[test]
    fn refuses_too_few_or_collinear_pairs() {
        let line: Vec<Vec3> = (0..5).map(|i| [i as f64, 2.0 * i as f64, 0.0]).collect();
        let spread: Vec<Vec3> = (0..5).map(|i| [i as f64, (i * i) as f64, 1.0]).collect();
        let message = |r: ShapesmithResult<Similarity>| format!("{:?}", r.unwrap_err());
        assert!(message(similarity_from_pairs(&spread[..3], &spread[..3])).contains("at least 4"));
        assert!(message(similarity_from_pairs(&line, &spread)).contains("one line"));
        assert!(message(similarity_from_pairs(&spread, &spread[..4])).contains("in pairs"));
    }

    #[test]
    fn principal_axes_find_a_rotated_scaled_box() {
        // An irregular closed box surface (different extents on each axis), rotated and scaled.
        let (points, triangles) = crate::wrap::tests::lumpy_box(6);
        let truth = Similarity { rotation: rotation(0.9, 2.4), scale: 3.0, translation: [1.0, 2.0, -3.0] };
        let moved: Vec<Vec3> = points.iter().map(|p| truth.apply(*p)).collect();
        let bvh = TriangleBvh::build(&moved, &triangles);
        let found = similarity_from_principal_axes(&points, &moved, &bvh, 500).unwrap();
        let error = points.iter().map(|p| crate::geometry::mat3::length(sub(found.apply(*p), truth.apply(*p)))).fold(0.0, f64::max);
        assert!(error < 0.05 * truth.scale, "max error {error}");
    }
}
