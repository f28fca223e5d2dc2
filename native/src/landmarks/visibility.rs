//! Global visibility, Eq. (4) of Zell & McDonnell 2022: per pose, the fraction of directions
//! in which a vertex can be seen (ambient-occlusion style), and its worst case over poses
//! `l[n] = min_k L_k[n]`. SPEC section 2.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;

use crate::geometry::bvh::{cross, dot, sub, TriangleBvh};
use crate::error::ShapesmithResult;
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

#[derive(Clone, Debug, PartialEq)]
pub struct Visibility {
    /// `l[n]` for each requested vertex, in the order given.
    pub worst: Vec<f64>,
    /// Rays traced through a whole posed mesh.
    pub rays_cast: u64,
    /// Rays of a shaped pose answered from the neutral's outcome or by the moving region's
    /// triangles alone, without tracing the whole pose.
    pub rays_reused: u64,
}

/// `l[n] = min_k L_k[n]` (Eq. 4) over the neutral pose and each of `shapes` at weight 1, for
/// each of `vertices`.
///
/// Hemisphere mode casts `rays` rays per vertex and pose: a jittered golden-ratio lattice
/// mapped to cosine-weighted directions (one stratum of `sin^2 theta` per ray), so that the
/// grazing directions from which a tracker cannot see a point count least. Each vertex draws
/// from its own ChaCha stream of `seed` (the same in every pose): results do not depend on
/// the number of threads. Camera mode counts a camera as seeing the vertex when it lies in
/// front (`n . (c - p) > 0`) and the segment to it is unobstructed.
///
/// A vertex whose posed normal vanishes (no triangle, or triangles that cancel) has no
/// hemisphere: it is sampled over the whole sphere, and every camera counts as in front.
///
/// Work saved, with the same answer as tracing every ray through every pose (`reuse =
/// false`; the tests compare the two):
/// - A pose stops casting for a vertex once it cannot lower that vertex's minimum, and a
///   vertex already at 0 casts nothing.
/// - Reuse across poses. A shape moves a small part of the head. In pose k the triangles
///   split into static ones (identical corners to the neutral's) and moved ones. A vertex
///   none of whose triangles moves has the neutral's origin, normal and so rays. Its ray is
///   blocked in pose k iff it meets a static triangle or a moved triangle as posed; in the
///   neutral iff it meets a static one or a moved one at rest. So: blocked if it meets the
///   posed moved triangles (a small BVH); else the neutral's outcome if it misses the moved
///   triangles at rest too (another small BVH); only otherwise is the whole pose traced.
pub fn worst_case_visibility(
    rig: &RigView,
    shapes: &[usize],
    vertices: &[u32],
    sampling: &Sampling,
    reuse: bool,
    progress: &dyn Progress,
) -> ShapesmithResult<Visibility> {
    let nudge = NUDGE_FRACTION * rig.bbox_diagonal();
    let mut worst = vec![1.0f64; vertices.len()];
    let (mut rays_cast, mut rays_reused) = (0u64, 0u64);
    let poses = shapes.len() + 1;
    progress.checkpoint(0.0)?;
    let neutral = PosedMesh::new(rig, None, None);
    // The neutral pose traces every ray and keeps the rays and their outcomes.
    let at_rest: Vec<RaysAtRest> = vertices.par_iter().map(|&v| neutral.outcomes(v, nudge, sampling)).collect();
    let total = sampling.rays_per_vertex();
    for (w, rest) in worst.iter_mut().zip(&at_rest) {
        let bits = &rest.escaped;
        *w = bits.iter().map(|b| b.count_ones() as f64).sum::<f64>() / total as f64;
        rays_cast += total as u64;
    }
    // Shaped poses refit the neutral's hierarchy: a shape moves a small part of the head, so
    // the boxes stay tight, and a refit costs far less than a build.
    let posed = |i: usize| shapes.get(i).map(|&k| PosedMesh::new(rig, Some(k), Some(&neutral.bvh)));
    let mut next = posed(0);
    for (i, &shape) in shapes.iter().enumerate() {
        progress.checkpoint((i + 1) as f64 / poses as f64)?;
        let Some(mesh) = next.take() else { break };
        let region = reuse.then(|| MovingRegion::new(rig, shape, &neutral.points, &mesh.points));
        let (per_vertex, prepared) = rayon::join(
            || {
                vertices
                    .par_iter()
                    .zip(&worst)
                    .zip(&at_rest)
                    .map(|((&v, &current), rest)| match &region {
                        Some(region) if region.is_static(v) => lower_visibility_reusing(&mesh, current, total, region, rest),
                        _ => (mesh.lower_visibility(v, current, nudge, sampling), 0),
                    })
                    .collect::<Vec<((f64, u64), u64)>>()
            },
            || posed(i + 1),
        );
        next = prepared;
        for (w, ((fraction, cast), reused)) in worst.iter_mut().zip(per_vertex) {
            *w = fraction;
            rays_cast += cast;
            rays_reused += reused;
        }
    }
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

/// The triangles shape k moves, at rest and posed, and the vertices none of whose
/// triangles moves (so their rays are the neutral's).
struct MovingRegion {
    at_rest: TriangleBvh,
    posed: TriangleBvh,
    touched: Vec<bool>,
}

impl MovingRegion {
    fn new(rig: &RigView, shape: usize, rest: &[[f64; 3]], posed: &[[f64; 3]]) -> Self {
        let delta = rig.delta(shape);
        let mut touched: Vec<bool> = delta.iter().map(|d| *d != [0.0; 3]).collect();
        let moved: Vec<[u32; 3]> = rig.triangles.iter().filter(|t| t.iter().any(|&v| touched[v as usize])).copied().collect();
        for t in &moved {
            for &v in t {
                touched[v as usize] = true;
            }
        }
        Self { at_rest: TriangleBvh::build(rest, &moved), posed: TriangleBvh::build(posed, &moved), touched }
    }

    fn is_static(&self, v: u32) -> bool {
        !self.touched[v as usize]
    }
}

/// One pose: positions, vertex normals and the BVH of its triangles.
struct PosedMesh {
    points: Vec<[f64; 3]>,
    normals: Vec<[f64; 3]>,
    bvh: TriangleBvh,
}

/// A ray from a vertex: direction, end (`t` in the direction's units), and whether an
/// observer there could see the vertex at all (cameras behind the surface cannot).
type Ray = ([f64; 3], f64, bool);

/// A vertex's rays in the neutral pose and which of them escaped (bit `i` of `escaped`):
/// a vertex a shape does not touch has the same rays in that pose.
struct RaysAtRest {
    origin: [f64; 3],
    rays: Vec<Ray>,
    escaped: Vec<u64>,
}

impl PosedMesh {
    /// The pose's points, normals and hierarchy: built, or `base` refitted.
    fn new(rig: &RigView, shape: Option<usize>, base: Option<&TriangleBvh>) -> Self {
        let points = posed_points(rig, shape);
        let normals = vertex_normals(&points, rig.triangles);
        let bvh = match base {
            Some(base) => base.refitted(&points, rig.triangles),
            None => TriangleBvh::build(&points, rig.triangles),
        };
        Self { points, normals, bvh }
    }

    /// The nudged origin and the lazy sequence of rays of vertex `v` in this pose.
    fn rays<'s>(&self, v: u32, nudge: f64, sampling: &'s Sampling) -> ([f64; 3], Box<dyn Iterator<Item = Ray> + 's>) {
        let normal = self.normals[v as usize];
        let origin: [f64; 3] = std::array::from_fn(|a| self.points[v as usize][a] + nudge * normal[a]);
        let rays: Box<dyn Iterator<Item = Ray>> = match sampling {
            Sampling::Hemisphere { rays, seed } => {
                Box::new(hemisphere_directions(&normal, *rays, *seed, v as u64).map(|d| (d, f64::INFINITY, true)))
            }
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

    /// Every ray of vertex `v` and its outcome.
    fn outcomes(&self, v: u32, nudge: f64, sampling: &Sampling) -> RaysAtRest {
        let mut escaped = vec![0u64; sampling.rays_per_vertex().div_ceil(64)];
        let (origin, rays) = self.rays(v, nudge, sampling);
        let rays: Vec<Ray> = rays.collect();
        for (i, (direction, t_max, in_front)) in rays.iter().enumerate() {
            if *in_front && !self.bvh.any_hit(&origin, direction, *t_max) {
                escaped[i / 64] |= 1u64 << (i % 64);
            }
        }
        RaysAtRest { origin, rays, escaped }
    }

    /// `min(current, L[v])` for this pose, and the rays it took.
    fn lower_visibility(&self, v: u32, current: f64, nudge: f64, sampling: &Sampling) -> (f64, u64) {
        let (origin, rays) = self.rays(v, nudge, sampling);
        let seen = rays.map(|(direction, t_max, in_front)| in_front && !self.bvh.any_hit(&origin, &direction, t_max));
        lower_visibility(current, sampling.rays_per_vertex(), seen)
    }
}

/// [`PosedMesh::lower_visibility`] for a vertex the pose does not touch: its rays are the
/// neutral's, and those that miss the moving region take the neutral's outcome (see
/// [`worst_case_visibility`]). Returns the result with the rays traced through the whole
/// pose, and the rays answered without.
fn lower_visibility_reusing(mesh: &PosedMesh, current: f64, total: usize, region: &MovingRegion, rest: &RaysAtRest) -> ((f64, u64), u64) {
    let origin = &rest.origin;
    let traced = std::cell::Cell::new(0u64);
    let seen = rest.rays.iter().enumerate().map(|(i, (direction, t_max, in_front))| {
        if !in_front || region.posed.any_hit(origin, direction, *t_max) {
            false
        } else if !region.at_rest.any_hit(origin, direction, *t_max) {
            rest.escaped[i / 64] >> (i % 64) & 1 == 1
        } else {
            traced.set(traced.get() + 1);
            !mesh.bvh.any_hit(origin, direction, *t_max)
        }
    });
    let (fraction, taken) = lower_visibility(current, total, seen);
    ((fraction, traced.get()), taken - traced.get())
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

/// `min(current, escaped / total)` from a lazy sequence of `total` ray outcomes (`true` =
/// escaped), and how many rays it took. Exact, but stops as soon as enough rays escape that
/// this pose cannot lower the minimum; a vertex already at 0 casts nothing.
fn lower_visibility(current: f64, total: usize, mut escapes: impl Iterator<Item = bool>) -> (f64, u64) {
    // Reaching `needed` escapes means `escaped / total >= current`.
    let needed = (current * total as f64).ceil() as usize;
    let mut escaped = 0;
    for cast in 0..total {
        if escaped >= needed {
            return (current, cast as u64);
        }
        escaped += escapes.next().unwrap_or(false) as usize;
    }
    if escaped >= needed {
        (current, total as u64)
    } else {
        (escaped as f64 / total as f64, total as u64)
    }
}

/// `rays` cosine-weighted directions around the unit `normal`: a jittered golden-ratio
/// lattice (one stratum of `sin^2 theta` per ray) drawn from ChaCha stream `stream` of `seed`;
/// the whole sphere when the normal is zero.
fn hemisphere_directions(normal: &[f64; 3], rays: usize, seed: u64, stream: u64) -> impl Iterator<Item = [f64; 3]> {
    const GOLDEN: f64 = 0.618_033_988_749_894_8;
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    rng.set_stream(stream);
    let rotation: f64 = rng.random();
    let normal = *normal;
    let has_normal = dot(&normal, &normal) > 0.0;
    let (tangent, bitangent) = tangent_frame(&normal);
    (0..rays).map(move |i| {
        let u = (i as f64 + rng.random::<f64>()) / rays as f64;
        let phi = std::f64::consts::TAU * (i as f64 * GOLDEN + rotation).fract();
        if has_normal {
            // Malley's method: uniform on the disc, lifted to the hemisphere.
            let (radius, height) = (u.sqrt(), (1.0 - u).sqrt());
            let (x, y) = (radius * phi.cos(), radius * phi.sin());
            std::array::from_fn(|a| x * tangent[a] + y * bitangent[a] + height * normal[a])
        } else {
            let z = 1.0 - 2.0 * u;
            let radius = (1.0 - z * z).max(0.0).sqrt();
            [radius * phi.cos(), radius * phi.sin(), z]
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

    /// Stopping early gives exactly `min(current, escaped / total)`, and never more rays.
    #[test]
    fn early_stop_is_exact() {
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        for _ in 0..500 {
            let total = rng.random_range(1..40);
            let outcomes: Vec<bool> = (0..total).map(|_| rng.random_bool(0.6)).collect();
            let current = [0.0, 1.0, rng.random::<f64>()][rng.random_range(0..3)];
            let full = outcomes.iter().filter(|&&o| o).count() as f64 / total as f64;
            let (got, cast) = lower_visibility(current, total, outcomes.iter().copied());
            assert_eq!(got, current.min(full), "{outcomes:?} from {current}");
            assert!(cast <= total as u64);
            if current == 0.0 {
                assert_eq!(cast, 0);
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
        let vis = worst_case_visibility(&rig, &[], &vertices, &sampling, true, &NoProgress).unwrap();
        assert!(vis.worst.iter().all(|&l| l == 1.0), "min {:?}", vis.worst.iter().cloned().fold(1.0, f64::min));
        assert_eq!(vis.rays_cast, 64 * points.len() as u64);
        // Cameras all around: a vertex sees the cameras in front of it, never those behind.
        let cameras: Vec<[f64; 3]> = icosphere(0, 5.0, [0.0; 3]).0;
        let vis = worst_case_visibility(&rig, &[], &vertices, &Sampling::Cameras(&cameras), true, &NoProgress).unwrap();
        assert!(vis.worst.iter().all(|&l| l > 0.0 && l < 1.0), "{:?}", &vis.worst[..5]);
    }

    #[test]
    fn enclosed_vertices_are_invisible() {
        let (points, triangles, inner) = sphere_in_box();
        let names: Vec<String> = vec![];
        let rig = RigView::new(&points, &[], &triangles, &names).unwrap();
        let vertices: Vec<u32> = (0..points.len() as u32).collect();
        let sampling = Sampling::Hemisphere { rays: 32, seed: 5 };
        let vis = worst_case_visibility(&rig, &[], &vertices, &sampling, true, &NoProgress).unwrap();
        assert!(vis.worst[..inner].iter().all(|&l| l == 0.0));
        // The box's own corners look outward onto nothing.
        assert!(vis.worst[inner..].iter().all(|&l| l == 1.0));
        let cameras = [[0.0, 0.0, 3.0], [3.0, 0.0, 0.0]];
        let vis = worst_case_visibility(&rig, &[], &vertices, &Sampling::Cameras(&cameras), true, &NoProgress).unwrap();
        assert!(vis.worst[..inner].iter().all(|&l| l == 0.0));
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
        let neutral_only = worst_case_visibility(&rig, &[], &[4], &sampling, true, &NoProgress).unwrap();
        let with_pose = worst_case_visibility(&rig, &[0], &[4], &sampling, true, &NoProgress).unwrap();
        assert!(neutral_only.worst[0] > 0.9, "{:?}", neutral_only.worst);
        assert!(with_pose.worst[0] < 0.05, "{:?}", with_pose.worst);
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
        let run = || worst_case_visibility(&rig, &[], &vertices, &sampling, true, &NoProgress).unwrap();
        let serial = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap().install(run);
        let parallel = rayon::ThreadPoolBuilder::new().num_threads(4).build().unwrap().install(run);
        assert_eq!(serial, parallel);
        assert!(serial.worst.iter().any(|&l| l > 0.0 && l < 1.0), "the test needs partial visibility");
    }

    /// Reusing the neutral's outcomes where a pose does not touch a vertex gives exactly the
    /// answer of tracing every ray through every pose, on random lumpy meshes whose shapes
    /// push random caps far out (so that they shadow the static part), in both modes.
    #[test]
    fn reuse_equals_the_full_computation_on_random_meshes() {
        let mut rng = ChaCha8Rng::seed_from_u64(8);
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
            let cameras: Vec<[f64; 3]> = icosphere(0, 4.0, [0.3, 0.1, 0.0]).0;
            let modes = [Sampling::Hemisphere { rays: 40, seed: trial }, Sampling::Cameras(&cameras)];
            for sampling in &modes {
                let shapes: Vec<usize> = (0..k_count).collect();
                let full = worst_case_visibility(&rig, &shapes, &vertices, sampling, false, &NoProgress).unwrap();
                let reused = worst_case_visibility(&rig, &shapes, &vertices, sampling, true, &NoProgress).unwrap();
                assert_eq!(full.worst, reused.worst, "trial {trial} {sampling:?}");
                assert_eq!(full.rays_reused, 0);
                assert!(reused.rays_reused > 0 && reused.rays_cast < full.rays_cast, "{reused:?} vs {full:?}");
                assert!(full.worst.iter().any(|&l| l > 0.0 && l < 1.0), "the test needs partial visibility");
            }
        }
    }
}
