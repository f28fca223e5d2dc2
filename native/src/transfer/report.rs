//! [`transfer_shapes`]: the whole transfer as the add-on runs it (set up, transfer or
//! personalise, score penetration), with the report method, section 3 asks for.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::OnceLock;
use std::time::Instant;

use rayon::prelude::*;

use crate::geometry::penetration::PenetrationBaseline;
use super::contact::CrossingJudge;
use super::{AddedCurve, ContactOutcome, ContactParams, DeformationTransfer, Penetration, PersonaliseParams, TemplateCurve, TransferParams};
use crate::error::ShapesmithResult;
use crate::geometry::weld::{weld_tolerance, Weld};
use crate::invalid;
use crate::progress::{NoProgress, Progress, Stage};

/// Everything [`transfer_shapes`] can be asked to do: the transfer tool's settings
/// ([`crate::settings`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TransferShapesParams {
    pub transfer: TransferParams,
    pub personalise: PersonaliseParams,
    /// Also run plain transfer (no virtual edges, no contact solve, no personalisation) and
    /// report its penetration beside the result's.
    pub compare_plain: bool,
    /// Score the penetration of every shape (template, result, plain) and of the neutral.
    pub measure_penetration: bool,
}

impl Default for TransferShapesParams {
    /// With the penetration measured: the add-on's report, panel and worse-shape list read it.
    fn default() -> Self {
        Self { transfer: TransferParams::default(), personalise: PersonaliseParams::default(), compare_plain: false, measure_penetration: true }
    }
}

/// Training expressions of the target for personalisation.
#[derive(Clone, Copy, Debug)]
pub struct TrainingExpressions<'a> {
    /// J x N target positions.
    pub positions: &'a [[f32; 3]],
    /// J x K blend weights, row-major.
    pub weights: &'a [f64],
}

/// One shape's penetration: on the result, on the template, before the contact solve and
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
    /// The curve the template's own shape adds to the template's neutral, per part, at the
    /// target's size and units (`template_to_target`), and the template shape's whole curve,
    /// per part, at that size ([`TemplateCurve`]): the curve allowances the wrap holds the keys
    /// it carries onto a character to.
    pub template_added: AddedCurve,
    pub template_crossing: AddedCurve,
    /// The curve the template's shape would let the shape add to the target's neutral, per
    /// part: the more of `template_added` (zero where it removes) and what `template_crossing`
    /// leaves beyond the target neutral's own curve ([`TemplateCurve::allowed`]); the wrap
    /// holds the keys it carries onto another topology to it, where no triangle matches.
    pub allowed: AddedCurve,
    /// The result before the contact solve (equal to the result when the pass left the shape
    /// alone); `None` when the pass is off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub before_contact_length: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub before_contact_pairs: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub before_contact_between_pieces: Option<f64>,
    /// What the contact solve did to the shape.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact: Option<ContactOutcome>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub plain_length: Option<f64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub plain_pairs: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub plain_between_pieces: Option<f64>,
    /// The criterion of method, section 3, per part: the intersection curve of the triangle
    /// pairs the result crosses that neither the target's neutral nor the template's shape
    /// crosses (by triangle, one ring wider where skin slides over what it rests through;
    /// [`crate::geometry::contact::Exemptions`]), the pairs the contact solve takes apart. Zero
    /// in both parts for a faithful copy of the template's shape. The add-on reads these
    /// instead of judging again.
    pub excess: AddedCurve,
    /// The same before the contact solve, and for plain transfer.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub before_contact_excess: Option<AddedCurve>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub plain_excess: Option<AddedCurve>,
}

/// Wall-clock seconds per stage.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct StageSeconds {
    /// Setup: alignment, gradient operators, normal matrix (per-shape factorisations of the
    /// reduced systems are part of `solves`).
    pub factorisation: f64,
    pub virtual_edges: f64,
    pub solves: f64,
    /// The contact solve: its share of the shapes' solves and its setup on the two neutrals.
    pub contact: f64,
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
    /// The factor the criterion reads the template's curve lengths with, in the target's units
    /// (1 unless the two neutrals' sizes are over [`super::deformation::OTHER_UNITS`] apart): a
    /// mesh the keys are carried onto in the target's units is judged with it too.
    pub template_to_target: f64,
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
///
/// Everything is solved on the welded surface ([`transfer_weld`]) and each copy of a seam
/// vertex gets its welded point's delta, bit for bit: the seams stay closed.
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
    let n = source_neutral.len();
    let fits = |rows: usize| n > 0 && rows.is_multiple_of(n);
    let weld = transfer_weld(source_neutral, source_deltas, target_neutral, triangles);
    // Inputs whose sizes disagree go through unwelded, for the solve's own checks to name.
    if weld.is_identity() || target_neutral.len() != n || !fits(source_deltas.len()) || !examples.is_none_or(|e| fits(e.positions.len())) {
        return transfer_welded(source_neutral, source_deltas, target_neutral, triangles, names, examples, template_penetration, params, progress);
    }
    let positions = examples.map(|e| weld.gather(e.positions));
    let examples = examples.zip(positions.as_deref()).map(|(e, positions)| TrainingExpressions { positions, ..e });
    let (deltas, report) = transfer_welded(
        &weld.gather(source_neutral),
        &weld.gather(source_deltas),
        &weld.gather(target_neutral),
        &weld.triangles,
        names,
        examples,
        template_penetration,
        params,
        progress,
    )?;
    Ok((weld.scatter_motion(deltas), report))
}

/// The welded surface template and target share (they have one topology, so one weld): the
/// template's coincident vertices ([`Weld::of_rig`]: copies its shapes move apart stay two
/// points), kept apart where the target neutral holds two copies apart (there the target's
/// surface is cut, and joining them would move one). A seam the importer left on both heads
/// is one point on both; every template shape moves its copies alike, so the template's
/// delta there is the representative's exactly.
pub fn transfer_weld(source_neutral: &[[f32; 3]], source_deltas: &[[f32; 3]], target_neutral: &[[f32; 3]], triangles: &[[u32; 3]]) -> Weld {
    let weld = Weld::of_rig(source_neutral, source_deltas, triangles);
    if target_neutral.len() != source_neutral.len() {
        return weld;
    }
    // The faults of either neutral are left out of both: one topology, one valid surface.
    weld.split_where_apart(target_neutral, weld_tolerance(target_neutral), triangles, &[source_neutral, target_neutral])
}

#[allow(clippy::too_many_arguments)]
fn transfer_welded(
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
    // Measuring penetration (a sweep per shape and one per plain shape) takes longer than the
    // solves, unless the contact solve measured the results as it judged them.
    let pass_measures = params.transfer.contact.is_some() && examples.is_none_or(|e| e.positions.is_empty()) && !params.compare_plain;
    let solved_at = match (params.measure_penetration, pass_measures) {
        (false, _) => 1.0,
        (true, true) => 0.9,
        (true, false) => 0.3,
    };
    let solving = Stage { whole: progress, start: 0.0, span: solved_at };
    let dt = DeformationTransfer::new(source_neutral, target_neutral, triangles, &params.transfer)?;
    let n = dt.n_vertices();
    let mut seconds = StageSeconds { factorisation: dt.setup_seconds, virtual_edges: dt.virtual_edge_seconds, ..Default::default() };
    // The template's own numbers, measured here once when not given: the report needs them
    // for every shape, and the contact solve then judges by them instead of sweeping the
    // template's shapes a second time.
    let measured_template;
    let template_penetration = match template_penetration {
        None if params.measure_penetration => {
            let start = Instant::now();
            measured_template = measure_rig_penetration(source_neutral, source_deltas, triangles)?;
            seconds.penetration += start.elapsed().as_secs_f64();
            Some(&measured_template)
        }
        given => given,
    };
    let mut example_noise = Vec::new();
    let (deltas, inert, weights, contact, before_contact) = match examples {
        Some(ex) if !ex.positions.is_empty() => {
            let out = dt.personalise(source_deltas, names, ex.positions, ex.weights, &params.personalise, &solving)?;
            seconds.personalisation = out.seconds;
            example_noise = out.noise;
            let k = names.len();
            let rows = out.weights.chunks(k.max(1)).map(|r| r.to_vec()).collect();
            (out.deltas, out.inert, rows, None, Vec::new())
        }
        _ => {
            let out = dt.transfer(source_deltas, names, &solving)?;
            seconds.solves = out.seconds;
            seconds.contact = out.contact_seconds;
            (out.deltas, out.inert, Vec::new(), out.contact, out.before_contact)
        }
    };
    let plain = if params.compare_plain && params.measure_penetration {
        let plain_params = TransferParams { virtual_edges: None, contact: None, ..params.transfer };
        let plain_dt = DeformationTransfer::new(source_neutral, target_neutral, triangles, &plain_params)?;
        Some(plain_dt.transfer(source_deltas, names, &NoProgress)?.deltas)
    } else {
        None
    };

    let (penetration, neutral_penetration, template_neutral_penetration) = match template_penetration {
        Some(template) if params.measure_penetration => {
            let start = Instant::now();
            // Swept only for what the contact solve did not already measure (its numbers
            // are those of a sweep of the written shape, to the bit): personalised shapes,
            // the plain comparison, or every shape when the pass is off.
            let baseline = OnceLock::new();
            let on_target = || baseline.get_or_init(|| PenetrationBaseline::new(target_neutral, triangles));
            let neutral = dt.rest_penetration().unwrap_or_else(|| on_target().neutral());
            // The contact solve's judge, or the same built here when the solve is off.
            let own_judge = OnceLock::new();
            let judge = || {
                dt.crossing_judge().unwrap_or_else(|| {
                    own_judge.get_or_init(|| CrossingJudge::new(&dt.source_neutral, &dt.target_neutral, &dt.triangles, ContactParams::default().distance))
                })
            };
            let done = AtomicUsize::new(0);
            let per_shape = (0..names.len())
                .into_par_iter()
                .map(|k| {
                    let rows = k * n..(k + 1) * n;
                    let template_delta = &source_deltas[rows.clone()];
                    let template_moving = OnceLock::new();
                    let template_moving = || template_moving.get_or_init(|| dt.moving_vertices(template_delta));
                    let template_added = AddedCurve::from_penetrations(&template.shapes[k], &template.neutral);
                    // A shape's penetration and the curve it adds beyond what its neutral and the
                    // template's shape cross.
                    let measure = |d: &[[f32; 3]]| {
                        if d.iter().all(|x| *x == [0.0; 3]) {
                            return (neutral, AddedCurve::default());
                        }
                        let (swept, penetration) = on_target().shape_swept(d);
                        // A shape crossing only where its neutral does adds nothing: no need
                        // to sweep the template's shape for what it licenses.
                        if swept.iter().all(|&(a, b, _)| on_target().rest_crosses(a, b)) {
                            return (penetration, AddedCurve::default());
                        }
                        let judge = judge();
                        let exempt = judge.exemptions_near(&dt, template_delta, template_moving(), template_added, &judge.asked(&swept));
                        (penetration, judge.added_curve(&swept, &exempt))
                    };
                    let outcome = contact.as_ref().map(|c| c[k]);
                    let (result, added) = match outcome.and_then(|c| c.penetration.zip(c.added)) {
                        Some(measured) => measured,
                        None => measure(&deltas[rows.clone()]),
                    };
                    let template_shape = template.shapes[k];
                    let before = outcome.map(|c| match (c.plain_penetration.zip(c.plain_added), before_contact.get(k)) {
                        (Some(measured), _) => measured,
                        (None, Some(Some(d))) => measure(d),
                        _ => (result, added),
                    });
                    let plain = plain.as_ref().map(|d| measure(&d[rows]));
                    // The template shape's curve at the target's size (its units and proportions).
                    let template_curve = TemplateCurve::from_penetrations(&template_shape, &template.neutral).scaled(dt.template_to_target);
                    let allowed = template_curve.allowed(&AddedCurve::crossing(&neutral));
                    let (before, before_added) = before.unzip();
                    let (plain, plain_added) = plain.unzip();
                    let row = ShapePenetration {
                        name: names[k].clone(),
                        length: result.length,
                        pairs: result.pairs,
                        between_pieces: result.between_pieces,
                        template_length: template_shape.length,
                        template_pairs: template_shape.pairs,
                        template_between_pieces: template_shape.between_pieces,
                        template_added: template_curve.added,
                        template_crossing: template_curve.crossing,
                        allowed,
                        before_contact_length: before.map(|p| p.length),
                        before_contact_pairs: before.map(|p| p.pairs),
                        before_contact_between_pieces: before.map(|p| p.between_pieces),
                        contact: outcome,
                        plain_length: plain.map(|p| p.length),
                        plain_pairs: plain.map(|p| p.pairs),
                        plain_between_pieces: plain.map(|p| p.between_pieces),
                        excess: added,
                        before_contact_excess: before_added,
                        plain_excess: plain_added,
                    };
                    let finished = done.fetch_add(1, Ordering::Relaxed) + 1;
                    progress.checkpoint(solved_at + (1.0 - solved_at) * finished as f64 / names.len() as f64)?;
                    Ok(row)
                })
                .collect::<ShapesmithResult<Vec<_>>>()?;
            seconds.penetration += start.elapsed().as_secs_f64();
            (per_shape, Some(neutral), Some(template.neutral))
        }
        _ => (Vec::new(), None, None),
    };
    let report = TransferReport {
        shapes: names.len() - inert.len(),
        inert,
        virtual_edges: dt.virtual_edges().len(),
        penetration,
        neutral_penetration,
        template_neutral_penetration,
        template_to_target: dt.template_to_target,
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
///
/// Measured on the welded surface ([`Weld::of_rig`]), as the transfer measures it: triangles
/// that meet across a seam are neighbours, not a crossing.
pub fn measure_rig_penetration(neutral: &[[f32; 3]], deltas: &[[f32; 3]], triangles: &[[u32; 3]]) -> ShapesmithResult<RigPenetration> {
    let n = neutral.len();
    crate::rig::validate_triangle_indices(n, triangles)?;
    crate::rig::validate_points(neutral, "neutral")?;
    if n == 0 || !deltas.len().is_multiple_of(n) {
        return Err(invalid!("deltas hold {} vertex rows, not a multiple of the {n} vertices of the neutral", deltas.len()));
    }
    let weld = Weld::of_rig(neutral, deltas, triangles);
    let (neutral, deltas) = (weld.gather(neutral), weld.gather(deltas));
    let n = weld.n_welded();
    let baseline = PenetrationBaseline::new(&neutral, &weld.triangles);
    let shapes = deltas.par_chunks(n).map(|d| baseline.shape(d)).collect();
    Ok(RigPenetration { neutral: baseline.neutral(), shapes })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transfer::contact_tests::{crossing_lengths, posed, skin_rising_over_teeth};
    use crate::transfer::tests::{lip_closing, lips};
    use crate::transfer::{measure_penetration, ContactParams, VirtualEdgeParams};
    use crate::NoProgress;

    /// `p` turned by 0.5 rad about z and moved: the pass works in the template's frame, the
    /// report measures the shapes where they are written.
    fn moved(p: &[f32; 3]) -> [f32; 3] {
        let (s, c) = 0.5f32.sin_cos();
        [c * p[0] - s * p[1] + 0.3, s * p[0] + c * p[1] - 0.2, p[2] + 0.1]
    }

    /// The root mean square distance of the points from their centroid.
    fn rms_radius(points: &[[f32; 3]]) -> f64 {
        let n = points.len() as f64;
        let c = [0, 1, 2].map(|a| points.iter().map(|p| f64::from(p[a])).sum::<f64>() / n);
        (points.iter().map(|p| (0..3).map(|a| (f64::from(p[a]) - c[a]).powi(2)).sum::<f64>()).sum::<f64>() / n).sqrt()
    }

    /// Runs `transfer_shapes` with and without the contact solve and checks every number the
    /// report gives against an exhaustive sweep of the shape as written; returns the shapes
    /// the pass changed.
    fn check_report(source: &[[f32; 3]], target: &[[f32; 3]], tris: &[[u32; 3]], deltas: &[[f32; 3]], transfer: TransferParams) -> usize {
        let n = source.len();
        let names: Vec<String> = (0..deltas.len() / n).map(|k| format!("shape {k}")).collect();
        let run = |contact: Option<ContactParams>, template: Option<&RigPenetration>| {
            let params = TransferShapesParams {
                transfer: TransferParams { contact, ..transfer },
                measure_penetration: true,
                compare_plain: true,
                ..Default::default()
            };
            transfer_shapes(source, deltas, target, tris, &names, None, template, &params, &NoProgress).unwrap()
        };
        let (out, report) = run(Some(ContactParams::default()), None);
        let (before, _) = run(None, None);
        let template = measure_rig_penetration(source, deltas, tris).unwrap();
        // Given or measured here, the template's numbers are the same and so is the result.
        let (given_out, given_report) = run(Some(ContactParams::default()), Some(&template));
        assert_eq!((given_out, &given_report.penetration), (out.clone(), &report.penetration));
        let neutral = measure_penetration(target, tris);
        assert_eq!(report.neutral_penetration, Some(neutral));
        assert_eq!(report.template_neutral_penetration, Some(template.neutral));
        let mut changed = 0;
        for (k, row) in report.penetration.iter().enumerate() {
            let rows = k * n..(k + 1) * n;
            let exhaustive = |d: &[[f32; 3]]| measure_penetration(&posed(target, d), tris);
            let (result, plain_solve) = (exhaustive(&out[rows.clone()]), exhaustive(&before[rows.clone()]));
            // To the bit: the pass's own sweeps, the pairs it re-tested after a re-solve
            // and the rest pairs of unmoved triangles add up to the exhaustive sweep.
            assert_eq!((row.length, row.pairs, row.between_pieces), (result.length, result.pairs, result.between_pieces), "{k}");
            let before_row = (row.before_contact_length, row.before_contact_pairs, row.before_contact_between_pieces);
            assert_eq!(before_row, (Some(plain_solve.length), Some(plain_solve.pairs), Some(plain_solve.between_pieces)), "{k}");
            let template_shape = measure_penetration(&posed(source, &deltas[rows.clone()]), tris);
            assert_eq!(template.shapes[k], template_shape);
            assert_eq!((row.template_length, row.template_pairs), (template_shape.length, template_shape.pairs));
            // The criterion, per part, against the template's shape in the target's units.
            let ratio = rms_radius(target) / rms_radius(source);
            let units = if ratio.ln().abs() > crate::transfer::deformation::OTHER_UNITS.ln() { ratio } else { 1.0 };
            let template_added = AddedCurve::from_penetrations(&template_shape, &template.neutral).scaled(units);
            let template_crossing = AddedCurve::crossing(&template_shape).scaled(units);
            assert_eq!((row.template_added, row.template_crossing), (template_added, template_crossing));
            // Per part, the more of the template's added curve and its own crossing beyond the
            // target's rest.
            let inside = |p: &Penetration| p.length - p.between_pieces;
            let allowed = AddedCurve {
                inside: template_added.inside.max(0.0).max(template_crossing.inside - inside(&neutral)),
                between: template_added.between.max(0.0).max(template_crossing.between - neutral.between_pieces),
            };
            assert!((row.allowed.inside - allowed.inside).abs() < 1e-12 && (row.allowed.between - allowed.between).abs() < 1e-12);
            // The criterion, by brute force: the curve of the pairs the shape crosses that
            // neither the target's rest nor the template's shape crosses counts, at least where
            // no such pair lies within one ring (the sliding the exemptions allow).
            let (rest_pairs, template_pairs) = (crossing_lengths(target, tris), crossing_lengths(&posed(source, &deltas[rows.clone()]), tris));
            let exempt = |a: u32, b: u32| rest_pairs.iter().chain(&template_pairs).any(|&(x, y, _)| (x, y) == (a, b));
            let touches = |a: u32, x: u32| tris[a as usize].iter().any(|v| tris[x as usize].contains(v));
            let near_exempt = |a: u32, b: u32| {
                rest_pairs.iter().chain(&template_pairs).any(|&(x, y, _)| (touches(a, x) && touches(b, y)) || (touches(a, y) && touches(b, x)))
            };
            let bounds = |d: &[[f32; 3]]| {
                let pairs = crossing_lengths(&posed(target, d), tris);
                let sum = |keep: &dyn Fn(u32, u32) -> bool| pairs.iter().filter(|p| keep(p.0, p.1)).map(|p| p.2).sum::<f64>();
                (sum(&|a, b| !near_exempt(a, b)), sum(&|a, b| !exempt(a, b)))
            };
            let within = |e: AddedCurve, (least, most): (f64, f64)| e.inside >= 0.0 && e.between >= 0.0 && e.total() >= least - 1e-12 && e.total() <= most + 1e-12;
            assert!(within(row.excess, bounds(&out[rows.clone()])), "{k}: {:?} against {:?}", row.excess, bounds(&out[rows.clone()]));
            let before_excess = row.before_contact_excess.expect("traced");
            assert!(within(before_excess, bounds(&before[rows.clone()])), "{k}: {before_excess:?} against {:?}", bounds(&before[rows.clone()]));
            assert!(row.plain_excess.is_some_and(|e| e.inside >= 0.0 && e.between >= 0.0));
            // The contact solve leaves nothing the criterion counts.
            if row.contact.is_some_and(|c| c.applied) {
                assert_eq!(row.excess.total(), 0.0, "{k}");
            }
            changed += usize::from(row.contact.is_some_and(|c| c.applied));
        }
        changed
    }

    #[test]
    fn report_takes_the_passs_numbers_and_they_equal_an_exhaustive_sweep() {
        // Skin resting through the teeth (rest pairs on both heads) rising through the
        // target's lower teeth top; a bump far away; a shape that does not move.
        let (source, target, tris, mut deltas) = skin_rising_over_teeth();
        let n = source.len();
        deltas.extend(vec![[0.0; 3]; n]);
        let target: Vec<[f32; 3]> = target.iter().map(moved).collect();
        let plain = TransferParams { virtual_edges: None, ..Default::default() };
        assert!(check_report(&source, &target, &tris, &deltas, plain) >= 1, "the pass should re-solve the rise");
        // Thick lips that virtual edges alone leave crossed, one piece.
        let (source, tris) = lips(0.08);
        let closing = lip_closing(&source, 0.08, 0.036);
        let target: Vec<[f32; 3]> = lips(0.04).0.iter().map(moved).collect();
        let springs = TransferParams { virtual_edges: Some(VirtualEdgeParams { tau_d: 0.05, ..Default::default() }), edge_weight: 1.0, ..Default::default() };
        assert_eq!(check_report(&source, &target, &tris, &closing, springs), 1, "the pass should re-solve the lips");
    }

    #[test]
    fn the_criterion_reads_the_templates_curve_at_the_targets_size_and_units() {
        // The template's own shape presses the lips through each other (the artist's
        // contact). Onto the template itself in centimetres (x100, moved and turned) the
        // transfer is the template's shape at that size: it adds exactly the template's curve,
        // x100, so it meets the criterion and the pass leaves it alone. Compared with the
        // template's curve in metres, it would add 100 times too much, and the pass would pull
        // the lips apart.
        let (source, tris) = lips(0.1);
        let pressing = lip_closing(&source, 0.1, 0.12);
        let template = measure_rig_penetration(&source, &pressing, &tris).unwrap();
        assert!(template.shapes[0].length > template.neutral.length + 0.05, "the template's shape should cross: {template:?}");
        let names = vec!["press".to_owned()];
        let transfer = TransferParams { contact: Some(ContactParams::default()), ..Default::default() };
        let params = TransferShapesParams { transfer, measure_penetration: true, ..Default::default() };
        for scale in [1.0f32, 100.0] {
            let target: Vec<[f32; 3]> = source.iter().map(|p| moved(&p.map(|x| scale * x))).collect();
            let (out, report) = transfer_shapes(&source, &pressing, &target, &tris, &names, None, Some(&template), &params, &NoProgress).unwrap();
            let row = &report.penetration[0];
            assert!(row.contact.is_some_and(|c| !c.applied), "scale {scale}: {:?}", row.contact);
            assert!(row.excess.inside + row.excess.between <= 1e-4 * f64::from(scale), "scale {scale}: {:?}", row.excess);
            let curve = (row.length - report.neutral_penetration.expect("measured").length) / f64::from(scale);
            let template_curve = template.shapes[0].length - template.neutral.length;
            assert!((curve - template_curve).abs() <= 1e-3 * template_curve, "scale {scale}: {curve} against {template_curve}");
            let expected: Vec<[f32; 3]> = source.iter().zip(&pressing).map(|(p, d)| moved(&[0, 1, 2].map(|a| scale * (p[a] + d[a])))).collect();
            let largest = out.iter().zip(&target).zip(&expected).map(|((d, t), e)| (0..3).map(|a| (t[a] + d[a] - e[a]).abs()).fold(0.0f32, f32::max)).fold(0.0, f32::max);
            assert!(largest <= 1e-4 * scale, "scale {scale}: the shape moved off the template's by {largest}");
        }
    }

    #[test]
    fn a_copy_crossing_where_only_the_templates_neutral_crosses_is_worse_and_the_solve_clears_it() {
        // The template's neutral lips press past each other (0.06 each way across the 0.1
        // gap) and its shape presses 0.09 further: its shape crosses over a wider contour than
        // its neutral. The target's neutral lips are clean, 0.1 apart; the shape copied onto
        // them crosses (0.09 each way) over a contour narrower than the template shape's.
        let (clean, tris) = lips(0.1);
        let source = posed(&clean, &lip_closing(&clean, 0.1, 0.06));
        let pressing = lip_closing(&clean, 0.1, 0.09);
        let template = measure_rig_penetration(&source, &pressing, &tris).unwrap();
        let names = vec!["mouthRollUpper".to_owned()];
        let judged = |target: &[[f32; 3]], contact: Option<ContactParams>| {
            let transfer = TransferParams { virtual_edges: None, contact, ..Default::default() };
            let params = TransferShapesParams { transfer, measure_penetration: true, ..Default::default() };
            transfer_shapes(&source, &pressing, target, &tris, &names, None, Some(&template), &params, &NoProgress).unwrap()
        };
        let (template_rest, template_shape) = (template.neutral, template.shapes[0]);
        assert!(template_rest.length > 0.0 && template_shape.length > template_rest.length, "{template:?}");
        let (out, report) = judged(&clean, Some(ContactParams::default()));
        let (_, without_report) = judged(&clean, None);
        let row = &without_report.penetration[0];
        assert_eq!(report.neutral_penetration.map(|p| p.pairs), Some(0));
        // The copy crosses less curve than the template's shape, and a judge of curve lengths
        // would let it be. But the lips cross where only the template's neutral crosses: no
        // crossing its shape makes, over a target whose lips are clean at rest. Worse, inside
        // one piece, by the curve of those pairs.
        assert!(row.length > 0.0 && row.length < template_shape.length, "{row:?} against the template's {template_shape:?}");
        assert!(row.excess.inside > 1e-3 && row.excess.inside <= row.length && row.excess.between == 0.0, "{row:?}");
        // The contact solve takes those pairs apart: nothing left for the judge, and what still
        // crosses, where the template's shape crosses, crosses no further than it does.
        let row = &report.penetration[0];
        assert!(row.contact.is_some_and(|c| c.applied && c.added_pairs > 0 && c.remaining_pairs == 0), "{:?}", row.contact);
        assert_eq!(row.excess.total(), 0.0);
        assert!(row.before_contact_excess.is_some_and(|e| e == without_report.penetration[0].excess), "{row:?}");
        assert!(measure_penetration(&posed(&clean, &out), &tris).length <= template_shape.length);
        // Onto the template's own neutral the same transfer is a faithful copy: every pair it
        // crosses, the template's neutral or its shape crosses. Not worse, and left alone.
        let (copy, report) = judged(&source, Some(ContactParams::default()));
        let row = &report.penetration[0];
        assert_eq!(row.excess.total(), 0.0, "{row:?}");
        assert!(row.contact.is_some_and(|c| !c.applied), "{:?}", row.contact);
        let largest = copy.iter().zip(&pressing).map(|(a, b)| (0..3).map(|i| (a[i] - b[i]).abs()).fold(0.0f32, f32::max)).fold(0.0, f32::max);
        assert!(largest <= 1e-5, "the copy moved off the template's shape by {largest}");
    }
}
