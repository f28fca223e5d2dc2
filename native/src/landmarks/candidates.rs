//! Relative displacement `r_k[n]` (Eq. 2), candidates `c_k[n] = r_k[n] >= eps` (Eq. 3), and
//! the folding of each shape onto one side of the face for symmetric layouts (Sec. 3.3.1).

use crate::geometry::mirror::MirrorMap;
use crate::rig::{norm, RigView};

/// Mirror partners that pick each other (`m(n) = m'` and `m(m') = n`, `m' != n`). Midline
/// vertices and one-sided matches have none: a layout stays symmetric when every landmark
/// with a partner brings that partner along.
pub fn mutual_partners(map: &MirrorMap) -> Vec<Option<u32>> {
    map.partner
        .iter()
        .enumerate()
        .map(|(n, m)| m.filter(|&m| m as usize != n && map.partner[m as usize] == Some(n as u32)))
        .collect()
}

/// Whether `n` (rather than its partner `m`) is the side that keeps a folded displacement:
/// the one with the larger lateral coordinate, the lower index on a tie.
pub fn is_kept_side(points: &[[f32; 3]], axis: usize, n: usize, m: usize) -> bool {
    let (a, b) = (points[n][axis], points[m][axis]);
    a > b || (a == b && n < m)
}

/// `r_k[n] = |D_k[n]| / max_n |D_k[n]|` (Eq. 2) for a non-inert shape. With `fold`, the
/// symmetric pre-processing of Sec. 3.3.1: of each mirror pair, the kept side takes the
/// larger of the two displacements and the other side gets zero (the maximum, and so the
/// normalisation, does not change).
pub fn relative_displacement(rig: &RigView, k: usize, fold: Option<&[Option<u32>]>, axis: usize) -> Vec<f64> {
    let lengths: Vec<f64> = rig.delta(k).iter().map(norm).collect();
    let folded: Vec<f64> = match fold {
        None => lengths,
        Some(partners) => (0..lengths.len())
            .map(|n| match partners[n] {
                None => lengths[n],
                Some(m) if is_kept_side(rig.neutral, axis, n, m as usize) => lengths[n].max(lengths[m as usize]),
                Some(_) => 0.0,
            })
            .collect(),
    };
    let max = folded.iter().copied().fold(0.0, f64::max);
    folded.iter().map(|&a| a / max).collect()
}

/// The candidate relation, vertex-major: for each vertex, the shapes it is a candidate for
/// (Eq. 3, `c_k[n] = 1` iff `r_k[n] >= eps`) with their `r_k[n]`, in ascending shape order.
pub fn candidate_relation(
    rig: &RigView,
    live_shapes: &[usize],
    epsilon: f64,
    fold: Option<&[Option<u32>]>,
    axis: usize,
) -> Vec<Vec<(usize, f64)>> {
    let mut relation = vec![Vec::new(); rig.n_vertices()];
    for &k in live_shapes {
        for (n, r) in relative_displacement(rig, k, fold, axis).into_iter().enumerate() {
            if r >= epsilon {
                relation[n].push((k, r));
            }
        }
    }
    relation
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Four vertices: a mirror pair at x = +-1, a midline vertex, and a lone vertex.
    fn strip() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        (vec![[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.7, 2.0, 0.0]], vec![[0, 1, 2], [0, 2, 3]])
    }

    #[test]
    fn folding_moves_the_larger_displacement_to_the_kept_side() {
        let (points, triangles) = strip();
        let names = vec!["leftOnly".to_string()];
        // Only the -x vertex of the pair moves (strongly); the lone vertex moves half as much.
        let deltas = vec![[0.0; 3], [0.0, 0.0, 2.0], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0]];
        let rig = RigView::new(&points, &deltas, &triangles, &names).unwrap();
        let map = MirrorMap::new(&points, 0, 1e-3);
        let partners = mutual_partners(&map);
        assert_eq!(partners, vec![Some(1), Some(0), None, None]);
        assert_eq!(relative_displacement(&rig, 0, None, 0), vec![0.0, 1.0, 0.5, 0.5]);
        assert_eq!(relative_displacement(&rig, 0, Some(&partners), 0), vec![1.0, 0.0, 0.5, 0.5]);
        let relation = candidate_relation(&rig, &[0], 0.5, Some(&partners), 0);
        assert_eq!(relation, vec![vec![(0, 1.0)], vec![], vec![(0, 0.5)], vec![(0, 0.5)]]);
        assert!(candidate_relation(&rig, &[0], 0.6, None, 0)[2].is_empty());
    }
}
