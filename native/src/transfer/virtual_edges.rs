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
//!
//! A key's contacts (`key_contacts.rs`) are the same definition on the template posed by the
//! key, among pairs apart at rest that it brings to touch.

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
    let trees = PieceTrees::new(neutral, &labels, n_pieces, 0..n);
    let adjacency = Adjacency::from_triangles(n, triangles);
    let graph = EdgeGraph::new(&points, &adjacency);
    let search = FarPairs { points: &points, labels: &labels, graph: &graph, params };
    let ball = |i: usize, ball: &mut Vec<(usize, f64)>| {
        ball.extend(trees.within(labels[i], points[i], radius).filter(|&(j, d)| j != i && d < radius));
    };
    search.thinned(spatial_order(&points), ball, |i, j| j > i, true)
}

/// One far-pair search: close pairs (one piece) that are far along the surface
/// (`g_ij > tau_r d_ij`), thinned. Its answer does not depend on the region each source's
/// breadth-first pass covers (its `ball`): that pass only proves pairs close by paths it
/// finds, and every pair it leaves open is decided by an exact bounded search.
pub(super) struct FarPairs<'a, L: EdgeLengths> {
    pub points: &'a [[f64; 3]],
    pub labels: &'a [u32],
    pub graph: &'a EdgeGraph<'a, L>,
    pub params: &'a VirtualEdgeParams,
}

impl<L: EdgeLengths> FarPairs<'_, L> {
    /// The virtual edges `(i, j)`, `i < j`, among the pairs `(i, j)` with `i` in `sources`,
    /// `(j, d_ij)` among those `ball(i, ..)` appends, and `candidate(i, j)`, shortest first:
    /// at most `max_per_vertex` per vertex, and once a pair is taken the one-ring neighbours
    /// of both ends take no further edge. `landmarks`: prune the farness checks with
    /// [`LandmarkBounds`] (worth its six whole-mesh Dijkstras when the sources are the whole
    /// mesh).
    pub(super) fn thinned(
        &self,
        sources: Vec<u32>,
        ball: impl Fn(usize, &mut Vec<(usize, f64)>) + Sync,
        candidate: impl Fn(usize, usize) -> bool + Sync,
        landmarks: bool,
    ) -> Vec<(u32, u32)> {
        let (n, params, graph, gather) = (self.points.len(), self.params, self.graph, ball);
        // Pairs (d_ij, i, j), i < j, that no short path proves close, shortest first.
        // Each split of the range keeps one scratch, ball and list for all its vertices.
        let mut uncertain: Vec<(f64, u32, u32)> = sources
            .into_par_iter()
            .with_min_len(512) // each split allocates its own O(N) scratch
            .fold(
                || (SurfaceSearch::new(n), Vec::new(), Vec::new()),
                |(mut search, mut ball, mut open), i| {
                    let i = i as usize;
                    ball.clear();
                    gather(i, &mut ball);
                    search.not_proven_close(graph, i, &ball, params.tau_r, |j| candidate(i, j), &mut open);
                    (search, ball, open)
                },
            )
            .flat_map_iter(|(_, _, open)| open)
            .collect();
        uncertain.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
        let bounds = if uncertain.is_empty() || !landmarks { None } else { Some(LandmarkBounds::new(graph, self.points, self.labels)) };
        let bounds = Distances { points: self.points, landmarks: bounds.as_ref() };

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
                        far.push(proofs.path_beside(graph, i, j, deadline).or_else(|| search.path_within(graph, &bounds, i, j, deadline)));
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
}

/// One k-d tree per connected piece, so that a vertex's ball is gathered from its own piece
/// alone: on a head whose pieces crowd the skin (lashes copied over the lids, eyeballs and
/// gums crossing it) a tree over every vertex returned the other pieces' vertices too, only
/// for them to be dropped.
pub(super) struct PieceTrees {
    trees: Vec<PointTree>,
    /// Per piece, its vertices' indices in the mesh, in the order of its tree's items.
    members: Vec<Vec<usize>>,
}

impl PieceTrees {
    /// Trees over the vertices `vertices` only (increasing).
    pub(super) fn new(points: &[[f32; 3]], labels: &[u32], n_pieces: usize, vertices: impl Iterator<Item = usize>) -> Self {
        let mut members = vec![Vec::new(); n_pieces];
        for v in vertices {
            members[labels[v] as usize].push(v);
        }
        let trees = members.iter().map(|piece| PointTree::new(&piece.iter().map(|&v| points[v]).collect::<Vec<_>>())).collect();
        Self { trees, members }
    }

    /// The vertices of piece `label` within `radius` of `query` (inclusive), with their
    /// distances.
    pub(super) fn within(&self, label: u32, query: [f64; 3], radius: f64) -> impl Iterator<Item = (usize, f64)> + '_ {
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
    fn path_beside<L: EdgeLengths>(&self, graph: &EdgeGraph<L>, a: usize, b: usize, deadline: f64) -> Option<f64> {
        let steps = |v: usize| {
            std::iter::once((v as u32, 0.0)).chain(graph.steps(v))
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
pub(super) fn spatial_order(points: &[[f64; 3]]) -> Vec<u32> {
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

pub(super) fn distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
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
    fn new<L: EdgeLengths>(graph: &EdgeGraph<L>, points: &[[f64; 3]], pieces: &[u32]) -> Self {
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
                    for (u, step) in graph.steps(v) {
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

/// The mesh's edge graph with each edge's length, [`Stored`] beside its target (compressed
/// rows) where every vertex is searched from, else [`Measured`] when stepped over, where few
/// are (a key's contacts: storing them cost a pass over every edge per key, a third of the 25k
/// head's search). The same lengths either way, `|p_u - p_v|` in one order; a type, not a
/// branch per step, which cost the rest's search 9% more instructions.
pub(super) struct EdgeGraph<'a, L: EdgeLengths> {
    adjacency: &'a Adjacency,
    lengths: L,
}

impl<'a> EdgeGraph<'a, Stored> {
    pub(super) fn new(points: &[[f64; 3]], adjacency: &'a Adjacency) -> Self {
        let lengths = (0..points.len())
            .flat_map(|v| adjacency.neighbours(v).iter().map(move |&u| distance(&points[u as usize], &points[v])))
            .collect();
        Self { adjacency, lengths: Stored(lengths) }
    }
}

impl<'a> EdgeGraph<'a, Measured<'a>> {
    pub(super) fn measured(points: &'a [[f64; 3]], adjacency: &'a Adjacency) -> Self {
        Self { adjacency, lengths: Measured(points) }
    }
}

impl<L: EdgeLengths> EdgeGraph<'_, L> {
    /// The neighbours of `v` as `(u, |p_u - p_v|)`.
    #[inline(always)]
    fn steps(&self, v: usize) -> impl Iterator<Item = (u32, f64)> + '_ {
        self.lengths.row(v, self.adjacency.offsets[v]..self.adjacency.offsets[v + 1], &self.adjacency.targets)
    }
}

/// How an [`EdgeGraph`] knows its edges' lengths.
pub(super) trait EdgeLengths: Sync {
    /// The row `v` of the compressed rows `targets[row]` as `(u, |p_u - p_v|)`.
    fn row<'b>(&'b self, v: usize, row: std::ops::Range<usize>, targets: &'b [u32]) -> impl Iterator<Item = (u32, f64)> + 'b;
}

/// Every edge's length, per row entry.
pub(super) struct Stored(Vec<f64>);

/// Lengths measured between these points.
pub(super) struct Measured<'a>(&'a [[f64; 3]]);

impl EdgeLengths for Stored {
    #[inline(always)]
    fn row<'b>(&'b self, _: usize, row: std::ops::Range<usize>, targets: &'b [u32]) -> impl Iterator<Item = (u32, f64)> + 'b {
        targets[row.clone()].iter().copied().zip(self.0[row].iter().copied())
    }
}

impl EdgeLengths for Measured<'_> {
    #[inline(always)]
    fn row<'b>(&'b self, v: usize, row: std::ops::Range<usize>, targets: &'b [u32]) -> impl Iterator<Item = (u32, f64)> + 'b {
        let from = self.0[v];
        targets[row].iter().map(move |&u| (u, distance(&self.0[u as usize], &from)))
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

    /// Appends to `open` the pairs `(d_ij, min, max)` of `source` and the `j` of its Euclidean
    /// `ball` with `candidate(j)` that a breadth-first pass inside the ball does not reach
    /// within `ratio x d_ij`. Each vertex keeps the shortest of the paths that reached it; any
    /// path's length bounds `g_ij` from above, so every pair left out is close. On smooth skin
    /// that is all of them.
    fn not_proven_close<L: EdgeLengths>(
        &mut self,
        graph: &EdgeGraph<L>,
        source: usize,
        ball: &[(usize, f64)],
        ratio: f64,
        candidate: impl Fn(usize) -> bool,
        open: &mut Vec<(f64, u32, u32)>,
    ) {
        let pending = ball.iter().filter(|&&(j, _)| candidate(j)).count();
        if pending == 0 {
            return;
        }
        self.breadth_first(graph, source, ball, pending, &candidate);
        open.extend(
            ball.iter()
                .filter(|&&(j, d)| candidate(j) && self.distance[j] > ratio * d)
                .map(|&(j, d)| (d, source.min(j) as u32, source.max(j) as u32)),
        );
        self.reset_distances();
    }

    /// A breadth-first pass from `source` over the vertices of `region`, until `targets`
    /// vertices for which `is_target` holds are reached; leaves the path lengths found in
    /// `distance` (reset by the caller).
    fn breadth_first<L: EdgeLengths>(&mut self, graph: &EdgeGraph<L>, source: usize, region: &[(usize, f64)], targets: usize, is_target: impl Fn(usize) -> bool) {
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
            for (u, step) in graph.steps(v) {
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
    fn path_within<L: EdgeLengths>(&mut self, graph: &EdgeGraph<L>, bounds: &Distances, source: usize, target: usize, deadline: f64) -> Option<f64> {
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
    fn reaches_within<L: EdgeLengths>(
        &mut self,
        graph: &EdgeGraph<L>,
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
            for (u, step) in graph.steps(v) {
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
#[path = "virtual_edges_tests.rs"]
pub(crate) mod tests;
