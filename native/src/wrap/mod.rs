//! Wrap: the template fitted onto a character of any topology, and the template's shapes
//! carried onto the character's own vertices. Method, section 5 (beyond the papers; the first
//! step of paper 000's pipeline, its figure 1).
//!
//! [`wrap_template`] aligns the template to the character with a similarity from point pairs
//! (Umeyama 1991; principal axes without pairs), then fits the template's skin onto the
//! character's surface by optimal-step non-rigid ICP (Amberg, Romdhani & Vetter 2007) and
//! carries the template's other pieces (eyes, teeth, lashes) along with the skin around them.
//! The add-on then transfers the template's shapes onto the wrapped template (same topology,
//! [`crate::transfer`], called from Python: tools are siblings), and [`carry_shapes`] carries
//! them onto the character's vertices through the deformation gradients.
//!
//! | paper symbol | identifier |
//! |---|---|
//! | `p_i`, `q_i` (point pairs on template and character) | [`PointPairs`] |
//! | `s`, `R`, `t` (Umeyama's similarity) | [`Similarity`] |
//! | `alpha` (stiffness), its schedule | [`FitParams::stiffness`] |
//! | `beta` (landmark weight, decays with `alpha`: `beta = landmark_weight * alpha`) | [`FitParams::landmark_weight`] |
//! | `w_i` (0 for rejected closest points) | `nricp::closest_points` |
//! | rim targets (a template rim vertex's place on the character's matching hole) | `rims::RimTarget`, weight [`FitParams::rim_weight`] |
//! | `u_i` (closest character point) | `SurfacePoint::point` |
//! | `H_{k,s}` (template delta gradient sampled on a character triangle) | `carry::Shape::delta_gradient` |
//!
//! # Deviations (each a decision in docs/design_wrap.md, with its numbers)
//! - **Displacements with a bending stiffness, not per-vertex affine maps.** The unknowns are
//!   the skin's displacements (N x N, three right-hand sides) with the bending energy
//!   `alpha |L d|^2` (`L` the template's uniform Laplacian) instead of Amberg's 3x4 affine map
//!   per vertex (4N x 4N, `|(M (x) G) X|^2`); like Amberg's it costs nothing for a translation
//!   and little for a smooth stretch, and it lands closer to the true correspondence.
//! - **One factorisation per stiffness step, weights frozen within the step**: a vertex whose
//!   closest point is rejected later in the step is held where it is, so the factor stays valid.
//! - **Pieces follow the skin, then fit the character's own.** Every template piece other than
//!   the skin moves by the similarity that best maps the skin around it; a piece whose centre
//!   and size match a character piece's (one to one, by place and size, not by the user's
//!   pairs) is then fitted onto it by a similarity ICP (`pieces`). Its carried keys are then not the gradients' but the
//!   template piece's own motion mapped by the similarity that placed it
//!   (`pieces::PieceMapping`): an eyeball's turn stays a turn about its centre.
//! - **Holes land on holes.** Closest points on the character's open boundary are rejected
//!   (the method), which leaves rim vertices without a data term; the skin's small boundary loops
//!   (ear canals, open lids or lips; not the neck cut) are paired with the character's by
//!   place and size, and each rim vertex targets its arc-length place on the matching loop
//!   (`rims`), with weight 1 like a closest point. An avatar's lid holes, which no template
//!   hole matches, land the template's lids about its eyeballs (`lids`).
//! - **Only the character's largest piece is fitted to by the skin**: its eyes, teeth or
//!   lashes would otherwise catch the template's eyelids and lips.
//! - **The carry is screened towards the barycentric copy**, `m_v / l^2 |d_v - c_v|^2` with
//!   `l` = 2 template edges, less on a coarser character (the copy sets the shape above that
//!   scale, the gradients below it), and each character triangle samples the template
//!   triangles whose normals agree, on the matching part, at four points.
//!   `anchor_length = 0` is the method's pure Poisson solve.
//! - **Symmetric in, symmetric out** (`symmetry`, beyond the method): with a symmetric template and
//!   character the fit gains mirrored pairs and is averaged with its mirror, and each carried
//!   shape is averaged with the mirror of its partner's before the collision pass.
//! - **Static vertices are zeroed after the solve.** Screened, the system is definite, so it
//!   is factorised once for all shapes and each shape is one back-substitution; the vertices
//!   bound to static template vertices are then set to exactly zero. With
//!   `anchor_length = 0` each shape factorises the submatrix on its moving vertices instead.
//! - **The carried keys get their own collision pass** (`collisions`, beyond method, section 5):
//!   the character's lips are closer and coarser than the wrapped template's, so a faithful
//!   copy of its motion still crosses them.

mod align;
mod carry;
mod collisions;
mod lids;
pub mod looks;
pub mod measures;
mod nricp;
mod pieces;
mod propose;
mod rims;
mod symmetric_pass;
mod symmetry;
#[cfg(test)]
pub(crate) mod tests;
#[cfg(test)]
mod symmetry_tests;

use std::time::Instant;

pub use align::{similarity_from_pairs, similarity_from_principal_axes, Similarity, MIN_PAIRS};
pub use carry::{bind, bind_facing_normals, carry_shapes as carry_shapes_unchecked, CarryParams, CarryResult, CarrySymmetry, MirrorMiss};
pub use collisions::{AddedCurve, CarryCollision, TemplateCurve};
pub use nricp::FitStats;
pub use symmetry::MirrorPlane;
pub use propose::{propose_pairs, Proposal, ProposedPair};

use crate::error::ShapesmithResult;
use crate::geometry::bvh::TriangleBvh;
use crate::geometry::mat3::{add, length, scale, sub, to_f64, Vec3};
use crate::geometry::topology::connected_components;
use crate::geometry::weld::Weld;
use crate::invalid;
use crate::progress::{Progress, Stage};
use crate::rig::{bbox_diagonal, validate_points, validate_triangle_indices};
use nricp::{fit_skin, FitMirror, Landmark, TargetSurface};
use pieces::{carry_pieces, fit_pieces};
pub use pieces::PieceMatch;
use lids::LidMeshes;
use rims::rim_targets;
pub use rims::HoleMatch;

/// Knobs of the non-rigid fit.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FitParams {
    /// `alpha` per step, decreasing (Amberg et al. step from stiff to loose).
    pub stiffness: Vec<f64>,
    /// Closest-point iterations per step at most (fewer once nothing moves).
    pub iterations: usize,
    /// `beta / alpha`: the landmark term's weight decays with the stiffness.
    pub landmark_weight: f64,
    /// Closest points whose surface normal differs from the template's by more are rejected.
    pub max_angle_degrees: f64,
    /// Closest points farther than this fraction of the character's bbox diagonal are rejected.
    pub max_distance: f64,
    /// Weight of a template rim vertex's pull to its place on the character's matching hole
    /// (`rims`), against 1 for a closest point.
    pub rim_weight: f64,
    /// A closest-point iteration that moves no vertex by more than this fraction of the
    /// diagonal ends its step.
    pub tolerance: f64,
}

impl Default for FitParams {
    fn default() -> Self {
        Self {
            stiffness: vec![100.0, 50.0, 20.0, 10.0, 5.0, 2.0, 1.0, 0.5],
            iterations: 3,
            landmark_weight: 100.0,
            max_angle_degrees: 60.0,
            max_distance: 0.1,
            rim_weight: 1.0,
            tolerance: 1e-4,
        }
    }
}

/// Knobs of [`wrap_template`]: the wrap tool's settings ([`crate::settings`]).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WrapParams {
    pub fit: FitParams,
    /// Stop after the similarity (the Align button): the template moved rigidly and scaled.
    pub align_only: bool,
    /// Fit as if the meshes were not symmetric (no mirrored pairs, no symmetric fit).
    pub ignore_symmetry: bool,
}

/// Whether the fit was made symmetric (`symmetry`), and why not.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct WrapSymmetry {
    pub symmetric: bool,
    /// Why the fit is not symmetric (empty when it is).
    pub reason: String,
    /// The template's mirror axis (0 = X) and the share of its skin its vertex map covers.
    pub template_axis: usize,
    pub template_coverage: f64,
    /// The share of the character's skin vertices whose mirror image lies on its surface.
    pub character_coverage: f64,
    /// The character's mirror plane (character space).
    pub plane: Option<MirrorPlane>,
    /// Point pairs added as the mirror images of the given ones.
    pub mirrored_pairs: usize,
}

/// Point pairs, each a point on the template and one on the character, in each mesh's own
/// space (the add-on turns vertex indices into points).
#[derive(Clone, Copy, Debug)]
pub struct PointPairs<'a> {
    pub template: &'a [[f32; 3]],
    pub character: &'a [[f32; 3]],
}

/// How well the wrapped template fits, distances relative to the character's bbox diagonal.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct WrapReport {
    /// "pairs" or "principal axes" (no pairs: a guess, check it).
    pub alignment: String,
    pub similarity: Similarity,
    pub pairs: usize,
    /// Pairs whose template point lies on the skin, used as landmarks by the fit.
    pub landmarks: usize,
    /// Mean and largest distance from the wrapped skin's vertices to the character's surface.
    pub mean_distance: f64,
    pub max_distance: f64,
    /// Per pair, the distance between the two points after the similarity alone and after
    /// the fit.
    pub aligned_pair_residuals: Vec<f64>,
    pub pair_residuals: Vec<f64>,
    pub fit: FitStats,
    /// Template pieces other than the skin (eyes, teeth, tongue, lashes), and how many of them
    /// were fitted onto a character piece of the same place and size (the others follow the
    /// skin around them); per piece, what it matched (`pieces::PieceMatch`).
    pub pieces: usize,
    pub pieces_fitted: usize,
    pub piece_matches: Vec<PieceMatch>,
    /// Holes of the template's skin (ear canals, open lids or lips) paired with the
    /// character's, whose rims the fit lands on the character's (`rims`), and the character's
    /// lid holes the template's lids landed on (`lids`), and which.
    pub holes_paired: usize,
    pub symmetry: WrapSymmetry,
    pub hole_matches: Vec<HoleMatch>,
    /// Character bbox diagonal (character units).
    pub diagonal: f64,
    pub template_vertices: usize,
    pub skin_vertices: usize,
    pub character_vertices: usize,
    pub align_seconds: f64,
    pub fit_seconds: f64,
    pub warnings: Vec<String>,
}

/// The wrapped template: template topology, in the character's space.
#[derive(Clone, Debug, PartialEq)]
pub struct Wrap {
    pub wrapped: Vec<[f32; 3]>,
    pub report: WrapReport,
}

/// Aligns and fits the template (`template`, `template_triangles`) onto the character.
/// Errors name what to fix: too few or degenerate pairs, a pair point off its mesh (placed on
/// the wrong object), a mesh without faces, non-finite coordinates.
///
/// Both meshes are fitted on their welded surfaces ([`Weld`]): a character split along its
/// UV seams is one skin (its seams are no holes, its islands no pieces), and every copy of a
/// template seam vertex lands at its welded point's place.
pub fn wrap_template(
    template: &[[f32; 3]],
    template_triangles: &[[u32; 3]],
    character: &[[f32; 3]],
    character_triangles: &[[u32; 3]],
    pairs: PointPairs,
    params: &WrapParams,
    progress: &dyn Progress,
) -> ShapesmithResult<Wrap> {
    let (template_weld, character_weld) = (Weld::new(template, template_triangles), Weld::new(character, character_triangles));
    let wrap = wrap_welded(
        &template_weld.gather(template),
        &template_weld.triangles,
        &character_weld.gather(character),
        &character_weld.triangles,
        pairs,
        params,
        progress,
    )?;
    let mut report = wrap.report;
    for row in &mut report.piece_matches {
        row.template_vertex = template_weld.vertex(row.template_vertex);
        row.character_vertex = row.character_vertex.map(|c| character_weld.vertex(c));
    }
    for row in &mut report.hole_matches {
        row.template_vertex = template_weld.vertex(row.template_vertex);
        row.character_vertex = character_weld.vertex(row.character_vertex);
    }
    Ok(Wrap { wrapped: template_weld.scatter_moved(wrap.wrapped, template), report })
}

fn wrap_welded(
    template: &[[f32; 3]],
    template_triangles: &[[u32; 3]],
    character: &[[f32; 3]],
    character_triangles: &[[u32; 3]],
    pairs: PointPairs,
    params: &WrapParams,
    progress: &dyn Progress,
) -> ShapesmithResult<Wrap> {
    let started = Instant::now();
    validate_mesh(template, template_triangles, "template")?;
    validate_mesh(character, character_triangles, "character")?;
    validate_points(pairs.template, "template pair points")?;
    validate_points(pairs.character, "character pair points")?;
    if pairs.template.len() != pairs.character.len() {
        return Err(invalid!("{} template pair points but {} character pair points", pairs.template.len(), pairs.character.len()));
    }
    if !pairs.template.is_empty() && pairs.template.len() < MIN_PAIRS {
        return Err(invalid!(
            "{} point pair(s) given; the alignment needs at least {MIN_PAIRS} (e.g. both eye corners, the nose tip and the chin), or none for a rough guess from the principal axes",
            pairs.template.len()
        ));
    }
    let template_points: Vec<Vec3> = template.iter().map(to_f64).collect();
    let character_points: Vec<Vec3> = character.iter().map(to_f64).collect();
    let diagonal = bbox_diagonal(character);
    let template_diagonal = bbox_diagonal(template);
    let mut warnings = Vec::new();

    // The skins: each mesh's largest piece.
    let template_skin = largest_piece(template.len(), template_triangles);
    let character_skin = largest_piece(character.len(), character_triangles);
    let skin_triangles: Vec<[u32; 3]> = pieces_triangles(template_triangles, &template_skin);
    let character_skin_triangles: Vec<[u32; 3]> = pieces_triangles(character_triangles, &character_skin);
    let surface = TargetSurface::new(&character_points, &character_skin_triangles);

    // Pair points on their meshes: a point far off its mesh was placed on another object.
    let template_bvh = TriangleBvh::build(&template_points, template_triangles);
    let character_bvh = TriangleBvh::build(&character_points, character_triangles);
    let mut on_template = Vec::with_capacity(pairs.template.len());
    for (i, (p, q)) in pairs.template.iter().zip(pairs.character).enumerate() {
        let hit = template_bvh.closest_point(&to_f64(p), f64::INFINITY).ok_or_else(|| invalid!("the template has no triangles"))?;
        let off_character = character_bvh.closest_point(&to_f64(q), f64::INFINITY).map_or(f64::INFINITY, |h| h.distance_squared.sqrt());
        for (what, distance, scale) in [("template", hit.distance_squared.sqrt(), template_diagonal), ("character", off_character, diagonal)] {
            if distance > 0.02 * scale {
                return Err(invalid!(
                    "pair {} : its {what} point lies {:.3}% of the {what}'s size away from the {what}'s surface: was it placed on another object?",
                    i + 1,
                    100.0 * distance / scale
                ));
            }
        }
        on_template.push(hit);
    }

    // Similarity.
    let pair_template: Vec<Vec3> = on_template.iter().map(|hit| hit.point).collect();
    let pair_character: Vec<Vec3> = pairs.character.iter().map(to_f64).collect();
    let (similarity, alignment) = if pairs.template.is_empty() {
        warnings.push(
            "no point pairs: the alignment is a guess from the bounding boxes and principal axes; check it, or add pairs".into(),
        );
        let skin_points: Vec<Vec3> = template_skin.iter().map(|&v| template_points[v as usize]).collect();
        let character_skin_points: Vec<Vec3> = character_skin.iter().map(|&v| character_points[v as usize]).collect();
        (similarity_from_principal_axes(&skin_points, &character_skin_points, &surface.bvh, 2000)?, "principal axes")
    } else {
        (similarity_from_pairs(&pair_template, &pair_character)?, "pairs")
    };
    let aligned: Vec<Vec3> = template_points.iter().map(|p| similarity.apply(*p)).collect();
    let mut is_skin = vec![false; template.len()];
    template_skin.iter().for_each(|&v| is_skin[v as usize] = true);
    let mut is_character_skin = vec![false; character.len()];
    character_skin.iter().for_each(|&v| is_character_skin[v as usize] = true);
    // The rims the fit lands on the character's holes (`rims`), from the aligned template.
    let rim_pairing = |aligned: &[Vec3]| rim_targets(aligned, &skin_triangles, &template_skin, &character_points, &character_skin_triangles, &character_skin);
    let (mut rims, mut hole_matches) = if params.align_only { (Vec::new(), Vec::new()) } else { rim_pairing(&aligned) };
    // An avatar's lid holes (`lids`: the character's holes no rim paired): their landmarks join
    // the pairs and the alignment is made again with them, so that the template's lids start
    // on the character's; the rims are then paired again from there.
    let (lid_landmarks, lid_holes) = if params.align_only {
        (Vec::new(), Vec::new())
    } else {
        lids::lid_landmarks(
            &LidMeshes { points: &aligned, triangles: template_triangles, is_skin: &is_skin, skin_triangles: &skin_triangles },
            &LidMeshes { points: &character_points, triangles: character_triangles, is_skin: &is_character_skin, skin_triangles: &character_skin_triangles },
            &hole_matches,
        )
    };
    let (similarity, aligned) = if lid_landmarks.is_empty() || pairs.template.is_empty() {
        (similarity, aligned)
    } else {
        let on_template_lids = lid_landmarks.iter().map(|l| (0..3).fold([0.0; 3], |acc, k| add(acc, scale(template_points[l.corners[k] as usize], l.barycentric[k]))));
        let both_template: Vec<Vec3> = pair_template.iter().copied().chain(on_template_lids).collect();
        let both_character: Vec<Vec3> = pair_character.iter().copied().chain(lid_landmarks.iter().map(|l| l.target)).collect();
        let similarity = similarity_from_pairs(&both_template, &both_character)?;
        let aligned: Vec<Vec3> = template_points.iter().map(|p| similarity.apply(*p)).collect();
        (rims, hole_matches) = rim_pairing(&aligned);
        (similarity, aligned)
    };
    hole_matches.extend(lid_holes);
    let residual = |positions: &[Vec3]| -> Vec<f64> {
        on_template
            .iter()
            .zip(&pair_character)
            .map(|(hit, q)| {
                let t = template_triangles[hit.triangle as usize];
                let p = (0..3).fold([0.0; 3], |acc, k| add(acc, positions[t[k] as usize].map(|x| x * hit.barycentric[k])));
                length(sub(p, *q)) / diagonal
            })
            .collect()
    };
    let aligned_pair_residuals = residual(&aligned);
    let align_seconds = started.elapsed().as_secs_f64();
    progress.checkpoint(0.05)?;

    // Fit.
    let fitting = Instant::now();
    let mut landmarks: Vec<Landmark> = on_template
        .iter()
        .zip(&pair_character)
        .filter_map(|(hit, q)| {
            let corners = template_triangles[hit.triangle as usize];
            corners.iter().all(|&v| is_skin[v as usize]).then_some(Landmark { corners, barycentric: hit.barycentric, target: *q })
        })
        .collect();
    let user_landmarks = landmarks.len();
    let character_skin_points: Vec<Vec3> = character_skin.iter().map(|&v| character_points[v as usize]).collect();
    let (mut symmetry, mirror) = if params.ignore_symmetry {
        (WrapSymmetry { reason: "symmetry ignored (asked)".into(), ..Default::default() }, None)
    } else {
        wrap_symmetry(template, &is_skin, &aligned, &character_skin_points, &surface, diagonal)
    };
    if let Some((partner, plane)) = &mirror {
        let template_plane = MirrorPlane::of_partners(&template_points, partner, &is_skin);
        let mirrored = mirrored_landmarks(&on_template, &pair_character, template_plane, plane, &template_bvh, &character_bvh, template_triangles, &is_skin, template_diagonal);
        symmetry.mirrored_pairs = mirrored.len();
        landmarks.extend(mirrored);
    }
    let fit_mirror = mirror.as_ref().map(|(partner, plane)| FitMirror { partner, plane: *plane, used: &is_skin });
    // A symmetric template whose plane did not cover the character before the fit is tried
    // again on the fitted template (its plane symmetrises the result).
    let mirror_after_fit = (mirror.is_none() && !params.ignore_symmetry && symmetry.template_coverage >= symmetry::MIN_COVERAGE)
        .then(|| symmetry::template_mirror(template, &is_skin).partner);
    let mut piece_matches = Vec::new();
    let (fitted, fit) = if params.align_only {
        (aligned.clone(), FitStats::default())
    } else {
        let stage = Stage { whole: progress, start: 0.05, span: 0.9 };
        landmarks.extend(lid_landmarks);
        let (mut fitted, stats) =
            fit_skin(&aligned, &template_skin, &skin_triangles, &landmarks, &rims, &surface, &params.fit, diagonal, fit_mirror.as_ref(), &stage)?;
        carry_pieces(&aligned, &mut fitted, template_triangles, &is_skin)?;
        piece_matches = fit_pieces(&aligned, &mut fitted, template_triangles, &is_skin, &character_points, character_triangles, &is_character_skin);
        let every = vec![true; fitted.len()];
        if let Some((partner, plane)) = &mirror {
            symmetry::symmetrize(&mut fitted, partner, &every, plane);
        } else if let Some(partner) = &mirror_after_fit {
            // The plane carried by the alignment was too far off (a strongly warped identity):
            // the fitted template's own plane, refined on the character, may cover it.
            if let Some(start) = MirrorPlane::of_partners(&fitted, partner, &is_skin) {
                let (plane, coverage) = symmetry::refine_plane(start, &character_skin_points, &surface, diagonal);
                if coverage >= symmetry::MIN_COVERAGE {
                    symmetry::symmetrize(&mut fitted, partner, &every, &plane);
                    symmetry = WrapSymmetry { symmetric: true, reason: String::new(), character_coverage: coverage, plane: Some(plane), ..symmetry };
                }
            }
        }
        (fitted, stats)
    };
    let distances: Vec<f64> = template_skin
        .iter()
        .map(|&v| surface.bvh.closest_point(&fitted[v as usize], f64::INFINITY).map_or(0.0, |h| h.distance_squared.sqrt()) / diagonal)
        .collect();
    let report = WrapReport {
        alignment: alignment.into(),
        similarity,
        pairs: pairs.template.len(),
        landmarks: user_landmarks,
        mean_distance: distances.iter().sum::<f64>() / distances.len().max(1) as f64,
        max_distance: distances.iter().copied().fold(0.0, f64::max),
        aligned_pair_residuals,
        pair_residuals: residual(&fitted),
        fit,
        pieces: piece_matches.len(),
        pieces_fitted: piece_matches.iter().filter(|m| m.fitted).count(),
        piece_matches,
        holes_paired: hole_matches.len(),
        hole_matches,
        symmetry,
        diagonal,
        template_vertices: template.len(),
        skin_vertices: template_skin.len(),
        character_vertices: character.len(),
        align_seconds,
        fit_seconds: fitting.elapsed().as_secs_f64(),
        warnings,
    };
    progress.checkpoint(1.0)?;
    Ok(Wrap { wrapped: fitted.iter().map(|p| p.map(|x| x as f32)).collect(), report })
}

/// Carries the template's shapes (K x Nt deltas of the wrapped template, shape-major) onto
/// the character's vertices (K x Nc); see the `carry` module. With `template_curve` (K
/// rows: each template shape's curve, added to the template's neutral and whole, in the
/// character's units), every carried shape is judged by it on the character (`penetration`),
/// and with [`CarryParams::collision_pass`] the pass holds those worse than that
/// (`collisions`).
///
/// With `template_neutral` (the template's rest, template vertex order) the carry is
/// symmetric when template and character are (`symmetry`; the result's `symmetry` says which
/// was done and the mirror misses); with `template_shapes` too (the template's own deltas,
/// K x Nt, template space, the shapes of `template_deltas` in their order) a matched piece's
/// keys are the template piece's own motion mapped by the similarity that placed it
/// (`pieces::PieceMapping`: eyeballs turn as eyeballs, teeth follow the jaw).
///
/// Carried between the welded surfaces: the wrapped template's ([`Weld::of_rig`], as the
/// transfer welds it) and the character's own (its UV seams), so that every copy of a
/// character seam vertex gets the same delta, bit for bit.
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
    if wrapped.is_empty()
        || !template_deltas.len().is_multiple_of(wrapped.len())
        || template_neutral.is_some_and(|t| t.len() != wrapped.len())
        || template_shapes.is_some_and(|t| t.len() != template_deltas.len())
    {
        return carry_welded(wrapped, template_triangles, template_deltas, character, character_triangles, template_curve, template_neutral, template_shapes, params, progress);
    }
    let template_weld = Weld::of_rig(wrapped, template_deltas, template_triangles);
    let character_weld = Weld::new(character, character_triangles);
    let mut result = carry_welded(
        &template_weld.gather(wrapped),
        &template_weld.triangles,
        &template_weld.gather(template_deltas),
        &character_weld.gather(character),
        &character_weld.triangles,
        template_curve,
        template_neutral.map(|neutral| template_weld.gather(neutral)).as_deref(),
        template_shapes.map(|shapes| template_weld.gather(shapes)).as_deref(),
        params,
        progress,
    )?;
    result.deltas = character_weld.scatter_motion(std::mem::take(&mut result.deltas));
    Ok(result)
}

#[allow(clippy::too_many_arguments)]
fn carry_welded(
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
    validate_mesh(wrapped, template_triangles, "wrapped template")?;
    validate_mesh(character, character_triangles, "character")?;
    if !template_deltas.len().is_multiple_of(wrapped.len()) {
        return Err(invalid!("template deltas: {} rows is not a multiple of the {} template vertices", template_deltas.len(), wrapped.len()));
    }
    validate_points(template_deltas, "template deltas")?;
    if !(params.static_fraction >= 0.0 && params.static_fraction < 1.0) {
        return Err(invalid!("static_fraction must be in [0, 1), got {}", params.static_fraction));
    }
    if !(params.anchor_length >= 0.0 && params.anchor_length.is_finite() && params.max_angle_degrees > 0.0) {
        return Err(invalid!("anchor_length must be at least 0 and max_angle positive"));
    }
    if let Some(curve) = template_curve {
        if curve.len() != template_deltas.len() / wrapped.len() {
            return Err(invalid!("{} template curve rows for {} shapes", curve.len(), template_deltas.len() / wrapped.len()));
        }
        let finite = |a: &AddedCurve| a.inside.is_finite() && a.between.is_finite();
        if !curve.iter().all(|c| finite(&c.added) && finite(&c.crossing)) {
            return Err(invalid!("the template's curve has non-finite values"));
        }
    }
    let collision = [params.collision_margin, params.collision_stiffness, params.collision_tolerance];
    if !collision.iter().all(|x| x.is_finite() && *x >= 0.0) || params.collision_stiffness <= 0.0 {
        return Err(invalid!("collision margin and tolerance must be at least 0 and the stiffness positive"));
    }
    if let Some(neutral) = template_neutral {
        if neutral.len() != wrapped.len() {
            return Err(invalid!("the template's rest has {} vertices but the wrapped template {}", neutral.len(), wrapped.len()));
        }
        validate_points(neutral, "template neutral")?;
    }
    if let Some(shapes) = template_shapes {
        if template_neutral.is_none() || shapes.len() != template_deltas.len() {
            return Err(invalid!("the template's own shapes need its rest, and as many rows as the wrapped template's deltas ({} for {})", shapes.len(), template_deltas.len()));
        }
        validate_points(shapes, "template shapes")?;
    }
    carry::carry_shapes(wrapped, template_triangles, template_deltas, character, character_triangles, template_curve, template_neutral, template_shapes, params, progress)
}

/// The symmetry of template and character (`symmetry`): the template's vertex map and the
/// character's plane when both cover [`symmetry::MIN_COVERAGE`] of their skin, else why not.
fn wrap_symmetry(
    template: &[[f32; 3]],
    is_skin: &[bool],
    aligned: &[Vec3],
    character_skin: &[Vec3],
    character_surface: &TargetSurface,
    diagonal: f64,
) -> (WrapSymmetry, Option<(Vec<Option<u32>>, MirrorPlane)>) {
    let found = symmetry::template_mirror(template, is_skin);
    let mut report = WrapSymmetry { template_axis: found.axis, template_coverage: found.coverage, ..Default::default() };
    let minimum = 100.0 * symmetry::MIN_COVERAGE;
    if found.coverage < symmetry::MIN_COVERAGE {
        report.reason = format!(
            "the template is not mirror-symmetric across X, Y or Z = 0 (its best mirror map covers {:.0}% of its skin, {minimum:.0}% needed)",
            100.0 * found.coverage
        );
        return (report, None);
    }
    let Some(start) = MirrorPlane::of_partners(aligned, &found.partner, is_skin) else {
        report.reason = "the template's mirror map pairs no vertices apart".into();
        return (report, None);
    };
    let (plane, coverage) = symmetry::refine_plane(start, character_skin, character_surface, diagonal);
    report.character_coverage = coverage;
    report.plane = Some(plane);
    if coverage < symmetry::MIN_COVERAGE {
        report.reason = format!(
            "the character is not mirror-symmetric: {:.0}% of its skin's vertices mirror onto its surface ({minimum:.0}% needed)",
            100.0 * coverage
        );
        return (report, None);
    }
    report.symmetric = true;
    (report, Some((found.partner, plane)))
}

/// The mirror images of the point pairs as landmarks: each template point reflected across
/// the template's plane and snapped onto its surface, tied to its character point reflected
/// across the character's plane and snapped onto its surface. Pairs on the plane (their image
/// is themselves) and images off the skin are left out.
#[allow(clippy::too_many_arguments)]
fn mirrored_landmarks(
    on_template: &[crate::geometry::closest_point::SurfacePoint],
    pair_character: &[Vec3],
    template_plane: Option<MirrorPlane>,
    character_plane: &MirrorPlane,
    template_bvh: &TriangleBvh,
    character_bvh: &TriangleBvh,
    template_triangles: &[[u32; 3]],
    is_skin: &[bool],
    template_diagonal: f64,
) -> Vec<Landmark> {
    let Some(template_plane) = template_plane else { return Vec::new() };
    on_template
        .iter()
        .zip(pair_character)
        .filter_map(|(hit, q)| {
            let image = template_plane.reflect(hit.point);
            if length(sub(image, hit.point)) < 1e-3 * template_diagonal {
                return None;
            }
            let on = template_bvh.closest_point(&image, 0.02 * template_diagonal)?;
            let corners = template_triangles[on.triangle as usize];
            let target = character_bvh.closest_point(&character_plane.reflect(*q), f64::INFINITY)?.point;
            corners.iter().all(|&v| is_skin[v as usize]).then_some(Landmark { corners, barycentric: on.barycentric, target })
        })
        .collect()
}

fn validate_mesh(points: &[[f32; 3]], triangles: &[[u32; 3]], what: &str) -> ShapesmithResult<()> {
    if points.is_empty() || triangles.is_empty() {
        return Err(invalid!("the {what} has no faces"));
    }
    validate_points(points, what)?;
    validate_triangle_indices(points.len(), triangles)?;
    if bbox_diagonal(points) <= 0.0 {
        return Err(invalid!("the {what} has all its vertices at one point"));
    }
    Ok(())
}

/// The vertices (sorted) of the piece with the most vertices.
fn largest_piece(n: usize, triangles: &[[u32; 3]]) -> Vec<u32> {
    let on_skin = skin_flags(n, triangles);
    (0..n as u32).filter(|&v| on_skin[v as usize]).collect()
}

/// Whether each vertex lies on the mesh's largest piece (by vertices), its skin.
fn skin_flags(n: usize, triangles: &[[u32; 3]]) -> Vec<bool> {
    let (label, count) = connected_components(n, triangles);
    let mut sizes = vec![0usize; count];
    label.iter().for_each(|&l| sizes[l as usize] += 1);
    let biggest = (0..count).max_by_key(|&l| sizes[l]).unwrap_or(0) as u32;
    label.iter().map(|&l| l == biggest).collect()
}

fn pieces_triangles(triangles: &[[u32; 3]], vertices: &[u32]) -> Vec<[u32; 3]> {
    let mut keep = vec![false; vertices.last().map_or(0, |&v| v as usize + 1)];
    vertices.iter().for_each(|&v| keep[v as usize] = true);
    triangles.iter().filter(|t| keep.get(t[0] as usize).copied().unwrap_or(false)).copied().collect()
}
