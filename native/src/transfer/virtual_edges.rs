//! Virtual edges (Li, Shen & Liu 2023, section 4): vertex pairs that are close in space but
//! far apart along the surface (opposite lips, eyelids, nostril walls). A soft spring on
//! each pair keeps the layers from passing through each other during transfer.
//!
//! Candidates `F_i = { j : d_ij < tau_d }` from a k-d tree; kept when the geodesic distance
//! (Dijkstra on the edge graph, stopped at `tau_r x d_ij`) exceeds `tau_r x d_ij` (the
//! paper's `G_i = { j in F_i : g_ij / d_ij > tau_r }`). Then, shortest first, at most
//! `max_per_vertex` edges per vertex, and once a pair is taken the one-ring neighbours of
//! both ends take no further edge (the paper's thinning).

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use rayon::prelude::*;

use crate::geometry::neighbours::PointTree;
use crate::geometry::topology::{connected_components, Adjacency};
use crate::rig::bbox_diagonal;

/// Knobs of the virtual-edge search; distances are fractions of the target's bbox diagonal.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct VirtualEdgeParams {
    /// Euclidean threshold `tau_d` as a fraction of the bounding-box diagonal.
    pub tau_d: f64,
    /// Geodesic-to-Euclidean ratio `tau_r` above which a close pair is a virtual edge.
    pub tau_r: f64,
    /// At most this many virtual edges per vertex (the paper keeps 3-5).
    pub max_per_vertex: usize,
}

impl Default for VirtualEdgeParams {
    fn default() -> Self {
        Self { tau_d: 0.015, tau_r: 4.0, max_per_vertex: 3 }
    }
}

/// Virtual edges `(i, j)`, `i < j`, of a mesh at rest, shortest first.
///
/// Only pairs inside one connected piece are candidates: across pieces the geodesic distance
/// is infinite, and a spring there would tie a separate piece (an eyeball, lashes) to its
/// neighbour, whereas the transfer gives each piece its position from its own static
/// vertices or its carried-over motion. Lips, eyelids and nostrils are one piece.
pub fn find_virtual_edges(neutral: &[[f32; 3]], triangles: &[[u32; 3]], params: &VirtualEdgeParams) -> Vec<(u32, u32)> {
    let n = neutral.len();
    let radius = params.tau_d * bbox_diagonal(neutral);
    if n == 0 || radius <= 0.0 || triangles.iter().flatten().any(|&v| v as usize >= n) {
        return Vec::new();
    }
    let points: Vec<[f64; 3]> = neutral.iter().map(|p| p.map(f64::from)).collect();
    let tree = PointTree::new(neutral);
    let (labels, _) = connected_components(n, triangles);
    let adjacency = Adjacency::from_triangles(n, triangles);

    let mut candidates: Vec<(f64, u32, u32)> = (0..n)
        .into_par_iter()
        .map_init(
            || DijkstraScratch::new(n),
            |scratch, i| {
                let close: Vec<(usize, f64)> = tree
                    .within(points[i], radius)
                    .into_iter()
                    .filter(|&(j, d)| j > i && d < radius && labels[j] == labels[i])
                    .collect();
                if close.is_empty() {
                    return Vec::new();
                }
                scratch
                    .far_along_surface(&points, &adjacency, i, &close, params.tau_r)
                    .into_iter()
                    .map(|(j, d)| (d, i as u32, j as u32))
                    .collect()
            },
        )
        .flatten()
        .collect();
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));

    let mut used = vec![0usize; n];
    let mut blocked = vec![false; n];
    let mut edges = Vec::new();
    for (_, i, j) in candidates {
        let (a, b) = (i as usize, j as usize);
        if blocked[a] || blocked[b] || used[a] >= params.max_per_vertex || used[b] >= params.max_per_vertex {
            continue;
        }
        used[a] += 1;
        used[b] += 1;
        edges.push((i, j));
        for &end in &[a, b] {
            for &nb in adjacency.neighbours(end) {
                blocked[nb as usize] = true;
            }
        }
    }
    edges
}

/// Reusable Dijkstra state: distances reset only where touched, so a bounded search costs
/// the size of its ball, not N.
struct DijkstraScratch {
    distance: Vec<f64>,
    touched: Vec<u32>,
    /// Per vertex: its index in the current candidate list plus one (0: not a candidate).
    candidate: Vec<u32>,
}

#[derive(PartialEq)]
struct Entry(f64, u32);

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, other: &Self) -> Ordering {
        // Min-heap on distance, ties by vertex index for determinism.
        other.0.total_cmp(&self.0).then(other.1.cmp(&self.1))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl DijkstraScratch {
    fn new(n: usize) -> Self {
        Self { distance: vec![f64::INFINITY; n], touched: Vec::new(), candidate: vec![0; n] }
    }

    /// The candidates `(j, d_ij)` whose edge-graph distance from `source` exceeds
    /// `ratio x d_ij`. The search stops once every candidate is settled or the front passes
    /// `ratio x max d_ij`.
    fn far_along_surface(
        &mut self,
        points: &[[f64; 3]],
        adjacency: &Adjacency,
        source: usize,
        candidates: &[(usize, f64)],
        ratio: f64,
    ) -> Vec<(usize, f64)> {
        let bound = ratio * candidates.iter().map(|c| c.1).fold(0.0, f64::max);
        for (slot, &(j, _)) in candidates.iter().enumerate() {
            self.candidate[j] = slot as u32 + 1;
        }
        let mut settled = vec![false; candidates.len()];
        let mut pending = candidates.len();
        let mut far = Vec::new();
        let mut heap = BinaryHeap::new();
        self.distance[source] = 0.0;
        self.touched.push(source as u32);
        heap.push(Entry(0.0, source as u32));
        while let Some(Entry(g, v)) = heap.pop() {
            let v = v as usize;
            if g > self.distance[v] {
                continue;
            }
            if g > bound || pending == 0 {
                break;
            }
            let slot = self.candidate[v];
            if slot > 0 && !settled[slot as usize - 1] {
                let (j, d) = candidates[slot as usize - 1];
                settled[slot as usize - 1] = true;
                pending -= 1;
                if g > ratio * d {
                    far.push((j, d));
                }
            }
            for &u in adjacency.neighbours(v) {
                let u = u as usize;
                let step = points[u].iter().zip(&points[v]).map(|(a, b)| (a - b) * (a - b)).sum::<f64>().sqrt();
                let next = g + step;
                if next < self.distance[u] {
                    if self.distance[u].is_infinite() {
                        self.touched.push(u as u32);
                    }
                    self.distance[u] = next;
                    heap.push(Entry(next, u as u32));
                }
            }
        }
        // Not reached within the bound: farther than ratio x d along the surface.
        far.extend(candidates.iter().zip(&settled).filter(|(_, &done)| !done).map(|(&c, _)| c));
        for &(j, _) in candidates {
            self.candidate[j] = 0;
        }
        for &v in &self.touched {
            self.distance[v as usize] = f64::INFINITY;
        }
        self.touched.clear();
        far.sort_by_key(|&(j, _)| j);
        far
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A flattened tube along x: its cross-section is a thin closed loop, a lower row at
    /// z = 0 and an upper row at z = `gap` (y from -0.5 to 0.5), joined at y = +-0.5. Opposite
    /// rows are close in space but far along the surface, like two lips joined at the
    /// corners. `len` cross-sections 0.1 apart; returns positions and triangles.
    pub fn folded_strip(len: usize, gap: f32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let steps = 10;
        let mut profile: Vec<[f32; 2]> = (0..=steps).map(|s| [-0.5 + s as f32 / steps as f32, 0.0]).collect();
        profile.extend((0..=steps).rev().map(|s| [-0.5 + s as f32 / steps as f32, gap]));
        let rows = profile.len();
        let mut pts = Vec::new();
        for i in 0..len {
            for q in &profile {
                pts.push([i as f32 * 0.1, q[0], q[1]]);
            }
        }
        let mut tris = Vec::new();
        for i in 0..len - 1 {
            for r in 0..rows {
                let a = (i * rows + r) as u32;
                let b = (i * rows + (r + 1) % rows) as u32;
                let c = a + rows as u32;
                let d = b + rows as u32;
                tris.push([a, b, d]);
                tris.push([a, d, c]);
            }
        }
        (pts, tris)
    }

    #[test]
    fn pairs_across_a_thin_gap_only() {
        let (pts, tris) = folded_strip(12, 0.02);
        let params = VirtualEdgeParams { tau_d: 0.1, ..Default::default() };
        let edges = find_virtual_edges(&pts, &tris, &params);
        assert!(!edges.is_empty());
        let diag = bbox_diagonal(&pts) as f32;
        for &(i, j) in &edges {
            let (p, q) = (pts[i as usize], pts[j as usize]);
            let d = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
            assert!(i < j && d < 0.1 * diag);
            // One end on each layer, away from the walls.
            assert!((p[2] - q[2]).abs() > 0.015, "{p:?} {q:?}");
        }
        let mut count = vec![0; pts.len()];
        for &(i, j) in &edges {
            count[i as usize] += 1;
            count[j as usize] += 1;
        }
        assert!(count.iter().all(|&c| c <= 3));
        // Thinning: no taken end is a one-ring neighbour of an end taken earlier.
        let adjacency = Adjacency::from_triangles(pts.len(), &tris);
        for (k, &(i, j)) in edges.iter().enumerate() {
            for &(a, b) in &edges[..k] {
                for end in [a, b] {
                    let ring = adjacency.neighbours(end as usize);
                    assert!(!ring.contains(&i) && !ring.contains(&j));
                }
            }
        }
    }

    #[test]
    fn flat_sheet_and_separate_pieces_have_none() {
        let (pts, tris) = folded_strip(6, 0.02);
        // A second copy shifted just beside the first: close, but another piece.
        let offset = pts.len() as u32;
        let mut all = pts.clone();
        all.extend(pts.iter().map(|p| [p[0], p[1], p[2] + 0.03]));
        let mut all_tris = tris.clone();
        all_tris.extend(tris.iter().map(|t| t.map(|v| v + offset)));
        let wide = VirtualEdgeParams { tau_d: 0.1, ..Default::default() };
        let within_first: Vec<_> = find_virtual_edges(&pts, &tris, &wide);
        let both = find_virtual_edges(&all, &all_tris, &wide);
        assert!(both.iter().all(|&(i, j)| (i < offset) == (j < offset)));
        assert!(!within_first.is_empty());
        // A thick slab: only same-layer neighbours are close, and they are close along the
        // surface too.
        let (open, open_tris) = folded_strip(6, 0.5);
        assert!(find_virtual_edges(&open, &open_tris, &wide).is_empty());
    }
}
