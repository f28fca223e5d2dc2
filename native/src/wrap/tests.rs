//! The wrap on synthetic closed surfaces: a lumpy ellipsoid sampled at two resolutions (so
//! that the two meshes share a surface but no vertex), deformed by a known smooth map and
//! moved by a known similarity.

use super::*;
use crate::geometry::mat3::{mat_mul, mat_vec, scale, Mat3};
use crate::progress::NoProgress;

/// A lumpy ellipsoid, `rings` latitude bands by `2 * rings` segments, outward triangles.
/// The lump breaks every symmetry, so that principal axes and closest points are unambiguous.
pub(crate) fn lumpy_box(rings: usize) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let surface = |theta: f64, phi: f64| -> Vec3 {
        let u = [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()];
        let lump = [0.5f64, 0.6, 0.62];
        let norm = length(lump);
        let closeness = (0..3).map(|a| (u[a] - lump[a] / norm).powi(2)).sum::<f64>();
        let r = 1.0 + 0.3 * (-closeness / 0.2).exp();
        [1.5 * r * u[0], 1.0 * r * u[1], 0.7 * r * u[2]]
    };
    sphere_mesh(rings, 2 * rings, 0.0, surface)
}

/// A closed mesh of `surface(theta, phi)` sampled at `rings` latitude bands by `segments`
/// (the segments turned by `phase`), a vertex at each pole, outward triangles.
pub(crate) fn sphere_mesh(rings: usize, segments: usize, phase: f64, surface: impl Fn(f64, f64) -> Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let mut points = vec![surface(0.0, 0.0)];
    for j in 1..rings {
        let theta = std::f64::consts::PI * j as f64 / rings as f64;
        points.extend((0..segments).map(|i| surface(theta, phase + 2.0 * std::f64::consts::PI * i as f64 / segments as f64)));
    }
    points.push(surface(std::f64::consts::PI, 0.0));
    let south = (points.len() - 1) as u32;
    let at = |j: usize, i: usize| (1 + (j - 1) * segments + i % segments) as u32;
    let mut triangles = Vec::new();
    for i in 0..segments {
        triangles.push([0, at(1, i), at(1, i + 1)]);
        triangles.push([south, at(rings - 1, i + 1), at(rings - 1, i)]);
    }
    for j in 1..rings - 1 {
        for i in 0..segments {
            triangles.push([at(j, i), at(j + 1, i), at(j + 1, i + 1)]);
            triangles.push([at(j, i), at(j + 1, i + 1), at(j, i + 1)]);
        }
    }
    (points, triangles)
}

pub(super) fn as_f32(points: &[Vec3]) -> Vec<[f32; 3]> {
    points.iter().map(|p| p.map(|x| x as f32)).collect()
}

/// A smooth non-rigid change of identity.
fn warp(p: Vec3) -> Vec3 {
    [p[0] * (1.0 + 0.1 * p[1]), 1.15 * p[1] + 0.1 * p[0] * p[0], 0.9 * p[2] + 0.08 * (2.0 * p[0]).sin()]
}

pub(super) fn rotation(a: f64, b: f64) -> Mat3 {
    let rz: Mat3 = [[a.cos(), -a.sin(), 0.0], [a.sin(), a.cos(), 0.0], [0.0, 0.0, 1.0]];
    let rx: Mat3 = [[1.0, 0.0, 0.0], [0.0, b.cos(), -b.sin()], [0.0, b.sin(), b.cos()]];
    mat_mul(&rz, &rx)
}

#[test]
fn fits_a_known_deformed_resampled_copy_in_other_units_and_axes() {
    let (template, triangles) = lumpy_box(16);
    let (dense, dense_triangles) = lumpy_box(23);
    let motion = Similarity { rotation: rotation(1.9, -0.6), scale: 100.0, translation: [5.0, -30.0, 12.0] };
    let character: Vec<Vec3> = dense.iter().map(|p| motion.apply(warp(*p))).collect();
    let truth: Vec<Vec3> = template.iter().map(|p| motion.apply(warp(*p))).collect();
    let picked = [0usize, 40, 77, 130, 200, 260, 300, 401, 455];
    let pair_template = as_f32(&picked.iter().map(|&v| template[v]).collect::<Vec<_>>());
    let pair_character = as_f32(&picked.iter().map(|&v| truth[v]).collect::<Vec<_>>());
    let wrap = wrap_template(
        &as_f32(&template),
        &triangles,
        &as_f32(&character),
        &dense_triangles,
        PointPairs { template: &pair_template, character: &pair_character },
        &WrapParams::default(),
        &NoProgress,
    )
    .unwrap();
    let report = &wrap.report;
    assert_eq!(report.alignment, "pairs");
    // The warp stretches by 15% and shears: harder than an identity change (measured 2.6e-3
    // here with the membrane stiffness this fit had before the bending term).
    assert!(report.mean_distance < 3e-3, "mean distance {} of the diagonal", report.mean_distance);
    // Correspondence: each wrapped vertex lies near where the warp took it.
    let errors: Vec<f64> =
        wrap.wrapped.iter().zip(&truth).map(|(w, t)| length(sub(to_f64(w), *t)) / report.diagonal).collect();
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    let aligned_only = wrap_template(
        &as_f32(&template),
        &triangles,
        &as_f32(&character),
        &dense_triangles,
        PointPairs { template: &pair_template, character: &pair_character },
        &WrapParams { align_only: true, ..Default::default() },
        &NoProgress,
    )
    .unwrap();
    let aligned_mean =
        aligned_only.wrapped.iter().zip(&truth).map(|(w, t)| length(sub(to_f64(w), *t)) / report.diagonal).sum::<f64>() / errors.len() as f64;
    // Closest points let the surface slide between the pairs: measured 1.6e-2 after the fit
    // (with the earlier membrane stiffness) against 3.1e-2 after the similarity alone.
    assert!(mean < 0.02 && mean < 0.6 * aligned_mean, "correspondence error {mean} after the fit, {aligned_mean} after the similarity");
    assert!(report.pair_residuals.iter().all(|&r| r < 0.01), "{:?}", report.pair_residuals);
}

/// A smooth local motion with a static region: the truth on any sampling of the surface.
fn local_motion(p: Vec3) -> Vec3 {
    let centre = [1.0, 0.5, 0.4];
    let falloff = (1.0 - length(sub(p, centre)).powi(2) / 0.8).max(0.0).powi(3);
    [0.12 * falloff * (1.0 + p[1]), -0.05 * falloff, 0.08 * falloff * p[0]]
}

#[test]
fn carry_reproduces_a_smooth_deformation_far_better_than_nearest_vertex() {
    let (template, triangles) = lumpy_box(14);
    let (character, character_triangles) = lumpy_box(37);
    let deltas: Vec<[f32; 3]> = template.iter().map(|p| local_motion(*p).map(|x| x as f32)).collect();
    let carried = carry_shapes(
        &as_f32(&template),
        &triangles,
        &deltas,
        &as_f32(&character),
        &character_triangles,
        None,
        None,
        None,
        &CarryParams::default(),
        &NoProgress,
    )
    .unwrap();
    assert_eq!(carried.deltas.len(), character.len());
    let tree = crate::geometry::neighbours::PointTree::new(&as_f32(&template));
    let (mut carry_error, mut nearest_error, mut magnitude, mut moving) = (0.0, 0.0, 0.0, 0usize);
    let mut static_exact = true;
    for (v, p) in character.iter().enumerate() {
        let truth = local_motion(*p);
        let got = to_f64(&carried.deltas[v]);
        if length(truth) == 0.0 {
            // Far from the motion the character stays exactly still.
            static_exact &= length(sub(*p, [1.0, 0.5, 0.4])) < 1.3 || got == [0.0; 3];
            continue;
        }
        moving += 1;
        magnitude += length(truth);
        carry_error += length(sub(got, truth));
        nearest_error += length(sub(to_f64(&deltas[tree.nearest(*p).0]), truth));
    }
    assert!(static_exact, "vertices far from the motion must keep zero deltas");
    let (carry_error, nearest_error, magnitude) = (carry_error / moving as f64, nearest_error / moving as f64, magnitude / moving as f64);
    // Measured: carry 3.2e-3, nearest vertex 8.7e-3, mean motion 4.2e-2 (the template has 14
    // rings, the character 37: the nearest template vertex is up to half a template edge away).
    assert!(carry_error < 0.5 * nearest_error, "carry {carry_error} vs nearest vertex {nearest_error}");
    assert!(carry_error < 0.1 * magnitude, "carry error {carry_error} for a mean motion of {magnitude}");
}

#[test]
fn a_loose_character_vertex_moves_with_its_nearest_surface_point_and_the_rest_is_as_without_it() {
    // A cut or an import can leave a vertex on no face: it has no mass and no gradient row
    // (the screened system was singular: a SolverError on the sample character with 1.3
    // eyeball radii of lid skin cut away). It is off the character's surface (the weld), and
    // carried by the motion of the character's surface point nearest it.
    let (template, triangles) = lumpy_box(14);
    let (character, character_triangles) = lumpy_box(37);
    let deltas: Vec<[f32; 3]> = template.iter().map(|p| local_motion(*p).map(|x| x as f32)).collect();
    let carry = |points: &[Vec3]| {
        carry_shapes(&as_f32(&template), &triangles, &deltas, &as_f32(points), &character_triangles, None, None, None, &CarryParams::default(), &NoProgress)
    };
    let without = carry(&character).unwrap();
    // The loose vertex sits on a template vertex that moves, off every character face.
    let moving = (0..template.len()).max_by(|&a, &b| length(local_motion(template[a])).total_cmp(&length(local_motion(template[b])))).unwrap();
    let mut loose = character.clone();
    loose.push(template[moving]);
    let with = carry(&loose).unwrap();
    assert_eq!(with.deltas.len(), character.len() + 1);
    let got = to_f64(&with.deltas[character.len()]);
    let weld = crate::geometry::weld::Weld::new(&as_f32(&loose), &character_triangles);
    let near = &weld.carried[0];
    assert_eq!((weld.carried.len(), near.vertex as usize), (1, character.len()));
    let mut expected = [0.0; 3];
    for (&p, &w) in near.corners.iter().zip(&near.weights) {
        let d = to_f64(&with.deltas[weld.vertex(p) as usize]);
        (0..3).for_each(|a| expected[a] += w * d[a]);
    }
    assert!(length(sub(got, expected)) < 1e-6 * length(expected), "{got:?} vs {expected:?}");
    // The surface under it moves (the template's motion there is large), so it is not left behind.
    assert!(length(got) > 0.5 * length(to_f64(&deltas[moving])), "{got:?} vs {:?}", deltas[moving]);
    assert_eq!(&with.deltas[..character.len()], &without.deltas[..]);
}

#[test]
fn principal_axes_without_pairs_are_reported_as_a_guess() {
    let (template, triangles) = lumpy_box(12);
    let motion = Similarity { rotation: rotation(0.4, 0.3), scale: 2.0, translation: [1.0, 0.0, 0.0] };
    let character: Vec<Vec3> = template.iter().map(|p| motion.apply(*p)).collect();
    let wrap = wrap_template(
        &as_f32(&template),
        &triangles,
        &as_f32(&character),
        &triangles,
        PointPairs { template: &[], character: &[] },
        &WrapParams::default(),
        &NoProgress,
    )
    .unwrap();
    assert_eq!(wrap.report.alignment, "principal axes");
    assert!(wrap.report.warnings[0].contains("guess"));
    assert!(wrap.report.mean_distance < 1e-3, "{}", wrap.report.mean_distance);
}

#[test]
fn bad_input_gets_a_clear_error() {
    let (template, triangles) = lumpy_box(8);
    let t32 = as_f32(&template);
    let pairs = [t32[0], t32[10], t32[20], t32[30], t32[40]];
    let run = |character: &[[f32; 3]], tris: &[[u32; 3]], template_pairs: &[[f32; 3]], character_pairs: &[[f32; 3]]| {
        match wrap_template(&t32, &triangles, character, tris, PointPairs { template: template_pairs, character: character_pairs }, &WrapParams::default(), &NoProgress) {
            Err(crate::error::ShapesmithError::InvalidInput(message)) => message,
            other => panic!("expected an input error, got {other:?}"),
        }
    };
    assert!(run(&t32, &triangles, &pairs[..3], &pairs[..3]).contains("at least 4"));
    assert!(run(&t32, &[], &pairs, &pairs).contains("no faces"));
    let mut nan = t32.clone();
    nan[5][1] = f32::NAN;
    assert!(run(&nan, &triangles, &pairs, &pairs).contains("vertex 5"));
    let mut off = pairs;
    off[2] = [40.0, 0.0, 0.0];
    assert!(run(&t32, &triangles, &pairs, &off).contains("pair 3"));
}

/// `points` moved by `motion`, and the triangles renumbered from `offset`.
fn placed(points: &[Vec3], triangles: &[[u32; 3]], motion: &Similarity, offset: u32) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    (points.iter().map(|p| motion.apply(*p)).collect(), triangles.iter().map(|t| t.map(|v| v + offset)).collect())
}

#[test]
fn a_piece_lands_on_the_characters_piece_of_its_place_and_size() {
    // Skin: a large lumpy box; an "eye": a small lumpy box inside it, another of other size
    // beside it (a distractor, never to be matched with the eye).
    let (skin, skin_triangles) = lumpy_box(12);
    let (small, small_triangles) = lumpy_box(12);
    let (dense_small, dense_small_triangles) = lumpy_box(17);
    let eye_at = |scale: f64, x: f64| Similarity { rotation: rotation(0.0, 0.0), scale, translation: [x, 0.1, 0.0] };
    let mut template = skin.clone();
    let mut triangles = skin_triangles.clone();
    let (eye, eye_triangles) = placed(&small, &small_triangles, &eye_at(0.2, 0.6), template.len() as u32);
    template.extend(eye);
    triangles.extend(eye_triangles);
    // The character: the same skin, its eye displaced, turned by a few degrees (what the skin's
    // motion leaves) and 15% larger, resampled; a
    // distractor half the size nearby.
    let true_eye = Similarity { rotation: rotation(0.1, 0.05), scale: 0.23, translation: [0.66, 0.05, 0.04] };
    let mut character = skin.clone();
    let mut character_triangles = skin_triangles.clone();
    let (eye, eye_triangles) = placed(&dense_small, &dense_small_triangles, &true_eye, character.len() as u32);
    character.extend(eye);
    character_triangles.extend(eye_triangles);
    let (distractor, distractor_triangles) = placed(&small, &small_triangles, &eye_at(0.1, 0.35), character.len() as u32);
    character.extend(distractor);
    character_triangles.extend(distractor_triangles);
    let mut fitted = template.clone();
    let is_skin: Vec<bool> = (0..template.len()).map(|v| v < skin.len()).collect();
    let is_character_skin: Vec<bool> = (0..character.len()).map(|v| v < skin.len()).collect();
    let rows = pieces::fit_pieces(&template, &mut fitted, &triangles, &is_skin, &character, &character_triangles, &is_character_skin);
    assert_eq!(rows.len(), 1);
    assert!(rows[0].fitted && rows[0].character_vertex == Some(skin.len() as u32), "{rows:?}");
    // Each template eye vertex lies on the true eye's surface, and the eye's centre and size
    // are the true eye's (up to the resampling of a lumpy surface).
    let truth_surface = TriangleBvh::build(&character, &character_triangles[skin_triangles.len()..skin_triangles.len() + dense_small_triangles.len()]);
    let eye_vertices = skin.len()..template.len();
    let worst = eye_vertices.clone().map(|v| truth_surface.closest_point(&fitted[v], f64::INFINITY).unwrap().distance_squared.sqrt()).fold(0.0, f64::max);
    // Tolerances: the two samplings' chords differ by up to 3% of the eye's size (the ICP's
    // pulls both ways settle between them); left where the skin put it, the eye would be
    // 0.09 away.
    assert!(worst < 0.05 * 0.23, "an eye vertex lies {worst} off the true eye");
    let expected: Vec<Vec3> = eye_vertices.clone().map(|v| true_eye.apply(small[v - skin.len()])).collect();
    let error = eye_vertices.map(|v| length(sub(fitted[v], expected[v - skin.len()]))).sum::<f64>() / expected.len() as f64;
    assert!(error < 0.05 * 0.23, "eye vertices {error} from where the true similarity takes them");
    // The skin is not touched.
    assert!(fitted[..skin.len()] == template[..skin.len()]);
}

#[test]
fn a_matched_eyeball_gets_the_templates_turn_mapped_by_its_similarity() {
    // Template: a lumpy skin and an eyeball (a sphere) inside it; one shape turns the eyeball
    // by 0.3 rad about its centre and moves the skin a little.
    let (skin, skin_triangles) = lumpy_box(12);
    let ball = |rings: usize, phase: f64| sphere_mesh(rings, 2 * rings, phase, |theta: f64, phi: f64| [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()]);
    let (unit_ball, ball_triangles) = ball(8, 0.0);
    let (centre, radius) = ([0.6, 0.1, 0.0], 0.2);
    let eye_rest = Similarity { rotation: IDENTITY_ROTATION, scale: radius, translation: centre };
    let mut template = skin.clone();
    let mut triangles = skin_triangles.clone();
    let (eye, eye_triangles) = placed(&unit_ball, &ball_triangles, &eye_rest, template.len() as u32);
    template.extend(eye);
    triangles.extend(eye_triangles);
    let turn = rotation(0.3, 0.2);
    let own: Vec<[f32; 3]> = template
        .iter()
        .enumerate()
        .map(|(v, p)| if v < skin.len() { local_motion(*p).map(|x| 0.2 * x) } else { sub(add(mat_vec(&turn, sub(*p, centre)), centre), *p) })
        .map(|d| d.map(|x| x as f32))
        .collect();
    // Wrapped: the skin under `skin_motion`, the eyeball under `eye_motion` (the skin's and the
    // piece's own fit), in other units and axes; its keys rotated and scaled as a whole (what
    // the transfer gives, blind to the piece's own turn).
    let skin_motion = Similarity { rotation: rotation(1.1, -0.4), scale: 50.0, translation: [3.0, -2.0, 7.0] };
    let piece_fit = Similarity { rotation: rotation(0.15, 0.1), scale: 1.08, translation: [0.4, -0.3, 0.2] };
    let eye_motion = Similarity {
        rotation: mat_mul(&piece_fit.rotation, &skin_motion.rotation),
        scale: piece_fit.scale * skin_motion.scale,
        translation: piece_fit.apply(skin_motion.translation),
    };
    let wrapped: Vec<Vec3> = template.iter().enumerate().map(|(v, p)| if v < skin.len() { skin_motion.apply(*p) } else { eye_motion.apply(*p) }).collect();
    let wrapped_deltas: Vec<[f32; 3]> =
        own.iter().map(|d| mat_vec(&skin_motion.rotation, to_f64(d)).map(|x| (x * skin_motion.scale) as f32)).collect();
    // Character: the skin resampled, the eyeball resampled (other rings, turned segments),
    // both where the wrapped template's are.
    let (dense_skin, dense_skin_triangles) = lumpy_box(19);
    let (dense_ball, dense_ball_triangles) = ball(11, 0.37);
    let mut character: Vec<Vec3> = dense_skin.iter().map(|p| skin_motion.apply(*p)).collect();
    let mut character_triangles = dense_skin_triangles.clone();
    let (eye, eye_triangles) = placed(&dense_ball, &dense_ball_triangles, &eye_rest, character.len() as u32);
    character.extend(eye.iter().map(|p| eye_motion.apply(*p)));
    character_triangles.extend(eye_triangles);
    let carry = |shapes: Option<&[[f32; 3]]>| {
        carry_shapes(
            &as_f32(&wrapped),
            &triangles,
            &wrapped_deltas,
            &as_f32(&character),
            &character_triangles,
            None,
            Some(&as_f32(&template)),
            shapes,
            &CarryParams::default(),
            &NoProgress,
        )
        .unwrap()
    };
    let mapped = carry(Some(&own));
    let carried = carry(None);
    // The truth at a character eyeball vertex c: the template's turn about its centre, mapped
    // by the eyeball's similarity: eye_motion(centre + turn (y - centre)) - c, y its preimage.
    let inverse = |c: Vec3| scale(mat_vec(&crate::geometry::mat3::transpose(&eye_motion.rotation), sub(c, eye_motion.translation)), 1.0 / eye_motion.scale);
    let largest = (2.0 * (0.3f64 / 2.0).sin()).max(0.2) * radius * eye_motion.scale;
    let miss = |result: &CarryResult| -> f64 {
        (dense_skin.len()..character.len())
            .map(|c| {
                let p = to_f32_point(character[c]);
                let y = inverse(p);
                let truth = sub(eye_motion.apply(add(mat_vec(&turn, sub(y, centre)), centre)), p);
                length(sub(to_f64(&result.deltas[c]), truth))
            })
            .fold(0.0, f64::max)
            / largest
    };
    // Exact up to f32 rounding (1e-7 of the 5e1 scale); the plain carry's gradients, sampled
    // without the piece's own turn, miss by far more.
    assert!(miss(&mapped) < 1e-5, "mapped eyeball misses by {} of its motion", miss(&mapped));
    assert!(miss(&carried) > 100.0 * miss(&mapped), "carried {} mapped {}", miss(&carried), miss(&mapped));
    // The skin is carried as without the template's own shapes.
    let skin_gap = (0..dense_skin.len()).map(|v| length(sub(to_f64(&mapped.deltas[v]), to_f64(&carried.deltas[v])))).fold(0.0, f64::max);
    assert!(skin_gap < 1e-6 * skin_motion.scale, "the skin changed by {skin_gap}");
}

const IDENTITY_ROTATION: Mat3 = crate::geometry::mat3::IDENTITY;

/// A point as the carry reads it (f32), back in f64.
fn to_f32_point(p: Vec3) -> Vec3 {
    p.map(|x| x as f32 as f64)
}
