//! Virtual edges (Li, Shen & Liu 2023, section 4): vertex pairs that are close in space but
//! far apart along the surface (opposite lips, eyelids, nostril walls). A soft spring on
//! each pair keeps the layers from passing through each other during transfer.
//!
//! Candidates `F_i = { j : d_ij < tau_d }` from a k-d tree; kept when the geodesic distance
//! `g_ij` (shortest path on the edge graph) exceeds `tau_r x d_ij` (the paper's
//! `G_i = { j in F_i : g_ij / d_ij > tau_r }`). Then, shortest first, at most
//! `max_per_vertex` edges per vertex, and once a pair is taken the one-ring neighbours of
//! both ends take no further edge (the paper's thinning).
//!
//! The result is exactly that definition, computed lazily: a breadth-first pass per vertex
//! proves most pairs close with no heap (the lengths of the paths it finds bound `g_ij` from
//! above), and the rest are checked by an A* search bounded at `tau_r x d_ij` only when the
//! thinning reaches them unblocked. Far pairs need a search over a ball of radius
//! `tau_r x d_ij`; most of them sit beside a shorter pair that blocks them first. Same edges,
//! measured on 2 cores against one bounded Dijkstra per vertex: 0.22 -> 0.09 s on the 19k
//! subdivided MakeHuman head, 0.44 -> 0.20 s on its 25k version with a denser face.
//!
//! The A* searches prune with a lower bound on the remaining path: the Euclidean distance,
//! and the landmark bound `|g(L, u) - g(L, j)|` (the triangle inequality of graph distances;
//! Goldberg & Harrelson 2005, "ALT") from six landmarks per piece, its extreme vertices along
//! the axes, each a Dijkstra over the piece computed once. Across a lip or a lid the two
//! layers' distances from the top or the bottom of the piece differ by the way round the
//! opening, so a far pair is proven far without exploring the ball around it. Any lower bound
//! leaves a search's answer as it was (see `reaches_within`): the same edges. On the 25k head
//! the whole search went from 0.33 to 0.26 CPU-seconds on one thread (`find_virtual_edges`,
//! the same 401 edges); the breadth-first pass is now about two thirds of it.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use rayon::prelude::*;

use super::gradients::{length, sub};
use crate::geometry::neighbours::PointTree;
use crate::geometry::topology::{connected_components, Adjacency};
use crate::rig::bbox_diagonal;

/// Knobs of the virtual-edge search; distances are fractions of the target's bbox diagonal.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
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
    let (labels, n_pieces) = connected_components(n, triangles);
    let trees = PieceTrees::new(neutral, &labels, n_pieces);
    let graph = EdgeGraph::new(&points, triangles);

    // Pairs (d_ij, i, j), i < j, that no short path proves close, shortest first.
    // Each split of the range keeps one scratch, ball and list for all its vertices.
    let mut uncertain: Vec<(f64, u32, u32)> = spatial_order(&points)
        .into_par_iter()
        .with_min_len(512) // each split allocates its own O(N) scratch
        .fold(
            || (SurfaceSearch::new(n), Vec::new(), Vec::new()),
            |(mut search, mut ball, mut open), i| {
                let i = i as usize;
                ball.clear();
                ball.extend(trees.within(labels[i], points[i], radius).filter(|&(j, d)| j != i && d < radius));
                search.not_proven_close(&graph, i, &ball, params.tau_r, &mut open);
                (search, ball, open)
            },
        )
        .flat_map_iter(|(_, _, open)| open)
        .collect();
    uncertain.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let bounds = if uncertain.is_empty() { None } else { Some(LandmarkBounds::new(&graph, &points, &labels)) };
    let bounds = Distances { points: &points, landmarks: bounds.as_ref() };

    let mut used = vec![0usize; n];
    let mut blocked = vec![false; n];
    let free = |used: &[usize], blocked: &[bool], i: u32, j: u32| {
        let (a, b) = (i as usize, j as usize);
        !blocked[a] && !blocked[b] && used[a] < params.max_per_vertex && used[b] < params.max_per_vertex
    };
    let mut edges = Vec::new();
    let mut next = 0;
    // Scratch handed from batch to batch: a fresh one per split of every batch cleared
    // 0.6 MB each time on the 25k head, 0.20 G of the search's 2.9 G instructions.
    let spare = std::sync::Mutex::new(Vec::new());
    let mut proofs = ClosePaths::new(n);
    while next < uncertain.len() {
        // The next pairs the thinning would take if they are far; checked in parallel, then
        // taken in order (a pair blocked by an earlier one of the batch is skipped).
        let batch: Vec<usize> =
            (next..uncertain.len()).filter(|&k| free(&used, &blocked, uncertain[k].1, uncertain[k].2)).take(FAR_CHECK_BATCH).collect();
        let Some(&last) = batch.last() else { break };
        // Per pair of the batch, the length of a path within its deadline (`None`: far).
        let close: Vec<Option<f64>> = batch
            .par_iter()
            .with_min_len(16)
            .fold(
                || (spare.lock().map(|mut s| s.pop()).ok().flatten().unwrap_or_else(|| SurfaceSearch::new(n)), Vec::new()),
                |(mut search, mut far), &k| {
                    let (d, i, j) = uncertain[k];
                    let (i, j, deadline) = (i as usize, j as usize, params.tau_r * d);
                    far.push(proofs.path_beside(&graph, i, j, deadline).or_else(|| search.path_within(&graph, &bounds, i, j, deadline)));
                    (search, far)
                },
            )
            .flat_map_iter(|(search, far)| {
                if let Ok(mut spare) = spare.lock() {
                    spare.push(search);
                }
                far
            })
            .collect();
        for (&k, &path) in batch.iter().zip(&close) {
            let (_, i, j) = uncertain[k];
            if let Some(length) = path {
                proofs.add(i, j, length);
                continue;
            }
            if !free(&used, &blocked, i, j) {
                continue;
            }
            used[i as usize] += 1;
            used[j as usize] += 1;
            edges.push((i, j));
            for end in [i, j] {
                for &nb in graph.adjacency.neighbours(end as usize) {
                    blocked[nb as usize] = true;
                }
            }
        }
        next = last + 1;
    }
    edges
}

/// One k-d tree per connected piece, so that a vertex's ball is gathered from its own piece
/// alone: on a head whose pieces crowd the skin (lashes copied over the lids, eyeballs and
/// gums crossing it) a tree over every vertex returned the other pieces' vertices too, only
/// for them to be dropped.
struct PieceTrees {
    trees: Vec<PointTree>,
    /// Per piece, its vertices' indices in the mesh, in the order of its tree's items.
    members: Vec<Vec<usize>>,
}

impl PieceTrees {
    fn new(points: &[[f32; 3]], labels: &[u32], n_pieces: usize) -> Self {
        let mut members = vec![Vec::new(); n_pieces];
        for (v, &label) in labels.iter().enumerate() {
            members[label as usize].push(v);
        }
        let trees = members.iter().map(|piece| PointTree::new(&piece.iter().map(|&v| points[v]).collect::<Vec<_>>())).collect();
        Self { trees, members }
    }

    /// The vertices of piece `label` within `radius` of `query` (inclusive), with their
    /// distances.
    fn within(&self, label: u32, query: [f64; 3], radius: f64) -> impl Iterator<Item = (usize, f64)> + '_ {
        let piece = &self.members[label as usize];
        self.trees[label as usize].within(query, radius).into_iter().map(move |(k, d)| (piece[k], d))
    }
}

/// The pairs the thinning proved close, with the length of the path that proved each: a
/// pair beside one of them (each end equal or adjacent to the proven pair's) is close when
/// the path through it, `|a i| + g_ij + |j b|`, is within its own deadline. Uncertain pairs
/// come in rows along a lip or a lid, and on a dense mesh most of a row's neighbours are
/// proven close this way without a search of their own.
struct ClosePaths {
    /// Per vertex, its partners in proven pairs and the paths' lengths.
    partners: Vec<Vec<(u32, f64)>>,
}

impl ClosePaths {
    fn new(n: usize) -> Self {
        Self { partners: vec![Vec::new(); n] }
    }

    fn add(&mut self, i: u32, j: u32, length: f64) {
        self.partners[i as usize].push((j, length));
        self.partners[j as usize].push((i, length));
    }

    /// The length of a path from `a` to `b` through a proven pair, when one is within
    /// `deadline`.
    fn path_beside(&self, graph: &EdgeGraph, a: usize, b: usize, deadline: f64) -> Option<f64> {
        let steps = |v: usize| {
            let row = graph.adjacency.offsets[v]..graph.adjacency.offsets[v + 1];
            std::iter::once((v as u32, 0.0)).chain(graph.adjacency.targets[row.clone()].iter().copied().zip(graph.lengths[row].iter().copied()))
        };
        for (i, to_i) in steps(a) {
            for &(j, length) in &self.partners[i as usize] {
                if to_i + length > deadline {
                    continue;
                }
                if let Some((_, to_b)) = steps(b).find(|&(u, _)| u == j) {
                    let through = to_i + length + to_b;
                    if through <= deadline {
                        return Some(through);
                    }
                }
            }
        }
        None
    }
}

/// The vertices along a Z-order curve over the bounding box, so that the balls searched one
/// after the other overlap and their vertices stay in cache (the production bench's 77k
/// target, one thread: 1.58 -> 1.37 CPU-seconds; subdivided meshes number their vertices by
/// level, not by place).
fn spatial_order(points: &[[f64; 3]]) -> Vec<u32> {
    let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for p in points {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a]);
            hi[a] = hi[a].max(p[a]);
        }
    }
    let cells = f64::from(1u32 << 10);
    let code = |p: &[f64; 3]| {
        (0..3).fold(0u32, |code, a| {
            let cell = ((p[a] - lo[a]) / (hi[a] - lo[a]).max(f64::MIN_POSITIVE) * cells).clamp(0.0, cells - 1.0) as u32;
            (0..10).fold(code, |code, bit| code | ((cell >> bit) & 1) << (3 * bit + a))
        })
    };
    let mut order: Vec<(u32, u32)> = points.iter().enumerate().map(|(v, p)| (code(p), v as u32)).collect();
    order.sort_unstable();
    order.into_iter().map(|(_, v)| v).collect()
}

fn distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    length(sub(*a, *b))
}

/// Landmarks per piece for the lower bounds: the piece's extreme vertices along the axes.
const LANDMARKS: usize = 6;

/// Per vertex, the edge-graph distance from each of its piece's [`LANDMARKS`] landmarks.
struct LandmarkBounds {
    from: Vec<[f64; LANDMARKS]>,
}

impl LandmarkBounds {
    /// One multi-source Dijkstra per landmark slot, all pieces at once: slot `s` starts from
    /// the `s`-th landmark of every piece, and a vertex can be reached only from its own
    /// piece's.
    fn new(graph: &EdgeGraph, points: &[[f64; 3]], pieces: &[u32]) -> Self {
        let n = points.len();
        let n_pieces = pieces.iter().map(|&p| p as usize + 1).max().unwrap_or(0);
        // Slot 2a: least coordinate a; slot 2a + 1: greatest (the lowest index on ties).
        let mut chosen = vec![[usize::MAX; LANDMARKS]; n_pieces];
        for (v, p) in points.iter().enumerate() {
            let slots = &mut chosen[pieces[v] as usize];
            for a in 0..3 {
                let (low, high) = (2 * a, 2 * a + 1);
                if slots[low] == usize::MAX || p[a] < points[slots[low]][a] {
                    slots[low] = v;
                }
                if slots[high] == usize::MAX || p[a] > points[slots[high]][a] {
                    slots[high] = v;
                }
            }
        }
        let per_slot: Vec<Vec<f64>> = (0..LANDMARKS)
            .into_par_iter()
            .map(|slot| {
                let mut distance = vec![f64::INFINITY; n];
                let mut heap = BinaryHeap::new();
                for landmarks in &chosen {
                    distance[landmarks[slot]] = 0.0;
                    heap.push(entry(0.0, landmarks[slot]));
                }
                while let Some(Reverse((bits, v))) = heap.pop() {
                    let v = v as usize;
                    if f64::from_bits(bits) > distance[v] {
                        continue;
                    }
                    let row = graph.adjacency.offsets[v]..graph.adjacency.offsets[v + 1];
                    for (&u, &step) in graph.adjacency.targets[row.clone()].iter().zip(&graph.lengths[row]) {
                        let next = distance[v] + step;
                        if next < distance[u as usize] {
                            distance[u as usize] = next;
                            heap.push(entry(next, u as usize));
                        }
                    }
                }
                distance
            })
            .collect();
        Self { from: (0..n).map(|v| std::array::from_fn(|slot| per_slot[slot][v])).collect() }
    }

    /// A lower bound on the edge-graph distance between `u` and `t` (one piece): the largest
    /// `|g(L, u) - g(L, t)|`, less a relative `1e-9` so that the rounding of the two sums
    /// can never lift it above the distance it bounds.
    fn between(&self, u: usize, t: usize) -> f64 {
        let (a, b) = (&self.from[u], &self.from[t]);
        let mut bound = 0.0f64;
        for slot in 0..LANDMARKS {
            let gap = (a[slot] - b[slot]).abs() - 1e-9 * a[slot].max(b[slot]);
            bound = bound.max(gap);
        }
        bound
    }
}

/// The A* searches' lower bound on the remaining path to a vertex: the Euclidean distance,
/// and the landmark bound when there are landmarks.
struct Distances<'a> {
    points: &'a [[f64; 3]],
    landmarks: Option<&'a LandmarkBounds>,
}

impl Distances<'_> {
    fn at_least(&self, u: usize, t: usize) -> f64 {
        let straight = distance(&self.points[u], &self.points[t]);
        match self.landmarks {
            Some(landmarks) => straight.max(landmarks.between(u, t)),
            None => straight,
        }
    }
}

/// The heuristic's weight of the quick search that proves most uncertain pairs close.
const GREEDY_WEIGHT: f64 = 3.0;

/// Pairs checked for farness at once by the thinning: enough to keep both cores busy, few
/// enough that pairs blocked by an earlier one of the same batch are rarely checked.
const FAR_CHECK_BATCH: usize = 128;

/// The mesh's edge graph with each edge's length beside its target (compressed rows).
struct EdgeGraph {
    adjacency: Adjacency,
    lengths: Vec<f64>,
}

impl EdgeGraph {
    fn new(points: &[[f64; 3]], triangles: &[[u32; 3]]) -> Self {
        let adjacency = Adjacency::from_triangles(points.len(), triangles);
        let lengths = (0..points.len())
            .flat_map(|v| adjacency.neighbours(v).iter().map(move |&u| distance(&points[u as usize], &points[v])))
            .collect();
        Self { adjacency, lengths }
    }
}

/// A heap entry: a non-negative estimate's bits (which order as the estimates do) and the
/// vertex, so the min-heap compares integers; ties go to the lower vertex index.
type Entry = Reverse<(u64, u32)>;

fn entry(estimate: f64, vertex: usize) -> Entry {
    Reverse((estimate.to_bits(), vertex as u32))
}

/// Reusable per-thread search state: distances and marks reset only where touched, so a
/// search costs the size of its ball, not N.
struct SurfaceSearch {
    distance: Vec<f64>,
    /// Per vertex: the bits of the estimate it was last queued with in [`Self::reaches_within`]
    /// (set whenever its distance is), so that a popped entry is known stale without
    /// measuring the distance to the target again.
    queued_estimate: Vec<u64>,
    touched: Vec<u32>,
    /// Per vertex: the current source plus one when the vertex lies in its Euclidean ball.
    in_ball: Vec<u32>,
    queue: Vec<u32>,
    heap: BinaryHeap<Entry>,
}

impl SurfaceSearch {
    fn new(n: usize) -> Self {
        Self {
            distance: vec![f64::INFINITY; n],
            queued_estimate: vec![0; n],
            touched: Vec::new(),
            in_ball: vec![0; n],
            queue: Vec::new(),
            heap: BinaryHeap::new(),
        }
    }

    /// Appends to `open` the pairs `(d_ij, source, j)`, `j > source`, of the Euclidean `ball`
    /// around `source` that a breadth-first pass inside the ball does not reach within
    /// `ratio x d_ij`. Each vertex keeps the shortest of the paths that reached it; any path's
    /// length bounds `g_ij` from above, so every pair left out is close. On smooth skin that
    /// is all of them.
    fn not_proven_close(&mut self, graph: &EdgeGraph, source: usize, ball: &[(usize, f64)], ratio: f64, open: &mut Vec<(f64, u32, u32)>) {
        let pending = ball.iter().filter(|&&(j, _)| j > source).count();
        if pending == 0 {
            return;
        }
        self.breadth_first(graph, source, ball, pending, |u| u > source);
        open.extend(ball.iter().filter(|&&(j, d)| j > source && self.distance[j] > ratio * d).map(|&(j, d)| (d, source as u32, j as u32)));
        self.reset_distances();
    }

    /// A breadth-first pass from `source` over the vertices of `region`, until `targets`
    /// vertices for which `is_target` holds are reached; leaves the path lengths found in
    /// `distance` (reset by the caller).
    fn breadth_first(&mut self, graph: &EdgeGraph, source: usize, region: &[(usize, f64)], targets: usize, is_target: impl Fn(usize) -> bool) {
        let mut pending = targets;
        let stamp = source as u32 + 1;
        for &(j, _) in region {
            self.in_ball[j] = stamp;
        }
        self.queue.clear();
        self.queue.push(source as u32);
        self.distance[source] = 0.0;
        self.touched.push(source as u32);
        let mut head = 0;
        while head < self.queue.len() && pending > 0 {
            let v = self.queue[head] as usize;
            head += 1;
            let row = graph.adjacency.offsets[v]..graph.adjacency.offsets[v + 1];
            for (&u, &step) in graph.adjacency.targets[row.clone()].iter().zip(&graph.lengths[row]) {
                let u = u as usize;
                if self.in_ball[u] != stamp {
                    continue;
                }
                let through_v = self.distance[v] + step;
                if self.distance[u].is_infinite() {
                    self.touched.push(u as u32);
                    self.queue.push(u as u32);
                    pending -= usize::from(is_target(u));
                }
                // Queued vertices keep the shortest path seen so far (a later, shorter one
                // matters where edge lengths vary a lot, e.g. beside split n-gons).
                self.distance[u] = self.distance[u].min(through_v);
            }
        }
    }

    /// The length of an edge path from `source` to `target` no longer than `deadline`, or
    /// `None` when every path is longer (the pair is far). A
    /// greedy search (weighted A*) usually finds a short enough path at once; when it runs
    /// out of vertices instead, that proves the pair far ([`Self::reaches_within`]), so no
    /// exact search follows it (it would explore the same region again and find the same;
    /// few greedy searches fail on a close pair, so this saves little: the searches' 0.91 ->
    /// 0.89 G instructions on the 25k head, one thread, the same edges).
    fn path_within(&mut self, graph: &EdgeGraph, bounds: &Distances, source: usize, target: usize, deadline: f64) -> Option<f64> {
        self.reaches_within(graph, bounds, source, target, deadline, GREEDY_WEIGHT)
    }

    /// A* from `source` to `target` ordered by `g + weight x h`, `h` a lower bound on the
    /// edge-graph distance to `target` ([`Distances::at_least`]), pruned where `g + h` exceeds
    /// `deadline` (no path through there can make it). It reaches `target` iff some path is no longer than `deadline`, whatever the
    /// weight: the order only decides how soon. There is no closed set (a vertex is expanded
    /// again whenever a shorter path to it turns up), so a search that runs out of vertices
    /// has settled every vertex at its shortest admitted distance (the least fixed point of
    /// `g(u) = min g(v) + |uv|` over the edges that pass the pruning, the same for any order:
    /// rounding is monotone), and a path within `deadline` passes the pruning at every vertex
    /// (`g + h` along it never exceeds its length, `h` being a lower bound), so its
    /// next-to-last vertex would have reached `target`. A larger weight runs straight at the
    /// target (most pairs are close); a tighter bound prunes more.
    fn reaches_within(
        &mut self,
        graph: &EdgeGraph,
        bounds: &Distances,
        source: usize,
        target: usize,
        deadline: f64,
        weight: f64,
    ) -> Option<f64> {
        let to_target = |v: usize| bounds.at_least(v, target);
        self.heap.clear();
        self.distance[source] = 0.0;
        self.touched.push(source as u32);
        let start = entry(weight * to_target(source), source);
        self.queued_estimate[source] = start.0 .0;
        self.heap.push(start);
        let mut reached = None;
        'search: while let Some(Reverse((bits, v))) = self.heap.pop() {
            let v = v as usize;
            let g = self.distance[v];
            // `g + weight x h(v)` as last queued: a different one means a shorter path since.
            if self.queued_estimate[v] != bits {
                continue; // superseded by a shorter path
            }
            let row = graph.adjacency.offsets[v]..graph.adjacency.offsets[v + 1];
            for (&u, &step) in graph.adjacency.targets[row.clone()].iter().zip(&graph.lengths[row]) {
                let u = u as usize;
                let next = g + step;
                if u == target && next <= deadline {
                    reached = Some(next);
                    break 'search;
                }
                // The distance to the target only for a shorter path (most neighbours have one).
                if next >= self.distance[u] {
                    continue;
                }
                let h = to_target(u);
                if next + h <= deadline {
                    if self.distance[u].is_infinite() {
                        self.touched.push(u as u32);
                    }
                    self.distance[u] = next;
                    let queued = entry(next + weight * h, u);
                    self.queued_estimate[u] = queued.0 .0;
                    self.heap.push(queued);
                }
            }
        }
        self.reset_distances();
        reached
    }

    fn reset_distances(&mut self) {
        for &v in &self.touched {
            self.distance[v as usize] = f64::INFINITY;
        }
        self.touched.clear();
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

    /// The paper's definition, computed the slow way: full Dijkstra from every vertex, every
    /// close pair of one piece with `g > tau_r d` kept, then the same thinning, shortest first.
    fn by_definition(neutral: &[[f32; 3]], triangles: &[[u32; 3]], params: &VirtualEdgeParams) -> Vec<(u32, u32)> {
        let n = neutral.len();
        let points: Vec<[f64; 3]> = neutral.iter().map(|p| p.map(f64::from)).collect();
        let radius = params.tau_d * bbox_diagonal(neutral);
        let adjacency = Adjacency::from_triangles(n, triangles);
        let mut far = Vec::new();
        for i in 0..n {
            let mut g = vec![f64::INFINITY; n];
            let mut done = vec![false; n];
            g[i] = 0.0;
            while let Some(v) = (0..n).filter(|&v| !done[v] && g[v].is_finite()).min_by(|&a, &b| g[a].total_cmp(&g[b])) {
                done[v] = true;
                for &u in adjacency.neighbours(v) {
                    g[u as usize] = g[u as usize].min(g[v] + distance(&points[v], &points[u as usize]));
                }
            }
            for j in i + 1..n {
                let d = distance(&points[i], &points[j]);
                // Another piece (no path at all) is no candidate.
                if d < radius && g[j].is_finite() && g[j] > params.tau_r * d {
                    far.push((d, i as u32, j as u32));
                }
            }
        }
        far.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        let (mut used, mut blocked, mut edges) = (vec![0; n], vec![false; n], Vec::new());
        for (_, i, j) in far {
            let (a, b) = (i as usize, j as usize);
            if blocked[a] || blocked[b] || used[a] >= params.max_per_vertex || used[b] >= params.max_per_vertex {
                continue;
            }
            used[a] += 1;
            used[b] += 1;
            edges.push((i, j));
            for end in [a, b] {
                for &nb in adjacency.neighbours(end) {
                    blocked[nb as usize] = true;
                }
            }
        }
        edges
    }

    #[test]
    fn lazy_search_gives_the_edges_of_the_definition() {
        // A jittered strip (uneven edges, so breadth-first paths are not shortest) and, with
        // the wider thresholds, close pairs around the folds whose short paths leave the
        // Euclidean ball: both of the lazy search's shortcuts are exercised.
        let (mut pts, tris) = folded_strip(12, 0.04);
        let mut state = 12345u64;
        for p in pts.iter_mut() {
            for coordinate in &mut p[..2] {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                *coordinate += ((state >> 33) as f32 / (1u64 << 31) as f32 - 0.5) * 0.06;
            }
        }
        for (tau_d, tau_r) in [(0.05, 4.0), (0.1, 4.0), (0.2, 2.0), (0.3, 1.5)] {
            let params = VirtualEdgeParams { tau_d, tau_r, ..Default::default() };
            let expected = by_definition(&pts, &tris, &params);
            assert!(!expected.is_empty(), "tau_d {tau_d}, tau_r {tau_r}: no edges to compare");
            assert_eq!(find_virtual_edges(&pts, &tris, &params), expected, "tau_d {tau_d}, tau_r {tau_r}");
        }
    }

    #[test]
    fn landmark_bounds_keep_the_edges_of_the_definition_on_several_pieces() {
        // Two jittered strips of other shapes, far enough apart that no pair joins them: each
        // piece searches with its own landmarks (one multi-source Dijkstra per slot serves
        // both), and the pruned searches must still find exactly the definition's edges.
        let (first, first_tris) = folded_strip(10, 0.05);
        let (second, second_tris) = folded_strip(7, 0.03);
        let offset = first.len() as u32;
        let mut pts: Vec<[f32; 3]> = first.clone();
        pts.extend(second.iter().map(|p| [p[1] + 3.0, p[0] * 1.3, p[2] - 0.2]));
        let mut tris = first_tris;
        tris.extend(second_tris.iter().map(|t| t.map(|v| v + offset)));
        let mut state = 987654321u64;
        for p in pts.iter_mut() {
            for coordinate in p.iter_mut() {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                *coordinate += ((state >> 33) as f32 / (1u64 << 31) as f32 - 0.5) * 0.01;
            }
        }
        for (tau_d, tau_r) in [(0.02, 4.0), (0.04, 3.0), (0.08, 1.5)] {
            let params = VirtualEdgeParams { tau_d, tau_r, ..Default::default() };
            let expected = by_definition(&pts, &tris, &params);
            assert!(expected.iter().any(|&(i, _)| i < offset) && expected.iter().any(|&(i, _)| i >= offset), "tau_d {tau_d}: both pieces need edges");
            assert_eq!(find_virtual_edges(&pts, &tris, &params), expected, "tau_d {tau_d}, tau_r {tau_r}");
        }
    }

    #[test]
    fn crossing_lips_among_many_pieces_give_the_edges_of_the_definition() {
        // A folded strip whose upper layer dips through the lower one mid-way (lips crossing
        // at rest), a second strip across it and a small one threaded through both (pieces
        // crossing the skin, as lashes and gums do), jittered: close pairs on both sides of
        // the crossing, far pairs between the layers, and other pieces within every ball.
        let (lips, lips_tris) = folded_strip(12, 0.04);
        let mut pts: Vec<[f32; 3]> = lips
            .iter()
            .map(|&[x, y, z]| {
                let dip = if z > 0.02 && y.abs() < 0.45 { 0.08 * (1.0 - (x - 0.55).abs() / 0.3).max(0.0) } else { 0.0 };
                [x, y, z - dip]
            })
            .collect();
        let mut tris = lips_tris;
        for (section, gap, place) in [(8, 0.05, [0.3f32, -0.2, -0.05]), (5, 0.02, [0.5, 0.1, 0.0])] {
            let (piece, piece_tris) = folded_strip(section, gap);
            let offset = pts.len() as u32;
            pts.extend(piece.iter().map(|p| [place[0] + p[1] * 0.6, place[1] + p[0], place[2] + p[2]]));
            tris.extend(piece_tris.iter().map(|t| t.map(|v| v + offset)));
        }
        let mut state = 424242u64;
        for p in pts.iter_mut() {
            for coordinate in p.iter_mut() {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                *coordinate += ((state >> 33) as f32 / (1u64 << 31) as f32 - 0.5) * 0.01;
            }
        }
        let (labels, pieces) = connected_components(pts.len(), &tris);
        assert_eq!(pieces, 3);
        for (tau_d, tau_r) in [(0.03, 4.0), (0.06, 4.0), (0.1, 3.0), (0.2, 1.5)] {
            let params = VirtualEdgeParams { tau_d, tau_r, ..Default::default() };
            let expected = by_definition(&pts, &tris, &params);
            let with_edges = (0..3).filter(|&piece| expected.iter().any(|&(i, _)| labels[i as usize] == piece)).count();
            assert!(with_edges >= 2, "tau_d {tau_d}: edges on {with_edges} pieces");
            assert_eq!(find_virtual_edges(&pts, &tris, &params), expected, "tau_d {tau_d}, tau_r {tau_r}");
        }
    }

    #[test]
    fn landmark_bound_is_a_lower_bound_on_every_pair() {
        let (pts, tris) = folded_strip(8, 0.04);
        let points: Vec<[f64; 3]> = pts.iter().map(|p| p.map(f64::from)).collect();
        let graph = EdgeGraph::new(&points, &tris);
        let (labels, _) = connected_components(pts.len(), &tris);
        let bounds = LandmarkBounds::new(&graph, &points, &labels);
        let adjacency = Adjacency::from_triangles(pts.len(), &tris);
        let mut tight = 0;
        for i in 0..pts.len() {
            // Dijkstra by scanning, as `by_definition` does.
            let mut g = vec![f64::INFINITY; pts.len()];
            let mut done = vec![false; pts.len()];
            g[i] = 0.0;
            while let Some(v) = (0..pts.len()).filter(|&v| !done[v] && g[v].is_finite()).min_by(|&a, &b| g[a].total_cmp(&g[b])) {
                done[v] = true;
                for &u in adjacency.neighbours(v) {
                    g[u as usize] = g[u as usize].min(g[v] + distance(&points[v], &points[u as usize]));
                }
            }
            for j in 0..pts.len() {
                let bound = bounds.between(i, j);
                assert!(bound <= g[j] * (1.0 + 1e-12), "{i} {j}: bound {bound} above the distance {}", g[j]);
                tight += usize::from(bound > distance(&points[i], &points[j]) * 1.5);
            }
        }
        // Across the fold the bound is far above the straight distance: that is its use.
        assert!(tight > pts.len(), "only {tight} pairs with a bound above 1.5x the straight distance");
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
