//! A bounding-volume hierarchy over a mesh's triangles, for the queries the tools ask:
//! occlusion rays ("does anything lie on this segment?", landmark visibility), box overlaps
//! (candidate pairs for the triangle-triangle tests of transfer's penetration metric) and
//! closest points (the wrap's bindings between two surfaces).
//! Binned surface-area-heuristic build, flat node array, stack traversal.

use super::closest_point::{closest_on_triangle, distance_squared, SurfacePoint};

/// Axis-aligned box; `lo > hi` on every axis when empty.
#[derive(Clone, Copy, Debug)]
pub struct Aabb {
    pub(super) lo: [f64; 3],
    pub(super) hi: [f64; 3],
}

impl Aabb {
    const EMPTY: Aabb = Aabb { lo: [f64::INFINITY; 3], hi: [f64::NEG_INFINITY; 3] };

    pub fn of_points(points: &[[f64; 3]]) -> Self {
        let mut b = Aabb::EMPTY;
        points.iter().for_each(|p| b.grow_point(p));
        b
    }

    /// Closed boxes: touching counts as overlapping. All six comparisons are made and
    /// combined without branching: in the pair sweeps about half the tests fail, at any
    /// axis, and a mispredicted early exit costs more than the comparisons it skips.
    pub fn overlaps(&self, other: &Aabb) -> bool {
        let axis = |a: usize| (self.lo[a] <= other.hi[a]) & (other.lo[a] <= self.hi[a]);
        axis(0) & axis(1) & axis(2)
    }

    fn grow_point(&mut self, p: &[f64; 3]) {
        for (a, &x) in p.iter().enumerate() {
            self.lo[a] = lower(self.lo[a], x);
            self.hi[a] = higher(self.hi[a], x);
        }
    }

    fn grow(&mut self, other: &Aabb) {
        for a in 0..3 {
            self.lo[a] = lower(self.lo[a], other.lo[a]);
            self.hi[a] = higher(self.hi[a], other.hi[a]);
        }
    }

    /// Squared distance from `p` to the box (0 inside).
    fn distance_squared(&self, p: &[f64; 3]) -> f64 {
        (0..3).map(|a| (self.lo[a] - p[a]).max(p[a] - self.hi[a]).max(0.0).powi(2)).sum()
    }

    pub(super) fn half_area(&self) -> f64 {
        let e = [self.hi[0] - self.lo[0], self.hi[1] - self.lo[1], self.hi[2] - self.lo[2]];
        if e.iter().any(|&x| x < 0.0) {
            return 0.0;
        }
        e[0] * e[1] + e[1] * e[2] + e[2] * e[0]
    }

    /// Slab test: where the ray enters the box, if it does at some `t` in `[0, t_max]`.
    fn entry(&self, origin: &[f64; 3], inverse_direction: &[f64; 3], t_max: f64) -> Option<f64> {
        let mut t_enter = 0.0f64;
        let mut t_exit = t_max;
        for a in 0..3 {
            let t0 = (self.lo[a] - origin[a]) * inverse_direction[a];
            let t1 = (self.hi[a] - origin[a]) * inverse_direction[a];
            // `min`/`max` drop a NaN (origin on a slab plane of a parallel ray): keep going.
            t_enter = t_enter.max(t0.min(t1));
            t_exit = t_exit.min(t0.max(t1));
        }
        (t_enter <= t_exit).then_some(t_enter)
    }
}

/// `min(current, x)` for growing a box, as one compare-and-select (`minsd`) where `f64::min`
/// adds a NaN fix-up: a NaN `x` is skipped all the same, and the box never holds one. Only a
/// tie of zeros of both signs can keep the other zero, and no test on a box tells them apart.
/// The bin growth of the build is most of its work: the target's and template's builds on
/// the 25k head, one thread, 0.60 -> 0.41 G instructions.
fn lower(current: f64, x: f64) -> f64 {
    if x < current { x } else { current }
}

/// `max(current, x)` as [`lower`] does it.
fn higher(current: f64, x: f64) -> f64 {
    if x > current { x } else { current }
}

/// An internal node's children are `first` and `first + 1`; a leaf holds the reordered
/// triangles `first..first + count`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Node {
    pub(super) bounds: Aabb,
    pub(super) first: u32,
    pub(super) count: u32,
}

/// Triangle corner `a` and edges `b - a`, `c - a`, as the ray test wants them.
#[derive(Clone, Copy, Debug)]
pub(super) struct PreparedTriangle {
    pub(super) a: [f64; 3],
    pub(super) ab: [f64; 3],
    pub(super) ac: [f64; 3],
}

#[derive(Clone)]
pub struct TriangleBvh {
    pub(super) nodes: Vec<Node>,
    /// In leaf order, with each one's box and index in the caller's triangle list.
    pub(super) triangles: Vec<PreparedTriangle>,
    boxes: Vec<Aabb>,
    original: Vec<u32>,
}

/// Where each triangle and node of a [`TriangleBvh`] sits: per triangle (indexed like the
/// list given to `build`) its slot in leaf order, per slot its leaf, per node its parent (the
/// root's: itself). [`TriangleBvh::refit_listed`] walks up from the leaves of the moved
/// triangles with them.
pub struct RefitLinks {
    slot: Vec<u32>,
    leaf: Vec<u32>,
    parent: Vec<u32>,
}

const LEAF_SIZE: usize = 4;
/// Subtrees of at most this many triangles meet each other in
/// [`TriangleBvh::overlapping_pairs`] by testing every pair of their boxes, branch-free in
/// chunks: with that, 32 sweeps the 25k head's template shapes 27% faster than 8 did
/// (16: 18%, 64: 10%; one thread, the same pairs).
const SMALL_SUBTREE: usize = 32;
const BINS: usize = 12;
/// Deeper nodes become leaves, so that the traversal stack (one slot per level plus one)
/// never overflows.
pub(super) const MAX_DEPTH: usize = 60;
const STACK: usize = MAX_DEPTH + 4;

impl TriangleBvh {
    /// Builds the hierarchy; triangle indices must be in range (the rig validated them).
    pub fn build(points: &[[f64; 3]], triangles: &[[u32; 3]]) -> Self {
        let corners: Vec<[[f64; 3]; 3]> =
            triangles.iter().map(|t| t.map(|v| points[v as usize])).collect();
        let bounds: Vec<Aabb> = corners.iter().map(|c| Aabb::of_points(c)).collect();
        let centroids: Vec<[f64; 3]> = corners
            .iter()
            .map(|c| std::array::from_fn(|a| (c[0][a] + c[1][a] + c[2][a]) / 3.0))
            .collect();
        let (nodes, order) = build::nodes(&bounds, &centroids);
        let triangles = order
            .iter()
            .map(|&t| {
                let [a, b, c] = corners[t as usize];
                PreparedTriangle { a, ab: sub(&b, &a), ac: sub(&c, &a) }
            })
            .collect();
        let boxes = order.iter().map(|&t| bounds[t as usize]).collect();
        Self { nodes, triangles, boxes, original: order }
    }

    /// The same hierarchy over moved corners (`points` indexed by the `triangles` given to
    /// `build`): boxes recomputed bottom-up, the tree kept. Far cheaper than a build; the
    /// boxes only loosen as the pose departs from the one built on, the answers stay exact.
    pub fn refitted(&self, points: &[[f64; 3]], triangles: &[[u32; 3]]) -> Self {
        self.at_corners(|t| triangles[t as usize].map(|v| points[v as usize]))
    }

    /// [`Self::refitted`] with the new corners of each triangle given directly (`corners(t)`,
    /// t an index into the list given to `build`): the same tree, its boxes recomputed.
    pub fn at_corners(&self, corners: impl Fn(u32) -> [[f64; 3]; 3]) -> Self {
        let (boxes, prepared): (Vec<Aabb>, Vec<PreparedTriangle>) = self
            .original
            .iter()
            .map(|&t| {
                let [a, b, c] = corners(t);
                (Aabb::of_points(&[a, b, c]), PreparedTriangle { a, ab: sub(&b, &a), ac: sub(&c, &a) })
            })
            .unzip();
        let mut nodes = self.nodes.clone();
        refit_bounds(&mut nodes, &boxes);
        Self { nodes, triangles: prepared, boxes, original: self.original.clone() }
    }

    /// The hierarchy over the triangles `keep` picks (indices into the list given to
    /// `build`), at new corners (`corners(t)`): [`Self::restricted`]'s cut of this tree with
    /// every box recomputed from the new corners. One pass over the nodes and no sorting, so
    /// far cheaper than a build, and as exact; as good a tree as this one is for the new
    /// corners (a pose that moves triangles a little loosens it a little). Returns the
    /// hierarchy, which answers positions in the returned list of kept triangles, that list,
    /// in the hierarchy's order, and their corners.
    pub fn subset(&self, keep: impl Fn(u32) -> bool, corners: impl Fn(u32) -> [[f64; 3]; 3]) -> (Self, Vec<u32>, Vec<[[f64; 3]; 3]>) {
        let mask: Vec<bool> = (0..self.original.len() as u32).map(keep).collect();
        // The cut's own boxes and corners are replaced here: only its tree and list are taken.
        let mut cut = self.restricted_as(&mask, false);
        let list = std::mem::take(&mut cut.original);
        let kept_corners: Vec<[[f64; 3]; 3]> = list.iter().map(|&t| corners(t)).collect();
        cut.triangles = kept_corners.iter().map(|[a, b, c]| PreparedTriangle { a: *a, ab: sub(b, a), ac: sub(c, a) }).collect();
        cut.boxes = kept_corners.iter().map(|c| Aabb::of_points(c)).collect();
        cut.original = (0..list.len() as u32).collect();
        refit_bounds(&mut cut.nodes, &cut.boxes);
        (cut, list, kept_corners)
    }

    /// The hierarchy over the triangles `keep` marks (by index in the list given to `build`),
    /// taken from this one: the same splits, subtrees without a kept triangle dropped, a node
    /// left with one kept child replaced by it, boxes those of the kept triangles. A subset of
    /// the mesh (a shape's moving region) costs one pass over the tree instead of a build, and
    /// where the subset is clustered its boxes are as tight; it is no deeper than this one.
    /// Triangle indices keep referring to the list given to `build` (pass that list to
    /// [`Self::refitted`]).
    pub fn restricted(&self, keep: &[bool]) -> Self {
        self.restricted_as(keep, true)
    }

    /// [`Self::restricted`]; without `geometry` the cut holds only its nodes (bounds left
    /// empty) and the kept triangles' indices, for a caller that supplies new corners. Every
    /// list is allocated once at its final size (growing them copied more than the cut).
    fn restricted_as(&self, keep: &[bool], geometry: bool) -> Self {
        let kept = self.original.iter().filter(|&&t| keep[t as usize]).count();
        let mut nodes = Vec::with_capacity((2 * kept).max(1));
        nodes.push(Node { bounds: Aabb::EMPTY, first: 0, count: 0 });
        let listed = |n: usize| if geometry { n } else { 0 };
        let mut out =
            Self { nodes, triangles: Vec::with_capacity(listed(kept)), boxes: Vec::with_capacity(listed(kept)), original: Vec::with_capacity(kept) };
        let holding = self.nodes_holding(keep);
        if holding[0] {
            self.restrict_into(0, 0, keep, &holding, &mut out, geometry);
        }
        out
    }

    /// Writes the restriction of node `index` (`holding[index]`, [`Self::nodes_holding`]) into
    /// `out.nodes[slot]`, its subtree after it (children side by side, after their parent);
    /// with `geometry`, the kept triangles' corners and boxes and the nodes' bounds too.
    fn restrict_into(&self, mut index: usize, slot: usize, keep: &[bool], holding: &[bool], out: &mut Self, geometry: bool) {
        while self.nodes[index].count == 0 {
            let left = self.nodes[index].first as usize;
            match (holding[left], holding[left + 1]) {
                (true, false) => index = left,
                (false, true) => index = left + 1,
                _ => break,
            }
        }
        let Node { first, count, .. } = self.nodes[index];
        let mut bounds = Aabb::EMPTY;
        if count > 0 {
            let start = out.original.len();
            for i in first as usize..(first + count) as usize {
                if keep[self.original[i] as usize] {
                    out.original.push(self.original[i]);
                    if geometry {
                        out.triangles.push(self.triangles[i]);
                        out.boxes.push(self.boxes[i]);
                        bounds.grow(&self.boxes[i]);
                    }
                }
            }
            out.nodes[slot] = Node { bounds, first: start as u32, count: (out.original.len() - start) as u32 };
        } else {
            let children = out.nodes.len();
            out.nodes.extend([Node { bounds: Aabb::EMPTY, first: 0, count: 0 }; 2]);
            for side in 0..2 {
                self.restrict_into(first as usize + side, children + side, keep, holding, out, geometry);
                bounds.grow(&out.nodes[children + side].bounds);
            }
            out.nodes[slot] = Node { bounds, first: children as u32, count: 0 };
        }
    }

    /// Where each triangle and node sits in this tree ([`RefitLinks`]), for
    /// [`Self::refit_listed`]: made once, valid for every refit and clone of this hierarchy.
    pub fn refit_links(&self) -> RefitLinks {
        let mut slot = vec![u32::MAX; self.original.iter().max().map_or(0, |&t| t as usize + 1)];
        for (s, &t) in self.original.iter().enumerate() {
            slot[t as usize] = s as u32;
        }
        let mut leaf = vec![0u32; self.original.len()];
        let mut parent = vec![0u32; self.nodes.len()];
        if !self.triangles.is_empty() {
            for (i, node) in self.nodes.iter().enumerate() {
                let (first, count) = (node.first as usize, node.count as usize);
                if count > 0 {
                    leaf[first..first + count].fill(i as u32);
                } else {
                    parent[first] = i as u32;
                    parent[first + 1] = i as u32;
                }
            }
        }
        RefitLinks { slot, leaf, parent }
    }

    /// [`Self::refitted`] in place after only the triangles `listed` (indexed like the list
    /// given to `build`, each once) moved since the last refit: their boxes are recomputed,
    /// then the bounds of their leaves and of those leaves' ancestors only. The same
    /// hierarchy, boxes and answers as `refitted(points)` to the bit (a box is the exact min
    /// and max of its corners, in any order; a node whose subtree kept its boxes keeps its
    /// bounds), without recomputing every triangle's box and node's bounds: the penetration
    /// report copies the rest tree for each shape and refits only what the shape moves.
    /// `links` is this hierarchy's [`Self::refit_links`] (or that of one it was refitted or
    /// cloned from).
    pub fn refit_listed(&mut self, links: &RefitLinks, points: &[[f64; 3]], triangles: &[[u32; 3]], listed: &[u32]) {
        let mut stale = vec![false; self.nodes.len()];
        for &t in listed {
            let slot = links.slot[t as usize] as usize;
            let [a, b, c] = triangles[t as usize].map(|v| points[v as usize]);
            self.boxes[slot] = Aabb::of_points(&[a, b, c]);
            self.triangles[slot] = PreparedTriangle { a, ab: sub(&b, &a), ac: sub(&c, &a) };
            stale[links.leaf[slot] as usize] = true;
        }
        // Children come after their parent in the array, so one backward pass refits every
        // stale child before its parent and marks the parent. A flag per node rather than a
        // heap of stale nodes: the template's shapes move thousands of triangles each (on
        // the 25k head the heap cost 302 M instructions over its 52 shapes, more than half a
        // full refit's 477 M).
        for i in (0..self.nodes.len()).rev() {
            if !stale[i] {
                continue;
            }
            let Node { first, count, .. } = self.nodes[i];
            let mut bounds = Aabb::EMPTY;
            if count > 0 {
                self.boxes[first as usize..(first + count) as usize].iter().for_each(|b| bounds.grow(b));
            } else {
                bounds.grow(&self.nodes[first as usize].bounds);
                bounds.grow(&self.nodes[first as usize + 1].bounds);
            }
            self.nodes[i].bounds = bounds;
            stale[links.parent[i] as usize] = true;
        }
    }

    /// Per node, whether its subtree holds a `marked` triangle (indexed like the list given
    /// to `build`): the pruning mask [`Self::closest_point_among`] takes.
    pub fn nodes_holding(&self, marked: &[bool]) -> Vec<bool> {
        let mut holds = vec![false; self.nodes.len()];
        if self.triangles.is_empty() {
            // The root of an empty hierarchy is no internal node.
            return holds;
        }
        // Children come after their parent in the array.
        for i in (0..self.nodes.len()).rev() {
            let Node { first, count, .. } = self.nodes[i];
            holds[i] = if count > 0 {
                self.original[first as usize..(first + count) as usize].iter().any(|&t| marked[t as usize])
            } else {
                holds[first as usize] || holds[first as usize + 1]
            };
        }
        holds
    }

    /// Calls `visit(t)` for every triangle `t` (an index into the list given to `build`)
    /// whose bounding box overlaps `query`.
    pub fn for_each_overlap(&self, query: &Aabb, mut visit: impl FnMut(u32)) {
        self.overlap_until(query, |t| {
            visit(t);
            false
        });
    }

    /// [`Self::for_each_overlap`] until `visit` returns `true`: then no further triangle is
    /// visited and the answer is `true` (a search for one triangle, or for a list that one
    /// kind of triangle completes, need not descend the rest of the tree).
    pub fn overlap_until(&self, query: &Aabb, mut visit: impl FnMut(u32) -> bool) -> bool {
        if self.triangles.is_empty() || !self.nodes[0].bounds.overlaps(query) {
            return false;
        }
        // Nodes on the stack overlap the query.
        let mut stack = [0u32; STACK];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if node.count > 0 {
                let range = node.first as usize..(node.first + node.count) as usize;
                for (b, &t) in self.boxes[range.clone()].iter().zip(&self.original[range]) {
                    if b.overlaps(query) && visit(t) {
                        return true;
                    }
                }
                continue;
            }
            for child in [node.first, node.first + 1] {
                if self.nodes[child as usize].bounds.overlaps(query) {
                    stack[top] = child;
                    top += 1;
                }
            }
        }
        false
    }

    /// Every unordered pair of distinct triangles whose boxes overlap and of which at least
    /// one is `marked` (indexed like the list given to `build`), passed to `visit` with the
    /// accumulator of the task that found it; one accumulator per task, from `init`. One
    /// descent of the tree against itself (rayon across its top node pairs): nearby pairs
    /// share the descent that one query per triangle would repeat, each pair is reached once,
    /// and subtrees without a marked triangle are never entered against each other.
    pub fn overlapping_pairs<T: Send>(
        &self,
        marked: &[bool],
        init: impl Fn() -> T + Sync,
        visit: impl Fn(&mut T, u32, u32) + Sync,
    ) -> Vec<T> {
        use rayon::prelude::*;
        if self.triangles.is_empty() {
            return Vec::new();
        }
        // The marks in leaf order, read without going through `original`.
        let slot_marked: Vec<bool> = self.original.iter().map(|&t| marked[t as usize]).collect();
        // Whether a node's subtree holds a marked triangle, and the slots it holds (children
        // follow their parent; a subtree's triangles are contiguous in leaf order, the left
        // child's first).
        let mut has_marked = vec![false; self.nodes.len()];
        let mut span = vec![(0usize, 0usize); self.nodes.len()];
        for i in (0..self.nodes.len()).rev() {
            let Node { first, count, .. } = self.nodes[i];
            let (first, count) = (first as usize, count as usize);
            (has_marked[i], span[i]) = if count > 0 {
                (slot_marked[first..first + count].iter().any(|&m| m), (first, first + count))
            } else {
                (has_marked[first] || has_marked[first + 1], (span[first].0, span[first + 1].1))
            };
        }
        let small = |i: u32| span[i as usize].1 - span[i as usize].0 <= SMALL_SUBTREE;
        // Node pairs `(i, j)` whose subtrees' triangles may overlap each other (`i == j`: a
        // subtree against itself); split into children until there are enough for the threads.
        let children = |i: u32| [self.nodes[i as usize].first, self.nodes[i as usize].first + 1];
        let worth = |i: u32, j: u32| {
            (has_marked[i as usize] || has_marked[j as usize])
                && (i == j || self.nodes[i as usize].bounds.overlaps(&self.nodes[j as usize].bounds))
        };
        // The node pairs a pair splits into (the first `count` of the array), without a heap
        // allocation per step of the descent.
        let split = |i: u32, j: u32| -> Option<([(u32, u32); 3], usize)> {
            let (a, b) = (&self.nodes[i as usize], &self.nodes[j as usize]);
            // Two small subtrees' triangles are tested against each other directly: the
            // descent's steps between them would cost more than the box tests they save.
            if small(i) && small(j) {
                return None;
            }
            if i == j {
                let [l, r] = children(i);
                return (a.count == 0).then_some(([(l, l), (r, r), (l, r)], 3));
            }
            // Split the internal node with the larger box (both when leaves: none).
            let first = match (a.count == 0, b.count == 0) {
                (false, false) => return None,
                (true, false) => true,
                (false, true) => false,
                (true, true) => a.bounds.half_area() >= b.bounds.half_area(),
            };
            let [x, y] = if first { children(i).map(|c| (c, j)) } else { children(j).map(|c| (i, c)) };
            Some(([x, y, (0, 0)], 2))
        };
        let mut tasks = vec![(0u32, 0u32)];
        while tasks.len() < 256 {
            let mut next = Vec::with_capacity(3 * tasks.len());
            let mut grew = false;
            for &(i, j) in &tasks {
                match split(i, j) {
                    Some((pairs, count)) => {
                        grew = true;
                        next.extend(pairs[..count].iter().copied().filter(|&(a, b)| worth(a, b)));
                    }
                    None => next.push((i, j)),
                }
            }
            tasks = next;
            if !grew {
                break;
            }
        }
        tasks
            .into_par_iter()
            .map(|task| {
                let mut found = init();
                let mut stack = vec![task];
                while let Some((i, j)) = stack.pop() {
                    match split(i, j) {
                        Some((pairs, count)) => stack.extend(pairs[..count].iter().copied().filter(|&(a, b)| worth(a, b))),
                        None => {
                            // Two leaves or small subtrees, or one against itself, slot by
                            // slot. A triangle of `i` outside `j`'s box, or unmarked against a
                            // subtree without a marked triangle, meets none of `j`'s: skipped
                            // without its loop.
                            let ((a_start, a_end), (b_start, b_end)) = (span[i as usize], span[j as usize]);
                            let (b_bounds, b_marked) = (&self.nodes[j as usize].bounds, has_marked[j as usize]);
                            for p in a_start..a_end {
                                let (p_marked, p_box) = (slot_marked[p], &self.boxes[p]);
                                if !(p_marked || b_marked) || (i != j && !p_box.overlaps(b_bounds)) {
                                    continue;
                                }
                                let from = if i == j { p + 1 } else { b_start };
                                // A chunk's overlaps as a bit mask, without a branch per pair
                                // (about half the tests fail, at any axis), then its hits.
                                for start in (from..b_end).step_by(64) {
                                    let end = (start + 64).min(b_end);
                                    let mut hits = 0u64;
                                    for (k, (q_box, &q_marked)) in self.boxes[start..end].iter().zip(&slot_marked[start..end]).enumerate() {
                                        hits |= u64::from(p_box.overlaps(q_box) & (p_marked | q_marked)) << k;
                                    }
                                    while hits != 0 {
                                        let q = start + hits.trailing_zeros() as usize;
                                        visit(&mut found, self.original[p], self.original[q]);
                                        hits &= hits - 1;
                                    }
                                }
                            }
                        }
                    }
                }
                found
            })
            .collect()
    }

    /// Whether the ray `origin + t * direction` meets a triangle at some `t` in `(0, t_max)`.
    /// Both faces count; `direction` need not be normalised (`t` is in its units).
    pub fn any_hit(&self, origin: &[f64; 3], direction: &[f64; 3], t_max: f64) -> bool {
        if self.triangles.is_empty() {
            return false;
        }
        let inverse = direction.map(|d| 1.0 / d);
        if self.nodes[0].bounds.entry(origin, &inverse, t_max).is_none() {
            return false;
        }
        // Nodes on the stack are known to be hit; the nearer child is visited first.
        let mut stack = [0u32; STACK];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if node.count > 0 {
                let range = node.first as usize..(node.first + node.count) as usize;
                if self.triangles[range].iter().any(|tri| ray_meets(tri, origin, direction, t_max)) {
                    return true;
                }
                continue;
            }
            let (left, right) = (node.first, node.first + 1);
            let enter = |child: u32| self.nodes[child as usize].bounds.entry(origin, &inverse, t_max);
            match (enter(left), enter(right)) {
                (Some(a), Some(b)) => {
                    let (near, far) = if a <= b { (left, right) } else { (right, left) };
                    stack[top] = far;
                    stack[top + 1] = near;
                    top += 2;
                }
                (Some(_), None) => {
                    stack[top] = left;
                    top += 1;
                }
                (None, Some(_)) => {
                    stack[top] = right;
                    top += 1;
                }
                (None, None) => {}
            }
        }
        false
    }
}

impl TriangleBvh {
    /// The surface point closest to `query` within `max_distance` (`None` when no triangle
    /// comes that close, or the mesh is empty). Nearer children first; a subtree is skipped
    /// once its box lies farther than the best point so far.
    pub fn closest_point(&self, query: &[f64; 3], max_distance: f64) -> Option<SurfacePoint> {
        self.closest_point_where(query, max_distance, |_| true)
    }

    /// [`Self::closest_point`] among the triangles `t` (indices into the list given to
    /// `build`) with `accept(t)`.
    pub fn closest_point_where(&self, query: &[f64; 3], max_distance: f64, accept: impl Fn(u32) -> bool) -> Option<SurfacePoint> {
        self.closest_point_pruned(query, max_distance, None, accept)
    }

    /// [`Self::closest_point_where`] among the triangles of `holding` ([`Self::nodes_holding`]
    /// of those `accept` takes): subtrees without one are never entered. The same point to the
    /// bit: a skipped subtree would only have tested triangles `accept` refuses, and the others
    /// are visited in the same order. Until a first accepted triangle bounds the search, the
    /// unpruned query descends every subtree of a large piece (the skin) looking for a small
    /// one (the teeth).
    pub fn closest_point_among(
        &self,
        query: &[f64; 3],
        max_distance: f64,
        holding: &[bool],
        accept: impl Fn(u32) -> bool,
    ) -> Option<SurfacePoint> {
        self.closest_point_pruned(query, max_distance, Some(holding), accept)
    }

    fn closest_point_pruned(
        &self,
        query: &[f64; 3],
        max_distance: f64,
        holding: Option<&[bool]>,
        accept: impl Fn(u32) -> bool,
    ) -> Option<SurfacePoint> {
        let enter = |node: u32| holding.is_none_or(|h| h[node as usize]);
        if self.triangles.is_empty() || !enter(0) {
            return None;
        }
        let mut best: Option<SurfacePoint> = None;
        let mut bound = if max_distance.is_finite() { max_distance * max_distance } else { f64::INFINITY };
        let mut stack = [0u32; STACK];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            if node.bounds.distance_squared(query) > bound {
                continue;
            }
            if node.count > 0 {
                for slot in node.first as usize..(node.first + node.count) as usize {
                    if self.boxes[slot].distance_squared(query) > bound || !accept(self.original[slot]) {
                        continue;
                    }
                    let tri = &self.triangles[slot];
                    let b = std::array::from_fn(|i| tri.a[i] + tri.ab[i]);
                    let c = std::array::from_fn(|i| tri.a[i] + tri.ac[i]);
                    let (point, barycentric) = closest_on_triangle(query, &tri.a, &b, &c);
                    let d = distance_squared(query, &point);
                    if d <= bound {
                        bound = d;
                        best = Some(SurfacePoint { triangle: self.original[slot], point, barycentric, distance_squared: d });
                    }
                }
                continue;
            }
            let (left, right) = (node.first, node.first + 1);
            let (dl, dr) = (self.nodes[left as usize].bounds.distance_squared(query), self.nodes[right as usize].bounds.distance_squared(query));
            let (near, far) = if dl <= dr { (left, right) } else { (right, left) };
            for child in [far, near] {
                if enter(child) {
                    stack[top] = child;
                    top += 1;
                }
            }
        }
        best
    }
}

/// Recomputes every node's box bottom-up from the triangles' `boxes` (children come after
/// their parent in the array); a tree without triangles keeps its empty root.
fn refit_bounds(nodes: &mut [Node], boxes: &[Aabb]) {
    if boxes.is_empty() {
        return;
    }
    for i in (0..nodes.len()).rev() {
        let Node { first, count, .. } = nodes[i];
        let mut bounds = Aabb::EMPTY;
        if count > 0 {
            boxes[first as usize..(first + count) as usize].iter().for_each(|b| bounds.grow(b));
        } else {
            bounds.grow(&nodes[first as usize].bounds);
            bounds.grow(&nodes[first as usize + 1].bounds);
        }
        nodes[i].bounds = bounds;
    }
}

/// Moller-Trumbore, double-sided, hit parameter strictly inside `(0, t_max)`.
pub(super) fn ray_meets(tri: &PreparedTriangle, origin: &[f64; 3], direction: &[f64; 3], t_max: f64) -> bool {
    let p = cross(direction, &tri.ac);
    let det = dot(&tri.ab, &p);
    if det == 0.0 {
        return false;
    }
    let inv = 1.0 / det;
    let s = sub(origin, &tri.a);
    let u = dot(&s, &p) * inv;
    if !(0.0..=1.0).contains(&u) {
        return false;
    }
    let q = cross(&s, &tri.ab);
    let v = dot(direction, &q) * inv;
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    let t = dot(&tri.ac, &q) * inv;
    t > 0.0 && t < t_max
}

pub(crate) fn sub(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub(crate) fn cross(a: &[f64; 3], b: &[f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

#[path = "bvh_build.rs"]
mod build;

#[cfg(test)]
#[path = "bvh_tests.rs"]
mod tests;
