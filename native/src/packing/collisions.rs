//! Collision conflicts (SPEC section 1, beyond the paper, for its goal 4: poseable
//! expressions): shapes A and B conflict when posing both adds intersection curve beyond
//! what each adds alone,
//!
//! $E(A, B) = L(A + B) - L(A) - L(B) + L(0) > \tau \cdot \mathrm{diag}$,
//!
//! with $L$ the penetration metric of SPEC section 3 (the length of the curve where
//! triangles sharing no vertex cross, inside one piece and between pieces) and $\tau$
//! [`super::PackingParams::collision_tolerance`].
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

/// The triangles that can take part in a crossing that touches both A and B (each list
/// ascending): `shared` (moved by both), `a_near_b` (moved by A only, whose box over rest and
/// pose A meets B's region) and `b_near_a`, and, around the shared ones, `near_shared` (moved
/// by one shape only, whose swept box meets the shared triangles' box over the four poses).
struct PairTriangles {
    shared: Vec<u32>,
    a_near_b: Vec<u32>,
    b_near_a: Vec<u32>,
    near_shared: Vec<u32>,
}

/// The box of a triangle's corners at rest and posed by one shape.
fn swept_box(rig: &RigView, k: usize, t: u32) -> Aabb {
    let corners = rig.triangles[t as usize];
    let rest = Pose::of(rig, &[]);
    let posed = Pose::of(rig, &[k]);
    Aabb::of_points(&[0, 1, 2, 3, 4, 5].map(|i| if i < 3 { rest.at(corners[i]) } else { posed.at(corners[i - 3]) }))
}

fn grown(region: &MovingRegion, margin: f64) -> Aabb {
    Aabb::of_points(&[region.lo.map(|x| x - margin), region.hi.map(|x| x + margin)])
}

impl PairTriangles {
    fn new(rig: &RigView, regions: &[MovingRegion], swept: &[Vec<Aabb>], (a, b): (usize, usize), margin: f64) -> Self {
        let (ra, rb) = (&regions[a], &regions[b]);
        let shared: Vec<u32> = ra.triangles.iter().copied().filter(|&t| rb.contains(t)).collect();
        let only = |k: usize, other: &MovingRegion, near: &Aabb| -> Vec<u32> {
            let region = &regions[k];
            region.triangles.iter().zip(&swept[k]).filter(|(t, b)| !other.contains(**t) && b.overlaps(near)).map(|p| *p.0).collect()
        };
        let (a_near_b, b_near_a) = (only(a, rb, &grown(rb, margin)), only(b, ra, &grown(ra, margin)));
        let near_shared = if shared.is_empty() {
            Vec::new()
        } else {
            let poses = [Pose::of(rig, &[]), Pose::of(rig, &[a]), Pose::of(rig, &[b]), Pose::of(rig, &[a, b])];
            let corners: Vec<Vec3> = shared
                .iter()
                .flat_map(|&t| rig.triangles[t as usize])
                .flat_map(|v| poses.iter().map(move |p| p.at(v)).collect::<Vec<_>>())
                .collect();
            let lo: Vec3 = std::array::from_fn(|a| corners.iter().map(|p| p[a]).fold(f64::INFINITY, f64::min) - margin);
            let hi: Vec3 = std::array::from_fn(|a| corners.iter().map(|p| p[a]).fold(f64::NEG_INFINITY, f64::max) + margin);
            let near = Aabb::of_points(&[lo, hi]);
            let mut list = only(a, rb, &near);
            list.extend(only(b, ra, &near));
            list.sort_unstable();
            list
        };
        Self { shared, a_near_b, b_near_a, near_shared }
    }

    /// The crossings in `pose` that touch both shapes, as (total length, length between
    /// pieces), summed in a fixed order. Every other triangle is at rest (`rest`,
    /// `rest_bvh`); `moved` tells the triangles either shape moves.
    fn crossing_length(&self, rig: &RigView, pose: &Pose, rest: &[Vec3], rest_bvh: &TriangleBvh, moved: impl Fn(u32) -> bool, piece: &[u32]) -> [f64; 2] {
        let triangles = rig.triangles;
        let shares_corner = |s: u32, t: u32| triangles[s as usize].iter().any(|v| triangles[t as usize].contains(v));
        let mut sum = [0.0; 2];
        let mut add = |s: u32, t: u32, len: f64| {
            sum[0] += len;
            if piece[s as usize] != piece[t as usize] {
                sum[1] += len;
            }
        };
        if !self.a_near_b.is_empty() && !self.b_near_a.is_empty() {
            let others = PosedTriangles::new(self.b_near_a.clone(), triangles, pose, |p| p);
            for &s in &self.a_near_b {
                let corners = triangles[s as usize].map(|v| pose.at(v));
                others.for_each_overlap(&Aabb::of_points(&corners), |j| {
                    let t = others.triangles[j as usize];
                    if !shares_corner(s, t) {
                        intersection_length(corners, others.corners[j as usize]).into_iter().for_each(|len| add(s, t, len));
                    }
                });
            }
        }
        if !self.shared.is_empty() {
            let mut near = self.shared.clone();
            near.extend(&self.near_shared);
            let near = PosedTriangles::new(near, triangles, pose, |p| p);
            for (i, &s) in self.shared.iter().enumerate() {
                let corners = near.corners[i];
                let query = Aabb::of_points(&corners);
                rest_bvh.for_each_overlap(&query, |t| {
                    if !moved(t) && !shares_corner(s, t) {
                        let at_rest = triangles[t as usize].map(|v| rest[v as usize]);
                        intersection_length(corners, at_rest).into_iter().for_each(|len| add(s, t, len));
                    }
                });
                // Shared pairs once, from the earlier of the two in `shared`.
                near.for_each_overlap(&query, |j| {
                    let t = near.triangles[j as usize];
                    if (j as usize >= self.shared.len() || j as usize > i) && !shares_corner(s, t) {
                        intersection_length(corners, near.corners[j as usize]).into_iter().for_each(|len| add(s, t, len));
                    }
                });
            }
        }
        sum
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
    let swept: Vec<Vec<Aabb>> = (0..rig.n_shapes())
        .into_par_iter()
        .map(|k| if involved[k] { regions[k].triangles.iter().map(|&t| swept_box(rig, k, t)).collect() } else { Vec::new() })
        .collect();
    let collisions = tested
        .par_iter()
        .filter_map(|&(a, b)| {
            let pair = PairTriangles::new(rig, regions, &swept, (a, b), margin);
            let moved = |t: u32| regions[a].contains(t) || regions[b].contains(t);
            let length = |shapes: &[usize]| pair.crossing_length(rig, &Pose::of(rig, shapes), &rest, &rest_bvh, moved, &piece);
            let [both, alone_a, alone_b, at_rest] = [length(&[a, b]), length(&[a]), length(&[b]), length(&[])];
            let added = |i: usize| (both[i] - alone_a[i] - alone_b[i] + at_rest[i]) / diagonal;
            (added(0) > tolerance).then(|| Collision { first: a, second: b, added: added(0), between_pieces: added(1) })
        })
        .collect();
    (collisions, tested.len())
}
