//! Shapes of the wrapped template carried onto the character's own vertices: each character
//! triangle samples the deformation gradient of the wrapped template's triangle under its
//! centroid (closest point among the triangles facing the same way, on the same part: skin
//! to skin, a piece to the template piece it matches, so the upper teeth never sample the
//! lower teeth they touch), and one screened
//! Poisson solve on the character's mesh integrates them (deformation transfer, Sumner &
//! Popovic 2004, across topologies through a surface binding). Method, section 5, "Carry to the
//! character".
//!
//! Per shape `k`, over the character's deltas `d` (gradient form, Botsch et al. 2006):
//! $$ \min_d \sum_t a_t \Big\| \sum_{i \in t} d_i \nabla\phi_i^\top - H_{k,s(t)} \Big\|_F^2,
//!    \qquad H_{k,s} = \tilde V_{k,s} V_s^{-1} - I $$
//! `s(t)` the template triangle bound to character triangle `t`, `V` the edge frames (S&P
//! Eq. (3)), plus the screening `sum_v m_v / l^2 |d_v - c_v|^2` towards the barycentric copy
//! `c` (see [`CarryParams::anchor_length`]). Normal equations `(L + M / l^2) d = b + M c / l^2`,
//! `L_ij = sum_t a_t grad phi_i . grad phi_j` (the cotangent Laplacian of the character,
//! assembled and ordered once), `M` the lumped mass, `b_j = sum_t a_t H_t grad phi_j`.
//! One factorisation serves all shapes; character vertices whose binding lies on static
//! template vertices are then set to zero (see the module's Deviations).

use std::time::Instant;

use rayon::prelude::*;

use crate::error::ShapesmithResult;
use crate::geometry::bvh::TriangleBvh;
use crate::geometry::closest_point::SurfacePoint;
use crate::geometry::mat3::{add, edge_frame, inverse, length, mat_mul, mat_vec, scale, to_f64, HatGradients, Mat3, Vec3, IDENTITY};
use crate::geometry::topology::connected_components;
use crate::progress::Progress;
use crate::sparse::SymmetricMatrix;

use super::collisions::{AddedCurve, CarryCollision, CarryPenetration, Guard, TemplateCurve};
use crate::geometry::penetration::{Penetration, PenetrationBaseline};
use super::pieces::ANY_PART;
use super::symmetric_pass::{symmetric_holds, PairOutcome};
use super::symmetry::{self, MirrorPlane, SurfaceMirror};

/// Knobs of [`carry_shapes`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CarryParams {
    /// A template vertex moving less than this fraction of a shape's largest displacement is
    /// static (the method's (section 3) rule, so the carry is static where the transfer was).
    pub static_fraction: f64,
    /// `l`, in mean template edge lengths: the screening term `sum_v m_v / l^2 |d_v - b_v|^2`
    /// holds the carried deltas to the barycentric copy `b` at scales above `l`, the gradients
    /// shape them below it (0: pure Poisson, the gradients alone). On a character coarser than
    /// the template, times the square of the ratio of the mean edges (docs/design_wrap.md:
    /// the template's keys on its half-decimated copy).
    pub anchor_length: f64,
    /// A binding (a character vertex or triangle to a template triangle) must have normals
    /// within this angle, so that an upper lip never binds to the lower lip it touches.
    pub max_angle_degrees: f64,
    /// Whether the collision pass holds the carried shapes worse than the template's added
    /// curve (when it is given to [`carry_shapes`]; without the pass they are only judged).
    pub collision_pass: bool,
    /// The collision pass's margin `m_u`, in mean lengths of the character's edges at `u`,
    /// as the transfer's.
    pub collision_margin: f64,
    /// `w_u / A_uu`, the weight of a held vertex's target against its row of the system.
    pub collision_stiffness: f64,
    /// A shape is worse than the template when its excess is over this fraction of the
    /// character's bbox diagonal (the criterion of method, section 3 as the add-on reads it).
    pub collision_tolerance: f64,
    /// With the template's rest given and a symmetric character, whether each shape is
    /// averaged with its mirror partner's (`symmetry`); false only measures the mirror misses.
    pub symmetrize: bool,
}

impl Default for CarryParams {
    fn default() -> Self {
        Self {
            static_fraction: 1e-4,
            anchor_length: 2.0,
            max_angle_degrees: 60.0,
            collision_pass: true,
            collision_margin: 0.25,
            collision_stiffness: 100.0,
            collision_tolerance: 1e-3,
            symmetrize: true,
        }
    }
}

/// Carried shapes.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct CarryResult {
    /// K x Nc character deltas, shape-major.
    #[serde(skip)]
    pub deltas: Vec<[f32; 3]>,
    /// Seconds binding and assembling (once) and solving (all shapes).
    pub setup_seconds: f64,
    pub solve_seconds: f64,
    /// Largest distance from a character vertex to the wrapped template, relative to the
    /// character's bbox diagonal: large values mean parts of the character the template does
    /// not cover (they get the nearest template motion).
    pub max_binding_distance: f64,
    /// Per shape, what the collision pass did (empty when it was off).
    pub collisions: Vec<CarryCollision>,
    /// The carried keys' penetration on the character and the criterion of method, section 3 on it (when
    /// the template's curve is given).
    pub penetration: Option<CarryPenetration>,
    /// Whether the carry was made symmetric and the mirror misses (when the template's rest
    /// is given).
    pub symmetry: Option<CarrySymmetry>,
}

/// Where each character triangle samples the wrapped template's deformation (barycentric):
/// its centroid and a point towards each corner; the mean of the sampled gradients is the
/// triangle's target. A character triangle spanning several template triangles (a coarser
/// character) so gets their mean gradient, which a centroid alone would miss (docs/design_wrap.md:
/// the error on a decimated template under a perfect alignment); a triangle within
/// one template triangle (a denser character) gets that triangle's, as with one sample.
const TRIANGLE_SAMPLES: [[f64; 3]; 4] = [[1.0 / 3.0; 3], [4.0 / 6.0, 1.0 / 6.0, 1.0 / 6.0], [1.0 / 6.0, 4.0 / 6.0, 1.0 / 6.0], [1.0 / 6.0, 1.0 / 6.0, 4.0 / 6.0]];

/// Each point's closest point on a surface (rayon across points).
pub fn bind(points: &[Vec3], surface: &TriangleBvh) -> Vec<SurfacePoint> {
    points
        .par_iter()
        .map(|p| surface.closest_point(p, f64::INFINITY).expect("the surface has triangles (validated by the caller)"))
        .collect()
}

/// Each point's closest point among the surface triangles (`surface_points`, `triangles`,
/// its hierarchy `surface`) facing within `cos_max_angle` of the point's normal, the plain
/// closest point where none does: the carry's binding without parts, so that a point on one
/// lip never binds to the other lip it touches.
pub fn bind_facing_normals(
    points: &[Vec3],
    normals: &[Vec3],
    surface_points: &[Vec3],
    triangles: &[[u32; 3]],
    surface: &TriangleBvh,
    cos_max_angle: f64,
) -> Vec<SurfacePoint> {
    let any_part = vec![ANY_PART; points.len()];
    bind_facing(points, normals, &any_part, surface, &triangle_normals(surface_points, triangles), &vec![ANY_PART; triangles.len()], cos_max_angle)
}

/// Each point's closest point among the surface triangles whose unit normal is within the
/// angle of the point's normal (`cos_max_angle`) and that lie on the point's part
/// (`point_part`, `triangle_part`: see [`super::pieces::parts`]); the plain closest point on
/// that part when none faces the point's way, on any part when the part has none.
fn bind_facing(
    points: &[Vec3],
    normals: &[Vec3],
    point_part: &[u32],
    surface: &TriangleBvh,
    surface_normals: &[Vec3],
    triangle_part: &[u32],
    cos_max_angle: f64,
) -> Vec<SurfacePoint> {
    points
        .par_iter()
        .zip(normals)
        .zip(point_part)
        .map(|((p, n), &part)| {
            let same_part = |t: u32| part == ANY_PART || triangle_part[t as usize] == part;
            surface
                .closest_point_where(p, f64::INFINITY, |t| same_part(t) && crate::geometry::mat3::dot(*n, surface_normals[t as usize]) >= cos_max_angle)
                .or_else(|| surface.closest_point_where(p, f64::INFINITY, same_part))
                .or_else(|| surface.closest_point(p, f64::INFINITY))
                .expect("the surface has triangles (validated by the caller)")
        })
        .collect()
}

fn triangle_normals(points: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| points[v as usize]);
            let n = crate::geometry::mat3::cross(crate::geometry::mat3::sub(b, a), crate::geometry::mat3::sub(c, a));
            let len = length(n);
            if len > 0.0 { n.map(|x| x / len) } else { n }
        })
        .collect()
}

/// Carries the K shapes `template_deltas` (K x Nt, shape-major) of the wrapped template
/// (`wrapped`, `template_triangles`) onto the character. With `template_curve` (per shape,
/// the template's own shape's curve, in the character's units), every carried shape is
/// judged by the criterion of method, section 3 ([`TemplateCurve::allowed`]) on the character's own mesh,
/// and with [`CarryParams::collision_pass`] each one worse than the template is re-solved by
/// the collision pass ([`super::collisions`]; screened carry only). With `template_neutral`
/// (the template's rest, its vertex mirror map's source) and a symmetric character, each shape
/// is averaged with the mirror of its partner's before the pass (`symmetry`). Inputs are
/// validated by the caller (`wrap::carry_shapes`).
#[allow(clippy::too_many_arguments)]
pub fn carry_shapes(
    wrapped: &[[f32; 3]],
    template_triangles: &[[u32; 3]],
    template_deltas: &[[f32; 3]],
    character: &[[f32; 3]],
    character_triangles: &[[u32; 3]],
    template_curve: Option<&[TemplateCurve]>,
    template_neutral: Option<&[[f32; 3]]>,
    template_shapes: Option<&[[f32; 3]]>,
    params: &CarryParams,
    progress: &dyn Progress,
) -> ShapesmithResult<CarryResult> {
    let started = Instant::now();
    let nt = wrapped.len();
    let nc = character.len();
    let n_shapes = if nt == 0 { 0 } else { template_deltas.len() / nt };
    let template: Vec<Vec3> = wrapped.iter().map(to_f64).collect();
    let points: Vec<Vec3> = character.iter().map(to_f64).collect();
    let surface = TriangleBvh::build(&template, template_triangles);
    let template_normals = triangle_normals(&template, template_triangles);
    let cos_max_angle = params.max_angle_degrees.to_radians().cos();
    let vertex_normals = crate::geometry::mat3::vertex_normals(&points, character_triangles);
    let parts = super::pieces::parts(&template, template_triangles, &points, character_triangles);
    // With the template's own rest and shapes, a matched piece's keys are its motion mapped by
    // the similarity that placed it (`pieces::PieceMapping`).
    let neutral: Option<Vec<Vec3>> = template_neutral.map(|n| n.iter().map(to_f64).collect());
    let mappings = match (&neutral, template_shapes) {
        (Some(neutral), Some(_)) => super::pieces::piece_mappings(&parts.matched, neutral, &template, &points),
        _ => Vec::new(),
    };
    let map_pieces = |k: usize, deltas: &mut [Vec3], fixed: &mut [bool]| {
        let Some(shapes) = template_shapes else { return };
        let own = &shapes[k * nt..(k + 1) * nt];
        let still = params.static_fraction * own.iter().map(|d| length(to_f64(d))).fold(0.0, f64::max);
        mappings.iter().for_each(|m| m.write(own, still, deltas, fixed));
    };
    let vertex_binding = bind_facing(&points, &vertex_normals, &parts.character_vertex, &surface, &template_normals, &parts.template_triangle, cos_max_angle);
    let samples: Vec<Vec3> = character_triangles
        .iter()
        .flat_map(|t| TRIANGLE_SAMPLES.map(|b| (0..3).fold([0.0; 3], |acc, i| add(acc, points[t[i] as usize].map(|x| x * b[i])))))
        .collect();
    let repeat = |per_triangle: Vec<Vec3>| -> Vec<Vec3> { per_triangle.into_iter().flat_map(|x| [x; TRIANGLE_SAMPLES.len()]).collect() };
    let repeat_part = |per_triangle: &[u32]| -> Vec<u32> { per_triangle.iter().flat_map(|&x| [x; TRIANGLE_SAMPLES.len()]).collect() };
    let character_normals = repeat(triangle_normals(&points, character_triangles));
    let sampled = bind_facing(&samples, &character_normals, &repeat_part(&parts.character_triangle), &surface, &template_normals, &parts.template_triangle, cos_max_angle);
    let triangle_binding: Vec<[u32; TRIANGLE_SAMPLES.len()]> =
        sampled.chunks(TRIANGLE_SAMPLES.len()).map(|hits| std::array::from_fn(|i| hits[i].triangle)).collect();
    let operators: Vec<Option<HatGradients>> = character_triangles.iter().map(|t| HatGradients::new(t.map(|v| points[v as usize]))).collect();
    let mut entries = Vec::with_capacity(6 * character_triangles.len() + nc);
    for (t, op) in character_triangles.iter().zip(&operators) {
        let Some(op) = op else { continue };
        for a in 0..3 {
            for b in 0..=a {
                entries.push((t[a] as usize, t[b] as usize, op.area * crate::geometry::mat3::dot(op.gradients[a], op.gradients[b])));
            }
        }
    }
    // Screening `m_v / l^2` on the diagonal (lumped mass m_v: a third of the incident area).
    let mean_edge = |points: &[Vec3], triangles: &[[u32; 3]]| {
        let edges = crate::geometry::topology::unique_edges(triangles);
        edges.iter().map(|&(a, b)| length(crate::geometry::mat3::sub(points[a as usize], points[b as usize]))).sum::<f64>()
            / edges.len().max(1) as f64
    };
    let edge_length = mean_edge(&template, template_triangles);
    // A character coarser than the template is screened more, by the square of the edges'
    // ratio (`CarryParams::anchor_length`).
    let coarser = (edge_length / mean_edge(&points, character_triangles).max(f64::MIN_POSITIVE)).min(1.0);
    let screening_length = params.anchor_length * edge_length * coarser * coarser;
    let screening = if params.anchor_length > 0.0 { 1.0 / screening_length.powi(2) } else { 0.0 };
    let mut mass = vec![0.0; nc];
    for (t, op) in character_triangles.iter().zip(&operators) {
        if let Some(op) = op {
            t.iter().for_each(|&v| mass[v as usize] += op.area / 3.0);
        }
    }
    // A vertex on no triangle of area (a loose vertex, as a cut or an import can leave) has no
    // mass and no gradient row: a unit screening row gives it its barycentric copy.
    let anchor: Vec<f64> = mass.iter().map(|&m| if m > 0.0 || screening == 0.0 { m * screening } else { 1.0 }).collect();
    entries.extend(anchor.iter().enumerate().map(|(v, &w)| (v, v, w)));
    let laplacian = SymmetricMatrix::from_triplets(nc, entries);
    let order = laplacian.fill_reducing_order()?;
    // Screened, the matrix is definite as it is: one factorisation serves every shape.
    let whole = if screening > 0.0 { Some(laplacian.factor(&order)?) } else { None };
    let rest_inverse: Vec<Option<Mat3>> = template_triangles.iter().map(|t| inverse(&edge_frame(t.map(|v| template[v as usize])))).collect();
    let (piece, n_pieces) = connected_components(nc, character_triangles);
    let diagonal = crate::rig::bbox_diagonal(character).max(f64::MIN_POSITIVE);
    let max_binding_distance = vertex_binding.iter().map(|hit| hit.distance_squared.sqrt()).fold(0.0, f64::max) / diagonal;
    let guard = match (template_curve, whole.is_some() && params.collision_pass) {
        (Some(_), true) => Some(Guard::new(
            &points,
            character,
            character_triangles,
            (&piece, n_pieces),
            &laplacian,
            &order,
            params,
            edge_length,
            diagonal,
        )),
        _ => None,
    };
    let mirror = template_neutral.map(|neutral| {
        let character = (&points[..], character_triangles, &vertex_normals[..]);
        carry_mirror(neutral, &template, template_triangles, template_deltas, character, cos_max_angle, diagonal)
    });
    let setup_seconds = started.elapsed().as_secs_f64();

    // Solve phase: each shape's plain carry. Resolve phase: the collision pass on it. With a
    // symmetric character every shape is solved first, and averaged with the mirror of its
    // partner's carry before the pass (`symmetry`).
    let solving = Instant::now();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let steps = if params.symmetrize && matches!(mirror, Some((_, Some(_)))) { 2 * n_shapes } else { n_shapes };
    let tick = || {
        let finished = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        progress.checkpoint(finished as f64 / steps.max(1) as f64)
    };
    let solve = |k: usize| -> ShapesmithResult<Solved> {
        let deltas = &template_deltas[k * nt..(k + 1) * nt];
        let shape = Shape { deltas, template: &template, template_triangles, rest_inverse: &rest_inverse };
        let (mut deltas, rhs, mut static_vertex) = shape.carry(
            &points,
            character_triangles,
            &operators,
            &vertex_binding,
            &triangle_binding,
            &laplacian,
            &order,
            whole.as_ref(),
            &anchor,
            (&piece, n_pieces),
            params.static_fraction,
        )?;
        // A mapped piece is its own component of the system and fixed for the pass: its rows
        // of the right-hand side are never read again.
        map_pieces(k, &mut deltas, &mut static_vertex);
        Ok(Solved { deltas, rhs, static_vertex })
    };
    let resolve = |k: usize, solved: Solved| -> ShapesmithResult<CarriedShape> {
        let result = match (&guard, template_curve) {
            (Some(guard), Some(curve)) => {
                let allowed = curve[k].allowed(&AddedCurve::crossing(&guard.rest()));
                let (deltas, outcome, penetration) = guard.resolve(&solved.deltas, &solved.rhs, &solved.static_vertex, &allowed, &laplacian)?;
                (deltas, Some((outcome, penetration)))
            }
            _ => (solved.deltas.iter().map(|d| d.map(|x| x as f32)).collect(), None),
        };
        tick()?;
        Ok(result)
    };
    // The barycentric copy of the wrapped template's shapes measured alike: what the
    // measure reads on this mesh for shapes as symmetric as the wrapped template's.
    let copied = |k: usize| -> Vec<Vec3> {
        let deltas = &template_deltas[k * nt..(k + 1) * nt];
        vertex_binding
            .iter()
            .map(|hit| {
                let t = template_triangles[hit.triangle as usize];
                (0..3).fold([0.0; 3], |acc, i| add(acc, scale(to_f64(&deltas[t[i] as usize]), hit.barycentric[i])))
            })
            .collect()
    };
    let fill = |report: &mut CarrySymmetry, mirror: &SurfaceMirror, plain: &[f64], kept: &[Vec<Vec3>], held_apart: &[(usize, usize)]| {
        for (row, &plain) in report.shapes.iter_mut().zip(plain) {
            let (i, j) = (row.first, row.second);
            row.copied = symmetry::worst_miss(&copied(i), &copied(j), |f, v| mirror.mirrored(f, v));
            row.plain = plain;
            row.carried = symmetry::worst_miss(&kept[i], &kept[j], |f, v| mirror.mirrored(f, v));
            row.held_apart = held_apart.contains(&(i, j));
        }
    };
    let (shapes, symmetry): (Vec<CarriedShape>, Option<CarrySymmetry>) = match mirror {
        Some((mut report, Some(symmetric))) if params.symmetrize => {
            let solved: Vec<Solved> = (0..n_shapes).into_par_iter().map(|k| { let s = solve(k)?; tick()?; Ok(s) }).collect::<ShapesmithResult<_>>()?;
            let (mut deltas, mut static_vertex): (Vec<Vec<Vec3>>, Vec<Vec<bool>>) = solved.into_iter().map(|s| (s.deltas, s.static_vertex)).unzip();
            let plain: Vec<f64> = symmetric.pairs.iter().map(|&(i, j)| symmetry::worst_miss(&deltas[i], &deltas[j], |f, v| symmetric.mirror.mirrored(f, v))).collect();
            for _ in 0..symmetry::MIRROR_AVERAGE_ROUNDS {
                symmetry::average_with_mirror(&mut deltas, &mut static_vertex, &symmetric.pairs, &symmetric.mirror);
            }
            // The mapped pieces stay their template piece's motion, not its average with the
            // mirror piece's (the fit may place the two eyes a little differently).
            deltas.iter_mut().zip(&mut static_vertex).enumerate().for_each(|(k, (d, s))| map_pieces(k, d, s));
            // The averaged shape is the plain solution of its own right-hand side, `A d`, so
            // the pass re-solves around held vertices as it does for any carried shape.
            let shapes: Vec<CarriedShape> = deltas
                .into_par_iter()
                .zip(static_vertex.clone())
                .enumerate()
                .map(|(k, (deltas, static_vertex))| {
                    let rhs = if guard.is_some() { apply_points(&laplacian, &deltas) } else { Vec::new() };
                    resolve(k, Solved { deltas, rhs, static_vertex })
                })
                .collect::<ShapesmithResult<_>>()?;
            let mut shapes = shapes;
            let mut held_apart = Vec::new();
            if let (Some(guard), Some(curve)) = (&guard, template_curve) {
                let allowed = |k: usize| curve[k].allowed(&AddedCurve::crossing(&guard.rest()));
                let outcomes = symmetric_holds(&mut shapes, &symmetric, guard, allowed, &static_vertex, &laplacian)?;
                held_apart = outcomes.into_iter().filter(|(_, outcome)| *outcome == PairOutcome::HeldApart).map(|(pair, _)| pair).collect();
            }
            let kept: Vec<Vec<Vec3>> = shapes.iter().map(|(d, _)| d.iter().map(to_f64).collect()).collect();
            fill(&mut report, &symmetric.mirror, &plain, &kept, &held_apart);
            (shapes, Some(report))
        }
        Some((mut report, Some(symmetric))) => {
            // Symmetry not applied: the carry as without it, its misses measured alike.
            let shapes: Vec<CarriedShape> = (0..n_shapes).into_par_iter().map(|k| resolve(k, solve(k)?)).collect::<ShapesmithResult<_>>()?;
            let kept: Vec<Vec<Vec3>> = shapes.iter().map(|(d, _)| d.iter().map(to_f64).collect()).collect();
            let plain: Vec<f64> = symmetric.pairs.iter().map(|&(i, j)| symmetry::worst_miss(&kept[i], &kept[j], |f, v| symmetric.mirror.mirrored(f, v))).collect();
            fill(&mut report, &symmetric.mirror, &plain, &kept, &[]);
            (report.symmetric, report.reason) = (false, "symmetry not applied (asked); the misses are those of the carry without it".into());
            (shapes, Some(report))
        }
        mirror => {
            let shapes = (0..n_shapes).into_par_iter().map(|k| resolve(k, solve(k)?)).collect::<ShapesmithResult<_>>()?;
            (shapes, mirror.map(|(report, _)| report))
        }
    };
    let collisions = shapes.iter().filter_map(|(_, outcome)| outcome.map(|o| o.0)).collect();
    // The pass measured the shapes it kept; without it they are swept here, so that the
    // criterion is always read on the character's own mesh.
    let penetration = template_curve.map(|curve| {
        let (neutral, shapes) = match &guard {
            Some(guard) => (guard.rest(), shapes.iter().filter_map(|(_, outcome)| outcome.map(|o| o.1)).collect()),
            None => {
                let baseline = PenetrationBaseline::new(character, character_triangles);
                (baseline.neutral(), shapes.par_iter().map(|(deltas, _)| baseline.shape(deltas)).collect())
            }
        };
        CarryPenetration::judged(neutral, shapes, curve)
    });
    Ok(CarryResult {
        deltas: shapes.into_iter().flat_map(|(deltas, _)| deltas).collect(),
        setup_seconds,
        solve_seconds: solving.elapsed().as_secs_f64(),
        max_binding_distance,
        collisions,
        penetration,
        symmetry,
    })
}

/// One shape's plain carry (the solve phase): deltas (static vertices zero), the normal
/// equations' right-hand side (empty without screening) and the static vertices.
struct Solved {
    deltas: Vec<Vec3>,
    rhs: Vec<Vec3>,
    static_vertex: Vec<bool>,
}

/// `A d` per coordinate.
pub(super) fn apply_points(matrix: &SymmetricMatrix, deltas: &[Vec3]) -> Vec<Vec3> {
    let columns: Vec<Vec<f64>> = (0..3).map(|a| matrix.apply(&deltas.iter().map(|d| d[a]).collect::<Vec<_>>())).collect();
    (0..deltas.len()).map(|v| [columns[0][v], columns[1][v], columns[2][v]]).collect()
}

/// What the carry's symmetry did (`symmetry`).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct CarrySymmetry {
    pub symmetric: bool,
    /// Why the carry is not symmetric (empty when it is).
    pub reason: String,
    pub template_coverage: f64,
    pub character_coverage: f64,
    /// The character's mirror plane.
    pub plane: Option<MirrorPlane>,
    /// Per mirror pair of shapes (`first == second` for a self-symmetric shape), the worst
    /// vertex's mirror miss in % of the shapes' largest motion / 100.
    pub shapes: Vec<MirrorMiss>,
}

/// The worst vertex's miss between the mirror of shape `first` and shape `second`, relative to
/// their largest motion: on the wrapped template by its vertex map (its keys' own asymmetry,
/// the template's carried by the transfer); on the character by its surface mirror, for the
/// barycentric copy of the wrapped template's shapes (what the measure reads on this mesh
/// for shapes that symmetric: on a character whose topology is not mirrored, the image
/// interpolated across a coarse triangle at a lid or lip margin), for the plain carry, and as
/// carried.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct MirrorMiss {
    pub first: usize,
    pub second: usize,
    pub template: f64,
    pub copied: f64,
    pub plain: f64,
    pub carried: f64,
    /// The collision pass held the pair's sides apart differently and no mirrored version of
    /// the pair met the criterion: its holds stay, re-solved from the pair's average when that
    /// misses less (`symmetric_pass`).
    pub held_apart: bool,
}

/// The character's surface mirror and the shapes' mirror pairs, when symmetric.
pub(super) struct SymmetricCarry<'a> {
    pub(super) mirror: SurfaceMirror<'a>,
    pub(super) pairs: Vec<(usize, usize)>,
}

/// The carry's symmetry: the template's vertex map (from its rest, `template_neutral`), the
/// wrapped template's plane through it, refined on the character's skin; the shapes' pairs on
/// the wrapped template and their misses there.
#[allow(clippy::type_complexity)]
fn carry_mirror<'a>(
    template_neutral: &[[f32; 3]],
    wrapped: &[Vec3],
    template_triangles: &[[u32; 3]],
    template_deltas: &[[f32; 3]],
    (points, triangles, normals): (&[Vec3], &'a [[u32; 3]], &[Vec3]),
    cos_max_angle: f64,
    diagonal: f64,
) -> (CarrySymmetry, Option<SymmetricCarry<'a>>) {
    let is_skin = super::skin_flags(wrapped.len(), template_triangles);
    let found = symmetry::template_mirror(template_neutral, &is_skin);
    let mut report = CarrySymmetry { template_coverage: found.coverage, ..Default::default() };
    let minimum = 100.0 * symmetry::MIN_COVERAGE;
    let Some(wrapped_plane) = MirrorPlane::of_partners(wrapped, &found.partner, &is_skin).filter(|_| found.coverage >= symmetry::MIN_COVERAGE) else {
        report.reason = format!("the template's mirror map covers {:.0}% of its skin ({minimum:.0}% needed)", 100.0 * found.coverage);
        return (report, None);
    };
    let is_character_skin = super::skin_flags(points.len(), triangles);
    let skin_triangles: Vec<[u32; 3]> = triangles.iter().filter(|t| is_character_skin[t[0] as usize]).copied().collect();
    let skin_points: Vec<Vec3> = (0..points.len()).filter(|&v| is_character_skin[v]).map(|v| points[v]).collect();
    let (plane, coverage) = symmetry::refine_plane(wrapped_plane, &skin_points, &super::nricp::TargetSurface::new(points, &skin_triangles), diagonal);
    (report.character_coverage, report.plane) = (coverage, Some(plane));
    if coverage < symmetry::MIN_COVERAGE {
        report.reason = format!("{:.0}% of the character's skin vertices mirror onto its surface ({minimum:.0}% needed)", 100.0 * coverage);
        return (report, None);
    }
    report.symmetric = true;
    let nt = wrapped.len();
    let pairs = symmetry::shape_partners(template_deltas, nt, &found.partner, &wrapped_plane);
    let field = |k: usize| -> Vec<Vec3> { template_deltas[k * nt..(k + 1) * nt].iter().map(to_f64).collect() };
    report.shapes = pairs
        .iter()
        .map(|&(i, j)| {
            let template = symmetry::worst_miss(&field(i), &field(j), |f, v| found.partner[v].map(|m| wrapped_plane.reflect_vector(f[m as usize])));
            MirrorMiss { first: i, second: j, template, ..Default::default() }
        })
        .collect();
    // Each character vertex's image on its own surface: on its piece's mirror piece (the skin
    // onto the skin, the left eye onto the right eye), facing the reflected normal's way.
    let bvh = TriangleBvh::build(points, triangles);
    let images: Vec<Vec3> = points.iter().map(|p| plane.reflect(*p)).collect();
    let image_normals: Vec<Vec3> = normals.iter().map(|n| plane.reflect_vector(*n)).collect();
    let (piece, n_pieces) = connected_components(points.len(), triangles);
    let image_piece = symmetry::mirror_pieces(points, &piece, n_pieces, &plane);
    let image_part: Vec<u32> = piece.iter().map(|&k| image_piece[k as usize]).collect();
    let triangle_piece: Vec<u32> = triangles.iter().map(|t| piece[t[0] as usize]).collect();
    let tolerance = (symmetry::SURFACE_TOLERANCE * diagonal).powi(2);
    let images = bind_facing(&images, &image_normals, &image_part, &bvh, &triangle_normals(points, triangles), &triangle_piece, cos_max_angle)
        .into_iter()
        .map(|hit| (hit.distance_squared <= tolerance).then_some(hit))
        .collect();
    (report, Some(SymmetricCarry { mirror: SurfaceMirror { plane, images, triangles }, pairs }))
}

/// A carried shape's deltas, and with the collision pass what it did and the kept result's
/// penetration.
pub(super) type CarriedShape = (Vec<[f32; 3]>, Option<(CarryCollision, Penetration)>);

/// One template shape on the wrapped template.
struct Shape<'a> {
    deltas: &'a [[f32; 3]],
    template: &'a [Vec3],
    template_triangles: &'a [[u32; 3]],
    rest_inverse: &'a [Option<Mat3>],
}

impl Shape<'_> {
    /// The delta gradient `H = V~ V^-1 - I` of template triangle `s` (zero when its corners
    /// are all static or it is degenerate).
    fn delta_gradient(&self, s: usize, is_static: &[bool]) -> Mat3 {
        let tri = self.template_triangles[s];
        let Some(rest_inverse) = self.rest_inverse[s] else { return [[0.0; 3]; 3] };
        if tri.iter().all(|&v| is_static[v as usize]) {
            return [[0.0; 3]; 3];
        }
        let deformed = tri.map(|v| add(self.template[v as usize], to_f64(&self.deltas[v as usize])));
        let gradient = mat_mul(&edge_frame(deformed), &rest_inverse);
        std::array::from_fn(|r| std::array::from_fn(|c| gradient[r][c] - IDENTITY[r][c]))
    }

    /// The mean of the delta gradients of the template triangles a character triangle samples.
    fn mean_delta_gradient(&self, bound: &[u32], is_static: &[bool]) -> Mat3 {
        let mut sum = [[0.0; 3]; 3];
        for &s in bound {
            let h = self.delta_gradient(s as usize, is_static);
            (0..3).for_each(|r| (0..3).for_each(|c| sum[r][c] += h[r][c] / bound.len() as f64));
        }
        sum
    }

    #[allow(clippy::too_many_arguments)]
    fn carry(
        &self,
        points: &[Vec3],
        triangles: &[[u32; 3]],
        operators: &[Option<HatGradients>],
        vertex_binding: &[SurfacePoint],
        triangle_binding: &[[u32; TRIANGLE_SAMPLES.len()]],
        laplacian: &SymmetricMatrix,
        order: &[usize],
        whole: Option<&crate::sparse::Cholesky>,
        anchor: &[f64],
        (piece, n_pieces): (&[u32], usize),
        static_fraction: f64,
    ) -> ShapesmithResult<(Vec<Vec3>, Vec<Vec3>, Vec<bool>)> {
        let nc = points.len();
        let largest = self.deltas.iter().map(|d| length(to_f64(d))).fold(0.0, f64::max);
        if largest == 0.0 {
            return Ok((vec![[0.0; 3]; nc], Vec::new(), vec![true; nc]));
        }
        let is_static: Vec<bool> = self.deltas.iter().map(|d| length(to_f64(d)) < static_fraction * largest).collect();
        // The barycentric copy: which character vertices are static, and where a piece that
        // moves as a whole goes.
        let mut static_vertex = vec![false; nc];
        let mut copied = vec![[0.0; 3]; nc];
        for (v, hit) in vertex_binding.iter().enumerate() {
            let tri = self.template_triangles[hit.triangle as usize];
            static_vertex[v] = (0..3).all(|i| hit.barycentric[i] <= 1e-9 || is_static[tri[i] as usize]);
            copied[v] = (0..3).fold([0.0; 3], |acc, i| add(acc, to_f64(&self.deltas[tri[i] as usize]).map(|x| x * hit.barycentric[i])));
        }
        // A piece with no static vertex is fixed by its first vertex, then shifted so that its
        // mean delta is the copy's mean (the gradient energy is blind to a piece's translation).
        let mut pinned = vec![None; n_pieces];
        let mut has_static = vec![false; n_pieces];
        for v in 0..nc {
            has_static[piece[v] as usize] |= static_vertex[v];
        }
        // With screening the system is definite on every piece: nothing to pin.
        let screened = anchor.iter().any(|&w| w > 0.0);
        for v in 0..nc {
            let p = piece[v] as usize;
            if !screened && !has_static[p] && pinned[p].is_none() {
                pinned[p] = Some(v);
                static_vertex[v] = true;
            }
        }
        let mut position = vec![u32::MAX; nc];
        let mut kept = 0usize;
        for v in 0..nc {
            if whole.is_some() || !static_vertex[v] {
                position[v] = kept as u32;
                kept += 1;
            }
        }
        let mut deltas = vec![[0.0; 3]; nc];
        let mut whole_rhs = Vec::new();
        if kept > 0 {
            let mut rhs = vec![[0.0; 3]; kept];
            for ((t, op), bound) in triangles.iter().zip(operators).zip(triangle_binding) {
                let Some(op) = op else { continue };
                let h = self.mean_delta_gradient(bound, &is_static);
                if h == [[0.0; 3]; 3] {
                    continue;
                }
                for (corner, &v) in t.iter().enumerate() {
                    let p = position[v as usize];
                    if p != u32::MAX {
                        rhs[p as usize] = add(rhs[p as usize], mat_vec(&h, op.gradients[corner]).map(|x| x * op.area));
                    }
                }
            }
            for v in 0..nc {
                let p = position[v];
                if p != u32::MAX {
                    rhs[p as usize] = add(rhs[p as usize], copied[v].map(|x| x * anchor[v]));
                }
            }
            let solved = match whole {
                Some(factor) => {
                    let solved = factor.solve_points(&rhs);
                    whole_rhs = rhs;
                    solved
                }
                None => laplacian.factor_restricted(&position, kept, order)?.solve_points(&rhs),
            };
            for v in 0..nc {
                if position[v] != u32::MAX && !static_vertex[v] {
                    deltas[v] = solved[position[v] as usize];
                }
            }
        }
        for (p, pin) in pinned.iter().enumerate() {
            if pin.is_none() {
                continue;
            }
            let members: Vec<usize> = (0..nc).filter(|&v| piece[v] as usize == p).collect();
            let count = members.len() as f64;
            let mean = |field: &[Vec3]| members.iter().fold([0.0; 3], |acc, &v| add(acc, field[v].map(|x| x / count)));
            let shift = crate::geometry::mat3::sub(mean(&copied), mean(&deltas));
            for &v in &members {
                deltas[v] = add(deltas[v], shift);
            }
        }
        Ok((deltas, whole_rhs, static_vertex))
    }
}
