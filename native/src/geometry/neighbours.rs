//! Nearest-neighbour queries on vertex positions (k-d tree, O(log N) per query).

use kiddo::{ImmutableKdTree, SquaredEuclidean};

/// A k-d tree over points; items are the points' indices. Immutable, so that many points on
/// one plane (a mesh's midline) cannot overflow a bucket.
pub struct PointTree {
    tree: ImmutableKdTree<f64, 3>,
}

impl PointTree {
    pub fn new(points: &[[f32; 3]]) -> Self {
        let coords: Vec<[f64; 3]> = points.iter().map(|p| p.map(f64::from)).collect();
        Self { tree: ImmutableKdTree::new_from_slice(&coords) }
    }

    /// The nearest point's index and its Euclidean distance.
    pub fn nearest(&self, query: [f64; 3]) -> (usize, f64) {
        let hit = self.tree.nearest_one::<SquaredEuclidean>(&query);
        (hit.item as usize, hit.distance.sqrt())
    }

    /// Every point within `radius` (inclusive), unsorted, with its Euclidean distance.
    pub fn within(&self, query: [f64; 3], radius: f64) -> Vec<(usize, f64)> {
        self.tree
            .within_unsorted::<SquaredEuclidean>(&query, radius * radius)
            .into_iter()
            .map(|hit| (hit.item as usize, hit.distance.sqrt()))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_brute_force_on_a_plane_of_ties() {
        // 200 points on x = 0 (a midline) plus a few off it.
        let mut pts: Vec<[f32; 3]> = (0..200).map(|i| [0.0, (i % 20) as f32, (i / 20) as f32]).collect();
        pts.push([0.5, 3.0, 3.0]);
        let tree = PointTree::new(&pts);
        let q = [0.4, 3.1, 2.9];
        let brute = (0..pts.len())
            .min_by(|&a, &b| dist(&pts[a], q).total_cmp(&dist(&pts[b], q)))
            .unwrap();
        assert_eq!(tree.nearest(q).0, brute);
        let mut near: Vec<usize> = tree.within([0.0, 3.0, 3.0], 1.01).into_iter().map(|h| h.0).collect();
        near.sort();
        let mut expect: Vec<usize> = (0..pts.len()).filter(|&i| dist(&pts[i], [0.0, 3.0, 3.0]) <= 1.01).collect();
        expect.sort();
        assert_eq!(near, expect);
    }

    fn dist(p: &[f32; 3], q: [f64; 3]) -> f64 {
        (0..3).map(|a| (p[a] as f64 - q[a]).powi(2)).sum::<f64>().sqrt()
    }
}
