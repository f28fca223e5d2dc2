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
//! therefore summed over those pairs only, each pose's crossings being found from the moved
//! triangles alone (a hierarchy over them in the pose, and the rest hierarchy for the rest),
//! and pairs whose [`MovingRegion`] boxes are apart are not tested at all (E = 0 exactly,
//! see `regions`).

use rayon::prelude::*;

use super::regions::{MovingRegion, Pose, PosedTriangles};
use crate::geometry::bvh::{Aabb, TriangleBvh};
use crate::geometry::mat3::Vec3;
use crate::geometry::penetration::{crossings, intersection_length};
use crate::rig::RigView;

/// Two shapes that collide when posed together.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Collision {
    pub first: usize,
    pub second: usize,
    /// E(A, B), the intersection curve the mix adds, as a fraction of the bounding-box
    /// diagonal.
    pub added: f64,
}

/// Crossing pairs `(a, b, length)`, `a < b`, with at least one triangle of `moved` (posed in
/// `pose`); every other triangle is at rest (`rest`, `rest_bvh`).
fn moved_crossings(
    pose: &Pose,
    moved: &[u32],
    is_moved: impl Fn(u32) -> bool,
    triangles: &[[u32; 3]],
    rest: &[Vec3],
    rest_bvh: &TriangleBvh,
) -> Vec<(u32, u32, f64)> {
    let posed = PosedTriangles::new(moved.to_vec(), triangles, pose, |p| p);
    let shares_corner = |a: u32, b: u32| triangles[a as usize].iter().any(|v| triangles[b as usize].contains(v));
    let mut found = Vec::new();
    for (i, &a) in moved.iter().enumerate() {
        let corners = posed.corners[i];
        let query = Aabb::of_points(&corners);
        rest_bvh.for_each_overlap(&query, |b| {
            if !is_moved(b) && !shares_corner(a, b) {
                if let Some(len) = intersection_length(corners, triangles[b as usize].map(|v| rest[v as usize])) {
                    found.push((a.min(b), a.max(b), len));
                }
            }
        });
        posed.for_each_overlap(&query, |j| {
            let b = posed.triangles[j as usize];
            if a < b && !shares_corner(a, b) {
                if let Some(len) = intersection_length(corners, posed.corners[j as usize]) {
                    found.push((a, b, len));
                }
            }
        });
    }
    found.sort_by_key(|&(a, b, _)| (a, b));
    found
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
    let tested: Vec<(usize, usize)> =
        candidates.iter().copied().filter(|&(a, b)| regions[a].meets(&regions[b], margin * diagonal)).collect();
    if tested.is_empty() {
        return (Vec::new(), 0);
    }
    let triangles = rig.triangles;
    let rest: Vec<Vec3> = rig.neutral.iter().map(|p| p.map(f64::from)).collect();
    let rest_bvh = TriangleBvh::build(&rest, triangles);
    let mut involved: Vec<usize> = tested.iter().flat_map(|&(a, b)| [a, b]).collect();
    involved.sort_unstable();
    involved.dedup();
    let union: Vec<bool> = (0..triangles.len() as u32).map(|t| involved.iter().any(|&k| regions[k].contains(t))).collect();
    let at_rest = crossings(&rest, triangles, &rest_bvh, Some(&union));
    let alone: Vec<Vec<(u32, u32, f64)>> = involved
        .par_iter()
        .map(|&k| {
            let region = &regions[k];
            moved_crossings(&Pose::of(rig, &[k]), &region.triangles, |t| region.contains(t), triangles, &rest, &rest_bvh)
        })
        .collect();
    let mut slot = vec![usize::MAX; rig.n_shapes()];
    involved.iter().enumerate().for_each(|(i, &k)| slot[k] = i);
    let alone_of = |k: usize| &alone[slot[k]];
    let collisions = tested
        .par_iter()
        .filter_map(|&(a, b)| {
            let (ra, rb) = (&regions[a], &regions[b]);
            let touches = |region: &MovingRegion, (s, t, _): &(u32, u32, f64)| region.contains(*s) || region.contains(*t);
            let both = |pair: &(u32, u32, f64)| touches(ra, pair) && touches(rb, pair);
            let mut moved: Vec<u32> = ra.triangles.iter().chain(&rb.triangles).copied().collect();
            moved.sort_unstable();
            moved.dedup();
            let mixed = moved_crossings(&Pose::of(rig, &[a, b]), &moved, |t| ra.contains(t) || rb.contains(t), triangles, &rest, &rest_bvh);
            let sum = |list: &[(u32, u32, f64)]| list.iter().filter(|p| both(p)).map(|p| p.2).sum::<f64>();
            let added = sum(&mixed) - sum(alone_of(a)) - sum(alone_of(b)) + sum(&at_rest);
            (added > tolerance * diagonal).then_some(Collision { first: a, second: b, added: added / diagonal })
        })
        .collect();
    (collisions, tested.len())
}
