//! Occlusion conflicts (SPEC section 1, beyond the paper, for its goal 4: observable
//! expressions): shape A conflicts with B when, posed together, A's active vertices (its
//! binary blendshape $b_A$, Eq. (2)) keep less than `keep` of the visibility they have with
//! A alone,
//!
//! $V(A + B) < \kappa\, V(A)$, with $V(P) = \#\{n : b_A[n] = 1,\ n \text{ seen in pose } P\}$,
//!
//! seen from the reference sheet's front camera: orthographic, along a direction `toward`
//! the camera. The scan of the expression could not see A's motion (eyeLookIn under
//! eyeBlink: the eyeball turns behind a closed lid).
//!
//! A vertex is seen when no triangle other than its own lies over it, nearer the camera. In
//! a frame whose third axis points at the camera, that is an axis-parallel ray, so the box
//! query of [`TriangleBvh`] finds its candidate triangles exactly. As for collisions, only
//! the triangles the two shapes move are posed (the rest are tested at rest) and a direction
//! is tested only when the two can interact: A's and B's moving regions meet, or the front
//! view's box of A's active vertices meets that of B's moving region. Otherwise B moves
//! nothing over A's vertices nor any of them, and V(A + B) = V(A) exactly.

use rayon::prelude::*;

use super::regions::{MovingRegion, Pose, PosedTriangles};
use crate::geometry::bvh::{Aabb, TriangleBvh};
use crate::geometry::mat3::{cross, dot, length, scale, Vec3};
use crate::rig::RigView;

/// Depth, as a fraction of the diagonal, by which a triangle must lie nearer the camera
/// than a vertex to hide it: surfaces resting on each other do not hide each other.
pub(super) const DEPTH_EPSILON: f64 = 1e-5;

/// Shape `hidden`'s motion, posed together with `by`, is mostly out of the camera's sight.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Occlusion {
    pub hidden: usize,
    pub by: usize,
    /// V(hidden + by) / V(hidden): the share of the visible active vertices still seen.
    pub kept: f64,
}

/// Coordinates with the camera along +z: (right, up, depth towards the camera).
struct ViewFrame {
    axes: [Vec3; 3],
}

impl ViewFrame {
    /// `None` when `toward` is not a finite, non-zero direction.
    fn new(toward: Vec3) -> Option<Self> {
        let n = length(toward);
        if !(n.is_finite() && n > 0.0) {
            return None;
        }
        let z = scale(toward, 1.0 / n);
        let helper = if z[2].abs() < 0.9 { [0.0, 0.0, 1.0] } else { [1.0, 0.0, 0.0] };
        let x = cross(helper, z);
        let x = scale(x, 1.0 / length(x));
        Some(Self { axes: [x, cross(z, x), z] })
    }

    fn map(&self, p: Vec3) -> Vec3 {
        self.axes.map(|axis| dot(axis, p))
    }
}

/// Whether triangle `c` (view coordinates) lies over `q` and nearer the camera by more than
/// `epsilon`. Edge-on triangles hide nothing.
pub(super) fn hides(c: &[Vec3; 3], q: Vec3, epsilon: f64) -> bool {
    let [a, b, c] = *c;
    let area = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
    if area == 0.0 {
        return false;
    }
    let la = ((b[0] - q[0]) * (c[1] - q[1]) - (c[0] - q[0]) * (b[1] - q[1])) / area;
    let lb = ((c[0] - q[0]) * (a[1] - q[1]) - (a[0] - q[0]) * (c[1] - q[1])) / area;
    let lc = 1.0 - la - lb;
    la >= 0.0 && lb >= 0.0 && lc >= 0.0 && la * a[2] + lb * b[2] + lc * c[2] > q[2] + epsilon
}

/// What every visibility count shares: the mesh at rest in view coordinates.
struct Scene<'a> {
    rig: &'a RigView<'a>,
    frame: ViewFrame,
    rest: Vec<Vec3>,
    rest_bvh: TriangleBvh,
    epsilon: f64,
}

impl Scene<'_> {
    /// How many of `vertices` are seen in `pose`, whose moved triangles are `moved`.
    fn seen(&self, pose: &Pose, vertices: &[u32], moved: &[u32], is_moved: impl Fn(u32) -> bool) -> usize {
        let triangles = self.rig.triangles;
        let posed = PosedTriangles::new(moved.to_vec(), triangles, pose, |p| self.frame.map(p));
        vertices
            .iter()
            .filter(|&&v| {
                let q = self.frame.map(pose.at(v));
                let ray = Aabb::of_points(&[q, [q[0], q[1], f64::INFINITY]]);
                let own = |t: u32| triangles[t as usize].contains(&v);
                let mut hidden = false;
                self.rest_bvh.for_each_overlap(&ray, |t| {
                    hidden = hidden
                        || (!is_moved(t) && !own(t) && hides(&triangles[t as usize].map(|u| self.rest[u as usize]), q, self.epsilon));
                });
                posed.for_each_overlap(&ray, |j| {
                    hidden = hidden || (!own(posed.triangles[j as usize]) && hides(&posed.corners[j as usize], q, self.epsilon));
                });
                !hidden
            })
            .count()
    }
}

/// Front-view box (x, y) of some points, grown by `margin`.
fn view_box(points: impl Iterator<Item = Vec3>, margin: f64) -> [f64; 4] {
    let mut b = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
    for p in points {
        b = [b[0].min(p[0]), b[1].min(p[1]), b[2].max(p[0]), b[3].max(p[1])];
    }
    [b[0] - margin, b[1] - margin, b[2] + margin, b[3] + margin]
}

fn boxes_meet(a: &[f64; 4], b: &[f64; 4]) -> bool {
    a[0] <= b[2] && b[0] <= a[2] && a[1] <= b[3] && b[1] <= a[3]
}

/// The candidate pairs, in both directions, where one shape hides the other's motion:
/// V(A + B) < `keep` V(A). `regions` and `active` hold every shape named in `candidates`;
/// `toward` points from the face to the camera. Returns the occlusions and how many
/// directions were tested; `None` when `toward` is not a direction.
pub fn find_occlusions(
    rig: &RigView,
    regions: &[MovingRegion],
    active: &[Vec<u32>],
    candidates: &[(usize, usize)],
    keep: f64,
    margin: f64,
    toward: Vec3,
) -> Option<(Vec<Occlusion>, usize)> {
    let frame = ViewFrame::new(toward)?;
    let diagonal = rig.bbox_diagonal();
    let margin = margin * diagonal;
    let mut involved: Vec<usize> = candidates.iter().flat_map(|&(a, b)| [a, b]).collect();
    involved.sort_unstable();
    involved.dedup();
    let mut active_box = vec![[0.0; 4]; rig.n_shapes()];
    let mut region_box = vec![[0.0; 4]; rig.n_shapes()];
    for &k in &involved {
        let pose = Pose::of(rig, &[k]);
        active_box[k] = view_box(active[k].iter().map(|&v| frame.map(pose.at(v))), margin);
        let corners = regions[k].triangles.iter().flat_map(|&t| rig.triangles[t as usize]);
        let rest = |v: u32| rig.neutral[v as usize].map(f64::from);
        region_box[k] = view_box(corners.flat_map(|v| [frame.map(rest(v)), frame.map(pose.at(v))]), 0.0);
    }
    let interacts = |hidden: usize, by: usize| {
        regions[hidden].meets(&regions[by], margin) || boxes_meet(&active_box[hidden], &region_box[by])
    };
    let tested: Vec<(usize, usize)> =
        candidates.iter().flat_map(|&(a, b)| [(a, b), (b, a)]).filter(|&(h, b)| interacts(h, b)).collect();
    if tested.is_empty() {
        return Some((Vec::new(), 0));
    }
    let rest: Vec<Vec3> = rig.neutral.iter().map(|p| frame.map(p.map(f64::from))).collect();
    let scene = Scene { rig, rest_bvh: TriangleBvh::build(&rest, rig.triangles), rest, frame, epsilon: DEPTH_EPSILON * diagonal };
    let mut hidden_shapes: Vec<usize> = tested.iter().map(|&(h, _)| h).collect();
    hidden_shapes.sort_unstable();
    hidden_shapes.dedup();
    let alone: Vec<usize> = hidden_shapes
        .par_iter()
        .map(|&k| scene.seen(&Pose::of(rig, &[k]), &active[k], &regions[k].triangles, |t| regions[k].contains(t)))
        .collect();
    let mut slot = vec![usize::MAX; rig.n_shapes()];
    hidden_shapes.iter().enumerate().for_each(|(i, &k)| slot[k] = i);
    let occlusions = tested
        .par_iter()
        .filter_map(|&(h, by)| {
            let seen_alone = alone[slot[h]];
            if seen_alone == 0 {
                return None;
            }
            let (rh, rb) = (&regions[h], &regions[by]);
            let mut moved: Vec<u32> = rh.triangles.iter().chain(&rb.triangles).copied().collect();
            moved.sort_unstable();
            moved.dedup();
            let seen = scene.seen(&Pose::of(rig, &[h, by]), &active[h], &moved, |t| rh.contains(t) || rb.contains(t));
            let kept = seen as f64 / seen_alone as f64;
            (kept < keep).then_some(Occlusion { hidden: h, by, kept })
        })
        .collect();
    Some((occlusions, tested.len()))
}
