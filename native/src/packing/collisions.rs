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
//! therefore summed over those pairs only: a triangle only A moves against one only B moves
//! (only those whose box over their two poses meets the other shape's region can meet), and
//! a triangle both move against the rest of the mesh (static triangles through the rest
//! hierarchy, moved ones near it posed). Pairs whose [`MovingRegion`] boxes are apart are
//! not tested at all (E = 0 exactly, see `regions`).

use rayon::prelude::*;

use super::regions::{MovingRegion, Pose, PosedTriangles};
use crate::geometry::bvh::{Aabb, TriangleBvh};
use crate::geometry::mat3::Vec3;
use crate::geometry::penetration::intersection_length;
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

impl Scene<'_> {
    /// E(A, B) and its part between pieces, in mesh units: the four poses' crossings that
    /// touch a triangle A moves and one B moves. Those are a triangle only A moves (and whose
    /// swept box meets B's region) against one only B moves, and a triangle both move
    /// against any other.
    fn added(&self, a: usize, b: usize, swept: &[Vec<Aabb>], margin: f64) -> [f64; 2] {
        let (rig, triangles) = (self.rig, self.rig.triangles);
        let (ra, rb) = (&self.regions[a], &self.regions[b]);
        let shared: Vec<u32> = ra.triangles.iter().copied().filter(|&t| rb.contains(t)).collect();
        let near_b = grown(rb, margin);
        let a_near_b: Vec<u32> = ra
            .triangles
            .iter()
            .zip(&swept[a])
            .filter(|(t, bounds)| !rb.contains(**t) && bounds.overlaps(&near_b))
            .map(|p| *p.0)
            .collect();
        let only_a = |t: u32| ra.contains(t) && !rb.contains(t);
        let only_b = |t: u32| rb.contains(t) && !ra.contains(t);
        let is_shared = |t: u32| ra.contains(t) && rb.contains(t);
        let shares_corner = |s: u32, t: u32| triangles[s as usize].iter().any(|v| triangles[t as usize].contains(v));
        let (posed_a, posed_b) = (self.posed.by_shape[a].as_ref(), self.posed.by_shape[b].as_ref());
        let mut total = [0.0; 2];
        for (sign, with_a, with_b) in [(1.0, true, true), (-1.0, true, false), (-1.0, false, true), (1.0, false, false)] {
            let shapes: Vec<usize> = [(a, with_a), (b, with_b)].iter().filter(|p| p.1).map(|p| p.0).collect();
            let pose = Pose::of(rig, self.regions, &shapes);
            let mut add = |s: u32, t: u32, corners: [Vec3; 3], other: [Vec3; 3]| {
                if !shares_corner(s, t) {
                    if let Some(len) = intersection_length(corners, other) {
                        total[0] += sign * len;
                        if self.piece[s as usize] != self.piece[t as usize] {
                            total[1] += sign * len;
                        }
                    }
                }
            };
            let at_rest = |t: u32| triangles[t as usize].map(|v| self.rest[v as usize]);
            // Triangles only A moves against those only B moves, wherever this pose puts them.
            for &s in &a_near_b {
                let corners = triangles[s as usize].map(|v| pose.at(v));
                let query = Aabb::of_points(&corners);
                match (with_b, posed_b) {
                    (true, Some(set)) => set.for_each_overlap(&query, |j| {
                        let t = set.triangles[j as usize];
                        if only_b(t) {
                            add(s, t, corners, set.corners[j as usize]);
                        }
                    }),
                    _ => self.rest_bvh.for_each_overlap(&query, |t| {
                        if only_b(t) {
                            add(s, t, corners, at_rest(t));
                        }
                    }),
                }
            }
            if shared.is_empty() {
                continue;
            }
            // Triangles both move against everything else, each shared pair once.
            let both_posed = (with_a && with_b).then(|| PosedTriangles::new(shared.clone(), triangles, &pose, |p| p));
            for (i, &s) in shared.iter().enumerate() {
                let corners = match &both_posed {
                    Some(set) => set.corners[i],
                    None => triangles[s as usize].map(|v| pose.at(v)),
                };
                let query = Aabb::of_points(&corners);
                let still = |t: u32| {
                    (!ra.contains(t) && !rb.contains(t))
                        || (only_a(t) && !with_a)
                        || (only_b(t) && !with_b)
                        || (is_shared(t) && !with_a && !with_b && t > s)
                };
                self.rest_bvh.for_each_overlap(&query, |t| {
                    if still(t) {
                        add(s, t, corners, at_rest(t));
                    }
                });
                for (moved_by, set, only, alone) in [(with_a, posed_a, &only_a as &dyn Fn(u32) -> bool, with_a && !with_b), (with_b, posed_b, &only_b, with_b && !with_a)] {
                    if let (true, Some(set)) = (moved_by, set) {
                        set.for_each_overlap(&query, |j| {
                            let t = set.triangles[j as usize];
                            if only(t) || (alone && is_shared(t) && t > s) {
                                add(s, t, corners, set.corners[j as usize]);
                            }
                        });
                    }
                }
                if let Some(set) = &both_posed {
                    set.for_each_overlap(&query, |j| {
                        if j as usize > i {
                            add(s, set.triangles[j as usize], corners, set.corners[j as usize]);
                        }
                    });
                }
            }
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
    let scene = Scene { rig, regions, rest, rest_bvh, posed: Posed { by_shape }, piece };
    let collisions = tested
        .par_iter()
        .filter_map(|&(a, b)| {
            let [added, between] = scene.added(a, b, &swept, margin).map(|x| x / diagonal);
            (between > tolerance).then_some(Collision { first: a, second: b, added, between_pieces: between })
        })
        .collect();
    (collisions, tested.len())
}
