//! Global visibility, Eq. (4) of Zell & McDonnell 2022: per pose, the fraction of directions
//! in which a vertex can be seen (ambient-occlusion style), and its worst case over poses
//! `l[n] = min_k L_k[n]`. Method, section 2.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::error::ShapesmithResult;
use crate::geometry::bvh::{cross, dot, sub, TriangleBvh};
use crate::geometry::wide_bvh::OcclusionBvh;
use crate::progress::Progress;
use crate::rig::RigView;

/// Ray origins sit this fraction of the bounding-box diagonal above the surface, along the
/// vertex normal, so that a ray does not hit the triangles around its own vertex.
pub const NUDGE_FRACTION: f64 = 1e-4;

/// Where the observers are.
#[derive(Clone, Copy, Debug)]
pub enum Sampling<'a> {
    /// Unknown cameras: `rays` cosine-weighted directions over the normal's hemisphere.
    Hemisphere { rays: usize, seed: u64 },
    /// Known camera positions (mesh-local): one segment from the vertex to each camera.
    Cameras(&'a [[f64; 3]]),
}

/// What a caller needs to know of a vertex's worst case `l[n]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Need {
    /// `l[n]` itself (a cost uses it, or it is reported).
    Exact,
    /// Only whether `l[n] >= threshold` (a rule that keeps or drops the vertex).
    AtLeast(f64),
}

/// A vertex's worst case, as far as it was needed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Seen {
    Exact(f64),
    /// `l[n] >= threshold`, not measured further.
    AtLeast(f64),
    /// `l[n] < threshold`, not measured further.
    Below(f64),
}

impl Seen {
    /// `l[n]` when it was measured.
    pub fn exact(&self) -> Option<f64> {
        match *self {
            Seen::Exact(l) => Some(l),
            _ => None,
        }
    }

    /// Whether `l[n] >= threshold`; `None` when the result cannot tell (it was measured
    /// against another threshold).
    pub fn at_least(&self, threshold: f64) -> Option<bool> {
        match *self {
            Seen::Exact(l) => Some(l >= threshold),
            Seen::AtLeast(t) => (threshold <= t).then_some(true),
            Seen::Below(t) => (threshold >= t).then_some(false),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct Visibility {
    /// For each requested vertex, in the order given.
    pub worst: Vec<Seen>,
    /// Rays traced through a whole posed mesh.
    pub rays_cast: u64,
    /// Rays of a shaped pose answered from the neutral's outcome or by the moving region's
    /// triangles alone, without tracing the whole pose.
    pub rays_reused: u64,
}

/// `l[n] = min_k L_k[n]` (Eq. 4) over the neutral pose and each of `shapes` at weight 1, for
/// each of `vertices`, as far as `needs` asks (one per vertex).
///
/// Hemisphere mode casts `rays` rays per vertex and pose: a jittered golden-ratio lattice
/// mapped to cosine-weighted directions (one stratum of `sin^2 theta` per ray), so that the
/// grazing directions from which a tracker cannot see a point count least. Each vertex draws
/// from its own ChaCha stream of `seed` (the same in every pose): results do not depend on
/// the number of threads, nor on which other vertices are asked. Camera mode counts a camera
/// as seeing the vertex when it lies in front (`n . (c - p) > 0`) and the segment to it is
/// unobstructed.
///
/// A vertex whose posed normal vanishes (no triangle, or triangles that cancel) has no
/// hemisphere: it is sampled over the whole sphere, and every camera counts as in front.
///
/// Work saved, with the same answer as tracing every ray through every pose (`reuse =
/// false`; the tests compare the two):
/// - A pose stops casting for a vertex once it cannot lower that vertex's minimum; a vertex
///   a shape moves traces the rays that escaped at rest first, to get there sooner. A vertex
///   asked only whether `l >= t` stops a pose once `t` of its rays escaped, and stops
///   altogether once a pose is certain to stay below `t`.
/// - Reuse across poses. A shape moves a small part of the head. In pose k the triangles
///   split into static ones (identical corners to the neutral's) and moved ones. A vertex
///   none of whose triangles moves has the neutral's origin, normal and so rays. Its ray is
///   blocked in pose k iff it meets a static triangle or a moved triangle as posed; in the
///   neutral iff it meets a static one or a moved one at rest. So: when the moved triangles
///   (posed and at rest) lie behind the vertex's tangent plane, no ray of its can reach
///   them and the pose sees what the neutral saw; else a ray is blocked if it meets the
///   posed moved triangles (a small hierarchy, cut from the neutral's), escapes if it
///   escaped at rest, takes the neutral's outcome if it misses the moved triangles at rest
///   too (another small one; the neutral traces a ray the first time its outcome is asked),
///   and only otherwise is traced through the whole pose.
pub fn worst_case_visibility(
    rig: &RigView,
    shapes: &[usize],
    vertices: &[u32],
    needs: &[Need],
    sampling: &Sampling,
    reuse: bool,
    progress: &dyn Progress,
) -> ShapesmithResult<Visibility> {
    let nudge = NUDGE_FRACTION * rig.bbox_diagonal();
    let total = sampling.rays_per_vertex();
    let (mut rays_cast, mut rays_reused) = (0u64, 0u64);
    let poses = shapes.len() + 1;
    progress.checkpoint(0.0)?;
    let (neutral, neutral_binary) = PosedMesh::neutral(rig);
    // The neutral pose keeps each vertex's rays and the outcomes it traced.
    let mut tracks: Vec<Track> = vertices
        .par_iter()
        .zip(needs)
        .map(|(&v, &need)| {
            let lattice = match sampling {
                Sampling::Hemisphere { rays, seed } => hemisphere_lattice(*rays, *seed, v as u64),
                Sampling::Cameras(_) => Vec::new(),
            };
            let (origin, rays) = neutral.rays(v, nudge, sampling, &lattice);
            let mut rest = RaysAtRest { origin, rays: rays.collect(), known: vec![0; total.div_ceil(64)], escaped: vec![0; total.div_ceil(64)] };
            let mut track = Track { vertex: v, level: 1.0, threshold: None, below: false, cast: 0, reused: 0, rest: RaysAtRest::default(), lattice: Vec::new() };
            if let Need::AtLeast(t) = need {
                track.level = t;
                track.threshold = Some(t);
            }
            let seen = (0..total).map(|i| rest.neutral_outcome(i, &neutral.bvh, &mut track.cast));
            let level = pose_visibility(track.level, total, track.threshold.is_none(), seen);
            track.settle(level);
            track.rest = rest;
            track.lattice = lattice;
            track
        })
        .collect();
    // Shaped poses refit the neutral's hierarchy: a shape moves a small part of the head, so
    // the boxes stay tight, and a refit costs far less than a build.
    // The next pose and its moving region are prepared on one thread while the others trace
    // the current pose.
    let posed = |i: usize| {
        shapes.get(i).map(|&k| {
            let mesh = PosedMesh::shaped(rig, k, &neutral_binary, &neutral.bvh);
            let region = reuse.then(|| MovingRegion::new(rig, k, &neutral_binary, &neutral.points, &mesh.points, nudge));
            (mesh, region)
        })
    };
    let mut next = posed(0);
    for i in 0..shapes.len() {
        progress.checkpoint((i + 1) as f64 / poses as f64)?;
        let Some((mesh, region)) = next.take() else { break };
        let ((), prepared) = rayon::join(
            || {
                tracks.par_iter_mut().filter(|t| !t.done()).for_each(|track| {
                    let v = track.vertex;
                    let exact_below = track.threshold.is_none();
                    let level = match &region {
                        Some(region) if region.is_static(v) => {
                            if region.behind(&track.rest.origin, &neutral.normals[v as usize]) {
                                track.reused += total as u64;
                                return;
                            }
                            let Track { rest, cast, reused, level, .. } = track;
                            let seen = (0..total).map(|r| region.outcome(r, rest, &mesh.bvh, &neutral.bvh, cast, reused));
                            pose_visibility(*level, total, exact_below, seen)
                        }
                        _ => {
                            let (origin, rays) = mesh.rays(v, nudge, sampling, &track.lattice);
                            // The rays that escaped at rest first: they likely escape in this
                            // pose too, and a pose that keeps the vertex's level stops at its
                            // `needed`-th escape (the answer is a count: the order is free).
                            let rays: Vec<Ray> = rays.collect();
                            let Track { rest, cast, level, .. } = track;
                            let first = (0..total).filter(|&r| rest.escaped_at_rest(r));
                            let order = first.chain((0..total).filter(|&r| !rest.escaped_at_rest(r)));
                            let seen = order.map(|r| {
                                let ray = &rays[r];
                                *cast += 1;
                                ray.2 && !mesh.bvh.any_hit(&origin, &ray.0, ray.1)
                            });
                            pose_visibility(*level, total, exact_below, seen)
                        }
                    };
                    track.settle(level);
                })
            },
            || posed(i + 1),
        );
        next = prepared;
    }
    let worst = tracks
        .iter()
        .map(|t| {
            rays_cast += t.cast;
            rays_reused += t.reused;
            match t.threshold {
                None => Seen::Exact(t.level),
                Some(threshold) if t.below => Seen::Below(threshold),
                Some(threshold) => Seen::AtLeast(threshold),
            }
        })
        .collect();
    progress.checkpoint(1.0)?;
    Ok(Visibility { worst, rays_cast, rays_reused })
}

impl Sampling<'_> {
    fn rays_per_vertex(&self) -> usize {
        match self {
            Sampling::Hemisphere { rays, .. } => *rays,
            Sampling::Cameras(cameras) => cameras.len(),
        }
    }
}

/// One vertex's state across the poses.
struct Track {
    vertex: u32,
    /// The minimum so far (exact); for a threshold, the threshold until a pose falls below.
    level: f64,
    threshold: Option<f64>,
    /// A pose fell below the threshold: nothing more to learn.
    below: bool,
    cast: u64,
    reused: u64,
    rest: RaysAtRest,
    /// Its hemisphere samples in the normal's frame (the same in every pose).
    lattice: Vec<Sample>,
}

impl Track {
    fn settle(&mut self, level: f64) {
        match self.threshold {
            Some(t) if level < t => self.below = true,
            _ => self.level = level,
        }
    }

    /// Nothing a later pose can change: below the threshold, or invisible.
    fn done(&self) -> bool {
        self.below || self.level == 0.0
    }
}

/// The triangles shape k moves, at rest and posed, one box around both, and the vertices
/// none of whose triangles moves (so their rays are the neutral's).
struct MovingRegion {
    at_rest: OcclusionBvh,
    posed: OcclusionBvh,
    bounds: Option<[[f64; 3]; 2]>,
    margin: f64,
    touched: Vec<bool>,
}

impl MovingRegion {
    /// `neutral`: the neutral pose's binary hierarchy, which the region's is cut from.
    fn new(rig: &RigView, shape: usize, neutral: &TriangleBvh, rest: &[[f64; 3]], posed: &[[f64; 3]], margin: f64) -> Self {
        let delta = rig.delta(shape);
        let mut touched: Vec<bool> = delta.iter().map(|d| *d != [0.0; 3]).collect();
        let moved: Vec<bool> = rig.triangles.iter().map(|t| t.iter().any(|&v| touched[v as usize])).collect();
        let mut bounds: Option<[[f64; 3]; 2]> = None;
        for t in rig.triangles.iter().zip(&moved).filter_map(|(t, &m)| m.then_some(t)) {
            for &v in t {
                touched[v as usize] = true;
                for p in [&rest[v as usize], &posed[v as usize]] {
                    let [lo, hi] = bounds.get_or_insert([*p, *p]);
                    for a in 0..3 {
                        lo[a] = lo[a].min(p[a]);
                        hi[a] = hi[a].max(p[a]);
                    }
                }
            }
        }
        // The neutral's hierarchy cut down to the moved triangles (no build), and refitted
        // to the pose.
        let binary = neutral.restricted(&moved);
        let at_rest = OcclusionBvh::new(&binary);
        let posed = at_rest.refitted(binary.refitted(posed, rig.triangles));
        Self { at_rest, posed, bounds, margin, touched }
    }

    fn is_static(&self, v: u32) -> bool {
        !self.touched[v as usize]
    }

    /// Whether the moved triangles lie (by `margin`) behind the plane through `origin` with
    /// normal `normal`: every ray that counts leaves into `n . d > 0` and cannot reach them.
    fn behind(&self, origin: &[f64; 3], normal: &[f64; 3]) -> bool {
        let Some([lo, hi]) = self.bounds else { return true };
        if dot(normal, normal) == 0.0 {
            return false;
        }
        let farthest: f64 = (0..3).map(|a| (normal[a] * (lo[a] - origin[a])).max(normal[a] * (hi[a] - origin[a]))).sum();
        farthest < -self.margin
    }

    /// Whether the ray meets the box around the moved triangles (padded by `margin`).
    fn reaches(&self, origin: &[f64; 3], direction: &[f64; 3], t_max: f64) -> bool {
        let Some([lo, hi]) = self.bounds else { return false };
        let (mut enter, mut exit) = (0.0f64, t_max);
        for a in 0..3 {
            let inverse = 1.0 / direction[a];
            let t0 = (lo[a] - self.margin - origin[a]) * inverse;
            let t1 = (hi[a] + self.margin - origin[a]) * inverse;
            enter = enter.max(t0.min(t1));
            exit = exit.min(t0.max(t1));
        }
        enter <= exit
    }

    /// Whether ray `r` of a static vertex escapes in the pose whose hierarchy is `pose`.
    ///
    /// A ray that misses the moved triangles as posed escapes in the pose iff it misses the
    /// static ones. When it escaped at rest it missed them (and the moved ones at rest), so
    /// the hierarchy at rest is asked only of rays blocked at rest, or not traced there yet:
    /// most rays escape, and this halves the small hierarchies' queries.
    fn outcome(&self, r: usize, rest: &mut RaysAtRest, pose: &OcclusionBvh, neutral: &OcclusionBvh, cast: &mut u64, reused: &mut u64) -> bool {
        let (direction, t_max, in_front) = rest.rays[r];
        if !in_front {
            *reused += 1;
            return false;
        }
        if !self.reaches(&rest.origin, &direction, t_max) {
            *reused += 1;
            return rest.neutral_outcome(r, neutral, cast);
        }
        if self.posed.any_hit(&rest.origin, &direction, t_max) {
            *reused += 1;
            return false;
        }
        if rest.escaped_at_rest(r) || !self.at_rest.any_hit(&rest.origin, &direction, t_max) {
            // Escaped at rest, or blocked at rest by static triangles alone (or not yet
            // traced: the neutral's outcome, traced now, is the pose's).
            *reused += 1;
            rest.neutral_outcome(r, neutral, cast)
        } else {
            *cast += 1;
            !pose.any_hit(&rest.origin, &direction, t_max)
        }
    }
}

/// One pose: positions, vertex normals and the four-wide hierarchy of its triangles (to be
/// traced).
struct PosedMesh {
    points: Vec<[f64; 3]>,
    normals: Vec<[f64; 3]>,
    bvh: OcclusionBvh,
}

/// A ray from a vertex: direction, end (`t` in the direction's units), and whether an
/// observer there could see the vertex at all (cameras behind the surface cannot).
type Ray = ([f64; 3], f64, bool);

/// A vertex's rays in the neutral pose and the outcomes traced so far (bit `i` of `known`,
/// and of `escaped` when the ray escaped): a vertex a shape does not touch has the same rays
/// in that pose.
#[derive(Default)]
struct RaysAtRest {
    origin: [f64; 3],
    rays: Vec<Ray>,
    known: Vec<u64>,
    escaped: Vec<u64>,
}

impl RaysAtRest {
    /// Whether ray `i` is known to escape in the neutral pose (traced there, and escaped).
    fn escaped_at_rest(&self, i: usize) -> bool {
        self.escaped[i / 64] & (1u64 << (i % 64)) != 0
    }

    /// Whether ray `i` escapes in the neutral pose, traced (and counted) the first time.
    fn neutral_outcome(&mut self, i: usize, neutral: &OcclusionBvh, cast: &mut u64) -> bool {
        let (word, bit) = (i / 64, 1u64 << (i % 64));
        if self.known[word] & bit == 0 {
            let (direction, t_max, in_front) = self.rays[i];
            *cast += 1;
            if in_front && !neutral.any_hit(&self.origin, &direction, t_max) {
                self.escaped[word] |= bit;
            }
            self.known[word] |= bit;
        }
        self.escaped[word] & bit != 0
    }
}

impl PosedMesh {
    /// The neutral pose, and its binary hierarchy (which the shaped poses refit).
    fn neutral(rig: &RigView) -> (Self, TriangleBvh) {
        let points = posed_points(rig, None);
        let normals = vertex_normals(&points, rig.triangles);
        let binary = TriangleBvh::build(&points, rig.triangles);
        let bvh = OcclusionBvh::new(&binary);
        (Self { points, normals, bvh }, binary)
    }

    /// Shape `shape` at weight 1: the neutral's hierarchies (`binary`, `wide`) refitted.
    fn shaped(rig: &RigView, shape: usize, binary: &TriangleBvh, wide: &OcclusionBvh) -> Self {
        let points = posed_points(rig, Some(shape));
        let normals = vertex_normals(&points, rig.triangles);
        let bvh = wide.refitted(binary.refitted(&points, rig.triangles));
        Self { points, normals, bvh }
    }

    /// The nudged origin and the lazy sequence of rays of vertex `v` in this pose (`lattice`:
    /// its hemisphere samples, [`hemisphere_lattice`]).
    fn rays<'s>(&self, v: u32, nudge: f64, sampling: &'s Sampling, lattice: &'s [Sample]) -> ([f64; 3], Box<dyn Iterator<Item = Ray> + 's>) {
        let normal = self.normals[v as usize];
        let origin: [f64; 3] = std::array::from_fn(|a| self.points[v as usize][a] + nudge * normal[a]);
        let rays: Box<dyn Iterator<Item = Ray>> = match sampling {
            Sampling::Hemisphere { .. } => Box::new(hemisphere_directions(normal, lattice).map(|d| (d, f64::INFINITY, true))),
            Sampling::Cameras(cameras) => Box::new(cameras.iter().map(move |camera| {
                let to_camera = sub(camera, &origin);
                // `t` runs from the vertex (0) to the camera (1): geometry behind the camera
                // is ignored.
                let in_front = dot(&normal, &to_camera) > 0.0 || dot(&normal, &normal) == 0.0;
                (to_camera, 1.0, in_front)
            })),
        };
        (origin, rays)
    }
}

/// `V0 + D_k` in f64 (the neutral for `None`).
fn posed_points(rig: &RigView, shape: Option<usize>) -> Vec<[f64; 3]> {
    let neutral = rig.neutral.iter().map(|p| p.map(f64::from));
    match shape {
        None => neutral.collect(),
        Some(k) => neutral
            .zip(rig.delta(k))
            .map(|(p, d)| std::array::from_fn(|a| p[a] + d[a] as f64))
            .collect(),
    }
}

/// Area-weighted vertex normals (the sum of the incident triangles' cross products),
/// normalised; zero where they vanish.
pub fn vertex_normals(points: &[[f64; 3]], triangles: &[[u32; 3]]) -> Vec<[f64; 3]> {
    let mut normals = vec![[0.0f64; 3]; points.len()];
    for tri in triangles {
        let [a, b, c] = tri.map(|v| points[v as usize]);
        let n = cross(&sub(&b, &a), &sub(&c, &a));
        for &v in tri {
            for axis in 0..3 {
                normals[v as usize][axis] += n[axis];
            }
        }
    }
    for n in &mut normals {
        let length = dot(n, n).sqrt();
        *n = if length > 0.0 { n.map(|x| x / length) } else { [0.0; 3] };
    }
    normals
}

/// The smallest escape count `e` with `e / total >= level`, computed as the callers compare.
fn escapes_needed(level: f64, total: usize) -> usize {
    let mut needed = ((level * total as f64).ceil() as usize).min(total);
    while needed > 0 && (needed - 1) as f64 / total as f64 >= level {
        needed -= 1;
    }
    while needed < total && (needed as f64 / total as f64) < level {
        needed += 1;
    }
    needed
}

/// One pose's `L` against `level` from a lazy sequence of `total` ray outcomes (`true` =
/// escaped), taking only the rays it needs: `level` as soon as enough rays escaped that
/// `L >= level`; below that `L` itself with `exact_below`, else as soon as `L < level` is
/// certain, some value below `level`. A level of 0 takes no ray.
fn pose_visibility(level: f64, total: usize, exact_below: bool, mut escapes: impl Iterator<Item = bool>) -> f64 {
    let needed = escapes_needed(level, total);
    let mut escaped = 0;
    for cast in 0..total {
        if escaped >= needed {
            return level;
        }
        if !exact_below && escaped + (total - cast) < needed {
            return (escaped + total - cast) as f64 / total as f64;
        }
        escaped += escapes.next().unwrap_or(false) as usize;
    }
    if escaped >= needed {
        level
    } else {
        escaped as f64 / total as f64
    }
}

/// One hemisphere sample: its stratum `u` of `sin^2 theta` and the cosine and sine of its
/// azimuth `phi`.
type Sample = [f64; 3];

/// `rays` samples of a jittered golden-ratio lattice (one stratum of `sin^2 theta` per ray)
/// drawn from ChaCha stream `stream` of `seed`. They do not depend on the pose, so a vertex
/// draws them once and each pose only turns them into its frame ([`hemisphere_directions`]):
/// the same directions as drawing them in every pose, without the random numbers and the
/// sine and cosine per ray and pose.
fn hemisphere_lattice(rays: usize, seed: u64, stream: u64) -> Vec<Sample> {
    const GOLDEN: f64 = 0.618_033_988_749_894_8;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    let rotation: f64 = rng.random();
    (0..rays)
        .map(|i| {
            let u = (i as f64 + rng.random::<f64>()) / rays as f64;
            let phi = std::f64::consts::TAU * (i as f64 * GOLDEN + rotation).fract();
            [u, phi.cos(), phi.sin()]
        })
        .collect()
}

/// The cosine-weighted directions of `lattice` around the unit `normal`; the whole sphere
/// when the normal is zero.
fn hemisphere_directions(normal: [f64; 3], lattice: &[Sample]) -> impl Iterator<Item = [f64; 3]> + '_ {
    let has_normal = dot(&normal, &normal) > 0.0;
    let (tangent, bitangent) = tangent_frame(&normal);
    lattice.iter().map(move |&[u, cos, sin]| {
        if has_normal {
            // Malley's method: uniform on the disc, lifted to the hemisphere.
            let (radius, height) = (u.sqrt(), (1.0 - u).sqrt());
            let (x, y) = (radius * cos, radius * sin);
            std::array::from_fn(|a| x * tangent[a] + y * bitangent[a] + height * normal[a])
        } else {
            let z = 1.0 - 2.0 * u;
            let radius = (1.0 - z * z).max(0.0).sqrt();
            [radius * cos, radius * sin, z]
        }
    })
}

/// Two unit vectors completing the unit `normal` to an orthonormal frame (Duff et al. 2017);
/// arbitrary axes for a zero normal.
fn tangent_frame(normal: &[f64; 3]) -> ([f64; 3], [f64; 3]) {
    let [x, y, z] = *normal;
    let sign = 1.0f64.copysign(z);
    let a = -1.0 / (sign + z);
    let b = x * y * a;
    ([1.0 + sign * x * x * a, sign * b, -sign * x], [b, sign + y * y * a, -y])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::NoProgress;

    /// An icosphere: the icosahedron subdivided `levels` times, projected to the sphere.
    pub(crate) fn icosphere(levels: usize, radius: f64, centre: [f64; 3]) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let t = (1.0 + 5f64.sqrt()) / 2.0;
        let mut points: Vec<[f64; 3]> = vec![
            [-1., t, 0.], [1., t, 0.], [-1., -t, 0.], [1., -t, 0.], [0., -1., t], [0., 1., t],
            [0., -1., -t], [0., 1., -t], [t, 0., -1.], [t, 0., 1.], [-t, 0., -1.], [-t, 0., 1.],
        ];
        let mut triangles: Vec<[u32; 3]> = vec![
            [0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
            [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
            [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1],
        ];
        for _ in 0..levels {
            let mut midpoints = std::collections::HashMap::new();
            let mut midpoint = |a: u32, b: u32, points: &mut Vec<[f64; 3]>| {
                *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    let (p, q) = (points[a as usize], points[b as usize]);
                    points.push(std::array::from_fn(|i| (p[i] + q[i]) / 2.0));
                    points.len() as u32 - 1
                })
            };
            triangles = triangles
                .iter()
                .flat_map(|&[a, b, c]| {
                    let (ab, bc, ca) = (midpoint(a, b, &mut points), midpoint(b, c, &mut points), midpoint(c, a, &mut points));
                    [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
                })
                .collect();
        }
        let points = points
            .iter()
            .map(|p| {
                let length = dot(p, p).sqrt();
                std::array::from_fn(|i| centre[i] + radius * p[i] / length)
            })
            .collect();
        (points, triangles)
    }

    /// A closed axis-aligned box of half-size `h` around the origin (12 triangles, outward).
    pub(crate) fn closed_box(h: f64) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let points = (0..8).map(|i| [(i & 1) as f64, (i >> 1 & 1) as f64, (i >> 2 & 1) as f64].map(|c| h * (2.0 * c - 1.0))).collect();
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        let triangles = quads.iter().flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]]).collect();
        (points, triangles)
    }

    fn to_rig_arrays(points: &[[f64; 3]]) -> Vec<[f32; 3]> {
        points.iter().map(|p| p.map(|c| c as f32)).collect()
    }

    /// A small sphere inside a closed box, plus the box itself.
    fn sphere_in_box() -> (Vec<[f32; 3]>, Vec<[u32; 3]>, usize) {
        let (mut points, mut triangles) = icosphere(2, 0.3, [0.1, 0.0, 0.0]);
        let inner = points.len();
        let (box_points, box_triangles) = closed_box(1.0);
        triangles.extend(box_triangles.iter().map(|t| t.map(|v| v + inner as u32)));
        points.extend(box_points);
        (to_rig_arrays(&points), triangles, inner)
    }

    /// Every vertex measured exactly.
    fn exact(rig: &RigView, shapes: &[usize], vertices: &[u32], sampling: &Sampling, reuse: bool) -> Visibility {
        worst_case_visibility(rig, shapes, vertices, &vec![Need::Exact; vertices.len()], sampling, reuse, &NoProgress).unwrap()
    }

    fn values(vis: &Visibility) -> Vec<f64> {
        vis.worst.iter().map(|s| s.exact().expect("measured exactly")).collect()
    }

    /// A pose's answer taken from the fewest rays equals the one from all of them: the
    /// minimum with the level when exact below it, the side of the level otherwise.
    #[test]
    fn stopping_early_keeps_the_answer() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for _ in 0..2000 {
            let total = rng.random_range(1..70);
            let outcomes: Vec<bool> = (0..total).map(|_| rng.random_bool(0.6)).collect();
            let level = [0.0, 1.0, 0.25, 0.3, rng.random::<f64>(), rng.random_range(0..=total) as f64 / total as f64][rng.random_range(0..6)];
            let full = outcomes.iter().filter(|&&o| o).count() as f64 / total as f64;
            let taken = std::cell::Cell::new(0);
            let counted = outcomes.iter().map(|&o| {
                taken.set(taken.get() + 1);
                o
            });
            let exact = pose_visibility(level, total, true, counted.clone());
            assert_eq!(exact, level.min(full), "{outcomes:?} at {level}");
            let sided = pose_visibility(level, total, false, outcomes.iter().copied());
            assert_eq!(sided >= level, full >= level, "{outcomes:?} at {level}: {sided}");
            if full < level {
                assert!(sided >= full, "an upper bound of the pose's value");
            }
            let needed = escapes_needed(level, total);
            assert!(needed as f64 / total as f64 >= level || needed == total);
            assert!(needed == 0 || ((needed - 1) as f64 / total as f64) < level);
            if level == 0.0 {
                taken.set(0);
                pose_visibility(level, total, true, counted);
                assert_eq!(taken.get(), 0, "a vertex at 0 casts nothing");
            }
        }
    }

    #[test]
    fn convex_sphere_is_fully_visible() {
        let (points, triangles) = icosphere(2, 1.0, [0.0; 3]);
        let points = to_rig_arrays(&points);
        let names = vec!["bulge".to_string()];
        let mut deltas = vec![[0.0f32; 3]; points.len()];
        deltas[0] = [0.0, 0.05, 0.0];
        let rig = RigView::new(&points, &deltas, &triangles, &names).unwrap();
        let vertices: Vec<u32> = (0..points.len() as u32).collect();
        let sampling = Sampling::Hemisphere { rays: 64, seed: 1 };
        let vis = exact(&rig, &[], &vertices, &sampling, true);
        assert!(values(&vis).iter().all(|&l| l == 1.0), "{:?}", vis.worst);
        assert_eq!(vis.rays_cast, 64 * points.len() as u64);
        // Cameras all around: a vertex sees the cameras in front of it, never those behind.
        let cameras: Vec<[f64; 3]> = icosphere(0, 5.0, [0.0; 3]).0;
        let vis = exact(&rig, &[], &vertices, &Sampling::Cameras(&cameras), true);
        assert!(values(&vis).iter().all(|&l| l > 0.0 && l < 1.0), "{:?}", &vis.worst[..5]);
    }

    #[test]
    fn enclosed_vertices_are_invisible() {
        let (points, triangles, inner) = sphere_in_box();
        let names: Vec<String> = vec![];
        let rig = RigView::new(&points, &[], &triangles, &names).unwrap();
        let vertices: Vec<u32> = (0..points.len() as u32).collect();
        let sampling = Sampling::Hemisphere { rays: 32, seed: 5 };
        let vis = values(&exact(&rig, &[], &vertices, &sampling, true));
        assert!(vis[..inner].iter().all(|&l| l == 0.0));
        // The box's own corners look outward onto nothing.
        assert!(vis[inner..].iter().all(|&l| l == 1.0));
        let cameras = [[0.0, 0.0, 3.0], [3.0, 0.0, 0.0]];
        let vis = values(&exact(&rig, &[], &vertices, &Sampling::Cameras(&cameras), true));
        assert!(vis[..inner].iter().all(|&l| l == 0.0));
    }

    /// A pose that slides a lid over a vertex makes its worst case (nearly) zero; the neutral
    /// alone, with the lid far to the side, does not.
    #[test]
    fn worst_case_takes_the_minimum_over_poses() {
        // A flat 3 x 3 patch (normal +z) and a wide lid 5 above it, 100 to the side.
        let mut points: Vec<[f32; 3]> = (0..9).map(|i| [(i % 3) as f32 - 1.0, (i / 3) as f32 - 1.0, 0.0]).collect();
        let mut triangles: Vec<[u32; 3]> =
            [0u32, 1, 3, 4].iter().flat_map(|&a| [[a, a + 1, a + 4], [a, a + 4, a + 3]]).collect();
        points.extend([[70.0, -30.0, 5.0], [130.0, -30.0, 5.0], [130.0, 30.0, 5.0], [70.0, 30.0, 5.0]]);
        triangles.extend([[9, 10, 11], [9, 11, 12]]);
        let mut deltas = vec![[0.0f32; 3]; points.len()];
        for d in &mut deltas[9..] {
            *d = [-100.0, 0.0, -4.9];
        }
        let names = vec!["lidDown".to_string()];
        let rig = RigView::new(&points, &deltas, &triangles, &names).unwrap();
        let sampling = Sampling::Hemisphere { rays: 64, seed: 0 };
        let neutral_only = exact(&rig, &[], &[4], &sampling, true);
        let with_pose = exact(&rig, &[0], &[4], &sampling, true);
        assert!(values(&neutral_only)[0] > 0.9, "{:?}", neutral_only.worst);
        assert!(values(&with_pose)[0] < 0.05, "{:?}", with_pose.worst);
        assert_eq!(with_pose.rays_cast + with_pose.rays_reused, 2 * 64);
        // The patch does not move: the lid's own triangles answer its rays in the pose.
        assert!(with_pose.rays_reused > 32, "{with_pose:?}");
    }

    #[test]
    fn same_result_on_one_thread_and_many() {
        let (points, triangles, _) = sphere_in_box();
        // Open the box's top so that visibility is fractional.
        let triangles: Vec<[u32; 3]> = triangles[..triangles.len() - 2].to_vec();
        let names: Vec<String> = vec![];
        let rig = RigView::new(&points, &[], &triangles, &names).unwrap();
        let vertices: Vec<u32> = (0..points.len() as u32).collect();
        let sampling = Sampling::Hemisphere { rays: 16, seed: 9 };
        let run = || exact(&rig, &[], &vertices, &sampling, true);
        let serial = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap().install(run);
        let parallel = rayon::ThreadPoolBuilder::new().num_threads(4).build().unwrap().install(run);
        assert_eq!(serial, parallel);
        assert!(values(&serial).iter().any(|&l| l > 0.0 && l < 1.0), "the test needs partial visibility");
    }

    /// Reusing the neutral's outcomes where a pose does not touch a vertex, and asking only
    /// a threshold of some vertices, give exactly the answer of tracing every ray through
    /// every pose, on random lumpy meshes whose shapes push random caps far out (so that
    /// they shadow the static part), in both modes.
    #[test]
    fn pruned_and_reused_equal_the_full_computation_on_random_meshes() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
        let mut sides = [0usize; 2];
        for trial in 0..6 {
            let (sphere, triangles) = icosphere(2, 1.0, [0.0; 3]);
            let points: Vec<[f64; 3]> = sphere.iter().map(|p| p.map(|c| c * (1.0 + 0.25 * rng.random::<f64>()))).collect();
            let n = points.len();
            let k_count = 4;
            let mut deltas = vec![[0.0f32; 3]; k_count * n];
            let names: Vec<String> = (0..k_count).map(|k| format!("cap{k}")).collect();
            for k in 0..k_count {
                let centre = sphere[rng.random_range(0..n)];
                let reach = rng.random_range(0.3..0.8);
                let push = rng.random_range(-0.6..1.5);
                for v in 0..n {
                    let d: f64 = (0..3).map(|a| (sphere[v][a] - centre[a]).powi(2)).sum::<f64>().sqrt();
                    if d < reach {
                        deltas[k * n + v] = sphere[v].map(|c| (c * push * (1.0 - d / reach)) as f32);
                    }
                }
            }
            let points = to_rig_arrays(&points);
            let rig = RigView::new(&points, &deltas, &triangles, &names).unwrap();
            let vertices: Vec<u32> = (0..n as u32).step_by(2).collect();
            let needs: Vec<Need> =
                vertices.iter().map(|_| if rng.random_bool(0.5) { Need::Exact } else { Need::AtLeast(rng.random_range(0.05..0.6)) }).collect();
            let cameras: Vec<[f64; 3]> = icosphere(0, 4.0, [0.3, 0.1, 0.0]).0;
            let modes = [Sampling::Hemisphere { rays: 40, seed: trial }, Sampling::Cameras(&cameras)];
            for sampling in &modes {
                let shapes: Vec<usize> = (0..k_count).collect();
                let full = exact(&rig, &shapes, &vertices, sampling, false);
                let reused = exact(&rig, &shapes, &vertices, sampling, true);
                assert_eq!(full.worst, reused.worst, "trial {trial} {sampling:?}");
                assert_eq!(full.rays_reused, 0);
                assert!(reused.rays_reused > 0 && reused.rays_cast < full.rays_cast, "{reused:?} vs {full:?}");
                assert!(values(&full).iter().any(|&l| l > 0.0 && l < 1.0), "the test needs partial visibility");
                for reuse in [false, true] {
                    let pruned = worst_case_visibility(&rig, &shapes, &vertices, &needs, sampling, reuse, &NoProgress).unwrap();
                    assert!(pruned.rays_cast < full.rays_cast);
                    for ((need, seen), l) in needs.iter().zip(&pruned.worst).zip(values(&full)) {
                        match *need {
                            Need::Exact => assert_eq!(*seen, Seen::Exact(l)),
                            Need::AtLeast(t) => {
                                assert_eq!(seen.at_least(t), Some(l >= t), "{seen:?} against {l}");
                                sides[(l >= t) as usize] += 1;
                            }
                        }
                    }
                }
            }
        }
        assert!(sides.iter().all(|&s| s > 20), "the test needs vertices on both sides of their thresholds: {sides:?}");
    }
}
