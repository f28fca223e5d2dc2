//! Importance weights of a shape (paper 000, section 4.3): displacement strength (Eq. (5)),
//! triangle distortion against a target neutral (Eqs. (6)-(7), with the method's `- 2`) and
//! the optional uniqueness (Eq. (8)), combined as Eq. (4) plus a floor.

use rayon::prelude::*;

use crate::geometry::mirror::delta_inner_products;
use crate::rig::{norm, RigView};

/// Added to every importance so that a shape of zero importance is still packed (the method
/// section 1): with it, every node of the program has a positive weight.
pub const IMPORTANCE_FLOOR: f64 = 0.01;

/// Eq. (5): $\bar d_k$ = mean $|D_{k,n}|$ over the active vertices, divided by its maximum
/// over k. Shapes without active vertices (inert) score 0 and do not set the maximum.
pub fn displacement_strength(rig: &RigView, active: &[Vec<u32>]) -> Vec<f64> {
    let mean: Vec<f64> = active
        .iter()
        .enumerate()
        .map(|(k, set)| {
            if set.is_empty() {
                return 0.0;
            }
            let delta = rig.delta(k);
            set.iter().map(|&n| norm(&delta[n as usize])).sum::<f64>() / set.len() as f64
        })
        .collect();
    normalise_by_max(mean)
}

/// Eq. (6) with the method's correction: for triangle (u, v, w) with edges vu and vw,
/// $s_t = \max(|vu_A|/|vu_B|, |vu_B|/|vu_A|) + \max(|vw_A|/|vw_B|, |vw_B|/|vw_A|) - 2$,
/// so that an undistorted (or uniformly unscaled) triangle scores 0. Both meshes must have
/// validated, non-degenerate triangles (every edge has a positive length).
pub fn triangle_scores(template: &[[f32; 3]], target: &[[f32; 3]], triangles: &[[u32; 3]]) -> Vec<f64> {
    let length = |points: &[[f32; 3]], a: u32, b: u32| {
        let (p, q) = (points[a as usize], points[b as usize]);
        norm(&[p[0] - q[0], p[1] - q[1], p[2] - q[2]])
    };
    let ratio = |a: f64, b: f64| (a / b).max(b / a);
    triangles
        .iter()
        .map(|&[u, v, w]| {
            let vu = ratio(length(template, v, u), length(target, v, u));
            let vw = ratio(length(template, v, w), length(target, v, w));
            vu + vw - 2.0
        })
        .collect()
}

/// Eq. (7): $s_k$ = sum of $s_t$ over the triangles with at least one active vertex, divided
/// by its maximum over k; all zero when every $s_k$ is zero.
pub fn triangle_distortion(scores: &[f64], triangles: &[[u32; 3]], active: &[Vec<u32>], n_vertices: usize) -> Vec<f64> {
    let sums: Vec<f64> = active
        .par_iter()
        .map(|set| {
            let mut is_active = vec![false; n_vertices];
            for &n in set {
                is_active[n as usize] = true;
            }
            triangles
                .iter()
                .zip(scores)
                .filter(|(tri, _)| tri.iter().any(|&v| is_active[v as usize]))
                .map(|(_, s)| s)
                .sum()
        })
        .collect();
    normalise_by_max(sums)
}

/// Cosines of the flattened delta fields of every two shapes (K x K, symmetric, 1 on the
/// diagonal of moving shapes, 0 for inert ones). Used for the cosine antagonists and Eq. (8).
/// One Gram matrix product, accumulated over blocks of vertices.
pub fn cosine_matrix(rig: &RigView) -> Vec<Vec<f64>> {
    let k_count = rig.n_shapes();
    let gram = delta_inner_products(rig, |k, n| rig.delta(k)[n].map(f64::from)).gram;
    let norms: Vec<f64> = (0..k_count).map(|k| gram[(k, k)].sqrt()).collect();
    (0..k_count)
        .map(|i| {
            (0..k_count)
                .map(|j| if norms[i] > 0.0 && norms[j] > 0.0 { gram[(i, j)] / (norms[i] * norms[j]) } else { 0.0 })
                .collect()
        })
        .collect()
}

/// Eq. (8) for the `candidates` given the shapes `placed` so far:
/// $U_k = \frac{1}{|R|}\sum_{r \in R} \max(\cos(D_k, D_r), 0)$ and
/// $\lambda_{U,k} = 1 - U_k / \max_{k'} U_{k'}$ over the candidates. Indexed by shape
/// (0 for non-candidates); all 0 when nothing is placed yet (the paper: the first expression
/// is unique by definition), all 1 when no candidate resembles any placed shape.
pub fn uniqueness(cosines: &[Vec<f64>], candidates: &[usize], placed: &[usize]) -> Vec<f64> {
    let mut out = vec![0.0; cosines.len()];
    if placed.is_empty() {
        return out;
    }
    let similarity: Vec<f64> = candidates
        .iter()
        .map(|&k| placed.iter().map(|&r| cosines[k][r].max(0.0)).sum::<f64>() / placed.len() as f64)
        .collect();
    let max = similarity.iter().copied().fold(0.0, f64::max);
    for (&k, s) in candidates.iter().zip(similarity) {
        out[k] = if max > 0.0 { 1.0 - s / max } else { 1.0 };
    }
    out
}

fn normalise_by_max(values: Vec<f64>) -> Vec<f64> {
    let max = values.iter().copied().fold(0.0, f64::max);
    if max > 0.0 {
        values.into_iter().map(|v| v / max).collect()
    } else {
        vec![0.0; values.len()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 3 x 3 grid of unit squares split into triangles.
    fn grid() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let mut pts = Vec::new();
        for y in 0..4 {
            for x in 0..4 {
                pts.push([x as f32, y as f32, 0.0]);
            }
        }
        (pts, crate::geometry::topology::grid_triangles(4, 4, 0))
    }

    #[test]
    fn displacement_strength_is_the_normalised_mean_over_active_vertices() {
        let (pts, tris) = grid();
        let n = pts.len();
        let names: Vec<String> = ["strong", "weak", "still"].map(String::from).to_vec();
        let mut deltas = vec![[0.0f32; 3]; 3 * n];
        deltas[0] = [0.0, 0.0, 2.0];
        deltas[1] = [0.0, 0.0, 1.0];
        deltas[2] = [0.0, 0.0, 0.1]; // below mu = 0.3 of the maximum: not averaged
        deltas[n + 5] = [0.5, 0.0, 0.0];
        let rig = RigView::new(&pts, &deltas, &tris, &names).unwrap();
        let active: Vec<Vec<u32>> = (0..3).map(|k| rig.active_vertices(k, 0.3)).collect();
        assert_eq!(active[0], vec![0, 1]);
        let dis = displacement_strength(&rig, &active);
        assert!((dis[0] - 1.0).abs() < 1e-12);
        assert!((dis[1] - 0.5 / 1.5).abs() < 1e-12, "{dis:?}");
        assert_eq!(dis[2], 0.0);
    }

    #[test]
    fn triangle_distortion_is_zero_without_distortion_and_grows_where_stretched() {
        let (pts, tris) = grid();
        assert!(triangle_scores(&pts, &pts, &tris).iter().all(|&s| s.abs() < 1e-12));
        // Stretch x by 2 only for x >= 2: triangles in the last column distort, the others
        // keep their shape (the paper's eq. 6 without `- 2` would give them all 2).
        let target: Vec<[f32; 3]> =
            pts.iter().map(|p| [if p[0] > 2.0 { 2.0 + 2.0 * (p[0] - 2.0) } else { p[0] }, p[1], p[2]]).collect();
        let scores = triangle_scores(&pts, &target, &tris);
        for (t, tri) in tris.iter().enumerate() {
            let in_last_column = tri.iter().all(|&v| pts[v as usize][0] >= 2.0);
            assert_eq!(scores[t] > 1e-9, in_last_column, "triangle {t}: {}", scores[t]);
        }
        // Shape 0 moves vertex 0 (left edge), shape 1 vertex 3 (right edge).
        let active = vec![vec![0u32], vec![3u32], vec![]];
        let td = triangle_distortion(&scores, &tris, &active, pts.len());
        assert_eq!(td, vec![0.0, 1.0, 0.0]);
        assert_eq!(triangle_distortion(&vec![0.0; tris.len()], &tris, &active, pts.len()), vec![0.0; 3]);
    }

    #[test]
    fn cosine_matrix_matches_the_direct_cosine() {
        let (pts, tris) = grid();
        let n = pts.len();
        let names: Vec<String> = ["a", "b", "c", "still"].map(String::from).to_vec();
        let deltas: Vec<[f32; 3]> = (0..4 * n)
            .map(|i| if i >= 3 * n { [0.0; 3] } else { [(i % 7) as f32 - 3.0, (i % 5) as f32 * 0.5, (i % 3) as f32 - 1.0] })
            .collect();
        let rig = RigView::new(&pts, &deltas, &tris, &names).unwrap();
        let cosines = cosine_matrix(&rig);
        for (i, row) in cosines.iter().enumerate() {
            for (j, &c) in row.iter().enumerate() {
                let direct = crate::geometry::mirror::cosine(rig.delta(i), rig.delta(j));
                assert!((c - direct).abs() < 1e-12, "{i} {j}: {c} vs {direct}");
            }
        }
        assert!((cosines[0][0] - 1.0).abs() < 1e-12 && cosines[3][3] == 0.0);
    }

    #[test]
    fn uniqueness_follows_eq_8() {
        let cosines = vec![
            vec![1.0, 0.8, -0.9, 0.0],
            vec![0.8, 1.0, 0.2, 0.4],
            vec![-0.9, 0.2, 1.0, 0.0],
            vec![0.0, 0.4, 0.0, 1.0],
        ];
        assert_eq!(uniqueness(&cosines, &[1, 2, 3], &[]), vec![0.0; 4]);
        // Placed {0}: similarities 0.8, 0 (negative clipped), 0 -> 1 - s / 0.8.
        let u = uniqueness(&cosines, &[1, 2, 3], &[0]);
        assert_eq!(u, vec![0.0, 0.0, 1.0, 1.0]);
        // Placed {0, 1}: candidates 2 -> (0 + 0.2) / 2, 3 -> (0 + 0.4) / 2.
        let u = uniqueness(&cosines, &[2, 3], &[0, 1]);
        assert!((u[2] - 0.5).abs() < 1e-12 && u[3].abs() < 1e-12, "{u:?}");
    }
}
