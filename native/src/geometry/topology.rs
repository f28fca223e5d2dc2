//! Mesh connectivity from the triangle list: unique edges, boundary edges, vertex
//! neighbours, connected components.

use std::collections::{HashMap, HashSet};

use super::mat3::{length, sub};

/// Unique undirected edges `(a, b)` with `a < b`, sorted.
pub fn unique_edges(triangles: &[[u32; 3]]) -> Vec<(u32, u32)> {
    let mut edges: Vec<(u32, u32)> = triangles
        .iter()
        .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
        .map(|(a, b)| (a.min(b), a.max(b)))
        .collect();
    edges.sort_unstable();
    edges.dedup();
    edges
}

/// The undirected edges `(a, b)`, `a < b`, that belong to one triangle only: the mesh's open
/// boundary.
pub fn boundary_edges(triangles: &[[u32; 3]]) -> HashSet<(u32, u32)> {
    let mut count = HashMap::<(u32, u32), u32>::new();
    for t in triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            *count.entry((a.min(b), a.max(b))).or_default() += 1;
        }
    }
    count.into_iter().filter(|&(_, n)| n == 1).map(|(edge, _)| edge).collect()
}

/// Vertex adjacency lists (compressed rows): neighbours of `v` are
/// `targets[offsets[v]..offsets[v + 1]]`.
pub struct Adjacency {
    pub offsets: Vec<usize>,
    pub targets: Vec<u32>,
}

impl Adjacency {
    pub fn from_triangles(n_vertices: usize, triangles: &[[u32; 3]]) -> Self {
        let edges = unique_edges(triangles);
        let mut degree = vec![0usize; n_vertices + 1];
        for &(a, b) in &edges {
            degree[a as usize + 1] += 1;
            degree[b as usize + 1] += 1;
        }
        for v in 0..n_vertices {
            degree[v + 1] += degree[v];
        }
        let offsets = degree;
        let mut fill = offsets.clone();
        let mut targets = vec![0u32; offsets[n_vertices]];
        for &(a, b) in &edges {
            targets[fill[a as usize]] = b;
            fill[a as usize] += 1;
            targets[fill[b as usize]] = a;
            fill[b as usize] += 1;
        }
        Self { offsets, targets }
    }

    pub fn neighbours(&self, v: usize) -> &[u32] {
        &self.targets[self.offsets[v]..self.offsets[v + 1]]
    }

    /// The mean length of the edges at each vertex (0 for a vertex on no edge): the local
    /// scale both collision passes measure their margins in.
    pub fn mean_edge_lengths(&self, points: &[[f64; 3]]) -> Vec<f64> {
        (0..self.offsets.len() - 1)
            .map(|v| {
                let ring = self.neighbours(v);
                let total: f64 = ring.iter().map(|&u| length(sub(points[u as usize], points[v]))).sum();
                total / ring.len().max(1) as f64
            })
            .collect()
    }
}

/// Per vertex, the triangles it is a corner of, in ascending order (compressed rows).
pub struct VertexTriangles {
    offsets: Vec<usize>,
    list: Vec<u32>,
}

impl VertexTriangles {
    /// Triangle indices must be below `n_vertices` (the rig validated them).
    pub fn new(n_vertices: usize, triangles: &[[u32; 3]]) -> Self {
        let mut offsets = vec![0usize; n_vertices + 1];
        triangles.iter().flatten().for_each(|&v| offsets[v as usize + 1] += 1);
        for v in 0..n_vertices {
            offsets[v + 1] += offsets[v];
        }
        let mut next = offsets.clone();
        let mut list = vec![0u32; 3 * triangles.len()];
        for (t, corners) in triangles.iter().enumerate() {
            for &v in corners {
                list[next[v as usize]] = t as u32;
                next[v as usize] += 1;
            }
        }
        Self { offsets, list }
    }

    /// The triangles vertex `v` is a corner of.
    pub fn of(&self, v: usize) -> &[u32] {
        &self.list[self.offsets[v]..self.offsets[v + 1]]
    }
}

/// Connected component label per vertex (0..count), and the count. A vertex in no triangle
/// is a component of its own.
pub fn connected_components(n_vertices: usize, triangles: &[[u32; 3]]) -> (Vec<u32>, usize) {
    let mut parent: Vec<u32> = (0..n_vertices as u32).collect();
    fn find(parent: &mut [u32], mut v: u32) -> u32 {
        while parent[v as usize] != v {
            parent[v as usize] = parent[parent[v as usize] as usize];
            v = parent[v as usize];
        }
        v
    }
    for t in triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2])] {
            let (ra, rb) = (find(&mut parent, a), find(&mut parent, b));
            if ra != rb {
                parent[ra.max(rb) as usize] = ra.min(rb);
            }
        }
    }
    let mut label = vec![u32::MAX; n_vertices];
    let mut count = 0;
    for v in 0..n_vertices {
        let root = find(&mut parent, v as u32) as usize;
        if label[root] == u32::MAX {
            label[root] = count;
            count += 1;
        }
        label[v] = label[root];
    }
    (label, count as usize)
}

/// The triangles of a `width` x `height` grid of vertices numbered row by row from `first`,
/// each cell split along the diagonal from its first corner: the small synthetic meshes the
/// crate's tests build.
#[cfg(test)]
pub(crate) fn grid_triangles(width: u32, height: u32, first: u32) -> Vec<[u32; 3]> {
    (0..height - 1)
        .flat_map(|y| (0..width - 1).map(move |x| first + y * width + x))
        .flat_map(|a| [[a, a + 1, a + width + 1], [a, a + width + 1, a + width]])
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_pieces_and_a_loose_vertex() {
        let tris = [[0, 1, 2], [1, 2, 3], [4, 5, 6]];
        let (label, count) = connected_components(8, &tris);
        assert_eq!(count, 3);
        assert_eq!(&label[..4], &[0, 0, 0, 0]);
        assert_eq!(&label[4..7], &[1, 1, 1]);
        assert_eq!(label[7], 2);
        let adj = Adjacency::from_triangles(8, &tris);
        let mut n1 = adj.neighbours(1).to_vec();
        n1.sort();
        assert_eq!(n1, vec![0, 2, 3]);
        let rings = VertexTriangles::new(8, &tris);
        let expected: [&[u32]; 8] = [&[0], &[0, 1], &[0, 1], &[1], &[2], &[2], &[2], &[]];
        for (v, triangles) in expected.iter().enumerate() {
            assert_eq!(rings.of(v), *triangles, "vertex {v}");
        }
        assert_eq!(unique_edges(&tris).len(), 8);
    }
}
