//! [`transfer_shapes`]: the whole transfer as the add-on runs it (set up, transfer or
//! personalise, score penetration), with the report SPEC section 3 asks for.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use crate::geometry::penetration::PenetrationBaseline;
use super::{AddedCurve, CollisionOutcome, DeformationTransfer, Penetration, PersonaliseParams, TransferParams};
use crate::error::ShapesmithResult;
use crate::invalid;
use crate::progress::{NoProgress, Progress, Stage};

/// Everything [`transfer_shapes`] can be asked to do.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct TransferShapesParams {
    pub transfer: TransferParams,
    pub personalise: PersonaliseParams,
    /// Also run plain transfer (no virtual edges, no collision pass, no personalisation) and
    /// report its penetration beside the result's.
    pub compare_plain: bool,
    /// Score the penetration of every shape (template, result, plain) and of the neutral.
    pub measure_penetration: bool,
}

/// Training expressions of the target for personalisation.
#[derive(Clone, Copy, Debug)]
pub struct TrainingExpressions<'a> {
    /// J x N target positions.
    pub positions: &'a [[f32; 3]],
    /// J x K blend weights, row-major.
    pub weights: &'a [f64],
}

/// One shape's penetration: on the result, on the template, before the collision pass and
/// with plain transfer (`between_pieces`: the part of the length where two separate pieces
/// cross, see [`Penetration`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ShapePenetration {
    pub name: String,
    pub length: f64,
    pub pairs: usize,
    pub between_pieces: f64,
    pub template_length: f64,
    pub template_pairs: usize,
    pub template_between_pieces: f64,
    /// The result before the collision pass (equal to the result when the pass left the shape
    /// alone); `None` when the pass is off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub before_collisions_length: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub before_collisions_pairs: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub before_collisions_between_pieces: Option<f64>,
    /// What the collision pass did to the shape.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub collisions: Option<CollisionOutcome>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub plain_length: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub plain_pairs: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub plain_between_pieces: Option<f64>,
}

/// Wall-clock seconds per stage.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct StageSeconds {
    /// Setup: alignment, gradient operators, normal matrix (per-shape factorisations of the
    /// reduced systems are part of `solves`).
    pub factorisation: f64,
    pub virtual_edges: f64,
    pub solves: f64,
    /// The collision pass: its share of the shapes' solves and the sweep of the target neutral.
    pub collisions: f64,
    pub personalisation: f64,
    pub penetration: f64,
}

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct TransferReport {
    /// Shapes transferred (every non-inert shape).
    pub shapes: usize,
    /// Shapes that do not move in the template: written as zero deltas.
    pub inert: Vec<String>,
    pub virtual_edges: usize,
    /// Per shape, empty unless penetration was measured.
    pub penetration: Vec<ShapePenetration>,
    /// The target neutral's own self-intersection, when measured.
    pub neutral_penetration: Option<Penetration>,
    /// The template neutral's, when measured: each shape is judged by what it adds to its
    /// neutral (the MakeHuman heads' eyes, teeth and lashes already cross the skin at rest).
    pub template_neutral_penetration: Option<Penetration>,
    pub seconds: StageSeconds,
    /// J x K weights the personalisation used (refined, or as given); empty without examples.
    pub weights: Vec<Vec<f64>>,
    /// Per training expression, the scan noise the personalisation estimated from the vertices
    /// none of its shapes moves (standard deviation per coordinate, target units); empty
    /// without examples.
    pub example_noise: Vec<f64>,
    pub params: TransferShapesParams,
}

/// Transfers the template's shapes onto `target_neutral` (personalised when `examples` are
/// given) and reports timings and penetration. Returns K x N target deltas.
///
/// `template_penetration`, when given, is the template's own (from
/// [`measure_rig_penetration`] on the template: the same for every target, so a batch over
/// many targets measures it once); otherwise it is measured here.
#[allow(clippy::too_many_arguments)]
pub fn transfer_shapes(
    source_neutral: &[[f32; 3]],
    source_deltas: &[[f32; 3]],
    target_neutral: &[[f32; 3]],
    triangles: &[[u32; 3]],
    names: &[String],
    examples: Option<TrainingExpressions<'_>>,
    template_penetration: Option<&RigPenetration>,
    params: &TransferShapesParams,
    progress: &dyn Progress,
) -> ShapesmithResult<(Vec<[f32; 3]>, TransferReport)> {
    if let Some(given) = template_penetration {
        if given.shapes.len() != names.len() {
            return Err(invalid!(
                "the template penetration given has {} shapes but the template has {}: measure it on the same template",
                given.shapes.len(),
                names.len()
            ));
        }
    }
    // Measuring penetration (three sweeps per shape) takes longer than the solves.
    let solved_at = if params.measure_penetration { 0.3 } else { 1.0 };
    let solving = Stage { whole: progress, start: 0.0, span: solved_at };
    let dt = DeformationTransfer::new(source_neutral, target_neutral, triangles, &params.transfer)?;
    let n = dt.n_vertices();
    let mut seconds = StageSeconds { factorisation: dt.setup_seconds, virtual_edges: dt.virtual_edge_seconds, ..Default::default() };
    let mut example_noise = Vec::new();
    let (deltas, inert, weights, collisions, before_collisions) = match examples {
        Some(ex) if !ex.positions.is_empty() => {
            let out = dt.personalise(source_deltas, names, ex.positions, ex.weights, &params.personalise, &solving)?;
            seconds.personalisation = out.seconds;
            example_noise = out.noise;
            let k = names.len();
            let rows = out.weights.chunks(k.max(1)).map(|r| r.to_vec()).collect();
            (out.deltas, out.inert, rows, None, Vec::new())
        }
        _ => {
            // The template's own numbers, when given, spare the collision pass a sweep of each
            // template shape it has to judge.
            let template_added: Option<Vec<AddedCurve>> = template_penetration.map(|t| {
                let inside = |p: &Penetration| p.length - p.between_pieces;
                let added =
                    |s: &Penetration| AddedCurve { inside: inside(s) - inside(&t.neutral), between: s.between_pieces - t.neutral.between_pieces };
                t.shapes.iter().map(added).collect()
            });
            let out = dt.transfer_judged(source_deltas, names, template_added.as_deref(), &solving)?;
            seconds.solves = out.seconds;
            seconds.collisions = out.collision_seconds;
            (out.deltas, out.inert, Vec::new(), out.collisions, out.before_collisions)
        }
    };
    let plain = if params.compare_plain && params.measure_penetration {
        let plain_params = TransferParams { virtual_edges: None, collisions: None, ..params.transfer };
        let plain_dt = DeformationTransfer::new(source_neutral, target_neutral, triangles, &plain_params)?;
        Some(plain_dt.transfer(source_deltas, names, &NoProgress)?.deltas)
    } else {
        None
    };

    let (penetration, neutral_penetration, template_neutral_penetration) = if params.measure_penetration {
        let start = Instant::now();
        let on_target = PenetrationBaseline::new(target_neutral, triangles);
        let on_template = template_penetration.is_none().then(|| PenetrationBaseline::new(source_neutral, triangles));
        let done = AtomicUsize::new(0);
        let per_shape = (0..names.len())
            .into_par_iter()
            .map(|k| {
                let rows = k * n..(k + 1) * n;
                let result = on_target.shape(&deltas[rows.clone()]);
                let template = match &on_template {
                    Some(baseline) => baseline.shape(&source_deltas[rows.clone()]),
                    None => template_penetration.map(|given| given.shapes[k]).unwrap_or_default(),
                };
                let before = collisions.as_ref().map(|_| match before_collisions.get(k) {
                    Some(Some(d)) => on_target.shape(d),
                    _ => result,
                });
                let plain = plain.as_ref().map(|d| on_target.shape(&d[rows]));
                let row = ShapePenetration {
                    name: names[k].clone(),
                    length: result.length,
                    pairs: result.pairs,
                    between_pieces: result.between_pieces,
                    template_length: template.length,
                    template_pairs: template.pairs,
                    template_between_pieces: template.between_pieces,
                    before_collisions_length: before.map(|p| p.length),
                    before_collisions_pairs: before.map(|p| p.pairs),
                    before_collisions_between_pieces: before.map(|p| p.between_pieces),
                    collisions: collisions.as_ref().map(|c| c[k]),
                    plain_length: plain.map(|p| p.length),
                    plain_pairs: plain.map(|p| p.pairs),
                    plain_between_pieces: plain.map(|p| p.between_pieces),
                };
                let finished = done.fetch_add(1, Ordering::Relaxed) + 1;
                progress.checkpoint(solved_at + (1.0 - solved_at) * finished as f64 / names.len() as f64)?;
                Ok(row)
            })
            .collect::<ShapesmithResult<Vec<_>>>()?;
        seconds.penetration = start.elapsed().as_secs_f64();
        let template_neutral = match &on_template {
            Some(baseline) => baseline.neutral(),
            None => template_penetration.map(|given| given.neutral).unwrap_or_default(),
        };
        (per_shape, Some(on_target.neutral()), Some(template_neutral))
    } else {
        (Vec::new(), None, None)
    };
    let report = TransferReport {
        shapes: names.len() - inert.len(),
        inert,
        virtual_edges: dt.virtual_edges().len(),
        penetration,
        neutral_penetration,
        template_neutral_penetration,
        seconds,
        weights,
        example_noise,
        params: *params,
    };
    Ok((deltas, report))
}

/// The self-intersection of a rig's neutral and of each shape at weight 1.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RigPenetration {
    pub neutral: Penetration,
    pub shapes: Vec<Penetration>,
}

/// [`super::measure_penetration`] of `neutral` and of `neutral + D_k` for each of the K shapes in
/// `deltas` (K x N); triangle indices are checked.
pub fn measure_rig_penetration(neutral: &[[f32; 3]], deltas: &[[f32; 3]], triangles: &[[u32; 3]]) -> ShapesmithResult<RigPenetration> {
    let n = neutral.len();
    crate::rig::validate_triangle_indices(n, triangles)?;
    crate::rig::validate_points(neutral, "neutral")?;
    if n == 0 || !deltas.len().is_multiple_of(n) {
        return Err(invalid!("deltas hold {} vertex rows, not a multiple of the {n} vertices of the neutral", deltas.len()));
    }
    let baseline = PenetrationBaseline::new(neutral, triangles);
    let shapes = deltas.par_chunks(n).map(|d| baseline.shape(d)).collect();
    Ok(RigPenetration { neutral: baseline.neutral(), shapes })
}
