//! Faults of real-world meshes that the tools refuse, found on the arrays every tool reads
//! so that the panel and batch refuse the same meshes with the same words: edges shared by
//! three or more triangles (no tool's surface operators are defined there), vertices in no
//! triangle (the transfer and the wrap would have nothing to solve them by), triangles of
//! zero area (their gradient operators are singular) and triangles listed twice (double
//! faces, which also make their edges non-manifold). Each fault is reported with its count
//! and its first occurrence, in index order, for the message.
//!
//! Loose edges are not a fault here: the tools read triangles only, so an edge outside every
//! face changes nothing (its corners, when in no triangle either, are loose vertices).

use std::collections::HashMap;

use serde::Serialize;

use crate::error::ShapesmithResult;
use crate::rig::{degenerate_triangles, validate_triangle_indices};

/// A fault's count and its first occurrence.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Fault<T> {
    pub count: usize,
    pub first: Option<T>,
}

impl<T: Copy> Fault<T> {
    fn from(items: &[T]) -> Self {
        Self { count: items.len(), first: items.first().copied() }
    }
}

#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MeshFaults {
    /// Edges (lower vertex first) shared by three or more triangles; `first` is the edge with
    /// the smallest vertices.
    pub non_manifold_edges: Fault<[u32; 2]>,
    /// Vertices in no triangle.
    pub loose_vertices: Fault<u32>,
    /// Triangles whose area is zero (within [`crate::rig::DEGENERATE_AREA_FRACTION`]) or that
    /// repeat a corner.
    pub zero_area_triangles: Fault<u32>,
    /// Triangles with the same three corners as an earlier one: `[earlier, later]`.
    pub duplicate_triangles: Fault<[u32; 2]>,
}

impl MeshFaults {
    pub fn any(&self) -> bool {
        self.non_manifold_edges.count + self.loose_vertices.count + self.zero_area_triangles.count + self.duplicate_triangles.count > 0
    }
}

/// The faults of the mesh (`points`, `triangles`); errors only on out-of-range indices.
pub fn find_mesh_faults(points: &[[f32; 3]], triangles: &[[u32; 3]]) -> ShapesmithResult<MeshFaults> {
    validate_triangle_indices(points.len(), triangles)?;
    let mut used = vec![false; points.len()];
    let mut edge_faces: HashMap<[u32; 2], u32> = HashMap::with_capacity(triangles.len() * 3 / 2);
    let mut first_with: HashMap<[u32; 3], u32> = HashMap::with_capacity(triangles.len());
    let mut duplicates = Vec::new();
    let mut repeated_corner = Vec::new();
    for (t, tri) in triangles.iter().enumerate() {
        tri.iter().for_each(|&v| used[v as usize] = true);
        let mut sorted = *tri;
        sorted.sort_unstable();
        if sorted[0] == sorted[1] || sorted[1] == sorted[2] {
            repeated_corner.push(t as u32);
            continue;
        }
        match first_with.get(&sorted) {
            Some(&earlier) => duplicates.push([earlier, t as u32]),
            None => {
                first_with.insert(sorted, t as u32);
            }
        }
        for edge in [[sorted[0], sorted[1]], [sorted[1], sorted[2]], [sorted[0], sorted[2]]] {
            *edge_faces.entry(edge).or_insert(0) += 1;
        }
    }
    let mut non_manifold: Vec<[u32; 2]> = edge_faces.into_iter().filter(|&(_, faces)| faces >= 3).map(|(e, _)| e).collect();
    non_manifold.sort_unstable();
    let loose: Vec<u32> = (0..points.len() as u32).filter(|&v| !used[v as usize]).collect();
    let mut zero_area = degenerate_triangles(points, triangles);
    zero_area.extend(repeated_corner);
    zero_area.sort_unstable();
    zero_area.dedup();
    Ok(MeshFaults {
        non_manifold_edges: Fault::from(&non_manifold),
        loose_vertices: Fault::from(&loose),
        zero_area_triangles: Fault::from(&zero_area),
        duplicate_triangles: Fault::from(&duplicates),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two triangles sharing the edge (1, 2), a unit square.
    fn square() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        (vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]], vec![[0, 1, 2], [1, 3, 2]])
    }

    #[test]
    fn a_clean_square_has_no_fault() {
        let (points, triangles) = square();
        assert!(!find_mesh_faults(&points, &triangles).unwrap().any());
    }

    #[test]
    fn each_fault_is_counted_with_its_first_occurrence() {
        let (mut points, mut triangles) = square();
        // A fin on the shared edge (1, 2): three triangles there.
        points.push([0.5, 0.5, 1.0]);
        triangles.push([1, 2, 4]);
        let faults = find_mesh_faults(&points, &triangles).unwrap();
        assert_eq!(faults.non_manifold_edges, Fault { count: 1, first: Some([1, 2]) });
        assert_eq!(faults.loose_vertices.count, 0);

        // Two vertices in no triangle.
        points.extend([[5.0, 5.0, 5.0], [6.0, 5.0, 5.0]]);
        let faults = find_mesh_faults(&points, &triangles).unwrap();
        assert_eq!(faults.loose_vertices, Fault { count: 2, first: Some(5) });

        // A triangle on three collinear corners and one that repeats a corner.
        let (points, mut triangles) = square();
        let mut points = points;
        points.push([2.0, 0.0, 0.0]);
        triangles.extend([[0, 1, 4], [3, 3, 2]]);
        let faults = find_mesh_faults(&points, &triangles).unwrap();
        assert_eq!(faults.zero_area_triangles, Fault { count: 2, first: Some(2) });

        // The first triangle again, wound the other way: a duplicate, and its edges non-manifold
        // where the square's other triangle also meets them.
        let (points, mut triangles) = square();
        triangles.push([2, 1, 0]);
        let faults = find_mesh_faults(&points, &triangles).unwrap();
        assert_eq!(faults.duplicate_triangles, Fault { count: 1, first: Some([0, 2]) });
        assert_eq!(faults.non_manifold_edges, Fault { count: 1, first: Some([1, 2]) });
    }

    #[test]
    fn an_index_out_of_range_is_an_error() {
        let (points, _) = square();
        assert!(find_mesh_faults(&points, &[[0, 1, 9]]).unwrap_err().to_string().contains("vertex 9"));
    }
}
