//! Occlusion conflicts (method, section 1, beyond the paper, for its goal 4: observable
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
//! query of [`crate::geometry::bvh::TriangleBvh`] finds its candidate triangles exactly. As for collisions, only
//! the triangles the two shapes move are posed (the rest are tested at rest) and a direction
//! is tested only when the two can interact: A's and B's moving regions meet, or the front
//! view's box of A's active vertices meets that of B's moving region. Otherwise B moves
//! nothing over A's vertices nor any of them, and V(A + B) = V(A) exactly. Each shape's
//! moved triangles are posed once, in one hierarchy that serves every direction it takes
//! part in (a triangle only B moves sits where B alone puts it), cut from the whole mesh's
//! hierarchy ([`super::regions::PosedTriangles`]) when a direction first needs it; per
//! direction only the triangles both move are posed anew, and only A's vertices
//! inside B's reach in the front view are traced (outside it nothing B moves can cover them),
//! until the count seen decides the direction.

use std::sync::OnceLock;

use rayon::prelude::*;

use super::regions::{MovingRegion, Pose, PosedTriangles, RestHierarchy};
use crate::geometry::bvh::Aabb;
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

/// What every visibility test shares: the mesh at rest in view coordinates.
struct Scene<'a> {
    rig: &'a RigView<'a>,
    regions: &'a [MovingRegion],
    frame: ViewFrame,
    /// Every triangle at rest, in view coordinates; position `t` is triangle `t`.
    rest: PosedTriangles,
    epsilon: f64,
    /// Per shape, the front-view box of its moved triangles at rest and in its pose.
    reach: Vec<Box2>,
    /// Per shape, its moved triangles in its pose, in view coordinates, taken from
    /// [`RestHierarchy::alone`] on first use ([`Scene::posed`]): many shapes are only ever a
    /// partner whose reach no vertex enters.
    posed: Vec<OnceLock<PosedTriangles>>,
    shared: &'a RestHierarchy<'a>,
}

/// A front-view box (x, y); empty when `lo > hi`.
#[derive(Clone, Copy)]
struct Box2 {
    lo: [f64; 2],
    hi: [f64; 2],
}

impl Box2 {
    const EMPTY: Box2 = Box2 { lo: [f64::INFINITY; 2], hi: [f64::NEG_INFINITY; 2] };

    fn of(points: impl IntoIterator<Item = Vec3>) -> Self {
        let mut b = Self::EMPTY;
        points.into_iter().for_each(|p| b.grow(p));
        b
    }

    fn grow(&mut self, p: Vec3) {
        for a in 0..2 {
            self.lo[a] = self.lo[a].min(p[a]);
            self.hi[a] = self.hi[a].max(p[a]);
        }
    }

    fn grown(self, margin: f64) -> Self {
        Self { lo: self.lo.map(|x| x - margin), hi: self.hi.map(|x| x + margin) }
    }

    /// Whether the front-view point `p` lies in the box (edges included).
    fn holds(&self, p: Vec3) -> bool {
        (0..2).all(|a| self.lo[a] <= p[a] && p[a] <= self.hi[a])
    }

    fn meets(&self, other: &Box2) -> bool {
        (0..2).all(|a| self.lo[a] <= other.hi[a] && other.lo[a] <= self.hi[a])
    }
}

/// Shape h posed alone: where its active vertices are seen from, and what hides each.
struct Alone {
    /// Per active vertex, where it is in pose h, in view coordinates.
    points: Vec<Vec3>,
    /// Per active vertex, the triangles that hide it in pose h; the search stops at the first
    /// one that no partner of h moves (the vertex then stays hidden with every partner, and
    /// [`Scene::seen_with`] asks of the list only whether all its triangles are moved by the
    /// partner, and whether it is empty).
    hiders: Vec<Vec<u32>>,
}

impl Scene<'_> {
    fn posed(&self, k: usize) -> &PosedTriangles {
        self.posed[k].get_or_init(|| self.shared.take_alone(k).mapped(|p| self.frame.map(p)))
    }

    fn view(&self, pose: &Pose, v: u32) -> Vec3 {
        self.frame.map(pose.at(v))
    }

    /// Passes to `found` the static triangles (at rest; those `skip` names are not) that hide
    /// the view point `q` of vertex `v`, until `found` returns `true` (then `true`).
    fn static_hiders(&self, v: u32, q: Vec3, skip: impl Fn(u32) -> bool, mut found: impl FnMut(u32) -> bool) -> bool {
        let triangles = self.rig.triangles;
        let ray = Aabb::of_points(&[q, [q[0], q[1], f64::INFINITY]]);
        self.rest.overlap_until(&ray, |t| {
            !skip(t) && !triangles[t as usize].contains(&v) && hides(&self.rest.corners[t as usize], q, self.epsilon) && found(t)
        })
    }

    /// Passes to `found` the triangles of `set` (but those `skip` names) that hide `q`, until
    /// `found` returns `true` (then `true`).
    fn posed_hiders(&self, set: &PosedTriangles, v: u32, q: Vec3, skip: impl Fn(u32) -> bool, mut found: impl FnMut(u32) -> bool) -> bool {
        let ray = Aabb::of_points(&[q, [q[0], q[1], f64::INFINITY]]);
        set.overlap_until(&ray, |j| {
            let t = set.triangles[j as usize];
            !skip(t) && !self.rig.triangles[t as usize].contains(&v) && hides(&set.corners[j as usize], q, self.epsilon) && found(t)
        })
    }

    /// Whether a triangle of `set` (but those `skip` names) hides `q`.
    fn posed_hidden(&self, set: &PosedTriangles, v: u32, q: Vec3, skip: impl Fn(u32) -> bool) -> bool {
        self.posed_hiders(set, v, q, skip, |_| true)
    }

    /// Pose h alone, for the `partners` it is tested with.
    fn alone(&self, h: usize, active: &[u32], partners: &[usize]) -> Alone {
        let posed = self.posed(h);
        let (rig, region) = (self.rig, &self.regions[h]);
        let mut moved_by_partner = vec![0u64; rig.triangles.len().div_ceil(64)];
        partners.iter().for_each(|&k| self.regions[k].add_to(&mut moved_by_partner));
        let stays = |t: u32| moved_by_partner[t as usize / 64] >> (t % 64) & 1 == 0;
        let pose = Pose::of(rig, self.regions, &[h]);
        let points: Vec<Vec3> = active.iter().map(|&v| self.view(&pose, v)).collect();
        let hiders = active
            .iter()
            .zip(&points)
            .map(|(&v, &q)| {
                let mut found = Vec::new();
                let mut take = |t: u32| {
                    found.push(t);
                    stays(t)
                };
                if !self.static_hiders(v, q, |t| region.contains(t), &mut take) {
                    self.posed_hiders(posed, v, q, |_| false, &mut take);
                }
                found
            })
            .collect();
        Alone { points, hiders }
    }

    /// How many of h's active vertices are seen with `by` posed too; once the count makes `enough` true the rest are not
    /// traced (any count it accepts decides the direction). A vertex `by` does not move (see
    /// `regions`) keeps its place: it is hidden by its hiders in pose h that `by` does not
    /// move, or by a triangle `by` moves: one only `by` moves sits where `by` alone puts it,
    /// one both move is posed here. One that `by` moves is traced afresh.
    ///
    /// Only the vertices inside `by`'s reach in the front view (the box of the triangles it
    /// moves, at rest and posed by it, and of those both move, posed by both) are traced: a
    /// triangle hides only points inside its own box, so a vertex outside, which `by` does
    /// not move, is seen exactly when every one of its hiders in pose h is one `by` moves
    /// away. The triangles both move are posed, and their hierarchy cut, only when a vertex
    /// that nothing else hides needs them.
    fn seen_with(&self, h: usize, by: usize, active: &[u32], alone: &Alone, enough: impl Fn(usize) -> bool) -> usize {
        let (rig, rh, rb) = (self.rig, &self.regions[h], &self.regions[by]);
        let pose = Pose::of(rig, self.regions, &[h, by]);
        let (fewer, other) = if rh.triangles.len() <= rb.triangles.len() { (rh, rb) } else { (rb, rh) };
        let shared: Vec<u32> = fewer.triangles.iter().copied().filter(|&t| other.contains(t)).collect();
        let mut reach = self.reach[by];
        shared.iter().flat_map(|&t| rig.triangles[t as usize]).for_each(|v| reach.grow(self.view(&pose, v)));
        let reach = reach.grown(self.epsilon);
        let mut count = 0;
        let mut near = Vec::new();
        for (i, &v) in active.iter().enumerate() {
            if rb.moves(v) || reach.holds(alone.points[i]) {
                near.push(i);
            } else if alone.hiders[i].iter().all(|&t| rb.contains(t)) {
                count += 1;
                if enough(count) {
                    return count;
                }
            }
        }
        if near.is_empty() {
            return count;
        }
        // Only whether a vertex is hidden matters here: each search stops at its first hider.
        // The triangles both move, posed by both, are cut when a vertex no other triangle
        // hides first needs them.
        let (shared_list, shared) = (shared, std::cell::OnceCell::new());
        for i in near {
            let v = active[i];
            let (q, hidden) = if rb.moves(v) {
                let q = self.view(&pose, v);
                let hidden = self.static_hiders(v, q, |t| rh.contains(t) || rb.contains(t), |_| true)
                    || self.posed_hidden(self.posed(h), v, q, |t| rb.contains(t));
                (q, hidden)
            } else if alone.hiders[i].iter().any(|&t| !rb.contains(t)) {
                continue;
            } else {
                (alone.points[i], false)
            };
            let hidden = hidden
                || self.posed_hidden(self.posed(by), v, q, |t| rh.contains(t))
                || (!shared_list.is_empty() && {
                    // Cut from the smaller of the two shapes' sets (the same triangles).
                    let shared = shared.get_or_init(|| {
                        let (from, other) = if rh.triangles.len() <= rb.triangles.len() { (h, rb) } else { (by, rh) };
                        self.posed(from).subset(|t| other.contains(t), |t| rig.triangles[t as usize].map(|v| self.view(&pose, v)))
                    });
                    self.posed_hidden(shared, v, q, |_| false)
                });
            if !hidden {
                count += 1;
                if enough(count) {
                    return count;
                }
            }
        }
        count
    }
}

/// The candidate pairs, in both directions, where one shape hides the other's motion:
/// V(A + B) < `keep` V(A). `regions` and `active` hold every shape named in `candidates`;
/// `toward` points from the face to the camera; `rest_hierarchy` is the rig's, shared with
/// the collision test. Returns the occlusions and how many directions were tested; `None`
/// when `toward` is not a direction.
pub fn find_occlusions(
    rig: &RigView,
    rest_hierarchy: &RestHierarchy,
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
    let k_count = rig.n_shapes();
    let mut involved = vec![false; k_count];
    candidates.iter().for_each(|&(a, b)| (involved[a], involved[b]) = (true, true));
    let rest_of = |v: u32| frame.map(rig.neutral[v as usize].map(f64::from));
    // Front-view boxes: of each shape's active vertices in its pose, and of its moved
    // triangles at rest and posed.
    let boxes: Vec<(Box2, Box2)> = (0..k_count)
        .into_par_iter()
        .map(|k| {
            if !involved[k] {
                return (Box2::EMPTY, Box2::EMPTY);
            }
            let pose = Pose::of(rig, regions, &[k]);
            let active_box = Box2::of(active[k].iter().map(|&v| frame.map(pose.at(v)))).grown(margin);
            let mut region_box = Box2::EMPTY;
            for &t in &regions[k].triangles {
                rig.triangles[t as usize].iter().for_each(|&v| {
                    region_box.grow(rest_of(v));
                    region_box.grow(frame.map(pose.at(v)));
                });
            }
            (active_box, region_box)
        })
        .collect();
    let interacts = |h: usize, by: usize| regions[h].meets(&regions[by], margin) || boxes[h].0.meets(&boxes[by].1);
    let tested: Vec<(usize, usize)> =
        candidates.iter().flat_map(|&(a, b)| [(a, b), (b, a)]).filter(|&(h, b)| interacts(h, b)).collect();
    if tested.is_empty() {
        return Some((Vec::new(), 0));
    }
    let rest: Vec<Vec3> = (0..rig.n_vertices() as u32).map(rest_of).collect();
    let reach = boxes.iter().map(|b| b.1).collect();
    let posed = (0..k_count).map(|_| OnceLock::new()).collect();
    let scene = Scene {
        rig,
        regions,
        rest: PosedTriangles::whole(rest_hierarchy, &rest, rig.triangles),
        frame,
        epsilon: DEPTH_EPSILON * diagonal,
        reach,
        posed,
        shared: rest_hierarchy,
    };
    let mut hidden_shapes: Vec<usize> = tested.iter().map(|&(h, _)| h).collect();
    hidden_shapes.sort_unstable();
    hidden_shapes.dedup();
    let occlusions: Vec<Vec<Occlusion>> = hidden_shapes
        .par_iter()
        .map(|&h| {
            let partners: Vec<usize> = tested.iter().filter(|p| p.0 == h).map(|p| p.1).collect();
            let alone = scene.alone(h, &active[h], &partners);
            let seen_alone = alone.hiders.iter().filter(|h| h.is_empty()).count();
            if seen_alone == 0 {
                return Vec::new();
            }
            partners
                .iter()
                .filter_map(|&by| {
                    let share = |count: usize| count as f64 / seen_alone as f64;
                    let kept = share(scene.seen_with(h, by, &active[h], &alone, |count| share(count) >= keep));
                    (kept < keep).then_some(Occlusion { hidden: h, by, kept })
                })
                .collect()
        })
        .collect();
    let mut occlusions: Vec<Occlusion> = occlusions.into_iter().flatten().collect();
    let order = |o: &Occlusion| tested.iter().position(|&p| p == (o.hidden, o.by));
    occlusions.sort_by_key(order);
    Some((occlusions, tested.len()))
}
