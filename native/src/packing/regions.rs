//! What a shape moves, for the poseability tests (SPEC section 1, "poseable and
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

use rayon::prelude::*;

use crate::geometry::bvh::Aabb;
use crate::geometry::mat3::Vec3;
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
    pub fn new(rig: &RigView, k: usize) -> Self {
        let delta = rig.delta(k);
        let floor = MOVING_FRACTION * rig.max_displacement(k);
        let mut vertices = vec![0u64; rig.n_vertices().div_ceil(64)];
        for (v, d) in delta.iter().enumerate() {
            if norm(d) > floor {
                vertices[v / 64] |= 1 << (v % 64);
            }
        }
        let moves = |v: u32| vertices[v as usize / 64] >> (v % 64) & 1 == 1;
        let triangles: Vec<u32> =
            (0..rig.triangles.len() as u32).filter(|&t| rig.triangles[t as usize].iter().any(|&v| moves(v))).collect();
        let mut mask = vec![0u64; rig.triangles.len().div_ceil(64)];
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for &t in &triangles {
            mask[t as usize / 64] |= 1 << (t % 64);
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

    /// Whether the two boxes, each grown by `margin` on every side, meet.
    pub fn meets(&self, other: &MovingRegion, margin: f64) -> bool {
        (0..3).all(|a| self.lo[a] - margin <= other.hi[a] && other.lo[a] - margin <= self.hi[a])
    }
}

/// The moving region of every shape marked in `wanted` (others get an empty one).
pub fn moving_regions(rig: &RigView, wanted: &[bool]) -> Vec<MovingRegion> {
    (0..rig.n_shapes())
        .into_par_iter()
        .map(|k| {
            if wanted[k] {
                MovingRegion::new(rig, k)
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
        let moving = || self.deltas.iter().filter(|(_, region)| region.moves(v)).map(|(d, _)| d[v as usize]);
        let v = v as usize;
        std::array::from_fn(|a| self.neutral[v][a] as f64 + moving().map(|d| d[a] as f64).sum::<f64>())
    }
}

/// A hierarchy over some triangles at their positions in a pose: the triangles are stored
/// corner by corner, so a query answers indices into `triangles`, mapped back here.
pub struct PosedTriangles {
    pub triangles: Vec<u32>,
    pub corners: Vec<[Vec3; 3]>,
    pub bvh: crate::geometry::bvh::TriangleBvh,
}

impl PosedTriangles {
    /// `transform` maps a posed point into the frame the hierarchy is built in.
    pub fn new(triangles: Vec<u32>, all: &[[u32; 3]], pose: &Pose, transform: impl Fn(Vec3) -> Vec3) -> Self {
        let corners: Vec<[Vec3; 3]> =
            triangles.iter().map(|&t| all[t as usize].map(|v| transform(pose.at(v)))).collect();
        Self::from_corners(triangles, corners)
    }

    /// The hierarchy over `triangles` whose corners, already posed, are `corners`.
    pub fn from_corners(triangles: Vec<u32>, corners: Vec<[Vec3; 3]>) -> Self {
        let flat: Vec<Vec3> = corners.iter().flatten().copied().collect();
        let local: Vec<[u32; 3]> = (0..corners.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        Self { bvh: crate::geometry::bvh::TriangleBvh::build(&flat, &local), triangles, corners }
    }

    /// Calls `visit(i)` for each position `i` in `triangles` whose box overlaps `query`.
    pub fn for_each_overlap(&self, query: &Aabb, visit: impl FnMut(u32)) {
        self.bvh.for_each_overlap(query, visit)
    }
}
