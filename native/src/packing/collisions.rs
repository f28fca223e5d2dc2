//! Collision conflicts (SPEC section 1, beyond the paper, for its goal 4: poseable
//! expressions): shapes A and B conflict when posing both adds intersection curve beyond
//! what each adds alone,
//!
//! $E(A, B) = L(A + B) - L(A) - L(B) + L(0)$,
//!
//! with $L$ the penetration metric of SPEC section 3 (the length of the curve where
//! triangles sharing no vertex cross). Both parts of E are measured, inside one piece and
//! between pieces; the conflict is $E_{\mathrm{between}}(A, B) > \tau \cdot \mathrm{diag}$
//! ($\tau$ = [`super::PackingParams::collision_tolerance`]). Calibrated on the bundled
//! Template (docs/pack.md): curve inside one piece is what an additive rig makes when shapes
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

use rayon::prelude::*;

use super::regions::{MovingRegion, Pose, PosedTriangles};
use crate::geometry::bvh::{Aabb, TriangleBvh};
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

/// Each involved shape's moved triangles posed by it alone: in any mix, a triangle that only
/// A moves sits where A alone puts it.
struct Posed {
    by_shape: Vec<Option<PosedTriangles>>,
}

/// The box of a triangle's corners at rest and posed by shape k.
fn swept_box(rig: &RigView, regions: &[MovingRegion], k: usize, t: u32) -> Aabb {
    let corners = rig.triangles[t as usize];
    let (rest, posed) = (Pose::of(rig, regions, &[]), Pose::of(rig, regions, &[k]));
    Aabb::of_points(&[0, 1, 2, 3, 4, 5].map(|i| if i < 3 { rest.at(corners[i]) } else { posed.at(corners[i - 3]) }))
}

fn grown(region: &MovingRegion, margin: f64) -> Aabb {
    Aabb::of_points(&[region.lo.map(|x| x - margin), region.hi.map(|x| x + margin)])
}

/// What the four poses of one pair share: the mesh at rest, the per-shape posed triangles,
/// the pieces.
struct Scene<'a> {
    rig: &'a RigView<'a>,
    regions: &'a [MovingRegion],
    rest: Vec<Vec3>,
    rest_bvh: TriangleBvh,
    posed: Posed,
    piece: Vec<u32>,
}

/// Crossing pairs `(s, t, length)`, `s < t`, in some order.
type Crossings = Vec<(u32, u32, f64)>;

impl Scene<'_> {
    fn shares_corner(&self, s: u32, t: u32) -> bool {
        let triangles = self.rig.triangles;
        triangles[s as usize].iter().any(|v| triangles[t as usize].contains(v))
    }

    fn at_rest(&self, t: u32) -> [Vec3; 3] {
        self.rig.triangles[t as usize].map(|v| self.rest[v as usize])
    }

    /// The crossings of shape k posed alone that involve a triangle it moves.
    fn alone(&self, k: usize) -> Crossings {
        let (region, mut found) = (&self.regions[k], Vec::new());
        let Some(posed) = &self.posed.by_shape[k] else { return found };
        for (i, &s) in posed.triangles.iter().enumerate() {
            let (corners, query) = (posed.corners[i], Aabb::of_points(&posed.corners[i]));
            self.rest_bvh.for_each_overlap(&query, |t| {
                if !region.contains(t) && !self.shares_corner(s, t) {
                    found.extend(intersection_length(corners, self.at_rest(t)).map(|len| (s.min(t), s.max(t), len)));
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

    /// The length of the crossings of A + B that touch a triangle A moves and one B moves, and
    /// its part between pieces: a triangle only A moves (whose swept box meets B's region)
    /// against one only B moves, and a triangle both move against any other.
    fn mixed(&self, a: usize, b: usize, swept: &[Vec<Aabb>], margin: f64) -> [f64; 2] {
        let (rig, triangles) = (self.rig, self.rig.triangles);
        let (ra, rb) = (&self.regions[a], &self.regions[b]);
        let (Some(posed_a), Some(posed_b)) = (&self.posed.by_shape[a], &self.posed.by_shape[b]) else { return [0.0; 2] };
        let only_a = |t: u32| ra.contains(t) && !rb.contains(t);
        let only_b = |t: u32| rb.contains(t) && !ra.contains(t);
        let mut total = [0.0; 2];
        let mut add = |s: u32, t: u32, corners: [Vec3; 3], other: [Vec3; 3]| {
            if !self.shares_corner(s, t) {
                if let Some(len) = intersection_length(corners, other) {
                    total[0] += len;
                    if self.piece[s as usize] != self.piece[t as usize] {
                        total[1] += len;
                    }
                }
            }
        };
        // Triangles only A moves sit where A alone puts them, those only B moves likewise.
        let near_b = grown(rb, margin);
        for (i, &s) in posed_a.triangles.iter().enumerate() {
            if only_a(s) && swept[a][i].overlaps(&near_b) {
                let corners = posed_a.corners[i];
                posed_b.for_each_overlap(&Aabb::of_points(&corners), |j| {
                    let t = posed_b.triangles[j as usize];
                    if only_b(t) {
                        add(s, t, corners, posed_b.corners[j as usize]);
                    }
                });
            }
        }
        let shared: Vec<u32> = ra.triangles.iter().copied().filter(|&t| rb.contains(t)).collect();
        if shared.is_empty() {
            return total;
        }
        let both = PosedTriangles::new(shared, triangles, &Pose::of(rig, self.regions, &[a, b]), |p| p);
        for (i, &s) in both.triangles.iter().enumerate() {
            let (corners, query) = (both.corners[i], Aabb::of_points(&both.corners[i]));
            self.rest_bvh.for_each_overlap(&query, |t| {
                if !ra.contains(t) && !rb.contains(t) {
                    add(s, t, corners, self.at_rest(t));
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

/// The candidate pairs that collide: E(A, B) > `tolerance` x diagonal. `regions` holds the
/// moving region of every shape named in `candidates`; pairs whose boxes (grown by `margin`
/// x diagonal) are apart are skipped. Returns the collisions, in the order of `candidates`,
/// and how many pairs were tested.
pub fn find_collisions(
    rig: &RigView,
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
    let rest: Vec<Vec3> = rig.neutral.iter().map(|p| p.map(f64::from)).collect();
    let rest_bvh = TriangleBvh::build(&rest, triangles);
    let (label, _) = connected_components(rig.n_vertices(), triangles);
    let piece: Vec<u32> = triangles.iter().map(|t| label[t[0] as usize]).collect();
    let mut involved = vec![false; rig.n_shapes()];
    tested.iter().for_each(|&(a, b)| (involved[a], involved[b]) = (true, true));
    let per_shape: Vec<(Vec<Aabb>, Option<PosedTriangles>)> = (0..rig.n_shapes())
        .into_par_iter()
        .map(|k| {
            if !involved[k] {
                return (Vec::new(), None);
            }
            let swept = regions[k].triangles.iter().map(|&t| swept_box(rig, regions, k, t)).collect();
            let posed = PosedTriangles::new(regions[k].triangles.clone(), triangles, &Pose::of(rig, regions, &[k]), |p| p);
            (swept, Some(posed))
        })
        .collect();
    let (swept, by_shape): (Vec<Vec<Aabb>>, Vec<Option<PosedTriangles>>) = per_shape.into_iter().unzip();
    let union: Vec<bool> = (0..triangles.len() as u32).map(|t| regions.iter().any(|r| !r.triangles.is_empty() && r.contains(t))).collect();
    let at_rest = crossings(&rest, triangles, &rest_bvh, Some(&union));
    let scene = Scene { rig, regions, rest, rest_bvh, posed: Posed { by_shape }, piece };
    let alone: Vec<Crossings> = (0..rig.n_shapes()).into_par_iter().map(|k| if involved[k] { scene.alone(k) } else { Vec::new() }).collect();
    let collisions = tested
        .par_iter()
        .filter_map(|&(a, b)| {
            let (ra, rb) = (&regions[a], &regions[b]);
            let touches_both = |&&(s, t, _): &&(u32, u32, f64)| (ra.contains(s) || ra.contains(t)) && (rb.contains(s) || rb.contains(t));
            let sum = |list: &Crossings| {
                let mut total = [0.0; 2];
                for &(s, t, len) in list.iter().filter(touches_both) {
                    total[0] += len;
                    if scene.piece[s as usize] != scene.piece[t as usize] {
                        total[1] += len;
                    }
                }
                total
            };
            let mixed = scene.mixed(a, b, &swept, margin);
            let (alone_a, alone_b, rest) = (sum(&alone[a]), sum(&alone[b]), sum(&at_rest));
            let [added, between] = [0, 1].map(|i| (mixed[i] - alone_a[i] - alone_b[i] + rest[i]) / diagonal);
            (between > tolerance).then_some(Collision { first: a, second: b, added, between_pieces: between })
        })
        .collect();
    (collisions, tested.len())
}
