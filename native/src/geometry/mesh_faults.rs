//! The faults of real-world meshes that the welded surface ([`super::weld::Weld`]) leaves
//! out, found by the weld itself so that the report names exactly what every tool left out:
//! triangles of zero area (their gradient operators are singular) or that repeat a corner,
//! triangles listed twice (double faces, which would also make their edges non-manifold), and
//! vertices in no remaining triangle (loose vertices, read at their nearest surface point).
//! Edges shared by three or more of the remaining triangles (a fin) are kept and counted: the
//! tools' per-triangle operators are defined there, though the rigger may not have meant them.
//!
//! Loose edges are not a fault here: the tools read triangles only, so an edge outside every
//! face changes nothing (its corners, when in no triangle either, are loose vertices).

use std::collections::HashMap;

use serde::Serialize;

use super::weld::{is_flat, weld_tolerance, Weld};
use crate::error::ShapesmithResult;
use crate::rig::{bbox_diagonal, validate_triangle_indices};

/// A fault's occurrences, in index order, with their count and the first.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Fault<T> {
    pub count: usize,
    pub first: Option<T>,
    pub all: Vec<T>,
}

impl<T: Copy> Fault<T> {
    fn from(items: Vec<T>) -> Self {
        Self { count: items.len(), first: items.first().copied(), all: items }
    }
}

#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MeshFaults {
    /// Edges (lower vertex first) shared by three or more of the kept triangles.
    pub non_manifold_edges: Fault<[u32; 2]>,
    /// Vertices in no kept triangle.
    pub loose_vertices: Fault<u32>,
    /// Triangles left out for a zero area ([`super::weld::is_flat`]) or a repeated corner.
    pub zero_area_triangles: Fault<u32>,
    /// Triangles left out for having the same three corners as an earlier one: `[earlier, later]`.
    pub duplicate_triangles: Fault<[u32; 2]>,
}

impl MeshFaults {
    pub fn any(&self) -> bool {
        self.non_manifold_edges.count + self.loose_vertices.count + self.zero_area_triangles.count + self.duplicate_triangles.count > 0
    }
}

/// The faults of the mesh (`points`, `triangles`), as its welded surface leaves them out;
/// errors only on out-of-range indices.
pub fn find_mesh_faults(points: &[[f32; 3]], triangles: &[[u32; 3]]) -> ShapesmithResult<MeshFaults> {
    validate_triangle_indices(points.len(), triangles)?;
    let weld = Weld::new(points, triangles);
    let mut kept = vec![false; triangles.len()];
    weld.triangle_of.iter().for_each(|&t| kept[t as usize] = true);
    // The kept triangle each welded corner set first appears as (a dropped copy names it).
    let welded_corners = |t: usize| {
        let mut w = triangles[t].map(|v| weld.representatives[weld.welded_of[v as usize] as usize]);
        w.sort_unstable();
        w
    };
    let first_with: HashMap<[u32; 3], u32> = weld.triangle_of.iter().map(|&t| (welded_corners(t as usize), t)).collect();
    let (diagonal, tolerance) = (bbox_diagonal(points), weld_tolerance(points));
    let (mut zero_area, mut duplicates) = (Vec::new(), Vec::new());
    for t in (0..triangles.len()).filter(|&t| !kept[t]) {
        let w = welded_corners(t);
        let flat = w[0] == w[1] || w[1] == w[2] || is_flat(points, &w, diagonal, tolerance);
        match first_with.get(&w) {
            Some(&earlier) if !flat => duplicates.push([earlier, t as u32]),
            _ => zero_area.push(t as u32),
        }
    }
    let mut edge_faces: HashMap<[u32; 2], u32> = HashMap::with_capacity(weld.triangles.len() * 3 / 2);
    for tri in &weld.triangles {
        let mut v = tri.map(|p| weld.vertex(p));
        v.sort_unstable();
        for edge in [[v[0], v[1]], [v[1], v[2]], [v[0], v[2]]] {
            *edge_faces.entry(edge).or_insert(0) += 1;
        }
    }
    let mut non_manifold: Vec<[u32; 2]> = edge_faces.into_iter().filter(|&(_, faces)| faces >= 3).map(|(e, _)| e).collect();
    non_manifold.sort_unstable();
    let loose: Vec<u32> = weld.carried.iter().map(|c| c.vertex).collect();
    Ok(MeshFaults {
        non_manifold_edges: Fault::from(non_manifold),
        loose_vertices: Fault::from(loose),
        zero_area_triangles: Fault::from(zero_area),
        duplicate_triangles: Fault::from(duplicates),
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
        // A fin on the shared edge (1, 2): three triangles there, all kept.
        points.push([0.5, 0.5, 1.0]);
        triangles.push([1, 2, 4]);
        let faults = find_mesh_faults(&points, &triangles).unwrap();
        assert_eq!(faults.non_manifold_edges, Fault { count: 1, first: Some([1, 2]), all: vec![[1, 2]] });
        assert_eq!(faults.loose_vertices.count, 0);

        // Two vertices in no triangle.
        points.extend([[5.0, 5.0, 5.0], [6.0, 5.0, 5.0]]);
        let faults = find_mesh_faults(&points, &triangles).unwrap();
        assert_eq!(faults.loose_vertices, Fault { count: 2, first: Some(5), all: vec![5, 6] });

        // A triangle on three collinear corners and one that repeats a corner; the collinear
        // corner 4 is then in no kept triangle.
        let (points, mut triangles) = square();
        let mut points = points;
        points.push([2.0, 0.0, 0.0]);
        triangles.extend([[0, 1, 4], [3, 3, 2]]);
        let faults = find_mesh_faults(&points, &triangles).unwrap();
        assert_eq!(faults.zero_area_triangles, Fault { count: 2, first: Some(2), all: vec![2, 3] });
        assert_eq!(faults.loose_vertices.all, vec![4]);

        // The first triangle again, wound the other way: a duplicate, left out, so its edges
        // stay manifold.
        let (points, mut triangles) = square();
        triangles.push([2, 1, 0]);
        let faults = find_mesh_faults(&points, &triangles).unwrap();
        assert_eq!(faults.duplicate_triangles, Fault { count: 1, first: Some([0, 2]), all: vec![[0, 2]] });
        assert_eq!(faults.non_manifold_edges.count, 0);
    }

    #[test]
    fn a_face_copied_across_a_seam_is_a_duplicate() {
        // The square's first triangle again on a copy of corner 0 (a seam split): the weld
        // makes it the same triangle.
        let (mut points, mut triangles) = square();
        points.push(points[0]);
        triangles.push([4, 1, 2]);
        let faults = find_mesh_faults(&points, &triangles).unwrap();
        assert_eq!(faults.duplicate_triangles.all, vec![[0, 2]]);
        assert!(faults.loose_vertices.all.is_empty(), "the copy is welded to corner 0, not loose");
    }

    #[test]
    fn an_index_out_of_range_is_an_error() {
        let (points, _) = square();
        assert!(find_mesh_faults(&points, &[[0, 1, 9]]).unwrap_err().to_string().contains("vertex 9"));
    }
}
