//! [`transfer_shapes`]: the whole transfer as the add-on runs it (set up, transfer or
//! personalise, score penetration), with the report SPEC section 3 asks for.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use super::penetration::PenetrationBaseline;
use super::{DeformationTransfer, Penetration, PersonaliseParams, TransferParams};
use crate::error::ShapesmithResult;
use crate::invalid;
use crate::progress::{NoProgress, Progress, Stage};

/// Everything [`transfer_shapes`] can be asked to do.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct TransferShapesParams {
    pub transfer: TransferParams,
    pub personalise: PersonaliseParams,
    /// Also run plain transfer (no virtual edges, no personalisation) and report its
    /// penetration beside the result's.
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

/// One shape's penetration: on the result, on the template, and with plain transfer
/// (`between_pieces`: the part of the length where two separate pieces cross, see
/// [`Penetration`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ShapePenetration {
    pub name: String,
    pub length: f64,
    pub pairs: usize,
    pub between_pieces: f64,
    pub template_length: f64,
    pub template_pairs: usize,
    pub template_between_pieces: f64,
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
    pub params: TransferShapesParams,
}

/// Transfers the template's shapes onto `target_neutral` (personalised when `examples` are
/// given) and reports timings and penetration. Returns K x N target deltas.
#[allow(clippy::too_many_arguments)]
pub fn transfer_shapes(
    source_neutral: &[[f32; 3]],
    source_deltas: &[[f32; 3]],
    target_neutral: &[[f32; 3]],
    triangles: &[[u32; 3]],
    names: &[String],
    examples: Option<TrainingExpressions<'_>>,
    params: &TransferShapesParams,
    progress: &dyn Progress,
) -> ShapesmithResult<(Vec<[f32; 3]>, TransferReport)> {
    // Measuring penetration (three sweeps per shape) takes longer than the solves.
    let solved_at = if params.measure_penetration { 0.3 } else { 1.0 };
    let solving = Stage { whole: progress, start: 0.0, span: solved_at };
    let dt = DeformationTransfer::new(source_neutral, target_neutral, triangles, &params.transfer)?;
    let n = dt.n_vertices();
    let mut seconds = StageSeconds { factorisation: dt.setup_seconds, virtual_edges: dt.virtual_edge_seconds, ..Default::default() };
    let (deltas, inert, weights) = match examples {
        Some(ex) if !ex.positions.is_empty() => {
            let out = dt.personalise(source_deltas, names, ex.positions, ex.weights, &params.personalise, &solving)?;
            seconds.personalisation = out.seconds;
            let k = names.len();
            let rows = out.weights.chunks(k.max(1)).map(|r| r.to_vec()).collect();
            (out.deltas, out.inert, rows)
        }
        _ => {
            let out = dt.transfer(source_deltas, names, &solving)?;
            seconds.solves = out.seconds;
            (out.deltas, out.inert, Vec::new())
        }
    };
    let plain = if params.compare_plain && params.measure_penetration {
        let plain_params = TransferParams { virtual_edges: None, ..params.transfer };
        let plain_dt = DeformationTransfer::new(source_neutral, target_neutral, triangles, &plain_params)?;
        Some(plain_dt.transfer(source_deltas, names, &NoProgress)?.deltas)
    } else {
        None
    };

    let (penetration, neutral_penetration, template_neutral_penetration) = if params.measure_penetration {
        let start = Instant::now();
        let on_target = PenetrationBaseline::new(target_neutral, triangles);
        let on_template = PenetrationBaseline::new(source_neutral, triangles);
        let done = AtomicUsize::new(0);
        let per_shape = (0..names.len())
            .into_par_iter()
            .map(|k| {
                let rows = k * n..(k + 1) * n;
                let result = on_target.shape(&deltas[rows.clone()]);
                let template = on_template.shape(&source_deltas[rows.clone()]);
                let plain = plain.as_ref().map(|d| on_target.shape(&d[rows]));
                let row = ShapePenetration {
                    name: names[k].clone(),
                    length: result.length,
                    pairs: result.pairs,
                    between_pieces: result.between_pieces,
                    template_length: template.length,
                    template_pairs: template.pairs,
                    template_between_pieces: template.between_pieces,
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
        (per_shape, Some(on_target.neutral()), Some(on_template.neutral()))
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
        params: *params,
    };
    Ok((deltas, report))
}

/// The self-intersection of a rig's neutral and of each shape at weight 1.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
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
