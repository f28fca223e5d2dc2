//! What a shape moves, for the poseability tests (method, section 1, "poseable and
//! observable"): the triangles with a moving corner, their box over the rest pose and the
//! posed one, and the positions of a mix of shapes.
//!
//! A vertex *moves* in shape k when it moves more than [`MOVING_FRACTION`] of the shape's
//! largest displacement; the tests pose each shape with the motion of its moving vertices
//! only. A sculpted shape's long tail of sub-millimetre motion (a jaw shape nudges most of
//! the lower face) cannot make or break a collision of centimetres or hide an eyeball, but
//! posing it would make most triangles of the face "moved" by every pair of shapes.
//!
//! The boxes make the pair pruning exact, not a heuristic: a triangle that shape A moves and
//! B does not lies, in every one of the poses rest, A, B and A + B, inside A's box (its
//! corners sit at rest or at rest + D_A). So when A's and B's boxes are apart, no triangle is
//! moved by both (its rest corners would lie in both boxes), and nothing A moves can meet
//! anything B moves in any of the four poses.

use std::sync::{Arc, Mutex, OnceLock};

use rayon::prelude::*;

use crate::geometry::bvh::{Aabb, TriangleBvh};
use crate::geometry::mat3::Vec3;
use crate::geometry::topology::VertexTriangles;
use crate::rig::{norm, RigView};

/// Share of a shape's largest displacement below which a vertex counts as still.
pub const MOVING_FRACTION: f64 = 0.05;

/// The triangles shape k moves and where they can be.
pub struct MovingRegion {
    /// Bit v is set when vertex v moves.
    vertices: Vec<u64>,
    /// Triangles with a corner whose delta is not exactly zero, ascending.
    pub triangles: Vec<u32>,
    /// Bit t is set when triangle t is in `triangles`.
    mask: Vec<u64>,
    /// Box of those triangles' corners at rest and at rest + D_k (`lo`, `hi`); empty
    /// (`lo > hi`) when the shape moves nothing.
    pub lo: Vec3,
    pub hi: Vec3,
}

impl MovingRegion {
    /// The triangles are those around the moving vertices (`incidence`), in ascending order:
    /// one pass over the moving vertices instead of one over every triangle per shape.
    fn new(rig: &RigView, k: usize, incidence: &VertexTriangles) -> Self {
        let delta = rig.delta(k);
        let norms: Vec<f64> = delta.iter().map(norm).collect();
        let floor = MOVING_FRACTION * norms.iter().copied().fold(0.0, f64::max);
        let mut vertices = vec![0u64; rig.n_vertices().div_ceil(64)];
        let mut mask = vec![0u64; rig.triangles.len().div_ceil(64)];
        for (v, &n) in norms.iter().enumerate() {
            if n > floor {
                vertices[v / 64] |= 1 << (v % 64);
                incidence.of(v).iter().for_each(|&t| mask[t as usize / 64] |= 1 << (t % 64));
            }
        }
        let moves = |v: u32| vertices[v as usize / 64] >> (v % 64) & 1 == 1;
        let mut triangles = Vec::new();
        for (w, &word) in mask.iter().enumerate() {
            let mut bits = word;
            while bits != 0 {
                triangles.push(64 * w as u32 + bits.trailing_zeros());
                bits &= bits - 1;
            }
        }
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for &t in &triangles {
            for &v in &rig.triangles[t as usize] {
                let rest = rig.neutral[v as usize];
                let step = if moves(v) { delta[v as usize] } else { [0.0; 3] };
                for a in 0..3 {
                    for x in [rest[a] as f64, rest[a] as f64 + step[a] as f64] {
                        lo[a] = lo[a].min(x);
                        hi[a] = hi[a].max(x);
                    }
                }
            }
        }
        Self { vertices, triangles, mask, lo, hi }
    }

    /// Whether vertex v moves in this shape.
    pub fn moves(&self, v: u32) -> bool {
        self.vertices[v as usize / 64] >> (v % 64) & 1 == 1
    }

    pub fn contains(&self, t: u32) -> bool {
        self.mask[t as usize / 64] >> (t % 64) & 1 == 1
    }

    /// Bit t of `union` is set for each triangle t in this region (`union` has one bit per
    /// triangle of the mesh).
    pub fn add_to(&self, union: &mut [u64]) {
        union.iter_mut().zip(&self.mask).for_each(|(u, m)| *u |= m);
    }

    /// Whether the two boxes, each grown by `margin` on every side, meet.
    pub fn meets(&self, other: &MovingRegion, margin: f64) -> bool {
        (0..3).all(|a| self.lo[a] - margin <= other.hi[a] && other.lo[a] - margin <= self.hi[a])
    }
}

/// The moving region of every shape marked in `wanted` (others get an empty one).
pub fn moving_regions(rig: &RigView, wanted: &[bool]) -> Vec<MovingRegion> {
    let incidence = VertexTriangles::new(rig.n_vertices(), rig.triangles);
    (0..rig.n_shapes())
        .into_par_iter()
        .map(|k| {
            if wanted[k] {
                MovingRegion::new(rig, k, &incidence)
            } else {
                MovingRegion {
                    vertices: Vec::new(),
                    triangles: Vec::new(),
                    mask: Vec::new(),
                    lo: [f64::INFINITY; 3],
                    hi: [f64::NEG_INFINITY; 3],
                }
            }
        })
        .collect()
}

/// `V0 + sum of D_k` over some shapes at full weight, each on its moving vertices only,
/// evaluated per vertex (f64 sums of the f32 arrays) so that a pose costs nothing to set up.
pub struct Pose<'a> {
    pub neutral: &'a [[f32; 3]],
    pub deltas: Vec<(&'a [[f32; 3]], &'a MovingRegion)>,
}

impl<'a> Pose<'a> {
    pub fn of(rig: &RigView<'a>, regions: &'a [MovingRegion], shapes: &[usize]) -> Self {
        Self { neutral: rig.neutral, deltas: shapes.iter().map(|&k| (rig.delta(k), &regions[k])).collect() }
    }

    pub fn at(&self, v: u32) -> Vec3 {
        // One pass over the shapes (not one per axis); each axis sums the same terms in the
        // same order as before.
        let mut step = [-0.0f64; 3];
        for (d, _) in self.deltas.iter().filter(|(_, region)| region.moves(v)) {
            (0..3).for_each(|a| step[a] += d[v as usize][a] as f64);
        }
        std::array::from_fn(|a| self.neutral[v as usize][a] as f64 + step[a])
    }
}

/// The hierarchy over the whole mesh at rest, built once, when a test first needs it, for
/// both tests: the collision test uses it as it is, the occlusion test refits it to the rest
/// pose in view coordinates ([`PosedTriangles::whole`]) instead of building its own (for the
/// default front camera the view frame is the mesh's axes reordered, so the refitted tree
/// is exactly as tight as one built there).
///
/// It also keeps, for both tests, the whole mesh at rest and each shape's moved triangles
/// posed by it alone ([`RestHierarchy::alone`]), in mesh coordinates: the occlusion test
/// takes the latter over into view coordinates ([`RestHierarchy::take_alone`],
/// [`PosedTriangles::mapped`]) instead of cutting each from the whole mesh again (the cuts
/// took about a third of the occlusion test on a 26k head), releasing the copy here.
pub struct RestHierarchy<'a> {
    rig: &'a RigView<'a>,
    regions: &'a [MovingRegion],
    bvh: OnceLock<TriangleBvh>,
    rest: OnceLock<PosedTriangles>,
    alone: Vec<Mutex<Option<Arc<PosedTriangles>>>>,
}

/// The hierarchy over the mesh at rest that [`RestHierarchy::get`] builds.
pub fn rest_bvh(rig: &RigView) -> TriangleBvh {
    let points: Vec<Vec3> = rig.neutral.iter().map(|p| p.map(f64::from)).collect();
    TriangleBvh::build(&points, rig.triangles)
}

impl<'a> RestHierarchy<'a> {
    /// `regions`: the moving region of every shape the tests will pose.
    pub fn new(rig: &'a RigView<'a>, regions: &'a [MovingRegion]) -> Self {
        Self::with(rig, regions, None)
    }

    /// [`Self::new`] with the hierarchy given when it is already built ([`rest_bvh`]): the
    /// packing builds it on one core while the other finds the regions.
    pub fn with(rig: &'a RigView<'a>, regions: &'a [MovingRegion], built: Option<TriangleBvh>) -> Self {
        let (alone, bvh) = ((0..regions.len()).map(|_| Mutex::new(None)).collect(), OnceLock::new());
        if let Some(built) = built {
            let _ = bvh.set(built);
        }
        Self { rig, regions, bvh, rest: OnceLock::new(), alone }
    }

    pub fn get(&self) -> &TriangleBvh {
        self.bvh.get_or_init(|| rest_bvh(self.rig))
    }

    /// Every triangle at rest, in mesh coordinates; position `t` is triangle `t`.
    pub fn rest(&self) -> &PosedTriangles {
        self.rest.get_or_init(|| {
            let points: Vec<Vec3> = self.rig.neutral.iter().map(|p| p.map(f64::from)).collect();
            PosedTriangles::whole(self, &points, self.rig.triangles)
        })
    }

    /// The triangles shape k moves, posed by k alone, in mesh coordinates: cut from
    /// [`Self::rest`] once, kept until [`Self::take_alone`] hands it over.
    pub fn alone(&self, k: usize) -> Arc<PosedTriangles> {
        let mut slot = self.alone[k].lock().unwrap_or_else(|poisoned| poisoned.into_inner());
        slot.get_or_insert_with(|| Arc::new(self.cut(k))).clone()
    }

    /// [`Self::alone`] for its last user, which takes it into its own frame: the copy here is
    /// released, so each shape's moved triangles are held once, not once per frame (on the
    /// 77k-vertex, 150-key head the two copies made most of the packing's peak memory).
    /// Cut afresh when it was never cut or is still in use elsewhere.
    pub fn take_alone(&self, k: usize) -> PosedTriangles {
        let taken = self.alone[k].lock().unwrap_or_else(|poisoned| poisoned.into_inner()).take();
        taken.and_then(|shared| Arc::try_unwrap(shared).ok()).unwrap_or_else(|| self.cut(k))
    }

    fn cut(&self, k: usize) -> PosedTriangles {
        let (rig, region) = (self.rig, &self.regions[k]);
        let pose = Pose::of(rig, self.regions, &[k]);
        self.rest().subset(|t| region.contains(t), |t| rig.triangles[t as usize].map(|v| pose.at(v)))
    }
}

/// A hierarchy over some triangles at their positions in a pose: the triangles are stored
/// corner by corner, so a query answers indices into `triangles`, mapped back here.
///
/// Each is cut from a hierarchy over the whole mesh ([`PosedTriangles::whole`], refitted
/// from the one [`RestHierarchy`]) or from another one ([`PosedTriangles::subset`]), with
/// [`TriangleBvh::subset`]: one pass over the nodes instead of a build per shape and per pair
/// (the builds took about 40% of a cold packing of a 26k head).
pub struct PosedTriangles {
    /// In the hierarchy's order (not ascending).
    pub triangles: Vec<u32>,
    pub corners: Vec<[Vec3; 3]>,
    pub bvh: TriangleBvh,
}

impl PosedTriangles {
    /// Every triangle of the mesh, at `points`, in a hierarchy refitted from `rest`'s tree
    /// (the same tree with its boxes at these corners: exact for any points, as good as a
    /// build for the rest pose in any axis-permuted frame): position `t` is triangle `t`.
    pub fn whole(rest: &RestHierarchy, points: &[Vec3], all: &[[u32; 3]]) -> Self {
        Self {
            bvh: rest.get().refitted(points, all),
            triangles: (0..all.len() as u32).collect(),
            corners: all.iter().map(|t| t.map(|v| points[v as usize])).collect(),
        }
    }

    /// The triangles of this set that `keep` picks, with corners `corners(t)` (t a triangle
    /// of the mesh), in a hierarchy cut from this one's.
    pub fn subset(&self, keep: impl Fn(u32) -> bool, corners: impl Fn(u32) -> [Vec3; 3]) -> Self {
        self.subset_at_positions(keep, |p| corners(self.triangles[p as usize]))
    }

    /// The same triangles and tree with every corner taken through `map` (into another
    /// frame): what [`Self::subset`] with the mapped corners would give, without the cut.
    pub fn mapped(&self, map: impl Fn(Vec3) -> Vec3) -> Self {
        let corners: Vec<[Vec3; 3]> = self.corners.iter().map(|c| c.map(&map)).collect();
        Self { bvh: self.bvh.at_corners(|p| corners[p as usize]), triangles: self.triangles.clone(), corners }
    }

    /// The triangles of this set that `keep` picks, at their corners here.
    pub fn part(&self, keep: impl Fn(u32) -> bool) -> Self {
        self.subset_at_positions(keep, |p| self.corners[p as usize])
    }

    /// The triangles `keep` picks, at `corners(p)` for the one at position `p` here.
    fn subset_at_positions(&self, keep: impl Fn(u32) -> bool, corners: impl Fn(u32) -> [Vec3; 3]) -> Self {
        let (bvh, positions, corners) = self.bvh.subset(|p| keep(self.triangles[p as usize]), corners);
        Self { triangles: positions.iter().map(|&p| self.triangles[p as usize]).collect(), corners, bvh }
    }

    /// Calls `visit(i)` for each position `i` in `triangles` whose box overlaps `query`.
    pub fn for_each_overlap(&self, query: &Aabb, visit: impl FnMut(u32)) {
        self.bvh.for_each_overlap(query, visit)
    }

    /// [`Self::for_each_overlap`] until `visit` returns `true` (then `true`).
    pub fn overlap_until(&self, query: &Aabb, visit: impl FnMut(u32) -> bool) -> bool {
        self.bvh.overlap_until(query, visit)
    }
}
