//! The symmetric wrap on synthetic heads: a lumpy ellipsoid with a lump either side of the
//! plane x = 0 (vertex-symmetric: its segments mirror onto segments), wrapped onto the same
//! surface warped symmetrically, sampled by other rings and segments turned off the plane (no
//! vertex has a mirror vertex), in other units and axes. Truths by construction: the
//! character's plane is the image of x = 0, the template's mirror map is found by brute force.

use super::tests::{as_f32, rotation, sphere_mesh};
use super::*;
use crate::geometry::closest_point::SurfacePoint;
use crate::geometry::mat3::dot;
use crate::progress::NoProgress;

/// The bound on a carried pair's miss: this many times the template's own miss (its Right
/// misses the mirror of its Left by up to 10% by construction, its Centre 0) plus the
/// measure's floor on the character (the same keys' image interpolated twice across its
/// triangles).
const MISS_FACTOR: f64 = 1.5;

/// A lumpy ellipsoid, `rings` bands by `segments`, the segments turned by `phase`; a broad
/// lump of 0.2 at each direction of `lumps`.
fn lumpy(rings: usize, segments: usize, phase: f64, lumps: &[Vec3]) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let surface = |theta: f64, phi: f64| -> Vec3 {
        let u = [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()];
        let r = 1.0 + lumps.iter().map(|l| 0.2 * (-(0..3).map(|a| (u[a] - l[a] / length(*l)).powi(2)).sum::<f64>() / 0.5).exp()).sum::<f64>();
        [1.5 * r * u[0], 1.0 * r * u[1], 0.7 * r * u[2]]
    };
    sphere_mesh(rings, segments, phase, surface)
}

const BOTH_SIDES: [Vec3; 2] = [[0.5, 0.6, 0.62], [-0.5, 0.6, 0.62]];

/// A symmetric change of identity (x -> -x maps it onto itself).
fn warp(p: Vec3) -> Vec3 {
    [p[0] * (1.0 + 0.1 * p[1]), 1.15 * p[1] + 0.1 * p[0] * p[0], 0.9 * p[2] + 0.08 * (2.0 * p[0]).cos()]
}

fn mirror_x(p: Vec3) -> Vec3 {
    [-p[0], p[1], p[2]]
}

fn bump(p: Vec3, centre: Vec3) -> f64 {
    (1.0 - length(sub(p, centre)).powi(2) / 0.5).max(0.0).powi(3)
}

/// Left (a bump on the +x side), Right (Left's mirror, 5% off it by a tilt), Centre (on the
/// plane, symmetric): K x N deltas, shape-major.
fn shapes(points: &[Vec3]) -> Vec<[f32; 3]> {
    let left = |p: Vec3| -> Vec3 { [0.1, 0.05, 0.08].map(|x| x * bump(p, [0.9, 0.3, 0.45])) };
    let right = |p: Vec3| -> Vec3 { mirror_x(left(mirror_x(p))).map(|x| x * (1.0 + 0.1 * p[1])) };
    let centre = |p: Vec3| -> Vec3 { [0.1 * p[0], 0.08, 0.05].map(|x| x * bump(p, [0.0, 0.6, 0.5])) };
    let fields: [&dyn Fn(Vec3) -> Vec3; 3] = [&left, &right, &centre];
    fields.iter().flat_map(|f| points.iter().map(move |p| f(*p).map(|x| x as f32))).collect()
}

/// The template's mirror vertex of each vertex, by brute force.
fn brute_partner(points: &[Vec3]) -> Vec<usize> {
    points
        .iter()
        .map(|p| (0..points.len()).min_by(|&a, &b| length(sub(points[a], mirror_x(*p))).total_cmp(&length(sub(points[b], mirror_x(*p))))).unwrap())
        .collect()
}

struct Chain {
    character: Vec<Vec3>,
    character_triangles: Vec<[u32; 3]>,
    wrap: Wrap,
    carried: CarryResult,
    plane: MirrorPlane,
    template_miss: [f64; 2],
}

/// The template wrapped onto the character built with `character_lumps`, its shapes (moved
/// into the character's frame) carried, with the template's rest given to the carry or not.
fn chain(character_lumps: &[Vec3], symmetric_carry: bool) -> Chain {
    let (template, triangles) = lumpy(16, 32, 0.0, &BOTH_SIDES);
    let (dense, dense_triangles) = lumpy(31, 63, 0.3, character_lumps);
    let motion = Similarity { rotation: rotation(1.9, -0.6), scale: 100.0, translation: [5.0, -30.0, 12.0] };
    let character: Vec<Vec3> = dense.iter().map(|p| motion.apply(warp(*p))).collect();
    let picked = [0usize, 40, 77, 130, 200, 260, 300, 401, 455];
    let pair_template = as_f32(&picked.iter().map(|&v| template[v]).collect::<Vec<_>>());
    // Each pair's character point: where the warp takes the template vertex, on the character's
    // surface (a character without the template's second lump has none there).
    let surface = TriangleBvh::build(&character, &dense_triangles);
    let on_character = |p: Vec3| surface.closest_point(&p, f64::INFINITY).unwrap().point;
    let pair_character = as_f32(&picked.iter().map(|&v| on_character(motion.apply(warp(template[v])))).collect::<Vec<_>>());
    let pairs = PointPairs { template: &pair_template, character: &pair_character };
    let wrap = wrap_template(&as_f32(&template), &triangles, &as_f32(&character), &dense_triangles, pairs, &WrapParams::default(), &NoProgress).unwrap();
    let deltas = shapes(&template);
    let partner = brute_partner(&template);
    let n = template.len();
    let field = |k: usize| -> Vec<Vec3> { deltas[k * n..(k + 1) * n].iter().map(to_f64).collect() };
    let template_miss = [(0, 1), (2, 2)].map(|(a, b)| {
        let (a, b) = (field(a), field(b));
        let largest = a.iter().chain(&b).map(|d| length(*d)).fold(0.0, f64::max);
        (0..n).map(|v| length(sub(mirror_x(a[partner[v]]), b[v]))).fold(0.0, f64::max) / largest
    });
    let moved: Vec<[f32; 3]> = deltas.iter().map(|d| crate::geometry::mat3::mat_vec(&motion.rotation, to_f64(d)).map(|x| (x * motion.scale) as f32)).collect();
    let carried = carry_shapes(
        &wrap.wrapped,
        &triangles,
        &moved,
        &as_f32(&character),
        &dense_triangles,
        None,
        symmetric_carry.then_some(&as_f32(&template)[..]),
        None,
        &CarryParams::default(),
        &NoProgress,
    )
    .unwrap();
    let plane = MirrorPlane { point: motion.translation, normal: crate::geometry::mat3::mat_vec(&motion.rotation, [1.0, 0.0, 0.0]) };
    Chain { character, character_triangles: dense_triangles, wrap, carried, plane, template_miss }
}

/// The worst vertex's miss between the mirror of carried shape `a` and shape `b` on the
/// character, across the true plane, each vertex's image at its closest surface point; and the
/// measure's floor: the worst miss of either shape against its mirror mirrored.
fn carried_miss(chain: &Chain, a: usize, b: usize) -> (f64, f64) {
    let nc = chain.character.len();
    let bvh = TriangleBvh::build(&chain.character, &chain.character_triangles);
    let images: Vec<SurfacePoint> = chain.character.iter().map(|p| bvh.closest_point(&chain.plane.reflect(*p), f64::INFINITY).unwrap()).collect();
    let mirrored = |f: &[Vec3]| -> Vec<Vec3> {
        images
            .iter()
            .map(|hit| {
                let t = chain.character_triangles[hit.triangle as usize];
                chain.plane.reflect_vector((0..3).fold([0.0; 3], |acc, i| add(acc, f[t[i] as usize].map(|x| x * hit.barycentric[i]))))
            })
            .collect()
    };
    let field = |k: usize| -> Vec<Vec3> { chain.carried.deltas[k * nc..(k + 1) * nc].iter().map(to_f64).collect() };
    let (a, b) = (field(a), field(b));
    let largest = a.iter().chain(&b).map(|d| length(*d)).fold(0.0, f64::max);
    let worst = |x: &[Vec3], y: &[Vec3]| x.iter().zip(y).map(|(p, q)| length(sub(*p, *q))).fold(0.0, f64::max) / largest;
    let floor = worst(&mirrored(&mirrored(&a)), &a).max(worst(&mirrored(&mirrored(&b)), &b));
    (worst(&mirrored(&a), &b), floor)
}

#[test]
fn a_symmetric_template_on_a_symmetric_character_of_other_topology_carries_mirrored_pairs() {
    let symmetric = chain(&BOTH_SIDES, true);
    let report = &symmetric.wrap.report.symmetry;
    assert!(report.symmetric && report.reason.is_empty(), "{report:?}");
    assert_eq!(report.template_axis, 0);
    // The character's plane is found: the image of x = 0, within a degree and 0.1% of the
    // diagonal (measured: 0.45 degrees; the 15% stretch and shear of the warp turn the plane the
    // pairs' similarity carries by more than the refinement takes back, so it is found on the
    // fitted template, without mirrored pairs).
    let plane = report.plane.unwrap();
    assert!(dot(plane.normal, symmetric.plane.normal).abs() > 1f64.to_radians().cos(), "{plane:?} vs {:?}", symmetric.plane);
    let diagonal = symmetric.wrap.report.diagonal;
    assert!(dot(sub(plane.point, symmetric.plane.point), symmetric.plane.normal).abs() < 1e-3 * diagonal, "{plane:?}");
    assert!(symmetric.wrap.report.mean_distance < 3e-3, "{}", symmetric.wrap.report.mean_distance);
    let carry = symmetric.carried.symmetry.as_ref().unwrap();
    assert!(carry.symmetric, "{carry:?}");
    let found: Vec<(usize, usize)> = carry.shapes.iter().map(|m| (m.first, m.second)).collect();
    assert_eq!(found, vec![(0, 1), (2, 2)]);
    // The carried pair and the self-symmetric shape mirror each other within MISS_FACTOR times
    // the template's own miss plus the measure's floor.
    let plain = chain(&BOTH_SIDES, false);
    let mut broken = 0;
    for (k, (a, b)) in [(0, 1), (2, 2)].into_iter().enumerate() {
        let ((miss, floor), (plain_miss, _)) = (carried_miss(&symmetric, a, b), carried_miss(&plain, a, b));
        let template = symmetric.template_miss[k];
        println!("shapes {a}/{b}: carried miss {miss:.4}, without the symmetric carry {plain_miss:.4}, template {template:.4}, floor {floor:.4}, report {:?}", carry.shapes[k]);
        assert!(miss <= MISS_FACTOR * (template + floor), "shapes {a}/{b}: carried miss {miss}, template {template}, floor {floor}");
        broken += usize::from(plain_miss > MISS_FACTOR * (template + floor));
    }
    // Measured: without the symmetric carry the Centre misses 11.8% against a bound of 7.9%.
    assert!(broken > 0, "the carry without symmetry meets the bound too");
}

#[test]
fn an_asymmetric_character_is_wrapped_and_carried_as_before_and_says_so() {
    let asymmetric = chain(&BOTH_SIDES[..1], true);
    let report = &asymmetric.wrap.report.symmetry;
    assert!(!report.symmetric && report.reason.contains("character is not mirror-symmetric"), "{report:?}");
    assert_eq!(report.mirrored_pairs, 0);
    assert!(asymmetric.wrap.report.mean_distance < 5e-3, "{}", asymmetric.wrap.report.mean_distance);
    let carry = asymmetric.carried.symmetry.as_ref().unwrap();
    assert!(!carry.symmetric && carry.shapes.is_empty(), "{carry:?}");
    // The carry is today's, bit for bit.
    let plain = chain(&BOTH_SIDES[..1], false);
    assert_eq!(asymmetric.carried.deltas, plain.carried.deltas);
    assert!(plain.carried.symmetry.is_none());
}

#[test]
fn each_average_with_the_mirror_leaves_less_of_what_a_surface_mirror_misses() {
    // A strip across the plane x = 0 whose columns do not mirror onto columns, so mirroring
    // twice interpolates twice and is not the identity; a self-symmetric shape's field, a
    // lump off the plane with a kink, misses its own mirror. One average leaves
    // `(d - M M d) / 2`; each further one leaves less, towards a field the surface mirror
    // maps onto itself.
    let xs = [-1.0, -0.86, -0.61, -0.47, -0.22, -0.09, 0.13, 0.31, 0.44, 0.68, 0.93, 1.0];
    let points: Vec<Vec3> = [0.0, 1.0].iter().flat_map(|&y| xs.iter().map(move |&x| [x, y, 0.0])).collect();
    let columns = xs.len() as u32;
    let triangles: Vec<[u32; 3]> = (0..columns - 1).flat_map(|i| [[i, i + 1, columns + i], [i + 1, columns + i + 1, columns + i]]).collect();
    let plane = MirrorPlane { point: [0.0; 3], normal: [1.0, 0.0, 0.0] };
    let bvh = TriangleBvh::build(&points, &triangles);
    let images: Vec<Option<SurfacePoint>> = points.iter().map(|p| bvh.closest_point(&plane.reflect(*p), f64::INFINITY)).collect();
    let mirror = symmetry::SurfaceMirror { plane, images, triangles: &triangles };
    let field: Vec<Vec3> = points.iter().map(|p| [0.05 * p[0], 0.0, (1.0 - (p[0] - 0.2).abs() / 0.5).max(0.0)]).collect();
    let mut deltas = vec![field];
    let mut is_static = vec![vec![false; points.len()]];
    let miss = |deltas: &[Vec<Vec3>]| symmetry::worst_miss(&deltas[0], &deltas[0], |f, v| mirror.mirrored(f, v));
    let mut misses = vec![miss(&deltas)];
    for _ in 0..symmetry::MIRROR_AVERAGE_ROUNDS {
        symmetry::average_with_mirror(&mut deltas, &mut is_static, &[(0, 0)], &mirror);
        misses.push(miss(&deltas));
    }
    println!("worst-vertex misses, before and after each average: {misses:?}");
    assert!(misses[1] > 0.05 * misses[0], "the strip mirrors exactly: {misses:?}");
    assert!(misses.windows(2).all(|w| w[1] < w[0]), "{misses:?}");
    // Measured: 0.79 before, 0.077 after one average, 0.040 after two, 0.032 after three.
    assert!(misses[symmetry::MIRROR_AVERAGE_ROUNDS] < 0.6 * misses[1], "{misses:?}");
}
