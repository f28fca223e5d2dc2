//! The welded surface: vertices that an importer split along UV seams or hard edges (copies
//! exactly on top of each other, each keeping its own UVs or normals) taken as one surface
//! point. Method, section 0, "Seams".
//!
//! The welded surface is also the valid surface: the weld leaves out the triangles no surface
//! operator is defined on (zero area, a repeated corner, a second copy of a face) and the
//! vertices in no remaining triangle (loose vertices, and those whose only faces were left
//! out). A loose vertex is read at the surface point nearest it at rest ([`Carried`]): every
//! per-vertex result gives it that point's value, and a motion written back carries it with
//! that point, so no tool divides by a zero area or solves a vertex no triangle holds, and
//! none leaves a loose vertex behind when the surface moves.
//!
//! Every tool welds at its entry, runs on the welded arrays and scatters its per-vertex
//! results back, so that each copy of a seam vertex gets the same value bit for bit (a seam
//! gap of exactly 0) while the user's mesh keeps its own vertices and order. Per-vertex
//! results are read at the welded point; a vertex reported by index (a landmark, a mirror
//! partner) is its welded point's representative, the lowest index among the copies.
//!
//! # Tolerance
//! Copies coincide when their rest positions are within [`weld_tolerance`]: [`WELD_FRACTION`]
//! (1e-7) of the bounding-box diagonal, or f32's rounding step at the mesh's largest
//! coordinate when that is more (a head far from the origin, as one in centimetres at a
//! body's height, stores its positions no finer). Importers write the copies from one source
//! vertex, so they agree to the bit; one rounding step (f32's epsilon is 1.2e-7) forgives a
//! copy that went through one more transform than its twin, and is four orders below the
//! spacing of any vertices a face mesh holds apart (its shortest edges, about 1e-3 of the
//! diagonal on the bundled 25k head). Closed lips modelled as separate vertices resting on
//! each other are not a seam: their shapes move them apart, and [`Weld::split_where_apart`]
//! keeps them two points.

use std::borrow::Cow;
use std::collections::HashSet;

use super::bvh::TriangleBvh;
use crate::rig::{bbox_diagonal, triangle_area, RigView, DEGENERATE_AREA_FRACTION};

/// Whether triangle `tri` of `points` has no area at the precision the mesh is stored in: its
/// area at most [`DEGENERATE_AREA_FRACTION`] of the squared `diagonal`, or its height (twice
/// its area over its longest edge) within `tolerance`, the weld's: a corner that close to the
/// opposite edge is on it, as two points that close are one. An exporter's collinear corners
/// (a vertex halfway along an edge, written in f32) keep a height of up to one rounding step
/// at their coordinates' size, far above the area bound yet as singular for a gradient
/// operator.
pub fn is_flat(points: &[[f32; 3]], tri: &[u32; 3], diagonal: f64, tolerance: f64) -> bool {
    let area = triangle_area(points, tri);
    let longest = (0..3)
        .map(|i| {
            let (p, q) = (points[tri[i] as usize], points[tri[(i + 1) % 3] as usize]);
            (0..3).map(|a| (f64::from(p[a]) - f64::from(q[a])).powi(2)).sum::<f64>().sqrt()
        })
        .fold(0.0, f64::max);
    area <= DEGENERATE_AREA_FRACTION * diagonal * diagonal || 2.0 * area <= tolerance * longest
}

/// Rest positions closer than this fraction of the bounding-box diagonal are one surface
/// point (see the module's Tolerance section).
pub const WELD_FRACTION: f64 = 1e-7;

/// The distance within which two rest positions of `points` are one point: [`WELD_FRACTION`]
/// of the bounding-box diagonal, and at least f32's rounding step at the largest finite
/// coordinate magnitude `c`, `f32::EPSILON * c` (an f32 value of size at most `c` is off by
/// half that step per axis at most, `sqrt(3) / 2` of it over the three axes).
pub fn weld_tolerance(points: &[[f32; 3]]) -> f64 {
    let largest = points.iter().flatten().map(|c| f64::from(c.abs())).filter(|c| c.is_finite()).fold(0.0, f64::max);
    (WELD_FRACTION * bbox_diagonal(points)).max(f64::from(f32::EPSILON) * largest)
}

/// A vertex in no triangle of the valid surface, read at the surface point nearest it at rest:
/// the welded corners of that point's triangle and its barycentric weights.
#[derive(Clone, Debug, PartialEq)]
pub struct Carried {
    pub vertex: u32,
    pub corners: [u32; 3],
    pub weights: [f64; 3],
}

/// The welded surface of a mesh: welded index of every vertex, a representative vertex per
/// welded point and the triangles on welded indices.
#[derive(Clone, Debug, PartialEq)]
pub struct Weld {
    /// The welded point of each of the N vertices (for a loose vertex, the corner nearest its
    /// surface point).
    pub welded_of: Vec<u32>,
    /// Per welded point (M of them, in ascending order of their representatives), its lowest
    /// vertex index among the vertices on the surface.
    pub representatives: Vec<u32>,
    /// The triangles on welded indices. Left out: a triangle two of whose corners weld into
    /// one point or that repeats a corner, one of zero area ([`is_flat`]) on any rest shape
    /// given, and the second copy of a triangle.
    pub triangles: Vec<[u32; 3]>,
    /// The input index of each welded triangle.
    pub triangle_of: Vec<u32>,
    /// The vertices in no welded triangle, each with the surface point that carries it.
    pub carried: Vec<Carried>,
    /// How many triangles the input had.
    pub input_triangles: usize,
}

impl Weld {
    /// Welds the vertices of `points` within [`weld_tolerance`], transitively. A hash grid in
    /// spirit: the points sorted by a cell key (cells 64 times the tolerance), each compared
    /// with its own cell and, near a cell wall only, with the neighbour cell's; O(N log N), a
    /// few milliseconds on a 25k head.
    /// Triangles with an index out of range leave the mesh unwelded, for the tool's own
    /// validation to name them in the user's numbering.
    pub fn new(points: &[[f32; 3]], triangles: &[[u32; 3]]) -> Self {
        if triangles.iter().flatten().any(|&v| v as usize >= points.len()) {
            return Self::identity(points.len(), triangles);
        }
        let tolerance = weld_tolerance(points);
        let cell = if tolerance > 0.0 { 64.0 * tolerance } else { 1.0 };
        let key = |p: &[f32; 3], shift: [i64; 3]| -> [i64; 3] {
            [0, 1, 2].map(|a| (f64::from(p[a]) / cell).floor() as i64 + shift[a])
        };
        let mut sorted: Vec<([i64; 3], u32)> = points.iter().enumerate().map(|(v, p)| (key(p, [0; 3]), v as u32)).collect();
        sorted.sort_unstable();
        let mut parent: Vec<u32> = (0..points.len() as u32).collect();
        let close = |a: u32, b: u32| {
            let (p, q) = (points[a as usize], points[b as usize]);
            let d2: f64 = (0..3).map(|i| (f64::from(p[i]) - f64::from(q[i])).powi(2)).sum();
            d2 <= tolerance * tolerance
        };
        for (at, &(own, v)) in sorted.iter().enumerate() {
            // The rest of its own cell (ascending order: each pair once).
            for &(other, u) in &sorted[at + 1..] {
                if other != own {
                    break;
                }
                if close(v, u) {
                    union(&mut parent, v, u);
                }
            }
            // Neighbour cells, only along the axes where the point is near a wall (within twice
            // the tolerance, against rounding); those cells' points are compared with this one from here only when
            // their key is greater, so that each pair is seen once.
            let p = points[v as usize];
            let (mut shifts, mut count) = ([[0i64; 3]; 8], 1);
            for a in 0..3 {
                let offset = f64::from(p[a]) / cell - (f64::from(p[a]) / cell).floor();
                let step = if offset * cell <= 2.0 * tolerance {
                    -1
                } else if (1.0 - offset) * cell <= 2.0 * tolerance {
                    1
                } else {
                    continue;
                };
                for i in 0..count {
                    shifts[count + i] = shifts[i];
                    shifts[count + i][a] = step;
                }
                count *= 2;
            }
            for shift in &shifts[1..count] {
                let neighbour = key(&p, *shift);
                if neighbour < own {
                    continue;
                }
                let start = sorted.partition_point(|(k, _)| *k < neighbour);
                for &(other, u) in &sorted[start..] {
                    if other != neighbour {
                        break;
                    }
                    if close(v, u) {
                        union(&mut parent, v, u);
                    }
                }
            }
        }
        // The lowest index of each group: the root of a union that always keeps the lower.
        let representative: Vec<u32> = (0..points.len() as u32).map(|v| find(&mut parent, v)).collect();
        Self::from_representatives(&representative, triangles, &[points])
    }

    /// The weld where every vertex is its own point and every triangle kept (no seam, no
    /// rest shape to find faults on).
    pub fn identity(n_vertices: usize, triangles: &[[u32; 3]]) -> Self {
        let representative: Vec<u32> = (0..n_vertices as u32).collect();
        Self::from_representatives(&representative, triangles, &[])
    }

    /// `representative[v]`: the lowest index of `v`'s group (`representative[v] <= v`, and a
    /// representative is its own). With `rests` (positions of the N vertices), the surface's
    /// faults are left out (see [`Weld::triangles`]) and the points in no triangle carried.
    fn from_representatives(representative: &[u32], triangles: &[[u32; 3]], rests: &[&[[f32; 3]]]) -> Self {
        let mut welded_of = vec![0u32; representative.len()];
        let mut representatives = Vec::new();
        for (v, &r) in representative.iter().enumerate() {
            if r as usize == v {
                welded_of[v] = representatives.len() as u32;
                representatives.push(r);
            } else {
                welded_of[v] = welded_of[r as usize];
            }
        }
        let input_triangles = triangles.len();
        let in_range = triangles.iter().flatten().all(|&v| (v as usize) < representative.len());
        let rests: Vec<&[[f32; 3]]> = rests.iter().copied().filter(|r| r.len() == representative.len()).collect();
        let mut welded_triangles = Vec::with_capacity(triangles.len());
        let mut triangle_of = Vec::with_capacity(triangles.len());
        if !in_range || rests.is_empty() {
            // Out-of-range indices pass through for the tool's validation to name them; without
            // a rest shape only what the weld itself collapses goes.
            for (t, tri) in triangles.iter().enumerate() {
                let w = tri.map(|v| welded_of.get(v as usize).copied().unwrap_or(v));
                if !collapsed(w) || collapsed(*tri) {
                    welded_triangles.push(w);
                    triangle_of.push(t as u32);
                }
            }
            return Self { welded_of, representatives, triangles: welded_triangles, triangle_of, carried: Vec::new(), input_triangles };
        }
        let bounds: Vec<(f64, f64)> = rests.iter().map(|r| (bbox_diagonal(r), weld_tolerance(r))).collect();
        let mut seen = HashSet::with_capacity(triangles.len());
        for (t, tri) in triangles.iter().enumerate() {
            let w = tri.map(|v| welded_of[v as usize]);
            if collapsed(w) {
                continue;
            }
            let at_points = w.map(|p| representatives[p as usize]);
            if rests.iter().zip(&bounds).any(|(rest, &(diagonal, tolerance))| is_flat(rest, &at_points, diagonal, tolerance)) {
                continue;
            }
            let mut sorted = w;
            sorted.sort_unstable();
            if seen.insert(sorted) {
                welded_triangles.push(w);
                triangle_of.push(t as u32);
            }
        }
        let mut weld = Self { welded_of, representatives, triangles: welded_triangles, triangle_of, carried: Vec::new(), input_triangles };
        weld.carry_loose(rests[0]);
        weld
    }

    /// Takes the welded points in no triangle off the surface: each of their vertices is read
    /// at the surface point nearest its `rest` position. Nothing to carry by when no triangle
    /// is left (the tools refuse a mesh without faces).
    fn carry_loose(&mut self, rest: &[[f32; 3]]) {
        let mut used = vec![false; self.n_welded()];
        self.triangles.iter().flatten().for_each(|&p| used[p as usize] = true);
        if self.triangles.is_empty() || used.iter().all(|&u| u) {
            return;
        }
        let mut renumbered = vec![u32::MAX; used.len()];
        let mut representatives = Vec::with_capacity(used.len());
        for (p, &r) in self.representatives.iter().enumerate() {
            if used[p] {
                renumbered[p] = representatives.len() as u32;
                representatives.push(r);
            }
        }
        let triangles: Vec<[u32; 3]> = self.triangles.iter().map(|t| t.map(|p| renumbered[p as usize])).collect();
        let surface: Vec<[f64; 3]> = representatives.iter().map(|&r| rest[r as usize].map(f64::from)).collect();
        let bvh = TriangleBvh::build(&surface, &triangles);
        let mut carried = Vec::new();
        for (v, point) in self.welded_of.iter_mut().enumerate() {
            if used[*point as usize] {
                *point = renumbered[*point as usize];
                continue;
            }
            // Every finite query has a closest point on a non-empty surface; a non-finite rest
            // (which every tool refuses by name) is read at the first triangle's first corner.
            let (corners, weights) = match bvh.closest_point(&rest[v].map(f64::from), f64::INFINITY) {
                Some(near) => (triangles[near.triangle as usize], near.barycentric),
                None => (triangles[0], [1.0, 0.0, 0.0]),
            };
            let nearest = (0..3).fold(0, |best, i| if weights[i] > weights[best] { i } else { best });
            *point = corners[nearest];
            carried.push(Carried { vertex: v as u32, corners, weights });
        }
        self.representatives = representatives;
        self.triangles = triangles;
        self.carried = carried;
    }

    /// Keeps apart the copies that `rows` (a multiple of N rows: more positions of the same
    /// vertices, such as another neutral, or the K shapes' deltas) put more than `tolerance`
    /// apart in any block: such a vertex leaves its group and stands alone. Closed lips
    /// resting on each other are two points by their shapes; a target neutral that holds two
    /// template copies apart keeps them apart. `rests` are the rest shapes the faults are
    /// found on (see [`Self::from_representatives`]); carried vertices are carried anew.
    pub fn split_where_apart(self, rows: &[[f32; 3]], tolerance: f64, triangles: &[[u32; 3]], rests: &[&[[f32; 3]]]) -> Self {
        let n = self.welded_of.len();
        if n == 0 || !rows.len().is_multiple_of(n) {
            return self;
        }
        let mut loose = vec![false; n];
        self.carried.iter().for_each(|c| loose[c.vertex as usize] = true);
        let representative: Vec<u32> = (0..n)
            .map(|v| {
                if loose[v] {
                    return v as u32;
                }
                let r = self.representatives[self.welded_of[v] as usize] as usize;
                let apart = r != v
                    && rows.chunks(n).any(|block| {
                        let (p, q) = (block[v], block[r]);
                        (0..3).map(|a| (f64::from(p[a]) - f64::from(q[a])).powi(2)).sum::<f64>() > tolerance * tolerance
                    });
                if apart { v as u32 } else { r as u32 }
            })
            .collect();
        Self::from_representatives(&representative, triangles, rests)
    }

    /// The weld of a rig: its neutral's coincident vertices, kept apart where a shape in
    /// `deltas` (K x N) moves the copies apart by more than the weld's tolerance (there the
    /// artist split the surface on purpose, as closed lips resting on each other).
    pub fn of_rig(neutral: &[[f32; 3]], deltas: &[[f32; 3]], triangles: &[[u32; 3]]) -> Self {
        Self::new(neutral, triangles).split_where_apart(deltas, weld_tolerance(neutral), triangles, &[neutral])
    }

    pub fn n_vertices(&self) -> usize {
        self.welded_of.len()
    }

    pub fn n_welded(&self) -> usize {
        self.representatives.len()
    }

    /// Whether every vertex is its own point and every triangle kept (nothing to gather or
    /// scatter; the triangles are the input's).
    pub fn is_identity(&self) -> bool {
        self.n_welded() == self.n_vertices() && self.triangles.len() == self.input_triangles
    }

    /// Vertices that share their point with another one (every copy counted).
    pub fn seam_vertices(&self) -> usize {
        let mut copies = vec![0u32; self.n_welded()];
        for &w in &self.welded_of {
            copies[w as usize] += 1;
        }
        copies.iter().filter(|&&c| c > 1).map(|&c| c as usize).sum()
    }

    /// Welded points made of two or more vertices.
    pub fn seam_groups(&self) -> usize {
        let mut copies = vec![0u32; self.n_welded()];
        for &w in &self.welded_of {
            copies[w as usize] += 1;
        }
        copies.iter().filter(|&&c| c > 1).count()
    }

    /// The representatives' rows of `rows` (a multiple of N rows, block by block: a neutral,
    /// or K shapes' deltas): M rows per block. Borrowed when there is no seam.
    pub fn gather<'a, T: Copy>(&self, rows: &'a [T]) -> Cow<'a, [T]> {
        let n = self.n_vertices();
        if self.n_welded() == n || n == 0 {
            return Cow::Borrowed(rows);
        }
        Cow::Owned(rows.chunks(n).flat_map(|block| self.representatives.iter().map(|&r| block[r as usize])).collect())
    }

    /// Every vertex's row from its welded point's (`rows`: a multiple of M rows, block by
    /// block): each copy gets the same value.
    pub fn scatter<T: Copy>(&self, rows: Vec<T>) -> Vec<T> {
        let m = self.n_welded();
        if m == self.n_vertices() || m == 0 {
            return rows;
        }
        rows.chunks(m).flat_map(|block| self.welded_of.iter().map(|&w| block[w as usize])).collect()
    }

    /// [`Self::scatter`] of rows that are motions (`rows`: a multiple of M rows, block by block,
    /// such as K shapes' deltas): a carried vertex moves as its surface point does, the
    /// barycentric mix of its triangle's corners.
    pub fn scatter_motion(&self, rows: Vec<[f32; 3]>) -> Vec<[f32; 3]> {
        let m = self.n_welded();
        if self.carried.is_empty() || m == 0 {
            return self.scatter(rows);
        }
        let mut out = self.scatter(rows.clone());
        let n = self.n_vertices();
        for (block, welded) in out.chunks_mut(n).zip(rows.chunks(m)) {
            for c in &self.carried {
                block[c.vertex as usize] = mix(c, |p| welded[p as usize].map(f64::from));
            }
        }
        out
    }

    /// [`Self::scatter`] of positions the surface moved to from `rest` (N rows): a carried
    /// vertex keeps its offset from its surface point, moved by that point's motion.
    pub fn scatter_moved(&self, moved: Vec<[f32; 3]>, rest: &[[f32; 3]]) -> Vec<[f32; 3]> {
        if self.carried.is_empty() || moved.len() != self.n_welded() || rest.len() != self.n_vertices() {
            return self.scatter(moved);
        }
        let motion = |p: u32| {
            let (to, from) = (moved[p as usize], rest[self.representatives[p as usize] as usize]);
            [0, 1, 2].map(|a| f64::from(to[a]) - f64::from(from[a]))
        };
        let mut out = self.scatter(moved.clone());
        for c in &self.carried {
            let d = mix(c, motion);
            let r = rest[c.vertex as usize];
            out[c.vertex as usize] = [0, 1, 2].map(|a| (f64::from(r[a]) + f64::from(d[a])) as f32);
        }
        out
    }

    /// The representative vertex of welded point `w`.
    pub fn vertex(&self, w: u32) -> u32 {
        self.representatives[w as usize]
    }

    /// Per input triangle, its welded triangle's value; `missing` for a dropped triangle.
    pub fn scatter_triangles<T: Copy>(&self, welded: &[T], n_triangles: usize, missing: T) -> Vec<T> {
        let mut out = vec![missing; n_triangles];
        for (w, &t) in self.triangle_of.iter().enumerate() {
            out[t as usize] = welded[w];
        }
        out
    }
}

/// A rig on its welded surface ([`Weld::of_rig`]): what a tool's entry hands its own code,
/// borrowing the caller's arrays when there is no seam.
pub struct WeldedRig<'a> {
    pub weld: Weld,
    neutral: Cow<'a, [[f32; 3]]>,
    deltas: Cow<'a, [[f32; 3]]>,
    names: &'a [String],
}

impl<'a> WeldedRig<'a> {
    /// A rig whose triangles index out of range, or whose deltas are not K x N rows, stays
    /// unwelded for the tool's validation to name the fault.
    pub fn new(rig: &RigView<'a>) -> Self {
        let n = rig.n_vertices();
        let weld = if n > 0 && rig.deltas.len().is_multiple_of(n) {
            Weld::of_rig(rig.neutral, rig.deltas, rig.triangles)
        } else {
            Weld::identity(n, rig.triangles)
        };
        let (neutral, deltas) = (weld.gather(rig.neutral), weld.gather(rig.deltas));
        Self { weld, neutral, deltas, names: rig.names }
    }

    pub fn view(&self) -> RigView<'_> {
        RigView { neutral: &self.neutral, deltas: &self.deltas, triangles: &self.weld.triangles, names: self.names }
    }
}

impl Weld {
    /// Every vertex of the welded points in `welded` (sorted), ascending: a welded vertex set
    /// in the user's numbering.
    /// Carried vertices are in no set: they are on no surface.
    pub fn expand(&self, welded: &[u32]) -> Vec<u32> {
        if self.n_welded() == self.n_vertices() {
            return welded.to_vec();
        }
        let mut wanted = vec![false; self.n_welded()];
        for &w in welded {
            wanted[w as usize] = true;
        }
        let mut loose = vec![false; self.n_vertices()];
        self.carried.iter().for_each(|c| loose[c.vertex as usize] = true);
        (0..self.n_vertices() as u32).filter(|&v| !loose[v as usize] && wanted[self.welded_of[v as usize] as usize]).collect()
    }
}

/// A triangle with a corner twice.
fn collapsed(t: [u32; 3]) -> bool {
    t[0] == t[1] || t[1] == t[2] || t[0] == t[2]
}

/// `sum_i w_i value(corner_i)` of a carried vertex.
fn mix(c: &Carried, value: impl Fn(u32) -> [f64; 3]) -> [f32; 3] {
    let mut sum = [0.0f64; 3];
    for (&p, &w) in c.corners.iter().zip(&c.weights) {
        let x = value(p);
        (0..3).for_each(|a| sum[a] += w * x[a]);
    }
    sum.map(|x| x as f32)
}

fn find(parent: &mut [u32], v: u32) -> u32 {
    let mut root = v;
    while parent[root as usize] != root {
        root = parent[root as usize];
    }
    let mut at = v;
    while parent[at as usize] != root {
        let next = parent[at as usize];
        parent[at as usize] = root;
        at = next;
    }
    root
}

/// Joins two groups under the lower root, so that a root is always its group's lowest index.
fn union(parent: &mut [u32], a: u32, b: u32) {
    let (ra, rb) = (find(parent, a), find(parent, b));
    let (low, high) = (ra.min(rb), ra.max(rb));
    parent[high as usize] = low;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::topology::connected_components;

    /// A unit cube of 8 corners and 12 triangles, then split along a seam: the four corners of
    /// the top face get copies (vertices 8..12) that the top's two triangles use, as an
    /// importer leaves a UV island.
    pub(crate) fn split_cube() -> (Vec<[f32; 3]>, Vec<[u32; 3]>, Vec<[u32; 3]>) {
        let mut points: Vec<[f32; 3]> = (0..8).map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32]).collect();
        let faces: [[u32; 4]; 6] = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]];
        let welded: Vec<[u32; 3]> = faces.iter().flat_map(|f| [[f[0], f[1], f[2]], [f[0], f[2], f[3]]]).collect();
        // Top face (z = 1) is faces[1]: corners 4, 6, 7, 5 become 8, 9, 10, 11.
        let copy = |v: u32| match v { 4 => 8, 6 => 9, 7 => 10, 5 => 11, v => v };
        points.extend([4, 6, 7, 5].map(|v| points[v]));
        let split: Vec<[u32; 3]> = welded.iter().enumerate().map(|(t, tri)| if t / 2 == 1 { tri.map(copy) } else { *tri }).collect();
        (points, split, welded)
    }

    /// Brute force: the lowest vertex within the tolerance, transitively.
    fn brute_force(points: &[[f32; 3]]) -> Vec<u32> {
        let tol = weld_tolerance(points);
        let mut parent: Vec<u32> = (0..points.len() as u32).collect();
        for a in 0..points.len() {
            for b in a + 1..points.len() {
                let d2: f64 = (0..3).map(|i| (f64::from(points[a][i]) - f64::from(points[b][i])).powi(2)).sum();
                if d2 <= tol * tol {
                    union(&mut parent, a as u32, b as u32);
                }
            }
        }
        (0..points.len() as u32).map(|v| find(&mut parent, v)).collect()
    }

    #[test]
    fn a_cube_split_along_a_seam_welds_into_the_cube() {
        let (points, split, welded) = split_cube();
        let weld = Weld::new(&points, &split);
        assert_eq!(weld.n_welded(), 8);
        assert_eq!(weld.welded_of[8..], [4, 6, 7, 5]);
        assert_eq!(weld.representatives, (0..8).collect::<Vec<u32>>());
        assert_eq!(weld.triangles, welded);
        assert_eq!((weld.seam_vertices(), weld.seam_groups()), (8, 4));
        // One piece welded, two split (the top's island and the rest).
        assert_eq!(connected_components(points.len(), &split).1, 2);
        assert_eq!(connected_components(weld.n_welded(), &weld.triangles).1, 1);
        // Gather takes the representatives' rows, scatter gives each copy the same.
        let rows: Vec<u32> = (0..12).chain(100..112).collect();
        assert_eq!(weld.gather(&rows).as_ref(), [(0..8).collect::<Vec<u32>>(), (100..108).collect()].concat());
        let back = weld.scatter(weld.gather(&rows).into_owned());
        assert_eq!(back[8..12], [4, 6, 7, 5]);
        assert_eq!(back[20..24], [104, 106, 107, 105]);
        assert_eq!(weld.scatter_triangles(&[true; 12], 12, false), vec![true; 12]);
    }

    #[test]
    fn an_unsplit_mesh_is_its_own_weld() {
        let (points, _, welded) = split_cube();
        let weld = Weld::new(&points[..8], &welded);
        assert!(weld.is_identity());
        assert_eq!(weld, Weld::identity(8, &welded));
        assert!(matches!(weld.gather(&points[..8]), Cow::Borrowed(_)));
    }

    #[test]
    fn the_grid_agrees_with_brute_force_near_cell_walls() {
        // Pairs placed a hair apart (below and above the tolerance) at random spots, many of
        // them straddling the grid's cell walls, and chains that weld transitively.
        let mut seed = 12345u64;
        let mut random = || {
            seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            (seed >> 40) as f64 / (1u64 << 24) as f64
        };
        let mut points: Vec<[f32; 3]> = vec![[0.0; 3], [1.0, 1.0, 1.0]];
        let tol = WELD_FRACTION * 3f64.sqrt();
        let cell = 64.0 * tol;
        for _ in 0..400 {
            let wall = (random() * 1000.0).floor() * cell;
            let p = [wall as f32, random() as f32, random() as f32];
            let step = (random() * 2.0 - 1.0) * 1.5 * tol;
            let q = [(wall + step) as f32, p[1], p[2]];
            let r = [(wall + 2.0 * step) as f32, p[1], p[2]];
            points.extend([p, q, r]);
        }
        let weld = Weld::new(&points, &[]);
        let expected = brute_force(&points);
        let got: Vec<u32> = weld.welded_of.iter().map(|&w| weld.representatives[w as usize]).collect();
        assert_eq!(got, expected);
        assert!(weld.n_welded() < points.len() && weld.n_welded() > 2 + 400, "both welds and non-welds: {}", weld.n_welded());
    }

    #[test]
    fn a_vertex_halfway_along_an_edge_far_from_the_origin_is_on_the_edge() {
        // An edge of a head modelled in centimetres at a body's height (coordinates near 67)
        // and its midpoint written in f32: the rounding leaves the triangle a height of
        // 3.8e-6, over ten times 1e-7 of the edge (here the diagonal), within one rounding step.
        let (a, b) = ([-1.230179f32, 66.68956, 14.469305], [-0.03371877f32, 66.71613, 14.8685]);
        let points = vec![a, b, [0, 1, 2].map(|i| 0.5 * (a[i] + b[i]))];
        let (diagonal, tolerance) = (bbox_diagonal(&points), weld_tolerance(&points));
        let height = 2.0 * triangle_area(&points, &[0, 1, 2]) / diagonal;
        assert!(height > 10.0 * WELD_FRACTION * diagonal && height < tolerance, "{height} {tolerance}");
        assert!(is_flat(&points, &[0, 1, 2], diagonal, tolerance));
        let weld = Weld::new(&points, &[[0, 1, 2]]);
        assert!(weld.triangles.is_empty() && weld.carried.is_empty(), "no surface left to carry by");
        // Centred on the origin, the same points keep the diagonal's tolerance.
        let centred: Vec<[f32; 3]> = points.iter().map(|p| [0, 1, 2].map(|i| p[i] - points[2][i])).collect();
        assert_eq!(weld_tolerance(&centred), WELD_FRACTION * bbox_diagonal(&centred));
    }

    #[test]
    fn copies_that_move_apart_stay_apart_and_collapsed_triangles_go() {
        let (points, split, _) = split_cube();
        let weld = Weld::new(&points, &split);
        // A shape moving corner 4's copy (8) off corner 4: 8 stands alone again.
        let mut deltas = vec![[0.0f32; 3]; 24];
        deltas[12 + 8] = [0.0, 0.0, 0.5];
        let parted = weld.clone().split_where_apart(&deltas, 1e-7, &split, &[&points]);
        assert_eq!(parted.n_welded(), 9);
        assert_eq!(parted.representatives[8], 8);
        assert_eq!(parted.welded_of[9..], [6, 7, 5]);
        // A triangle with two corners on one point has no area: dropped, reported as missing.
        let mut tris = split.clone();
        tris.push([0, 8, 4]);
        let weld = Weld::new(&points, &tris);
        assert_eq!((weld.triangles.len(), weld.triangle_of.len()), (12, 12));
        assert_eq!(weld.scatter_triangles(&[1; 12], 13, 0)[12], 0);
    }
}
