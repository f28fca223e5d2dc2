//! Collision conflicts (method, section 1, beyond the paper, for its goal 4: poseable
//! expressions): shapes A and B conflict when posing both adds intersection curve beyond
//! what each adds alone,
//!
//! $E(A, B) = L(A + B) - L(A) - L(B) + L(0)$,
//!
//! with $L$ the penetration metric of method, section 3 (the length of the curve where
//! triangles sharing no vertex cross). Both parts of E are measured, inside one piece and
//! between pieces; the conflict is $E_{\mathrm{between}}(A, B) > \tau \cdot \mathrm{diag}$
//! ($\tau$ = [`super::PackingParams::collision_tolerance`]). Calibrated on the bundled
//! Template (docs/design_pack.md): curve inside one piece is what an additive rig makes when shapes
//! a face poses every day are mixed (the lips or lids folding into themselves, which
//! corrective shapes fix: mouthSmileLeft with mouthSmileRight adds 3.99 cm of curve, eyeBlink
//! with eyeSquint 7.06 cm), while a pose the actor cannot hold puts one piece through
//! another (the tongue through the lips and teeth: tongueOut with mouthClose adds 7.22 cm
//! between pieces, everyday mixes at most 3.78 cm).
//!
//! Only triangle pairs that touch a triangle A moves *and* one B moves can contribute to E:
//! a pair that neither shape moves crosses alike in all four poses, and a pair only A moves
//! is posed the same in A + B as in A, and in B as at rest, so its four terms cancel. E is
//! therefore summed over those pairs only. L(0) and each shape's L(A) over the triangles it
//! moves are found once (and filtered per pair); L(A + B) per pair from a triangle only A
//! moves against one only B moves (only those whose box over their two poses meets the
//! other shape's region can meet; both sit where their own shape alone puts them) and a
//! triangle both move against any other. Pairs whose [`MovingRegion`] boxes are apart are
//! not tested at all (E = 0 exactly, see `regions`).
//!
//! The decision needs only $E_{\mathrm{between}}$, the sum over pairs of triangles in two
//! different pieces, and every such pair has a triangle outside the largest piece (the
//! skin): so each search starts from, or looks only among, the few triangles of the small
//! pieces (eyes, teeth, tongue). Two shapes that move only the skin add curve between pieces
//! only where a triangle both move meets a small piece, and none where only one moves; most
//! pairs of a face are such, and cost a few box queries. The total E, which the report
//! gives beside it, is measured in full only for the pairs that collide.

use std::sync::Arc;

use rayon::prelude::*;

use super::regions::{MovingRegion, Pose, PosedTriangles, RestHierarchy};
use crate::geometry::bvh::Aabb;
use crate::geometry::mat3::Vec3;
use crate::geometry::penetration::{crossings, intersection_length};
use crate::geometry::topology::connected_components;
use crate::rig::RigView;

/// Two shapes that collide when posed together.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Collision {
    pub first: usize,
    pub second: usize,
    /// E(A, B), the intersection curve the mix adds, as a fraction of the bounding-box
    /// diagonal.
    pub added: f64,
    /// The part of `added` where two different connected pieces cross.
    pub between_pieces: f64,
}

/// The connected piece of each triangle. Triangles of two pieces never share a corner.
struct Pieces {
    of: Vec<u32>,
    largest: u32,
}

impl Pieces {
    fn new(rig: &RigView) -> Self {
        let (label, count) = connected_components(rig.n_vertices(), rig.triangles);
        let of: Vec<u32> = rig.triangles.iter().map(|t| label[t[0] as usize]).collect();
        let mut size = vec![0usize; count];
        of.iter().for_each(|&p| size[p as usize] += 1);
        let largest = (0..count).max_by_key(|&p| (size[p], std::cmp::Reverse(p))).unwrap_or(0) as u32;
        Self { of, largest }
    }

    /// Outside the largest piece.
    fn small(&self, t: u32) -> bool {
        self.of[t as usize] != self.largest
    }

    fn differ(&self, s: u32, t: u32) -> bool {
        self.of[s as usize] != self.of[t as usize]
    }
}

/// One shape's moved triangles posed by it alone (in any mix, a triangle that only A moves
/// sits where A alone puts it), all of them and those outside the largest piece, each with
/// its box over the rest pose and the posed one (`swept`, `small_swept`, in the order of
/// `posed` and `small`). Both hierarchies are cut from the whole mesh's; `posed` is the one
/// [`RestHierarchy::alone`] keeps for both tests.
struct Moved {
    posed: Arc<PosedTriangles>,
    swept: Vec<Aabb>,
    small: PosedTriangles,
    small_swept: Vec<Aabb>,
}

impl Moved {
    /// Each corner is posed once ([`RestHierarchy::alone`]), and the swept boxes and the small
    /// pieces' part take the posed corners from there.
    fn new(shared: &RestHierarchy, pieces: &Pieces, k: usize) -> Self {
        let (whole, posed) = (shared.rest(), shared.alone(k));
        let small = posed.part(|t| pieces.small(t));
        let swept = |set: &PosedTriangles| -> Vec<Aabb> {
            let with_rest = |t: u32, c: &[Vec3; 3]| {
                let r = whole.corners[t as usize];
                Aabb::of_points(&[r[0], r[1], r[2], c[0], c[1], c[2]])
            };
            set.triangles.iter().zip(&set.corners).map(|(&t, c)| with_rest(t, c)).collect()
        };
        Self { swept: swept(&posed), small_swept: swept(&small), posed, small }
    }

    /// The triangles a triangle (outside the largest piece or not) can cross in another
    /// piece: all, or only those outside the largest piece.
    fn partners(&self, from_small: bool) -> &PosedTriangles {
        if from_small {
            &self.posed
        } else {
            &self.small
        }
    }
}

fn grown(region: &MovingRegion, margin: f64) -> Aabb {
    Aabb::of_points(&[region.lo.map(|x| x - margin), region.hi.map(|x| x + margin)])
}

/// What the four poses of every pair share: the mesh at rest (all of it, and the small
/// pieces alone), the per-shape posed triangles, the pieces.
struct Scene<'a> {
    rig: &'a RigView<'a>,
    regions: &'a [MovingRegion],
    /// Every triangle at rest; position `j` is triangle `j`.
    rest: &'a PosedTriangles,
    /// The triangles outside the largest piece, at rest.
    rest_small: PosedTriangles,
    moved: Vec<Option<Moved>>,
    pieces: Pieces,
}

/// Crossing pairs `(s, t, length)`, `s < t`, in some order.
type Crossings = Vec<(u32, u32, f64)>;

impl Scene<'_> {
    fn shares_corner(&self, s: u32, t: u32) -> bool {
        let triangles = self.rig.triangles;
        triangles[s as usize].iter().any(|v| triangles[t as usize].contains(v))
    }

    /// The triangles at rest that a triangle (outside the largest piece or not) can cross
    /// in another piece.
    fn rest_partners(&self, from_small: bool) -> &PosedTriangles {
        if from_small {
            self.rest
        } else {
            &self.rest_small
        }
    }

    /// The crossings between pieces at rest that involve a triangle in `union`, each found
    /// from its triangle outside the largest piece (the lower one when both are).
    fn at_rest_between(&self, union: &[bool]) -> Crossings {
        let (small, pieces) = (&self.rest_small, &self.pieces);
        let mut found = Vec::new();
        for (i, &s) in small.triangles.iter().enumerate() {
            let corners = small.corners[i];
            self.rest.for_each_overlap(&Aabb::of_points(&corners), |t| {
                if pieces.differ(s, t) && (union[s as usize] || union[t as usize]) && (!pieces.small(t) || t > s) {
                    found.extend(intersection_length(corners, self.rest.corners[t as usize]).map(|len| (s.min(t), s.max(t), len)));
                }
            });
        }
        found
    }

    /// The crossings between pieces of shape k posed alone that involve a triangle it
    /// moves. A pair of two moved triangles is found from the one in the largest piece, or
    /// from the lower one when neither is.
    fn alone_between(&self, k: usize) -> Crossings {
        let (region, pieces, mut found) = (&self.regions[k], &self.pieces, Vec::new());
        let Some(moved) = &self.moved[k] else { return found };
        for (i, &s) in moved.posed.triangles.iter().enumerate() {
            let (corners, query) = (moved.posed.corners[i], Aabb::of_points(&moved.posed.corners[i]));
            let from_small = pieces.small(s);
            let rest = self.rest_partners(from_small);
            rest.for_each_overlap(&query, |j| {
                let t = rest.triangles[j as usize];
                if !region.contains(t) && pieces.differ(s, t) {
                    found.extend(intersection_length(corners, rest.corners[j as usize]).map(|len| (s.min(t), s.max(t), len)));
                }
            });
            let own = moved.partners(from_small);
            own.for_each_overlap(&query, |j| {
                let t = own.triangles[j as usize];
                if pieces.differ(s, t) && (!from_small || (pieces.small(t) && t > s)) {
                    found.extend(intersection_length(corners, own.corners[j as usize]).map(|len| (s.min(t), s.max(t), len)));
                }
            });
        }
        found
    }

    /// The length of the crossings between pieces of A + B that touch a triangle A moves and
    /// one B moves: a triangle only A moves (whose swept box meets B's region) against one
    /// only B moves, and a triangle both move against any other.
    fn mixed_between(&self, a: usize, b: usize, margin: f64) -> f64 {
        let (ra, rb, pieces) = (&self.regions[a], &self.regions[b], &self.pieces);
        let (Some(ma), Some(mb)) = (&self.moved[a], &self.moved[b]) else { return 0.0 };
        let mut total = 0.0;
        let mut add = |corners: [Vec3; 3], other: [Vec3; 3]| total += intersection_length(corners, other).unwrap_or(0.0);
        // A triangle only A moves against one only B moves, in another piece: one of them is
        // outside the largest piece. When B moves nothing there, A's must be.
        let near_b = grown(rb, margin);
        let (a_triangles, a_corners, a_swept) = if mb.small.triangles.is_empty() {
            (&ma.small.triangles, &ma.small.corners, &ma.small_swept)
        } else {
            (&ma.posed.triangles, &ma.posed.corners, &ma.swept)
        };
        for (i, &s) in a_triangles.iter().enumerate() {
            if rb.contains(s) || !a_swept[i].overlaps(&near_b) {
                continue;
            }
            let corners = a_corners[i];
            let set = mb.partners(pieces.small(s));
            set.for_each_overlap(&Aabb::of_points(&corners), |j| {
                let t = set.triangles[j as usize];
                if !ra.contains(t) && pieces.differ(s, t) {
                    add(corners, set.corners[j as usize]);
                }
            });
        }
        let (fewer, other) = if ra.triangles.len() <= rb.triangles.len() { (ra, rb) } else { (rb, ra) };
        let shared: Vec<u32> = fewer.triangles.iter().copied().filter(|&t| other.contains(t)).collect();
        if shared.is_empty() {
            return total;
        }
        let (triangles, pose) = (self.rig.triangles, Pose::of(self.rig, self.regions, &[a, b]));
        let shared_small = ma.small.subset(|t| rb.contains(t), |t| triangles[t as usize].map(|v| pose.at(v)));
        for &s in &shared {
            let corners = triangles[s as usize].map(|v| pose.at(v));
            let (query, from_small) = (Aabb::of_points(&corners), pieces.small(s));
            let rest = self.rest_partners(from_small);
            rest.for_each_overlap(&query, |j| {
                let t = rest.triangles[j as usize];
                if !ra.contains(t) && !rb.contains(t) && pieces.differ(s, t) {
                    add(corners, rest.corners[j as usize]);
                }
            });
            for (moved, not_in) in [(ma, rb), (mb, ra)] {
                let set = moved.partners(from_small);
                set.for_each_overlap(&query, |j| {
                    let t = set.triangles[j as usize];
                    if !not_in.contains(t) && pieces.differ(s, t) {
                        add(corners, set.corners[j as usize]);
                    }
                });
            }
            // Two shared triangles: from the one in the largest piece, else the lower one.
            shared_small.for_each_overlap(&query, |j| {
                let t = shared_small.triangles[j as usize];
                if pieces.differ(s, t) && (!from_small || t > s) {
                    add(corners, shared_small.corners[j as usize]);
                }
            });
        }
        total
    }

    /// The crossings of shape k posed alone, in every piece, that touch a triangle k moves:
    /// a moved triangle against one it does not move at rest, or against another moved one
    /// (each such pair once). Found once per shape and filtered per pair ([`touching_both`]),
    /// instead of searched again for every pair the shape is in: a filtered list keeps the
    /// order of the whole one, so each pair's sum is the same to the bit.
    fn alone_all(&self, k: usize) -> Crossings {
        let (region, mut found) = (&self.regions[k], Vec::new());
        let Some(moved) = &self.moved[k] else { return found };
        let posed = &moved.posed;
        for (i, &s) in posed.triangles.iter().enumerate() {
            let (corners, query) = (posed.corners[i], Aabb::of_points(&posed.corners[i]));
            self.rest.for_each_overlap(&query, |t| {
                if !region.contains(t) && !self.shares_corner(s, t) {
                    found.extend(intersection_length(corners, self.rest.corners[t as usize]).map(|len| (s.min(t), s.max(t), len)));
                }
            });
            posed.for_each_overlap(&query, |j| {
                let t = posed.triangles[j as usize];
                if t > s && !self.shares_corner(s, t) {
                    found.extend(intersection_length(corners, posed.corners[j as usize]).map(|len| (s, t, len)));
                }
            });
        }
        found
    }

    /// The length of the crossings of A + B that touch a triangle A moves and one B moves, in
    /// every piece: as [`Self::mixed_between`], without the restriction to two pieces.
    fn mixed(&self, a: usize, b: usize, margin: f64) -> f64 {
        let (rig, triangles) = (self.rig, self.rig.triangles);
        let (ra, rb) = (&self.regions[a], &self.regions[b]);
        let (Some(ma), Some(mb)) = (&self.moved[a], &self.moved[b]) else { return 0.0 };
        let (posed_a, posed_b) = (&ma.posed, &mb.posed);
        let only_a = |t: u32| ra.contains(t) && !rb.contains(t);
        let only_b = |t: u32| rb.contains(t) && !ra.contains(t);
        let mut total = 0.0;
        let mut add = |s: u32, t: u32, corners: [Vec3; 3], other: [Vec3; 3]| {
            if !self.shares_corner(s, t) {
                total += intersection_length(corners, other).unwrap_or(0.0);
            }
        };
        let near_b = grown(rb, margin);
        for (i, &s) in posed_a.triangles.iter().enumerate() {
            if only_a(s) && ma.swept[i].overlaps(&near_b) {
                let corners = posed_a.corners[i];
                posed_b.for_each_overlap(&Aabb::of_points(&corners), |j| {
                    let t = posed_b.triangles[j as usize];
                    if only_b(t) {
                        add(s, t, corners, posed_b.corners[j as usize]);
                    }
                });
            }
        }
        // The triangles both move, posed by both.
        let pose = Pose::of(rig, self.regions, &[a, b]);
        let both = posed_a.subset(|t| rb.contains(t), |t| triangles[t as usize].map(|v| pose.at(v)));
        for (i, &s) in both.triangles.iter().enumerate() {
            let (corners, query) = (both.corners[i], Aabb::of_points(&both.corners[i]));
            self.rest.for_each_overlap(&query, |t| {
                if !ra.contains(t) && !rb.contains(t) {
                    add(s, t, corners, self.rest.corners[t as usize]);
                }
            });
            for (set, only) in [(posed_a, &only_a as &dyn Fn(u32) -> bool), (posed_b, &only_b)] {
                set.for_each_overlap(&query, |j| {
                    let t = set.triangles[j as usize];
                    if only(t) {
                        add(s, t, corners, set.corners[j as usize]);
                    }
                });
            }
            // Each shared pair once.
            both.for_each_overlap(&query, |j| {
                if j as usize > i {
                    add(s, both.triangles[j as usize], corners, both.corners[j as usize]);
                }
            });
        }
        total
    }
}

/// The part of `list` whose pairs touch a triangle of both regions.
fn touching_both(list: &Crossings, ra: &MovingRegion, rb: &MovingRegion) -> f64 {
    list.iter().filter(|&&(s, t, _)| (ra.contains(s) || ra.contains(t)) && (rb.contains(s) || rb.contains(t))).map(|c| c.2).sum()
}

/// The candidate pairs that collide: E(A, B) > `tolerance` x diagonal. `regions` holds the
/// moving region of every shape named in `candidates`; pairs whose boxes (grown by `margin`
/// x diagonal) are apart are skipped; `rest_hierarchy` is the rig's, shared with the
/// occlusion test. Returns the collisions, in the order of `candidates`, and how many pairs
/// were tested.
pub fn find_collisions(
    rig: &RigView,
    rest_hierarchy: &RestHierarchy,
    regions: &[MovingRegion],
    candidates: &[(usize, usize)],
    tolerance: f64,
    margin: f64,
) -> (Vec<Collision>, usize) {
    let diagonal = rig.bbox_diagonal();
    let margin = margin * diagonal;
    let tested: Vec<(usize, usize)> =
        candidates.iter().copied().filter(|&(a, b)| regions[a].meets(&regions[b], margin)).collect();
    if tested.is_empty() {
        return (Vec::new(), 0);
    }
    let triangles = rig.triangles;
    let pieces = Pieces::new(rig);
    let rest = rest_hierarchy.rest();
    let rest_small = rest.part(|t| pieces.small(t));
    let mut involved = vec![false; rig.n_shapes()];
    tested.iter().for_each(|&(a, b)| (involved[a], involved[b]) = (true, true));
    let moved: Vec<Option<Moved>> =
        (0..rig.n_shapes()).into_par_iter().map(|k| involved[k].then(|| Moved::new(rest_hierarchy, &pieces, k))).collect();
    let union: Vec<bool> = (0..triangles.len() as u32).map(|t| regions.iter().any(|r| !r.triangles.is_empty() && r.contains(t))).collect();
    let scene = Scene { rig, regions, rest, rest_small, moved, pieces };
    let at_rest = scene.at_rest_between(&union);
    let alone: Vec<Crossings> =
        (0..rig.n_shapes()).into_par_iter().map(|k| if involved[k] { scene.alone_between(k) } else { Vec::new() }).collect();
    let between: Vec<((usize, usize), f64)> = tested
        .par_iter()
        .map(|&(a, b)| {
            let (ra, rb) = (&regions[a], &regions[b]);
            let mixed = scene.mixed_between(a, b, margin);
            let added = mixed - touching_both(&alone[a], ra, rb) - touching_both(&alone[b], ra, rb) + touching_both(&at_rest, ra, rb);
            ((a, b), added / diagonal)
        })
        .filter(|&(_, between)| between > tolerance)
        .collect();
    (total_curve(&scene, &between, margin, diagonal), tested.len())
}

/// The collisions with their total E (every piece) beside the part between pieces that
/// decided them: per colliding pair, each shape's crossings alone (listed once per shape,
/// [`Scene::alone_all`]) that touch the other's region, and those at rest among the triangles of the smaller of the two regions (a crossing that
/// touches both regions has a triangle in each).
fn total_curve(scene: &Scene, between: &[((usize, usize), f64)], margin: f64, diagonal: f64) -> Vec<Collision> {
    if between.is_empty() {
        return Vec::new();
    }
    let (rig, regions) = (scene.rig, scene.regions);
    let smaller = |a: usize, b: usize| if regions[a].triangles.len() <= regions[b].triangles.len() { a } else { b };
    let mut marked = vec![false; rig.triangles.len()];
    for &((a, b), _) in between {
        regions[smaller(a, b)].triangles.iter().for_each(|&t| marked[t as usize] = true);
    }
    let rest: Vec<Vec3> = rig.neutral.iter().map(|p| p.map(f64::from)).collect();
    // `scene.rest` holds triangle t at position t: its hierarchy answers triangle indices.
    let at_rest = crossings(&rest, rig.triangles, &scene.rest.bvh, Some(&marked));
    let mut colliding = vec![false; rig.n_shapes()];
    between.iter().for_each(|&((a, b), _)| (colliding[a], colliding[b]) = (true, true));
    let alone: Vec<Crossings> =
        (0..rig.n_shapes()).into_par_iter().map(|k| if colliding[k] { scene.alone_all(k) } else { Vec::new() }).collect();
    between
        .par_iter()
        .map(|&((a, b), between_pieces)| {
            let (ra, rb) = (&regions[a], &regions[b]);
            let added = scene.mixed(a, b, margin) - touching_both(&alone[a], ra, rb) - touching_both(&alone[b], ra, rb)
                + touching_both(&at_rest, ra, rb);
            Collision { first: a, second: b, added: added / diagonal, between_pieces }
        })
        .collect()
}
