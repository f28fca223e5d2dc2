//! Bindings of [`crate::packing::pack_expressions`] and [`crate::packing::pack_greedy`]:
//! shape names in, shape names out.

use numpy::{PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use serde_json::{json, Value};

use super::arrays;
use super::errors::py_err;
use super::run::detached_with_progress;
use super::settings::settings as read_settings;
use crate::error::ShapesmithResult;
use crate::invalid;
use crate::packing::{self, Packing, PackingParams};
use crate::rig::RigView;
use crate::settings::settings_to_json;

type NamePairs = Vec<(String, String)>;

/// The rig's data both packers take beside their settings, by shape name as Python passed it.
struct Refinements {
    pairs: Option<NamePairs>,
    pin_together: NamePairs,
    keep_apart: NamePairs,
    exclude: Vec<String>,
    /// An earlier report's `known`, as JSON (shape names).
    known: Option<String>,
}

/// [`packing::KnownPoseability`] from the JSON [`known_to_json`] writes (shape names, values
/// as the bits of their f64).
fn known_from_json(text: &str, names: &[String]) -> ShapesmithResult<packing::KnownPoseability> {
    let stale = || invalid!("the stored poseability results do not belong to this rig: pack again without them");
    let value: Value = serde_json::from_str(text).map_err(|_| stale())?;
    let index = |v: &Value| v.as_str().and_then(|n| names.iter().position(|m| m == n)).ok_or_else(stale);
    let pair = |v: &Value| -> ShapesmithResult<(usize, usize)> {
        let (i, j) = (index(&v[0])?, index(&v[1])?);
        Ok((i.min(j), i.max(j)))
    };
    // Bits, not decimals: a reused value must equal the one measured, to the last bit.
    let number = |v: &Value| v.as_u64().map(f64::from_bits).ok_or_else(stale);
    let list = |key: &str| value[key].as_array().cloned().ok_or_else(stale);
    Ok(packing::KnownPoseability {
        collision_tested: list("collision_tested")?.iter().map(pair).collect::<ShapesmithResult<_>>()?,
        collisions: list("collisions")?
            .iter()
            .map(|c| {
                let (first, second) = pair(&c["shapes"])?;
                Ok(packing::collisions::Collision { first, second, added: number(&c["added"])?, between_pieces: number(&c["between_pieces"])? })
            })
            .collect::<ShapesmithResult<_>>()?,
        occlusion_tested: list("occlusion_tested")?.iter().map(pair).collect::<ShapesmithResult<_>>()?,
        occlusions: list("occlusions")?
            .iter()
            .map(|o| Ok(packing::occlusion::Occlusion { hidden: index(&o["hidden"])?, by: index(&o["by"])?, kept: number(&o["kept"])? }))
            .collect::<ShapesmithResult<_>>()?,
    })
}

fn known_to_json(known: &packing::KnownPoseability, names: &[String]) -> Value {
    let pairs = |pairs: &[(usize, usize)]| pairs.iter().map(|&(i, j)| [names[i].clone(), names[j].clone()]).collect::<Vec<_>>();
    json!({
        "collision_tested": pairs(&known.collision_tested),
        "collisions": known.collisions.iter().map(|c| json!({
            "shapes": [names[c.first].clone(), names[c.second].clone()], "added": c.added.to_bits(),
            "between_pieces": c.between_pieces.to_bits(),
        })).collect::<Vec<_>>(),
        "occlusion_tested": pairs(&known.occlusion_tested),
        "occlusions": known.occlusions.iter().map(|o| json!({
            "hidden": names[o.hidden].clone(), "by": names[o.by].clone(), "kept": o.kept.to_bits(),
        })).collect::<Vec<_>>(),
    })
}

impl Refinements {
    /// The settings with the refinements and the stored results as shape indices.
    fn apply(&self, settings: PackingParams, names: &[String]) -> ShapesmithResult<PackingParams> {
        let index = |name: &str, what: &str| {
            names.iter().position(|n| n == name).ok_or_else(|| invalid!("{what}: there is no shape key named '{name}'"))
        };
        let pairs = |list: &NamePairs, what: &str| -> ShapesmithResult<Vec<(usize, usize)>> {
            list.iter().map(|(a, b)| Ok((index(a, what)?, index(b, what)?))).collect()
        };
        Ok(PackingParams {
            pairs: self.pairs.as_ref().map(|p| pairs(p, "pairs")).transpose()?,
            pin_together: pairs(&self.pin_together, "pin_together")?,
            keep_apart: pairs(&self.keep_apart, "keep_apart")?,
            exclude: self.exclude.iter().map(|n| index(n, "exclude")).collect::<ShapesmithResult<_>>()?,
            known: self.known.as_deref().map(|text| known_from_json(text, names)).transpose()?,
            ..settings
        })
    }

    /// The report's `params`: the settings used and the refinements by name.
    fn echo(&self, settings: &PackingParams) -> Value {
        let mut echoed = settings_to_json(settings);
        if let Value::Object(map) = &mut echoed {
            map.insert("pairs".into(), json!(self.pairs));
            map.insert("pin_together".into(), json!(self.pin_together));
            map.insert("keep_apart".into(), json!(self.keep_apart));
            map.insert("exclude".into(), json!(self.exclude));
        }
        echoed
    }
}

type Packer = fn(&RigView, Option<&[[f32; 3]]>, &PackingParams, &dyn crate::Progress) -> ShapesmithResult<Packing>;

#[allow(clippy::too_many_arguments)]
fn run<'py>(
    py: Python<'py>,
    packer: Packer,
    neutral: PyReadonlyArray2<'py, f32>,
    deltas: PyReadonlyArray3<'py, f32>,
    triangles: PyReadonlyArray2<'py, i32>,
    names: Vec<String>,
    target_neutral: Option<PyReadonlyArray2<'py, f32>>,
    settings: PackingParams,
    refinements: Refinements,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let points = arrays::points(&neutral, "neutral").map_err(py_err(py))?;
    let (delta_rows, _) = arrays::deltas(&deltas, points.len()).map_err(py_err(py))?;
    let tris = arrays::triangles(&triangles).map_err(py_err(py))?;
    let target = target_neutral.as_ref().map(|t| arrays::points(t, "target_neutral")).transpose().map_err(py_err(py))?;
    let params = refinements.apply(settings, &names).map_err(py_err(py))?;
    let packing = detached_with_progress(py, progress.as_ref(), |progress| {
        let rig = RigView::new(points, delta_rows, &tris, &names)?;
        packer(&rig, target, &params, progress)
    })?;
    arrays::to_python(py, &named(&packing, &names, refinements.echo(&params)))
}

fn named(p: &Packing, names: &[String], params: Value) -> Value {
    let list = |shapes: &[usize]| shapes.iter().map(|&k| names[k].clone()).collect::<Vec<_>>();
    let pairs = |pairs: &[(usize, usize)]| pairs.iter().map(|&(i, j)| [names[i].clone(), names[j].clone()]).collect::<Vec<_>>();
    json!({
        "expressions": p.expressions.iter().map(|e| json!({
            "shapes": list(&e.shapes), "importance": e.importance, "vertices": e.vertices,
            "status": e.status, "optimal": e.optimal,
        })).collect::<Vec<_>>(),
        "importance": names.iter().cloned().zip(p.importance.iter().map(|&l| json!(l))).collect::<serde_json::Map<String, Value>>(),
        "inert": list(&p.inert),
        "excluded": list(&p.excluded),
        "unplaced": list(&p.unplaced),
        "pairs": pairs(&p.pairs),
        "antagonists": pairs(&p.antagonists),
        "conflicts": p.conflicts.iter().map(|c| json!({
            "shapes": [names[c.first].clone(), names[c.second].clone()], "reasons": c.reasons,
        })).collect::<Vec<_>>(),
        "collisions": p.poseability.collisions.iter().map(|c| json!({
            "shapes": [names[c.first].clone(), names[c.second].clone()], "added": c.added,
            "between_pieces": c.between_pieces,
        })).collect::<Vec<_>>(),
        "occlusions": p.poseability.occlusions.iter().map(|o| json!({
            "hidden": names[o.hidden].clone(), "by": names[o.by].clone(), "kept": o.kept,
        })).collect::<Vec<_>>(),
        "poseability": {
            "pairs_reused": p.poseability.pairs_reused,
            "known": serde_json::to_string(&known_to_json(&p.poseability.known, names)).unwrap_or_default(),
            "collision_pairs_tested": p.poseability.collision_pairs_tested,
            "occlusion_directions_tested": p.poseability.occlusion_directions_tested,
            "seconds": {
                "regions": p.poseability.seconds_regions, "collisions": p.poseability.seconds_collisions,
                "occlusions": p.poseability.seconds_occlusions,
            },
        },
        "regions": p.expressions.iter().flat_map(|e| e.shapes.iter()).map(|&k| (names[k].clone(), json!(p.active[k])))
            .collect::<serde_json::Map<String, Value>>(),
        "weights": p.weights(),
        "fewest": p.fewest,
        "params": params,
    })
}

/// pack_expressions(neutral, deltas, triangles, names, settings=None, *, target_neutral=None,
///     pairs=None, pin_together=[], keep_apart=[], exclude=[], known=None, progress=None) -> dict
///
/// Packs the shape keys into as few reference expressions as possible (Carrigan et al. 2020).
/// `settings`: a dict onto [`PackingParams`] (None: `default_settings("pack")`): mu, a, beta,
/// max_expressions, symmetric, axis, mirror_tolerance, pair_tolerance, antagonist_iou,
/// antagonist_cosine, fewest, time_limit, collision_conflicts, collision_tolerance,
/// occlusion_conflicts, occlusion_keep, camera_direction; a key left out keeps its default,
/// an unknown one is an InvalidInputError naming it.
/// `pairs`, `pin_together` and `keep_apart` are lists of (name, name); `exclude` a list of
/// names. Returns a dict: expressions, importance, inert, excluded, unplaced, pairs,
/// antagonists, conflicts (each edge's shapes and reasons: user, antagonist, overlap,
/// collision, occlusion), collisions (added curve / diagonal), occlusions (kept share),
/// poseability (pairs tested and reused, seconds, and `known`: every pair decided so far as a
/// JSON string, to pass back as `known` when packing the same rig with the same mu,
/// collision tolerance, occlusion keep share and camera, which then skips those pairs;
/// InvalidInputError when it names shapes the rig lacks), regions (each placed shape's strongly moving
/// vertices, for the reference sheet), weights (J x K 0/1 in the order of `names`),
/// fewest, params (the settings used and the refinements). `progress(fraction)`, when given,
/// is called on the calling thread as the work advances (the collision and occlusion tests
/// take most of it); returning False cancels (CancelledError).
#[pyfunction]
#[pyo3(signature = (neutral, deltas, triangles, names, settings=None, *, target_neutral=None, pairs=None,
                    pin_together=Vec::new(), keep_apart=Vec::new(), exclude=Vec::new(), known=None, progress=None))]
#[allow(clippy::too_many_arguments)]
fn pack_expressions<'py>(
    py: Python<'py>,
    neutral: PyReadonlyArray2<'py, f32>,
    deltas: PyReadonlyArray3<'py, f32>,
    triangles: PyReadonlyArray2<'py, i32>,
    names: Vec<String>,
    settings: Option<Bound<'py, PyAny>>,
    target_neutral: Option<PyReadonlyArray2<'py, f32>>,
    pairs: Option<NamePairs>,
    pin_together: NamePairs,
    keep_apart: NamePairs,
    exclude: Vec<String>,
    known: Option<String>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let settings: PackingParams = read_settings(py, settings.as_ref(), "pack")?;
    let refinements = Refinements { pairs, pin_together, keep_apart, exclude, known };
    run(py, packing::pack_expressions, neutral, deltas, triangles, names, target_neutral, settings, refinements, progress)
}

/// pack_greedy(...) -> dict, with the arguments of `pack_expressions`; the settings' `fewest`
/// and `time_limit` are not used (nothing is solved): the first-fit baseline on the same
/// conflicts, nodes in order of importance. Expressions carry `status` None and `optimal` False.
#[pyfunction]
#[pyo3(signature = (neutral, deltas, triangles, names, settings=None, *, target_neutral=None, pairs=None,
                    pin_together=Vec::new(), keep_apart=Vec::new(), exclude=Vec::new(), known=None, progress=None))]
#[allow(clippy::too_many_arguments)]
fn pack_greedy<'py>(
    py: Python<'py>,
    neutral: PyReadonlyArray2<'py, f32>,
    deltas: PyReadonlyArray3<'py, f32>,
    triangles: PyReadonlyArray2<'py, i32>,
    names: Vec<String>,
    settings: Option<Bound<'py, PyAny>>,
    target_neutral: Option<PyReadonlyArray2<'py, f32>>,
    pairs: Option<NamePairs>,
    pin_together: NamePairs,
    keep_apart: NamePairs,
    exclude: Vec<String>,
    known: Option<String>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let settings: PackingParams = read_settings(py, settings.as_ref(), "pack")?;
    let settings = PackingParams { fewest: false, time_limit: None, ..settings };
    let refinements = Refinements { pairs, pin_together, keep_apart, exclude, known };
    run(py, packing::pack_greedy, neutral, deltas, triangles, names, target_neutral, settings, refinements, progress)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(pack_expressions, m)?)?;
    m.add_function(wrap_pyfunction!(pack_greedy, m)?)
}
