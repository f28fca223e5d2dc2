//! The transfer's contact solve (method, section 3; Incremental Potential Contact, Li et al.
//! 2020): a solved shape that adds a crossing to the target's neutral, beyond those its
//! neutral has and the contacts the template's own shape makes, is solved again with the
//! barrier over the region around the added crossings ([`ContactScene::resolve`]). Every
//! other shape is returned bit for bit: the template onto its own neutral has nothing to do,
//! since each contact of its result is one its template shape makes.
//!
//! The shape's energy is the transfer's own (gradients and virtual edges, the normal matrix
//! `A`), whose minimiser is the plain solve; static pieces (teeth, eyeballs) are not unknowns.
//! The crossings are read where the keys are written (the target's own frame, f32), as the
//! report measures them, so its numbers are taken from here to the bit.

use rayon::prelude::*;

use super::deformation::DeformationTransfer;
use super::gradients::{add, sub, to_f64, Vec3};
use crate::error::ShapesmithResult;
use crate::geometry::bvh::TriangleBvh;
use crate::geometry::contact::{ContactScene, Exemptions, NewtonParams, TemplateShape};
use crate::geometry::penetration::{crossings, shape_penetration, triangle_pieces, AddedCurve, Penetration};

/// Knobs of the contact solve, defaults from method, section 3.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ContactParams {
    /// `d_hat`, the distance below which two surfaces push each other apart, as a fraction of
    /// the mean length of the edges at a vertex on the target's neutral (method: a quarter).
    pub distance: f64,
}

impl Default for ContactParams {
    fn default() -> Self {
        Self { distance: 0.25 }
    }
}

/// What the contact solve did to one shape.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct ContactOutcome {
    /// Crossing triangle pairs the plain solve added (neither at the target's rest nor the
    /// template shape's own contacts).
    pub added_pairs: usize,
    /// Added pairs left in the result (0: the solve keeps every iterate apart).
    pub remaining_pairs: usize,
    /// Unknowns of the contact solve (vertices).
    pub region_vertices: usize,
    /// Newton iterations.
    pub iterations: usize,
    /// Whether the solve started from the plain solve untangled ([`crate::geometry::contact::untangle`]);
    /// when not, around what the untangling left it started at the neutral.
    pub untangled: bool,
    /// Pairs within `d_hat` at the end: the contacts the barrier holds.
    pub contacts: usize,
    pub converged: bool,
    /// Whether the result is the contact solve's; `false` when the plain solve added nothing.
    pub applied: bool,
    /// The penetration of the result and of the plain solve, from the sweeps of the written
    /// positions (equal to [`crate::geometry::penetration::measure_penetration`] of them to
    /// the bit): the report reads them instead of sweeping the shapes again.
    #[serde(skip)]
    pub penetration: Option<Penetration>,
    #[serde(skip)]
    pub plain_penetration: Option<Penetration>,
    /// The curve the result and the plain solve add beyond the exemptions, per part
    /// ([`CrossingJudge::added_curve`]): the report's criterion, taken from here.
    #[serde(skip)]
    pub added: Option<AddedCurve>,
    #[serde(skip)]
    pub plain_added: Option<AddedCurve>,
}

/// What a shape is judged by (method, section 3): the two neutrals (working frame) as the
/// contact solve sees them, whose exemptions (the crossings of the target's rest and of the
/// template's shape, by triangle) decide which crossings a shape adds. The report counts
/// exactly the crossings the contact solve removes.
pub(super) struct CrossingJudge {
    target: ContactScene,
    template: ContactScene,
}

impl CrossingJudge {
    /// `distance`: the contact solve's `d_hat` ([`ContactParams::distance`]); the judgement
    /// itself does not depend on it.
    pub(super) fn new(source: &[Vec3], target: &[Vec3], triangles: &[[u32; 3]], distance: f64) -> Self {
        let (target, template) = rayon::join(|| ContactScene::new(target, triangles, distance), || ContactScene::new(source, triangles, distance));
        Self { target, template }
    }

    /// What a target shape transferred from the template's shape `delta` (moving vertices
    /// `moving`) may leave crossing.
    pub(super) fn exemptions(&self, dt: &DeformationTransfer, delta: &[[f32; 3]], moving: &[bool]) -> Exemptions {
        let positions = template_positions(dt, delta);
        self.target.exemptions(Some(TemplateShape { scene: &self.template, positions: &positions, moving, scale: dt.template_to_target }))
    }

    /// [`Self::exemptions`] enough to judge the pairs `asked` ([`ContactScene::exemptions_near`]):
    /// `added`, the curve the template's shape adds to its neutral, per part.
    pub(super) fn exemptions_near(&self, dt: &DeformationTransfer, delta: &[[f32; 3]], moving: &[bool], added: AddedCurve, asked: &[(u32, u32)]) -> Exemptions {
        let positions = template_positions(dt, delta);
        let template = TemplateShape { scene: &self.template, positions: &positions, moving, scale: dt.template_to_target };
        self.target.exemptions_near(template, added, asked)
    }

    /// The pairs of `swept` not crossing at the target's rest: all the judge needs to ask of
    /// the template's shape.
    pub(super) fn asked(&self, swept: &[(u32, u32, f64)]) -> Vec<(u32, u32)> {
        swept.iter().filter(|&&(a, b, _)| !self.target.rest_crosses(a, b)).map(|&(a, b, _)| (a, b)).collect()
    }

    /// The curve of the crossings of `swept` beyond `exempt`, per part.
    pub(super) fn added_curve(&self, swept: &[(u32, u32, f64)], exempt: &Exemptions) -> AddedCurve {
        self.target.added_curve(swept, exempt)
    }
}

/// The template's shape `delta` posed on its neutral, in the working frame.
fn template_positions(dt: &DeformationTransfer, delta: &[[f32; 3]]) -> Vec<Vec3> {
    dt.source_neutral.iter().zip(delta).map(|(p, d)| add(*p, to_f64(d))).collect()
}

/// What the contact solve needs of the two neutrals, computed once per transfer.
pub(super) struct ContactGuard {
    pub(super) judge: CrossingJudge,
    /// The target's neutral as written (its own frame, f32), its hierarchy and rest crossings.
    written_neutral: Vec<[f32; 3]>,
    written_bvh: TriangleBvh,
    rest_swept: Vec<(u32, u32, f64)>,
    triangle_piece: Vec<u32>,
    pub(super) rest_penetration: Penetration,
}

impl ContactGuard {
    /// `source` and `target` in the working frame, `written_neutral` as given.
    pub(super) fn new(source: &[Vec3], target: &[Vec3], written_neutral: &[[f32; 3]], triangles: &[[u32; 3]], params: ContactParams) -> Self {
        let (judge, (written_bvh, rest_swept)) = rayon::join(
            || CrossingJudge::new(source, target, triangles, params.distance),
            || {
                let written: Vec<Vec3> = written_neutral.iter().map(to_f64).collect();
                let bvh = TriangleBvh::build(&written, triangles);
                let swept = crossings(&written, triangles, &bvh, None);
                (bvh, swept)
            },
        );
        let triangle_piece = triangle_pieces(target.len(), triangles);
        let rest_penetration = shape_penetration(&[], &rest_swept, &vec![false; triangles.len()], &triangle_piece);
        Self { judge, written_neutral: written_neutral.to_vec(), written_bvh, rest_swept, triangle_piece, rest_penetration }
    }

    /// The crossings of the shape whose working-frame deltas are `deltas`, swept where they
    /// are written, and its penetration.
    fn sweep(&self, dt: &DeformationTransfer, deltas: &[Vec3]) -> (Vec<(u32, u32, f64)>, Penetration) {
        let written = dt.to_target_frame(deltas);
        let points: Vec<Vec3> = self.written_neutral.iter().zip(&written).map(|(p, d)| [0, 1, 2].map(|a| (p[a] + d[a]) as f64)).collect();
        let moved: Vec<bool> = dt.triangles.par_iter().map(|t| t.iter().any(|&v| written[v as usize] != [0.0; 3])).collect();
        let swept = crossings(&points, &dt.triangles, &self.written_bvh.refitted(&points, &dt.triangles), Some(&moved));
        let penetration = shape_penetration(&swept, &self.rest_swept, &moved, &self.triangle_piece);
        (swept, penetration)
    }
}

impl DeformationTransfer {
    /// Runs the contact solve on the solved deltas `out` (working frame) of the template shape
    /// `delta`, whose moving vertices are `moving`.
    pub(super) fn contact_solve(&self, guard: &ContactGuard, delta: &[[f32; 3]], moving: &[bool], out: &mut [Vec3]) -> ShapesmithResult<ContactOutcome> {
        let (swept, plain) = guard.sweep(self, out);
        let none = Some(AddedCurve::default());
        let mut outcome =
            ContactOutcome { penetration: Some(plain), plain_penetration: Some(plain), added: none, plain_added: none, ..Default::default() };
        let (scene, judge) = (&guard.judge.target, &guard.judge);
        if swept.iter().all(|&(a, b, _)| scene.rest_crosses(a, b)) {
            return Ok(outcome);
        }
        let exempt = judge.exemptions(self, delta, moving);
        let added = scene.added_crossings(&swept, &exempt);
        outcome.added_pairs = added.len();
        if added.is_empty() {
            return Ok(outcome);
        }
        outcome.plain_added = Some(judge.added_curve(&swept, &exempt));
        let minimiser: Vec<Vec3> = self.target_neutral.iter().zip(out.iter()).map(|(p, d)| add(*p, *d)).collect();
        let resolved = scene.resolve(self.matrix.rows(), &minimiser, moving, &added, &exempt, &NewtonParams::default())?;
        for &v in &resolved.region {
            out[v] = sub(resolved.newton.positions[v], self.target_neutral[v]);
        }
        let (swept, result) = guard.sweep(self, out);
        Ok(ContactOutcome {
            remaining_pairs: scene.added_crossings(&swept, &exempt).len(),
            added: Some(judge.added_curve(&swept, &exempt)),
            region_vertices: resolved.region.len(),
            iterations: resolved.newton.iterations,
            untangled: resolved.untangled,
            contacts: resolved.newton.contacts,
            converged: resolved.newton.converged,
            applied: true,
            penetration: Some(result),
            ..outcome
        })
    }
}
