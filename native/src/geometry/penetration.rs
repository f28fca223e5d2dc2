//! The penetration metric of SPEC section 3: the total length of the intersection curves
//! between triangles that share no vertex, and the number of such intersecting pairs. The
//! length is also split by where it lies: inside one connected piece (lips or lids passing
//! through each other, what virtual edges act on) or between two pieces (skin through a
//! separate eyeball, lashes or teeth).
//!
//! Triangle-triangle test after Moller (1997): each triangle cuts the other's plane in a
//! segment on the planes' common line; the overlap of the two segments is the pair's piece
//! of the intersection curve. Coplanar pairs contribute no length (a touching, not a
//! crossing). BVH-accelerated, rayon over triangles. The shapes of one rest mesh are swept by
//! [`RestSweep`], which skips, exactly, the pairs a shape cannot have brought together.

use rayon::prelude::*;

use std::collections::HashMap;

use super::mat3::{add, cross, dot, inverse, length, mat_mul, mat_vec, scale, sub, Mat3, Vec3};
use super::bvh::{Aabb, TriangleBvh};
use super::topology::connected_components;

/// Self-intersection of a surface.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Penetration {
    /// Total length of the intersection segments, in the mesh's units.
    pub length: f64,
    /// Number of intersecting pairs of triangles that share no vertex.
    pub pairs: usize,
    /// The part of `length` where triangles of two different connected pieces cross.
    pub between_pieces: f64,
}

/// Measures the self-intersection of `positions` with `triangles` (indices must be in range).
pub fn measure_penetration(positions: &[[f32; 3]], triangles: &[[u32; 3]]) -> Penetration {
    let points: Vec<Vec3> = positions.iter().map(|p| p.map(f64::from)).collect();
    total(&crossings(&points, triangles, &TriangleBvh::build(&points, triangles), None), &triangle_pieces(positions.len(), triangles))
}

/// The connected piece of each triangle.
fn triangle_pieces(n_vertices: usize, triangles: &[[u32; 3]]) -> Vec<u32> {
    let (label, _) = connected_components(n_vertices, triangles);
    triangles.iter().map(|t| label[t[0] as usize]).collect()
}

/// A rest mesh kept to score its shapes: each is swept by [`RestSweep`], which tests only
/// the pairs the shape moves enough to cross.
pub struct PenetrationBaseline<'a> {
    neutral: &'a [[f32; 3]],
    sweep: RestSweep,
    /// The rest mesh's own crossing pairs `(a, b, length)`.
    rest: Vec<(u32, u32, f64)>,
    /// The connected piece of each triangle.
    piece: Vec<u32>,
}

impl<'a> PenetrationBaseline<'a> {
    pub fn new(neutral: &'a [[f32; 3]], triangles: &[[u32; 3]]) -> Self {
        let points: Vec<Vec3> = neutral.iter().map(|p| p.map(f64::from)).collect();
        let sweep = RestSweep::new(&points, triangles);
        let rest = sweep.crossings(&points, None);
        Self { neutral, sweep, rest, piece: triangle_pieces(neutral.len(), triangles) }
    }

    /// The rest mesh's own penetration.
    pub fn neutral(&self) -> Penetration {
        total(&self.rest, &self.piece)
    }

    /// The penetration of `neutral + delta` (N rows).
    pub fn shape(&self, delta: &[[f32; 3]]) -> Penetration {
        let points: Vec<Vec3> =
            self.neutral.iter().zip(delta).map(|(p, d)| [0, 1, 2].map(|a| (p[a] + d[a]) as f64)).collect();
        total(&self.sweep.crossings(&points, None), &self.piece)
    }
}

fn total(pairs: &[(u32, u32, f64)], piece: &[u32]) -> Penetration {
    // Summed in a fixed order so the result does not depend on the thread count.
    Penetration {
        length: pairs.iter().map(|p| p.2).sum(),
        pairs: pairs.len(),
        between_pieces: pairs.iter().filter(|p| piece[p.0 as usize] != piece[p.1 as usize]).map(|p| p.2).sum(),
    }
}

/// Crossing pairs `(a, b, length)`, `a < b`, of triangles that share no vertex, `bvh` being
/// over `points`. With `moved`, only pairs with at least one moved triangle are tested.
pub fn crossings(points: &[Vec3], triangles: &[[u32; 3]], bvh: &TriangleBvh, moved: Option<&[bool]>) -> Vec<(u32, u32, f64)> {
    let corners = |t: usize| triangles[t].map(|v| points[v as usize]);
    let normals: Vec<Vec3> = (0..triangles.len()).map(|t| normal(corners(t))).collect();
    let is_moved = |t: usize| moved.is_none_or(|m| m[t]);
    let per_triangle: Vec<Vec<(u32, u32, f64)>> = (0..triangles.len())
        .into_par_iter()
        .map(|a| {
            let mut found = Vec::new();
            if !is_moved(a) {
                return found;
            }
            bvh.for_each_overlap(&Aabb::of_points(&corners(a)), |b| {
                let b = b as usize;
                // Each pair once: from its lower index when both moved, else from the moved one.
                if (b <= a && is_moved(b)) || a == b || triangles[a].iter().any(|v| triangles[b].contains(v)) {
                    return;
                }
                let (lo, hi) = (a.min(b), a.max(b));
                if let Some(len) = crossing_length(corners(lo), normals[lo], corners(hi), normals[hi]) {
                    found.push((lo as u32, hi as u32, len));
                }
            });
            found
        })
        .collect();
    let mut all: Vec<(u32, u32, f64)> = per_triangle.into_iter().flatten().collect();
    all.sort_by_key(|&(a, b, _)| (a, b));
    all
}

/// A rest mesh prepared to sweep deformations of it for crossing pairs: the same pairs and
/// lengths as [`crossings`] over the deformed points, without testing the pairs that provably
/// cannot cross.
///
/// Why a pair can be skipped: each point of a triangle moves by a convex combination of its
/// corners' displacements, so by at most the largest, `delta_t`. Two triangles at least `s`
/// apart at rest are therefore still apart while `delta_a + delta_b < s`. `s` is a lower bound
/// on the rest distance: the widest gap between the two triangles' projections onto a few
/// axes (separating-axis theorem; a unit axis's gap is at most the distance). The same holds
/// after any invertible affine map `F(p) = A (p - m) + x_bar` (it maps crossing triangles to
/// crossing triangles): pulled back through `F`, corner `v` sits `|A^-1 r_v| <= |A^-1|_F |r_v|`
/// from its rest place, `r_v = x_v - F(x0_v)` its residual. `F` is fitted to the deformation
/// over a cluster of the rest mesh (a grid cell), so a region the shape translates, turns or
/// stretches (a jaw opening, a lip pushed forward) has small residuals and its neighbours
/// are skipped as well as those of a region that hardly moves.
///
/// Pairs near at rest (gap at most `reach`) are listed once. A pair farther apart can only
/// cross when `delta_a + delta_b > reach`: each triangle moving more than half of `reach` is
/// queried against a hierarchy refitted to the deformed points, as [`crossings`] does, for
/// the unlisted pairs.
pub struct RestSweep {
    triangles: Vec<[u32; 3]>,
    rest: Vec<Vec3>,
    /// Over `rest`, refitted to a deformation when some triangle moves far.
    bvh: TriangleBvh,
    reach: f64,
    /// Per triangle `a` (compressed rows), the partners `b > a` sharing no vertex with it
    /// whose rest gap `s` is at most `reach`, as `(b, s)`, by `b`.
    near_offsets: Vec<usize>,
    near: Vec<(u32, f64)>,
    /// Added to every bound: the rounding of the points' coordinates.
    slack: f64,
    /// The cluster of each triangle, and per cluster its rest frame.
    cluster: Vec<u32>,
    frames: Vec<RestFrame>,
}

/// A cluster's rest data for the least-squares affine fit `min sum_v |A q_v + t - x_v|^2 +
/// lambda |A - I|_F^2` over its corners (`q_v = x0_v - centre`; since `sum_v q_v = 0`, `t` is
/// the mean of the `x_v` and `A = (sum_v x_v q_v^T + lambda I) (sum_v q_v q_v^T + lambda I)^-1`).
/// The ridge keeps `A` well defined on a flat cluster (its normal column is otherwise fitted
/// to noise); any invertible `A` gives a valid bound, a good one a tight bound.
struct RestFrame {
    centre: Vec3,
    lambda: f64,
    inverse_moment: Mat3,
    vertices: Vec<u32>,
}

/// A cluster's fitted map on one deformation: `F(p) = map (p - centre) + mean`; `stretch` is
/// `|map^-1|_F` (infinite when the map is singular).
#[derive(Clone, Copy)]
struct Frame {
    map: Mat3,
    mean: Vec3,
    stretch: f64,
}

/// The near list's reach and the clusters' cell size, in mean edge lengths.
const NEAR_REACH_EDGES: f64 = 1.0;
const CLUSTER_EDGES: f64 = 6.0;

impl RestSweep {
    /// Indices must be in range (the rig validated them).
    pub fn new(rest: &[Vec3], triangles: &[[u32; 3]]) -> Self {
        let bvh = TriangleBvh::build(rest, triangles);
        let corners = |t: usize| triangles[t].map(|v| rest[v as usize]);
        let edges: f64 = triangles.iter().map(|t| (0..3).map(|i| length(sub(rest[t[i] as usize], rest[t[(i + 1) % 3] as usize]))).sum::<f64>()).sum();
        let mean_edge = edges / (3 * triangles.len()).max(1) as f64;
        let reach = NEAR_REACH_EDGES * mean_edge;
        let whole = Aabb::of_points(rest);
        let diagonal = if rest.is_empty() { 0.0 } else { length(sub(whole.hi, whole.lo)) };
        let rows: Vec<Vec<(u32, f64)>> = (0..triangles.len())
            .into_par_iter()
            .map(|a| {
                let mut row = Vec::new();
                let around = Aabb::of_points(&corners(a));
                let around = Aabb { lo: around.lo.map(|x| x - reach), hi: around.hi.map(|x| x + reach) };
                bvh.for_each_overlap(&around, |b| {
                    if b as usize > a && !triangles[a].iter().any(|v| triangles[b as usize].contains(v)) {
                        let gap = rest_gap(corners(a), corners(b as usize));
                        if gap <= reach {
                            row.push((b, gap));
                        }
                    }
                });
                row.sort_unstable_by_key(|p| p.0);
                row
            })
            .collect();
        let mut near_offsets = Vec::with_capacity(rows.len() + 1);
        near_offsets.push(0);
        for row in &rows {
            near_offsets.push(near_offsets.last().unwrap() + row.len());
        }
        let near = rows.into_iter().flatten().collect();
        let (cluster, frames) = clusters(rest, triangles, CLUSTER_EDGES * mean_edge);
        Self { triangles: triangles.to_vec(), rest: rest.to_vec(), bvh, reach, near_offsets, near, slack: 1e-9 * diagonal, cluster, frames }
    }

    /// [`crossings`] of `points` (the rest points moved), without the pairs that cannot cross.
    /// With `moved`, only pairs with at least one moved triangle are reported, as there.
    pub fn crossings(&self, points: &[Vec3], moved: Option<&[bool]>) -> Vec<(u32, u32, f64)> {
        let triangles = &self.triangles;
        let displacement: Vec<f64> = points.par_iter().zip(&self.rest).map(|(p, r)| length(sub(*p, *r))).collect();
        let corners = |t: usize| triangles[t].map(|v| points[v as usize]);
        let spread: Vec<f64> = triangles.par_iter().map(|t| t.iter().map(|&v| displacement[v as usize]).fold(0.0, f64::max)).collect();
        let frames: Vec<Frame> = self.frames.par_iter().map(|f| f.fit(&self.rest, points)).collect();
        // Per triangle, its corners' largest residual under its own cluster's map.
        let residual_in = |t: usize, c: usize| {
            let (frame, rest) = (&frames[c], &self.frames[c]);
            triangles[t].iter().map(|&v| frame.residual(rest, self.rest[v as usize], points[v as usize])).fold(0.0, f64::max)
        };
        let residual: Vec<f64> = (0..triangles.len()).into_par_iter().map(|t| residual_in(t, self.cluster[t] as usize)).collect();
        let far = |t: usize| 2.0 * spread[t] > self.reach - self.slack;
        let refitted = (0..triangles.len()).any(far).then(|| self.bvh.refitted(points, triangles));
        let normals: Vec<Vec3> = (0..triangles.len()).into_par_iter().map(|t| normal(corners(t))).collect();
        let tested = |a: usize, b: usize| moved.is_none_or(|m| m[a] || m[b]);
        let per_triangle: Vec<Vec<(u32, u32, f64)>> = (0..triangles.len())
            .into_par_iter()
            .map(|a| {
                let mut found = Vec::new();
                let mut test = |lo: usize, hi: usize| {
                    if let Some(len) = crossing_length(corners(lo), normals[lo], corners(hi), normals[hi]) {
                        found.push((lo as u32, hi as u32, len));
                    }
                };
                let home = self.cluster[a] as usize;
                for &(b, gap) in self.row(a) {
                    let b = b as usize;
                    if !tested(a, b) || gap > spread[a] + spread[b] + self.slack {
                        continue;
                    }
                    let other = if self.cluster[b] as usize == home { residual[b] } else { residual_in(b, home) };
                    if gap > frames[home].stretch * (residual[a] + other) + self.slack {
                        continue;
                    }
                    test(a, b);
                }
                if let Some(bvh) = refitted.as_ref().filter(|_| far(a)) {
                    bvh.for_each_overlap(&Aabb::of_points(&corners(a)), |b| {
                        let b = b as usize;
                        // An unlisted pair: from its lower index when both are far, else from the far one.
                        if a == b || (far(b) && b < a) || !tested(a, b) || triangles[a].iter().any(|v| triangles[b].contains(v)) {
                            return;
                        }
                        let (lo, hi) = (a.min(b), a.max(b));
                        if self.row(lo).binary_search_by_key(&(hi as u32), |p| p.0).is_err() {
                            test(lo, hi);
                        }
                    });
                }
                found
            })
            .collect();
        let mut all: Vec<(u32, u32, f64)> = per_triangle.into_iter().flatten().collect();
        all.sort_by_key(|&(a, b, _)| (a, b));
        all
    }

    fn row(&self, a: usize) -> &[(u32, f64)] {
        &self.near[self.near_offsets[a]..self.near_offsets[a + 1]]
    }
}

impl RestFrame {
    /// The least-squares map of this cluster from `rest` to `points`.
    fn fit(&self, rest: &[Vec3], points: &[Vec3]) -> Frame {
        let count = self.vertices.len().max(1) as f64;
        let mean = scale(self.vertices.iter().fold([0.0; 3], |s, &v| add(s, points[v as usize])), 1.0 / count);
        let mut moment: Mat3 = std::array::from_fn(|r| std::array::from_fn(|k| if r == k { self.lambda } else { 0.0 }));
        for &v in &self.vertices {
            let (q, x) = (sub(rest[v as usize], self.centre), points[v as usize]);
            for r in 0..3 {
                for k in 0..3 {
                    moment[r][k] += x[r] * q[k];
                }
            }
        }
        let map = mat_mul(&moment, &self.inverse_moment);
        let stretch = inverse(&map).map_or(f64::INFINITY, |m| m.iter().flatten().map(|x| x * x).sum::<f64>().sqrt());
        Frame { map, mean, stretch: if stretch.is_finite() { stretch } else { f64::INFINITY } }
    }
}

impl Frame {
    /// `|x - F(x0)|`: how far the map misses a vertex.
    fn residual(&self, rest: &RestFrame, x0: Vec3, x: Vec3) -> f64 {
        length(sub(x, add(mat_vec(&self.map, sub(x0, rest.centre)), self.mean)))
    }
}

/// Clusters of triangles by the grid cell (side `cell`) holding their centroid, and each
/// cluster's rest frame over its triangles' corners.
fn clusters(rest: &[Vec3], triangles: &[[u32; 3]], cell: f64) -> (Vec<u32>, Vec<RestFrame>) {
    let mut index: HashMap<[i64; 3], u32> = HashMap::new();
    let mut members: Vec<Vec<u32>> = Vec::new();
    let cluster: Vec<u32> = triangles
        .iter()
        .map(|t| {
            let centre = scale(t.iter().fold([0.0; 3], |s, &v| add(s, rest[v as usize])), 1.0 / 3.0);
            let key = if cell > 0.0 { centre.map(|x| (x / cell).floor() as i64) } else { [0; 3] };
            let next = index.len() as u32;
            let c = *index.entry(key).or_insert(next);
            if c == next {
                members.push(Vec::new());
            }
            members[c as usize].extend_from_slice(t);
            c
        })
        .collect();
    let frames = members
        .into_par_iter()
        .map(|mut vertices| {
            vertices.sort_unstable();
            vertices.dedup();
            let count = vertices.len() as f64;
            let centre = scale(vertices.iter().fold([0.0; 3], |s, &v| add(s, rest[v as usize])), 1.0 / count);
            let mut moment: Mat3 = [[0.0; 3]; 3];
            for &v in &vertices {
                let q = sub(rest[v as usize], centre);
                for r in 0..3 {
                    for k in 0..3 {
                        moment[r][k] += q[r] * q[k];
                    }
                }
            }
            let lambda = FRAME_RIDGE * (moment[0][0] + moment[1][1] + moment[2][2]) / 3.0;
            for (r, row) in moment.iter_mut().enumerate() {
                row[r] += lambda;
            }
            // A cluster of one degenerate point has no inverse: its map is the identity's
            // ridge alone, and its bound infinite (`stretch`).
            let inverse_moment = inverse(&moment).unwrap_or([[0.0; 3]; 3]);
            RestFrame { centre, lambda, inverse_moment, vertices }
        })
        .collect();
    (cluster, frames)
}

/// The ridge of the clusters' affine fit, relative to their mean squared spread per axis.
const FRAME_RIDGE: f64 = 1e-2;

/// A lower bound on the distance between two triangles: the widest gap between their
/// projections onto their normals, the axis joining their centroids and the in-plane normals
/// of their edges (0 when no such axis separates them).
fn rest_gap(a: [Vec3; 3], b: [Vec3; 3]) -> f64 {
    let (na, nb) = (normal(a), normal(b));
    let centre = |t: [Vec3; 3]| scale(add(add(t[0], t[1]), t[2]), 1.0 / 3.0);
    let mut axes = vec![na, nb, sub(centre(b), centre(a))];
    for (t, n) in [(a, na), (b, nb)] {
        axes.extend((0..3).map(|i| cross(n, sub(t[(i + 1) % 3], t[i]))));
    }
    axes.iter()
        .filter_map(|&u| {
            let norm = length(u);
            (norm > 0.0).then(|| {
                let (pa, pb) = (a.map(|p| dot(u, p)), b.map(|p| dot(u, p)));
                let (a_lo, a_hi) = (pa.iter().copied().fold(f64::INFINITY, f64::min), pa.iter().copied().fold(f64::NEG_INFINITY, f64::max));
                let (b_lo, b_hi) = (pb.iter().copied().fold(f64::INFINITY, f64::min), pb.iter().copied().fold(f64::NEG_INFINITY, f64::max));
                (b_lo - a_hi).max(a_lo - b_hi) / norm
            })
        })
        .fold(0.0, f64::max)
}

/// The length of the segment where two triangles cross, or `None` when they do not cross
/// (or are coplanar).
pub fn intersection_length(a: [Vec3; 3], b: [Vec3; 3]) -> Option<f64> {
    crossing_length(a, normal(a), b, normal(b))
}

/// The unnormalised normal `(p1 - p0) x (p2 - p0)` that [`intersection_length`] uses.
fn normal(t: [Vec3; 3]) -> Vec3 {
    cross(sub(t[1], t[0]), sub(t[2], t[0]))
}

/// [`intersection_length`] with both normals given. The cheap rejections (one triangle
/// strictly on one side of the other's plane) come first; a crossing is computed with the
/// same arithmetic in any order, so the length is the same to the bit.
fn crossing_length(a: [Vec3; 3], na: Vec3, b: [Vec3; 3], nb: Vec3) -> Option<f64> {
    let a_side = a.map(|p| dot(nb, sub(p, b[0])));
    if one_side(a_side) {
        return None;
    }
    let b_side = b.map(|p| dot(na, sub(p, a[0])));
    if one_side(b_side) {
        return None;
    }
    let line = cross(na, nb);
    let line_len = length(line);
    if line_len <= 1e-14 * length(na) * length(nb) {
        return None;
    }
    let (a_lo, a_hi) = plane_cut(a, a_side, line)?;
    let (b_lo, b_hi) = plane_cut(b, b_side, line)?;
    let overlap = (a_hi.min(b_hi) - a_lo.max(b_lo)) / line_len;
    (overlap > 0.0).then_some(overlap)
}

/// Whether all three corners lie strictly on one side of a plane (`side`: their heights).
fn one_side(side: [f64; 3]) -> bool {
    side.iter().all(|&s| s > 0.0) || side.iter().all(|&s| s < 0.0)
}

/// Where triangle `t`, whose corners lie at heights `side` over a plane, cuts that plane, as
/// an interval of the projection onto `line` (on the plane).
fn plane_cut(t: [Vec3; 3], side: [f64; 3], line: Vec3) -> Option<(f64, f64)> {
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut take = |p: Vec3| {
        let x = dot(p, line);
        lo = lo.min(x);
        hi = hi.max(x);
    };
    for i in 0..3 {
        let j = (i + 1) % 3;
        if side[i] == 0.0 {
            take(t[i]);
        }
        if (side[i] < 0.0 && side[j] > 0.0) || (side[i] > 0.0 && side[j] < 0.0) {
            let f = side[i] / (side[i] - side[j]);
            take(add(t[i], scale(sub(t[j], t[i]), f)));
        }
    }
    (lo <= hi).then_some((lo, hi))
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn crossing_triangles_give_the_known_segment() {
        // A in z = 0; B upright in y = 0, cut by z = 0 between x = 0.5 and x = 1.5.
        let a = [[-1.0, -1.0, 0.0], [3.0, -1.0, 0.0], [-1.0, 3.0, 0.0]];
        let b = [[0.0, 0.0, -1.0], [2.0, 0.0, -1.0], [1.0, 0.0, 1.0]];
        assert!((intersection_length(a, b).unwrap() - 1.0).abs() < 1e-12);
        assert!((intersection_length(b, a).unwrap() - 1.0).abs() < 1e-12);
        // Clipped by A's hypotenuse x + y = 2: shift B to x in [1.5, 2.5] at z = 0 -> 0.5.
        let b2 = b.map(|p| [p[0] + 1.0, p[1], p[2]]);
        assert!((intersection_length(a, b2).unwrap() - 0.5).abs() < 1e-12);
        // Lifted above A: no crossing. Coplanar: no length.
        let b3 = b.map(|p| [p[0], p[1], p[2] + 1.5]);
        assert!(intersection_length(a, b3).is_none());
        let flat = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert!(intersection_length(a, flat).is_none());
    }

    #[test]
    fn adjacent_triangles_do_not_count_and_a_piercing_one_does() {
        // Triangle 1 shares vertex 0 with triangle 0 and cuts through it: adjacent, not counted.
        let pts = [
            [0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 1.0, 0.0],
            [0.6, 0.3, -0.5], [0.2, 0.3, -1.0], [0.4, 0.3, 1.0], [0.3, 0.6, 1.0], [0.6, 0.3, 0.5],
        ];
        let pts32: Vec<[f32; 3]> = pts.iter().map(|p: &[f64; 3]| p.map(|x| x as f32)).collect();
        assert!(intersection_length([pts[0], pts[1], pts[2]], [pts[0], pts[3], pts[7]]).unwrap() > 0.5);
        let folded = [[0u32, 1, 2], [0, 3, 7]];
        assert_eq!(measure_penetration(&pts32, &folded), Penetration::default());
        // A third triangle, sharing no vertex, pierces the first (and misses the second).
        let with_pierce = [[0u32, 1, 2], [0, 3, 7], [4, 5, 6]];
        let p = measure_penetration(&pts32, &with_pierce);
        assert_eq!(p.pairs, 1);
        let expect = intersection_length(
            [pts[0], pts[1], pts[2]].map(|q| q.map(|x| x as f32 as f64)),
            [pts[4], pts[5], pts[6]].map(|q| q.map(|x| x as f32 as f64)),
        )
        .unwrap();
        assert!((p.length - expect).abs() < 1e-12 && p.length > 0.0);
        // The piercing triangle is a piece of its own: all of the curve lies between pieces.
        assert_eq!(p.between_pieces, p.length);
        // Joined to the first piece by a bridge triangle above them all (it crosses nothing),
        // the same crossing lies inside one piece.
        let mut bridged = pts32.clone();
        bridged.push([5.0, 5.0, 5.0]);
        let joined = [[0u32, 1, 2], [0, 3, 7], [4, 5, 6], [6, 8, 7]];
        let q = measure_penetration(&bridged, &joined);
        assert_eq!((q.pairs, q.length), (p.pairs, p.length));
        assert_eq!(q.between_pieces, 0.0);
    }

    #[test]
    fn baseline_scores_a_shape_like_a_full_sweep() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let pts: Vec<[f32; 3]> = (0..240).map(|_| [rng.random(), rng.random(), rng.random()]).collect();
        let tris: Vec<[u32; 3]> = (0..80).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
        let baseline = PenetrationBaseline::new(&pts, &tris);
        assert_eq!(baseline.neutral(), measure_penetration(&pts, &tris));
        // Move a third of the triangles.
        let delta: Vec<[f32; 3]> =
            (0..pts.len()).map(|v| if v % 9 < 3 { [0.2, -0.1, 0.05 * (v % 4) as f32] } else { [0.0; 3] }).collect();
        let posed: Vec<[f32; 3]> = pts.iter().zip(&delta).map(|(p, d)| [p[0] + d[0], p[1] + d[1], p[2] + d[2]]).collect();
        let full = measure_penetration(&posed, &tris);
        let fast = baseline.shape(&delta);
        assert!(full.pairs > 5 && full != baseline.neutral());
        assert_eq!(fast.pairs, full.pairs);
        assert!((fast.length - full.length).abs() < 1e-9);
    }

    #[test]
    fn cheap_metric_equals_a_full_sweep_on_random_meshes() {
        // Random crumpled grids (one connected piece, shared corners) plus a random soup
        // (pieces of their own); each shape moves a random subset of vertices by a random
        // amount. Re-testing only triangles with a moved corner must give exactly the full
        // sweep's pairs, length and split by piece.
        for seed in 0..12u64 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(100 + seed);
            let w = 9usize;
            let mut pts: Vec<[f32; 3]> = (0..w * w)
                .map(|v| {
                    let (x, y) = ((v % w) as f32 / w as f32, (v / w) as f32 / w as f32);
                    [x, y, 0.4 * (7.0 * x + rng.random::<f32>()).sin() * (5.0 * y).cos()]
                })
                .collect();
            let mut tris: Vec<[u32; 3]> = Vec::new();
            for y in 0..w - 1 {
                for x in 0..w - 1 {
                    let v = (y * w + x) as u32;
                    tris.push([v, v + 1, v + w as u32 + 1]);
                    tris.push([v, v + w as u32 + 1, v + w as u32]);
                }
            }
            for _ in 0..30 {
                let start = pts.len() as u32;
                let centre: [f32; 3] = [rng.random(), rng.random(), rng.random::<f32>() - 0.5];
                for _ in 0..3 {
                    pts.push([0, 1, 2].map(|a| centre[a] + 0.3 * (rng.random::<f32>() - 0.5)));
                }
                tris.push([start, start + 1, start + 2]);
            }
            let baseline = PenetrationBaseline::new(&pts, &tris);
            assert_eq!(baseline.neutral(), measure_penetration(&pts, &tris));
            let share = rng.random::<f64>();
            let delta: Vec<[f32; 3]> = (0..pts.len())
                .map(|_| if rng.random::<f64>() < share { [0, 1, 2].map(|_| 0.2 * (rng.random::<f32>() - 0.5)) } else { [0.0; 3] })
                .collect();
            let posed: Vec<[f32; 3]> = pts.iter().zip(&delta).map(|(p, d)| [p[0] + d[0], p[1] + d[1], p[2] + d[2]]).collect();
            let (full, cheap) = (measure_penetration(&posed, &tris), baseline.shape(&delta));
            assert!(full.pairs > 0, "seed {seed}: nothing crosses");
            assert_eq!(cheap.pairs, full.pairs, "seed {seed}");
            assert!((cheap.length - full.length).abs() < 1e-9, "seed {seed}: {cheap:?} vs {full:?}");
            assert!((cheap.between_pieces - full.between_pieces).abs() < 1e-9, "seed {seed}");
        }
    }

    /// Every pair of triangles sharing no vertex, tested (lower index first).
    fn all_pairs(points: &[Vec3], tris: &[[u32; 3]]) -> Vec<(u32, u32, f64)> {
        let mut found = Vec::new();
        for a in 0..tris.len() {
            for b in a + 1..tris.len() {
                if tris[a].iter().any(|v| tris[b].contains(v)) {
                    continue;
                }
                if let Some(len) = intersection_length(tris[a].map(|v| points[v as usize]), tris[b].map(|v| points[v as usize])) {
                    found.push((a as u32, b as u32, len));
                }
            }
        }
        found
    }

    #[test]
    fn rest_sweep_finds_every_pair_all_pairs_find() {
        // A crumpled grid folded onto itself (near pairs at rest, crossing ones too) plus a
        // soup; each deformation moves every vertex by a little (as a global solve does),
        // a region by a lot (far movers: the refitted hierarchy) and some not at all. The
        // pairs and lengths must be those of testing every pair, to the bit.
        for seed in 0..10u64 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(700 + seed);
            let w = 12usize;
            let mut pts: Vec<Vec3> = (0..w * w)
                .map(|v| {
                    let (x, y) = ((v % w) as f64 / w as f64, (v / w) as f64 / w as f64);
                    [x, y, 0.3 * (6.0 * x + rng.random::<f64>()).sin() * (4.0 * y).cos()]
                })
                .collect();
            let mut tris: Vec<[u32; 3]> = Vec::new();
            for y in 0..w - 1 {
                for x in 0..w - 1 {
                    let v = (y * w + x) as u32;
                    tris.push([v, v + 1, v + w as u32 + 1]);
                    tris.push([v, v + w as u32 + 1, v + w as u32]);
                }
            }
            for _ in 0..25 {
                let start = pts.len() as u32;
                let centre: [f64; 3] = [rng.random(), rng.random(), rng.random::<f64>() - 0.5];
                pts.extend((0..3).map(|_| [0, 1, 2].map(|a| centre[a] + 0.25 * (rng.random::<f64>() - 0.5))));
                tris.push([start, start + 1, start + 2]);
            }
            let sweep = RestSweep::new(&pts, &tris);
            assert_eq!(sweep.crossings(&pts, None), all_pairs(&pts, &tris), "seed {seed}: rest");
            let tiny = 10f64.powi(-(rng.random_range(2..7)));
            let region: [f64; 2] = [rng.random(), rng.random()];
            let posed: Vec<Vec3> = pts
                .iter()
                .enumerate()
                .map(|(v, p)| {
                    if v % 7 == 0 {
                        return *p;
                    }
                    let near = (p[0] - region[0]).hypot(p[1] - region[1]) < 0.3;
                    let size = if near { 0.15 } else { tiny };
                    [0, 1, 2].map(|a| p[a] + size * (rng.random::<f64>() - 0.5))
                })
                .collect();
            let expected = all_pairs(&posed, &tris);
            assert!(expected.len() > 3, "seed {seed}: nothing crosses");
            assert_eq!(sweep.crossings(&posed, None), expected, "seed {seed}");
            // Turned, stretched and moved as a whole with a little noise: every triangle moves
            // far, the clusters' maps explain nearly all of it.
            let (c, sn) = (0.8f64.cos(), 0.8f64.sin());
            let turned: Vec<Vec3> = posed
                .iter()
                .map(|p| [c * p[0] - sn * p[2] + 0.5, 1.3 * p[1] - 0.2, sn * p[0] + c * p[2]].map(|x| x + tiny * (rng.random::<f64>() - 0.5)))
                .collect();
            assert_eq!(sweep.crossings(&turned, None), all_pairs(&turned, &tris), "seed {seed}: turned");
            // With `moved`, the pairs with a moved triangle among them.
            let moved: Vec<bool> = (0..tris.len()).map(|t| t % 3 != 0).collect();
            let kept: Vec<_> = expected.iter().copied().filter(|&(a, b, _)| moved[a as usize] || moved[b as usize]).collect();
            assert_eq!(sweep.crossings(&posed, Some(&moved)), kept, "seed {seed}: moved");
        }
    }

    #[test]
    fn rest_gap_is_at_most_the_distance() {
        // Sampled points of both triangles: no two closer than the bound.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut separated = 0;
        for _ in 0..300 {
            let tri = |rng: &mut rand_chacha::ChaCha8Rng, o: f64| -> [Vec3; 3] { std::array::from_fn(|_| [0, 1, 2].map(|_| o + rng.random::<f64>())) };
            let (a, b) = (tri(&mut rng, 0.0), tri(&mut rng, 0.6));
            let gap = rest_gap(a, b);
            separated += usize::from(gap > 0.0);
            let sample = |t: [Vec3; 3], u: f64, v: f64| {
                let (u, v) = if u + v > 1.0 { (1.0 - u, 1.0 - v) } else { (u, v) };
                add(t[0], add(scale(sub(t[1], t[0]), u), scale(sub(t[2], t[0]), v)))
            };
            for _ in 0..200 {
                let p = sample(a, rng.random(), rng.random());
                let q = sample(b, rng.random(), rng.random());
                assert!(length(sub(p, q)) >= gap - 1e-12);
            }
        }
        assert!(separated > 50, "too few separated pairs to test the bound: {separated}");
    }

    #[test]
    fn bvh_sweep_matches_all_pairs() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let pts: Vec<[f32; 3]> = (0..150).map(|_| [rng.random(), rng.random(), rng.random()]).collect();
        let tris: Vec<[u32; 3]> = (0..50).map(|t| [3 * t, 3 * t + 1, 3 * t + 2]).collect();
        let found = measure_penetration(&pts, &tris);
        let p64: Vec<Vec3> = pts.iter().map(|p| p.map(f64::from)).collect();
        let mut brute = Penetration::default();
        for a in 0..tris.len() {
            for b in a + 1..tris.len() {
                if let Some(len) = intersection_length(tris[a].map(|v| p64[v as usize]), tris[b].map(|v| p64[v as usize])) {
                    brute.length += len;
                    brute.pairs += 1;
                }
            }
        }
        assert!(brute.pairs > 5, "the random soup should cross itself");
        assert_eq!(found.pairs, brute.pairs);
        assert!((found.length - brute.length).abs() < 1e-9);
    }
}
