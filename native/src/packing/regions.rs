//! What a shape moves, for the poseability tests (SPEC section 1, "poseable and
//! observable"): the triangles with a moving corner, their box over the rest pose and the
//! posed one, and the positions of a mix of shapes.
//!
//! The boxes make the pair pruning exact, not a heuristic: a triangle that shape A moves and
//! B does not lies, in every one of the poses rest, A, B and A + B, inside A's box (its
//! corners sit at rest or at rest + D_A). So when A's and B's boxes are apart, no triangle is
//! moved by both (its rest corners would lie in both boxes), and nothing A moves can meet
//! anything B moves in any of the four poses.

use rayon::prelude::*;

use crate::geometry::bvh::Aabb;
use crate::geometry::mat3::Vec3;
use crate::rig::RigView;

/// The triangles shape k moves and where they can be.
pub struct MovingRegion {
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
        let moves = |v: u32| delta[v as usize] != [0.0; 3];
        let triangles: Vec<u32> =
            (0..rig.triangles.len() as u32).filter(|&t| rig.triangles[t as usize].iter().any(|&v| moves(v))).collect();
        let mut mask = vec![0u64; rig.triangles.len().div_ceil(64)];
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for &t in &triangles {
            mask[t as usize / 64] |= 1 << (t % 64);
            for &v in &rig.triangles[t as usize] {
                let rest = rig.neutral[v as usize];
                for a in 0..3 {
                    for x in [rest[a] as f64, rest[a] as f64 + delta[v as usize][a] as f64] {
                        lo[a] = lo[a].min(x);
                        hi[a] = hi[a].max(x);
                    }
                }
            }
        }
        Self { triangles, mask, lo, hi }
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
                MovingRegion { triangles: Vec::new(), mask: Vec::new(), lo: [f64::INFINITY; 3], hi: [f64::NEG_INFINITY; 3] }
            }
        })
        .collect()
}

/// `V0 + sum of D_k` over some shapes at full weight, evaluated per vertex (f64 sums of the
/// f32 arrays) so that a pose costs nothing to set up.
pub struct Pose<'a> {
    pub neutral: &'a [[f32; 3]],
    pub deltas: Vec<&'a [[f32; 3]]>,
}

impl<'a> Pose<'a> {
    pub fn of(rig: &RigView<'a>, shapes: &[usize]) -> Self {
        Self { neutral: rig.neutral, deltas: shapes.iter().map(|&k| rig.delta(k)).collect() }
    }

    pub fn at(&self, v: u32) -> Vec3 {
        let v = v as usize;
        std::array::from_fn(|a| self.neutral[v][a] as f64 + self.deltas.iter().map(|d| d[v][a] as f64).sum::<f64>())
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
        let flat: Vec<Vec3> = corners.iter().flatten().copied().collect();
        let local: Vec<[u32; 3]> = (0..corners.len() as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        Self { bvh: crate::geometry::bvh::TriangleBvh::build(&flat, &local), triangles, corners }
    }

    /// Calls `visit(i)` for each position `i` in `triangles` whose box overlaps `query`.
    pub fn for_each_overlap(&self, query: &Aabb, visit: impl FnMut(u32)) {
        self.bvh.for_each_overlap(query, visit)
    }
}
