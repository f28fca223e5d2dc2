//! The penetration metric of method, section 3: the total length of the intersection curves
//! between triangles that share no vertex, and the number of such intersecting pairs. The
//! length is also split by where it lies: inside one connected piece (lips or lids passing
//! through each other, what virtual edges act on) or between two pieces (skin through a
//! separate eyeball, lashes or teeth).
//!
//! Triangle-triangle test after Moller (1997): each triangle cuts the other's plane in a
//! segment on the planes' common line; the overlap of the two segments is the pair's piece
//! of the intersection curve. Coplanar pairs contribute no length (a touching, not a
//! crossing). BVH-accelerated, rayon over triangles.

use rayon::prelude::*;

use super::mat3::{add, cross, dot, length, scale, sub, Vec3};
use super::bvh::{Aabb, RefitLinks, TriangleBvh};
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

/// Which triangles of `positions` cross a triangle they share no vertex with, leaving out the
/// pairs that already cross in `rest` when it is given: what a picture paints and a rigger
/// selects to see where a shape passes through itself beyond what the neutral does.
pub fn intersecting_triangles(positions: &[[f32; 3]], rest: Option<&[[f32; 3]]>, triangles: &[[u32; 3]]) -> Vec<bool> {
    let pairs = |positions: &[[f32; 3]]| {
        let points: Vec<Vec3> = positions.iter().map(|p| p.map(f64::from)).collect();
        crossings(&points, triangles, &TriangleBvh::build(&points, triangles), None)
    };
    let at_rest: std::collections::HashSet<(u32, u32)> =
        rest.map(|rest| pairs(rest).into_iter().map(|(a, b, _)| (a, b)).collect()).unwrap_or_default();
    let mut crossed = vec![false; triangles.len()];
    for (a, b, _) in pairs(positions) {
        if !at_rest.contains(&(a, b)) {
            crossed[a as usize] = true;
            crossed[b as usize] = true;
        }
    }
    crossed
}

/// The connected piece of each triangle (that of its first corner).
pub fn triangle_pieces(n_vertices: usize, triangles: &[[u32; 3]]) -> Vec<u32> {
    let (label, _) = connected_components(n_vertices, triangles);
    triangles.iter().map(|t| label[t[0] as usize]).collect()
}

/// The intersection curve a shape adds to its neutral (its length in the shape minus at
/// rest), split as the criterion of method, section 3 judges it: inside one connected piece (lip through lip)
/// and between two pieces (skin through teeth, an eyeball, lashes). Over a neutral that
/// crosses nowhere ([`AddedCurve::crossing`]) it is a shape's whole curve, per part.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct AddedCurve {
    pub inside: f64,
    pub between: f64,
}

impl AddedCurve {
    /// The curve a shape whose penetration is `shape` adds to its neutral's `rest`.
    pub fn from_penetrations(shape: &Penetration, rest: &Penetration) -> Self {
        let inside = |p: &Penetration| p.length - p.between_pieces;
        AddedCurve { inside: inside(shape) - inside(rest), between: shape.between_pieces - rest.between_pieces }
    }

    /// The whole curve of `p`, per part.
    pub fn crossing(p: &Penetration) -> Self {
        Self::from_penetrations(p, &Penetration::default())
    }

    /// The curve added by the crossing pairs `(a, b, length)` of a shape beyond the rest
    /// total `rest`, `piece` giving each triangle's piece.
    pub fn of(pairs: impl Iterator<Item = (u32, u32, f64)>, piece: impl Fn(u32) -> u32, rest: AddedCurve) -> Self {
        let mut added = AddedCurve { inside: -rest.inside, between: -rest.between };
        for (a, b, l) in pairs {
            if piece(a) == piece(b) {
                added.inside += l;
            } else {
                added.between += l;
            }
        }
        added
    }

    /// How much more this adds than `allowed` ([`TemplateCurve::allowed`]), both parts
    /// together, removing in one part not paying for adding in the other. Zero when the shape
    /// meets the criterion.
    pub fn excess(&self, allowed: &AddedCurve) -> f64 {
        self.excess_parts(allowed).total()
    }

    /// Both parts together.
    pub fn total(&self) -> f64 {
        self.inside + self.between
    }

    /// The same curve at `factor` times the size (lengths scale linearly): a template
    /// shape's curve at the target's size and units, before it is compared with the target's.
    pub fn scaled(&self, factor: f64) -> Self {
        AddedCurve { inside: factor * self.inside, between: factor * self.between }
    }

    /// [`Self::excess`] part by part (each zero or more): what the report gives per shape, so
    /// the add-on reads the criterion instead of computing it again.
    pub fn excess_parts(&self, allowed: &AddedCurve) -> AddedCurve {
        AddedCurve { inside: (self.inside - allowed.inside).max(0.0), between: (self.between - allowed.between).max(0.0) }
    }
}

/// A pair crossing at a neutral's rest is acted on (by the transfer's and the carry's collision
/// passes) once its curve grows by more than this fraction in a shape: skin resting against an
/// eyeball or the teeth adds curve by sliding deeper along pairs that already cross.
pub const REST_GROWTH: f64 = 0.05;

/// What the template's shape allows a target shape (the criterion of method, section 3), per part, at the
/// target's size and units: the curve it adds to the template's neutral (`added`) and its
/// own whole curve (`crossing`). Part by part, a target shape is worse than the template's
/// when its curve exceeds both its own neutral's plus `added` (a removal counting as none:
/// where the template adds none, the transfer adds none) and `crossing` (a template whose
/// neutral crosses where the target's does not, copied faithfully, crosses no more than the
/// template's shape). The transfer's pass and report and the wrap's carry all judge by it.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct TemplateCurve {
    pub added: AddedCurve,
    pub crossing: AddedCurve,
}

impl TemplateCurve {
    /// The template shape whose penetration is `shape`, over its neutral's `rest`.
    pub fn from_penetrations(shape: &Penetration, rest: &Penetration) -> Self {
        TemplateCurve { added: AddedCurve::from_penetrations(shape, rest), crossing: AddedCurve::crossing(shape) }
    }

    /// Both curves at `factor` times the size ([`AddedCurve::scaled`]).
    pub fn scaled(&self, factor: f64) -> Self {
        TemplateCurve { added: self.added.scaled(factor), crossing: self.crossing.scaled(factor) }
    }

    /// The curve a target shape may add to a neutral whose own curve is `rest` (per part,
    /// [`AddedCurve::crossing`] of the target's neutral): per part the more of `added` (zero
    /// where the template removes) and what `crossing` leaves beyond `rest`. Zero or more.
    pub fn allowed(&self, rest: &AddedCurve) -> AddedCurve {
        let part = |added: f64, crossing: f64, rest: f64| added.max(0.0).max(crossing - rest);
        AddedCurve {
            inside: part(self.added.inside, self.crossing.inside, rest.inside),
            between: part(self.added.between, self.crossing.between, rest.between),
        }
    }
}

/// The self-intersections of a rest mesh, kept so that each of its shapes is scored by
/// re-testing only the triangles the shape moves: a pair of unmoved triangles crosses
/// exactly as at rest.
pub struct PenetrationBaseline<'a> {
    neutral: &'a [[f32; 3]],
    triangles: &'a [[u32; 3]],
    /// `(a, b, length)` with `a < b`, sorted by `(a, b)`.
    rest: Vec<(u32, u32, f64)>,
    /// Built on the rest pose; a copy is refitted to each shape where it moves.
    bvh: TriangleBvh,
    /// Where each triangle and node of `bvh` sits, for [`TriangleBvh::refit_listed`].
    links: RefitLinks,
    /// The connected piece of each triangle.
    piece: Vec<u32>,
}

impl<'a> PenetrationBaseline<'a> {
    pub fn new(neutral: &'a [[f32; 3]], triangles: &'a [[u32; 3]]) -> Self {
        let points: Vec<Vec3> = neutral.iter().map(|p| p.map(f64::from)).collect();
        let bvh = TriangleBvh::build(&points, triangles);
        let rest = crossings(&points, triangles, &bvh, None);
        let links = bvh.refit_links();
        Self { neutral, triangles, rest, bvh, links, piece: triangle_pieces(neutral.len(), triangles) }
    }

    /// Whether triangles `a < b` cross at rest.
    pub fn rest_crosses(&self, a: u32, b: u32) -> bool {
        self.rest.binary_search_by_key(&(a, b), |&(x, y, _)| (x, y)).is_ok()
    }

    /// The rest mesh's own penetration.
    pub fn neutral(&self) -> Penetration {
        total(&self.rest, &self.piece)
    }

    /// The penetration of `neutral + delta` (N rows). A vertex moves when its delta is not
    /// exactly zero.
    pub fn shape(&self, delta: &[[f32; 3]]) -> Penetration {
        self.shape_swept(delta).1
    }

    /// [`Self::shape`] with the crossing pairs `(a, b, length)` of the triangles the shape
    /// moves (every other pair crosses as at rest).
    pub fn shape_swept(&self, delta: &[[f32; 3]]) -> (Vec<(u32, u32, f64)>, Penetration) {
        let points: Vec<Vec3> =
            self.neutral.iter().zip(delta).map(|(p, d)| [0, 1, 2].map(|a| (p[a] + d[a]) as f64)).collect();
        let moved: Vec<bool> =
            self.triangles.iter().map(|t| t.iter().any(|&v| delta[v as usize] != [0.0; 3])).collect();
        // Only the moved triangles' boxes and their ancestors' bounds are recomputed: an unmoved
        // triangle's box is its rest box, so the tree is `refitted(points)`'s to the bit (the
        // 25k head's template shapes move 8-64% of its 49,732 triangles, 23% on average).
        let listed: Vec<u32> = (0..moved.len() as u32).filter(|&t| moved[t as usize]).collect();
        let mut bvh = self.bvh.clone();
        bvh.refit_listed(&self.links, &points, self.triangles, &listed);
        let swept = crossings(&points, self.triangles, &bvh, Some(&moved));
        let penetration = shape_penetration(&swept, &self.rest, &moved, &self.piece);
        (swept, penetration)
    }
}

/// The penetration of a shape from the pairs `swept` that [`crossings`] found with `moved`
/// (each has a moved triangle) and the rest mesh's pairs `rest` (`(a, b, length)` sorted),
/// of which those with both triangles unmoved cross exactly as at rest. Summed in the order
/// of a sweep of every triangle, so the numbers equal [`measure_penetration`]'s of the shape
/// to the bit.
pub fn shape_penetration(swept: &[(u32, u32, f64)], rest: &[(u32, u32, f64)], moved: &[bool], piece: &[u32]) -> Penetration {
    let unmoved = rest.iter().filter(|&&(a, b, _)| !moved[a as usize] && !moved[b as usize]);
    let mut all: Vec<(u32, u32, f64)> = swept.iter().chain(unmoved).copied().collect();
    all.sort_unstable_by_key(|&(a, b, _)| (a, b));
    total(&all, piece)
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
/// over `points`. With `moved`, only pairs with at least one moved triangle are tested. Each
/// pair is tested lower index first, as a sweep of every pair would, so the lengths are the
/// same to the bit whatever `moved` is. Candidate pairs come from one descent of the
/// hierarchy against itself ([`TriangleBvh::overlapping_pairs`]), not one query per triangle.
pub fn crossings(points: &[Vec3], triangles: &[[u32; 3]], bvh: &TriangleBvh, moved: Option<&[bool]>) -> Vec<(u32, u32, f64)> {
    let corners = |t: usize| triangles[t].map(|v| points[v as usize]);
    let everything;
    let marked = match moved {
        Some(moved) => moved,
        None => {
            everything = vec![true; triangles.len()];
            &everything
        }
    };
    // The normals of the triangles a test can involve, each computed once instead of per
    // pair; when few triangles are marked (a re-sweep after a local change) they meet few
    // others, and each pair computes its own (the same arithmetic: the same lengths).
    let few = marked.iter().filter(|&&m| m).count() * FEW_MARKED < triangles.len();
    let normals: Vec<Vec3> =
        if few { Vec::new() } else { (0..triangles.len()).into_par_iter().map(|t| normal(corners(t))).collect() };
    let normal_of = |t: usize| if few { normal(corners(t)) } else { normals[t] };
    let per_task = bvh.overlapping_pairs(marked, Vec::new, |found, a, b| {
        let (a, b) = (a as usize, b as usize);
        if triangles[a].iter().any(|v| triangles[b].contains(v)) {
            return;
        }
        // Lower index first, as a sweep of every pair would.
        let (lo, hi) = (a.min(b), a.max(b));
        if let Some(len) = crossing_length(corners(lo), normal_of(lo), corners(hi), normal_of(hi)) {
            found.push((lo as u32, hi as u32, len));
        }
    });
    let mut all: Vec<(u32, u32, f64)> = per_task.into_iter().flatten().collect();
    all.sort_by_key(|&(a, b, _)| (a, b));
    all
}

/// Below one marked triangle in this many, [`crossings`] computes normals per pair.
const FEW_MARKED: usize = 16;

/// [`crossings`] with `moved` set for the triangles `listed` only (each once): the pairs, with
/// their lengths to the bit, of a listed triangle and any triangle it shares no vertex with.
/// One query of the hierarchy per listed triangle: after a local change (the collision pass's
/// re-solve moves a few hundred triangles of a large mesh) the dual descent of
/// [`TriangleBvh::overlapping_pairs`] from the root, and its per-call marks over every
/// triangle and node, cost more than the queries (measured: 217M against 298M instructions
/// for the re-sweeps of the collision pass on the bundled head). From one triangle in
/// [`FEW_LISTED`] on, [`crossings`]' one descent is taken instead: its neighbouring triangles
/// share the descent that the queries repeat (measured on the 25k head's template shapes, one
/// thread, a region of 3,000 triangles around each: 5.4 ms a shape against 7.3 ms for the
/// queries; of 300: 1.8 ms against 1.1 ms). The same pairs and lengths either way.
pub fn crossings_of(points: &[Vec3], triangles: &[[u32; 3]], bvh: &TriangleBvh, listed: &[u32]) -> Vec<(u32, u32, f64)> {
    let corners = |t: usize| triangles[t].map(|v| points[v as usize]);
    let mut is_listed = vec![false; triangles.len()];
    for &t in listed {
        is_listed[t as usize] = true;
    }
    if listed.len() * FEW_LISTED >= triangles.len() {
        return crossings(points, triangles, bvh, Some(&is_listed));
    }
    let mut all: Vec<(u32, u32, f64)> = listed
        .par_iter()
        .with_min_len(QUERIES_PER_TASK)
        .fold(Vec::new, |mut found, &t| {
            let t = t as usize;
            let (at_t, normal_t) = (corners(t), normal(corners(t)));
            bvh.for_each_overlap(&Aabb::of_points(&at_t), |q| {
                let q = q as usize;
                // A pair of two listed triangles is taken from its lower one's query.
                if q == t || (is_listed[q] && q < t) || triangles[t].iter().any(|v| triangles[q].contains(v)) {
                    return;
                }
                // Lower index first, as a sweep of every pair would.
                let (at_q, normal_q) = (corners(q), normal(corners(q)));
                let length = if t < q {
                    crossing_length(at_t, normal_t, at_q, normal_q)
                } else {
                    crossing_length(at_q, normal_q, at_t, normal_t)
                };
                if let Some(length) = length {
                    found.push((t.min(q) as u32, t.max(q) as u32, length));
                }
            });
            found
        })
        .flatten_iter()
        .collect();
    all.sort_by_key(|&(a, b, _)| (a, b));
    all
}

/// From one triangle listed in this many, [`crossings_of`] takes one dual descent instead of
/// a query per listed triangle.
const FEW_LISTED: usize = 32;

/// Listed triangles a task of [`crossings_of`] queries at least.
const QUERIES_PER_TASK: usize = 64;

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
        // Exactly the pierced and the piercing triangle are flagged, not the folded neighbour.
        assert_eq!(intersecting_triangles(&pts32, None, &with_pierce), vec![true, false, true]);
        // Measured against itself as the rest pose, nothing is new.
        assert_eq!(intersecting_triangles(&pts32, Some(&pts32), &with_pierce), vec![false; 3]);
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

    /// A `w` x `w` grid crumpled by a random sine of `amplitude` (one connected piece, shared
    /// corners) plus `soup` random triangles of size `size` (pieces of their own).
    fn crumpled_grid_and_soup(rng: &mut impl Rng, w: usize, amplitude: f64, soup: usize, size: f64) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let mut pts: Vec<Vec3> = (0..w * w)
            .map(|v| {
                let (x, y) = ((v % w) as f64 / w as f64, (v / w) as f64 / w as f64);
                [x, y, amplitude * (7.0 * x + rng.random::<f64>()).sin() * (5.0 * y).cos()]
            })
            .collect();
        let mut tris = crate::geometry::topology::grid_triangles(w as u32, w as u32, 0);
        for _ in 0..soup {
            let start = pts.len() as u32;
            let centre: Vec3 = [rng.random(), rng.random(), rng.random::<f64>() - 0.5];
            pts.extend((0..3).map(|_| [0, 1, 2].map(|a| centre[a] + size * (rng.random::<f64>() - 0.5))));
            tris.push([start, start + 1, start + 2]);
        }
        (pts, tris)
    }

    #[test]
    fn cheap_metric_equals_a_full_sweep_on_random_meshes() {
        // Random crumpled grids and soups; each shape moves a random subset of vertices by a
        // random amount. Re-testing only triangles with a moved corner must give exactly the full
        // sweep's pairs, length and split by piece.
        for seed in 0..12u64 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(100 + seed);
            let (pts, tris) = crumpled_grid_and_soup(&mut rng, 9, 0.4, 30, 0.3);
            let pts: Vec<[f32; 3]> = pts.iter().map(|p| p.map(|x| x as f32)).collect();
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

    #[test]
    fn moved_sweep_gives_the_all_pairs_lengths_to_the_bit() {
        // A crumpled grid and a soup; pairs with a moved triangle, found through the
        // hierarchy, must be exactly those of testing every pair, with the same lengths.
        let (mut crossing_pairs, mut few_crossing) = (0, 0);
        for seed in 0..8u64 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(700 + seed);
            let (pts, tris) = crumpled_grid_and_soup(&mut rng, 10, 0.3, 25, 0.25);
            let mut every = Vec::new();
            for a in 0..tris.len() {
                for b in a + 1..tris.len() {
                    if tris[a].iter().any(|v| tris[b].contains(v)) {
                        continue;
                    }
                    if let Some(len) = intersection_length(tris[a].map(|v| pts[v as usize]), tris[b].map(|v| pts[v as usize])) {
                        every.push((a as u32, b as u32, len));
                    }
                }
            }
            crossing_pairs += every.len();
            let bvh = TriangleBvh::build(&pts, &tris);
            assert_eq!(crossings(&pts, &tris, &bvh, None), every, "seed {seed}");
            let moved: Vec<bool> = (0..tris.len()).map(|_| rng.random::<f64>() < 0.3).collect();
            let kept: Vec<_> = every.iter().copied().filter(|&(a, b, _)| moved[a as usize] || moved[b as usize]).collect();
            assert_eq!(crossings(&pts, &tris, &bvh, Some(&moved)), kept, "seed {seed}: moved");
            let listed: Vec<u32> = (0..tris.len() as u32).filter(|&t| moved[t as usize]).collect();
            assert!(listed.len() * FEW_LISTED >= tris.len(), "seed {seed}: the dual descent is taken");
            assert_eq!(crossings_of(&pts, &tris, &bvh, &listed), kept, "seed {seed}: listed");
            // Under one triangle in FEW_LISTED, one query each: the same pairs as every pair
            // with one of them.
            let crosses = |t: u32| every.iter().any(|&(a, b, _)| a == t || b == t);
            let mut few: Vec<u32> = listed.iter().copied().filter(|&t| crosses(t)).take(2).collect();
            few.extend(listed.iter().copied().filter(|&t| !crosses(t)).take(2));
            let few_pairs: Vec<_> = every.iter().copied().filter(|&(a, b, _)| few.contains(&a) || few.contains(&b)).collect();
            assert!(few.len() * FEW_LISTED < tris.len() && !few.is_empty(), "seed {seed}: the queries are taken");
            assert_eq!(crossings_of(&pts, &tris, &bvh, &few), few_pairs, "seed {seed}: few listed");
            few_crossing += few_pairs.len();
        }
        assert!(crossing_pairs > 10, "the random meshes should cross themselves: {crossing_pairs} pairs");
        assert!(few_crossing > 0, "some of the few listed triangles should cross");
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
