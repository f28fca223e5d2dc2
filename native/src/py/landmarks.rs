//! Bindings of [`crate::landmarks::place_landmarks`] and [`crate::landmarks::score_layout`].
//! Shapes are reported by name.

use numpy::{PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use serde::Serialize;

use super::arrays;
use super::errors::py_err;
use super::run::detached_with_progress;
use super::settings::settings as read_settings;
use crate::ilp::SolveStatus;
use crate::invalid;
use crate::landmarks::{
    place_landmarks as place, score_layout_reporting as score, CurvePoint, DesignStop, LandmarkLayout, LandmarkParams, ScoreParams,
};
use crate::rig::RigView;
use crate::settings::settings_to_json;

#[derive(Serialize)]
struct NamedLandmark {
    vertex: u32,
    position: [f64; 3],
    shapes: Vec<String>,
    strongest: String,
    visibility: f64,
    round: usize,
    added: Option<usize>,
}

#[derive(Serialize)]
struct Seconds {
    visibility: f64,
    solve: f64,
    design: f64,
}

#[derive(Serialize)]
struct LayoutReport {
    landmarks: Vec<NamedLandmark>,
    optimal: bool,
    statuses: Vec<SolveStatus>,
    uncovered: Vec<String>,
    inert: Vec<String>,
    rounds: usize,
    seconds: Seconds,
    rays_cast: u64,
    rays_reused: u64,
    visibility_vertices: usize,
    rays_per_second: f64,
    predicted_error: f64,
    curve: Vec<CurvePoint>,
    design_stop: Option<DesignStop>,
    /// The settings used, with `cameras` their count.
    params: serde_json::Value,
}

/// The settings as the report gives them: the cameras as their count.
fn echo(params: &LandmarkParams) -> serde_json::Value {
    let mut echoed = settings_to_json(params);
    if let serde_json::Value::Object(map) = &mut echoed {
        map.insert("cameras".into(), params.cameras.as_ref().map_or(0, Vec::len).into());
    }
    echoed
}

fn report(layout: LandmarkLayout, names: &[String], params: &LandmarkParams) -> LayoutReport {
    let name = |k: &usize| names[*k].clone();
    LayoutReport {
        landmarks: layout
            .landmarks
            .iter()
            .map(|l| NamedLandmark {
                vertex: l.vertex,
                position: l.position,
                shapes: l.shapes.iter().map(name).collect(),
                strongest: name(&l.strongest),
                visibility: l.visibility,
                round: l.round,
                added: l.added,
            })
            .collect(),
        optimal: layout.optimal,
        statuses: layout.statuses,
        uncovered: layout.uncovered.iter().map(name).collect(),
        inert: layout.inert.iter().map(name).collect(),
        rounds: layout.rounds,
        seconds: Seconds { visibility: layout.seconds_visibility, solve: layout.seconds_solve, design: layout.seconds_design },
        rays_cast: layout.rays_cast,
        rays_reused: layout.rays_reused,
        visibility_vertices: layout.visibility_vertices,
        rays_per_second: if layout.seconds_visibility > 0.0 {
            layout.rays_cast as f64 / layout.seconds_visibility
        } else {
            0.0
        },
        predicted_error: layout.predicted_error,
        curve: layout.curve,
        design_stop: layout.design_stop,
        params: echo(params),
    }
}

/// place_landmarks(neutral, deltas, triangles, names, settings=None, *, cameras=None,
///                 allowed=None, progress=None) -> dict
///
/// `settings`: a dict onto [`LandmarkParams`] (None: `default_settings("landmarks")`):
/// epsilon, alpha, gamma, rays, symmetric, axis, mirror_tolerance, max_per_shape, radius,
/// share_limit, min_visibility, seed, time_limit, landmarks, target_error, criterion,
/// pool_epsilon, pool_visibility, noise, curve_to, reuse_visibility; a key left out keeps its
/// default, an unknown one is an InvalidInputError naming it. `landmarks` / `target_error`:
/// add landmarks after the cover by the design `criterion` ("a": the predicted error, "d":
/// the log-determinant) up to this count in all, or until the predicted error (fraction of
/// the diagonal) reaches the target.
/// `cameras`: optional (C, 3) float32 camera positions in the mesh's local space.
/// `allowed`: optional list of N bools, the vertices a landmark may go on (a face's skin,
/// not its teeth and eyes); every vertex still moves and hides others.
/// `progress(fraction)` is called on the calling thread as the work advances; returning
/// `False` stops it (`CancelledError`).
#[pyfunction]
#[pyo3(signature = (neutral, deltas, triangles, names, settings=None, *, cameras=None, allowed=None, progress=None))]
#[allow(clippy::too_many_arguments)]
fn place_landmarks<'py>(
    py: Python<'py>,
    neutral: PyReadonlyArray2<'py, f32>,
    deltas: PyReadonlyArray3<'py, f32>,
    triangles: PyReadonlyArray2<'py, i32>,
    names: Vec<String>,
    settings: Option<Bound<'py, PyAny>>,
    cameras: Option<PyReadonlyArray2<'py, f32>>,
    allowed: Option<Vec<bool>>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let settings: LandmarkParams = read_settings(py, settings.as_ref(), "landmarks")?;
    if settings.landmarks == Some(0) {
        return Err(py_err(py)(invalid!("landmarks must be at least 1, got 0")));
    }
    let points = arrays::points(&neutral, "neutral").map_err(py_err(py))?;
    let (delta_rows, _) = arrays::deltas(&deltas, points.len()).map_err(py_err(py))?;
    let tris = arrays::triangles(&triangles).map_err(py_err(py))?;
    let cameras = match &cameras {
        Some(array) => Some(arrays::points(array, "cameras").map_err(py_err(py))?.iter().map(|c| c.map(f64::from)).collect()),
        None => None,
    };
    let params = LandmarkParams { cameras, allowed, ..settings };
    let layout = detached_with_progress(py, progress.as_ref(), |progress| {
        let rig = RigView::new(points, delta_rows, &tris, &names)?;
        place(&rig, &params, progress)
    })?;
    arrays::to_python(py, &report(layout, &names, &params))
}

/// score_layout(neutral, deltas, triangles, names, vertices, settings=None, *,
///              extra_poses=None, progress=None) -> dict with mean, max, poses, landmarks
///
/// `settings`: a dict onto [`ScoreParams`] (noise, seed, random_mixes; None:
/// `default_settings("score")`). `vertices`: a list or array of vertex indices;
/// `extra_poses`: optional (P, K) float32; `progress(fraction)` is called as the poses are
/// scored (False stops: CancelledError).
#[pyfunction]
#[pyo3(signature = (neutral, deltas, triangles, names, vertices, settings=None, *, extra_poses=None, progress=None))]
#[allow(clippy::too_many_arguments)]
fn score_layout<'py>(
    py: Python<'py>,
    neutral: PyReadonlyArray2<'py, f32>,
    deltas: PyReadonlyArray3<'py, f32>,
    triangles: PyReadonlyArray2<'py, i32>,
    names: Vec<String>,
    vertices: Vec<i64>,
    settings: Option<Bound<'py, PyAny>>,
    extra_poses: Option<PyReadonlyArray2<'py, f32>>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let settings: ScoreParams = read_settings(py, settings.as_ref(), "score")?;
    let points = arrays::points(&neutral, "neutral").map_err(py_err(py))?;
    let (delta_rows, _) = arrays::deltas(&deltas, points.len()).map_err(py_err(py))?;
    let tris = arrays::triangles(&triangles).map_err(py_err(py))?;
    let landmarks: Vec<u32> = vertices
        .iter()
        .map(|&v| u32::try_from(v).map_err(|_| invalid!("landmark vertex {v} does not exist: indices start at 0")))
        .collect::<Result<_, _>>()
        .map_err(py_err(py))?;
    let extra_poses = match &extra_poses {
        None => Vec::new(),
        Some(array) => {
            if array.shape()[1] != names.len() {
                return Err(py_err(py)(invalid!(
                    "extra_poses must have shape (P, {}) to match the shape names, got {:?}",
                    names.len(),
                    array.shape()
                )));
            }
            array.as_array().outer_iter().map(|row| row.iter().map(|&w| f64::from(w)).collect()).collect()
        }
    };
    let params = ScoreParams { extra_poses, ..settings };
    let result = detached_with_progress(py, progress.as_ref(), |progress| {
        let rig = RigView::new(points, delta_rows, &tris, &names)?;
        score(&rig, &landmarks, &params, progress)
    })?;
    arrays::to_python(py, &result)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(place_landmarks, m)?)?;
    m.add_function(wrap_pyfunction!(score_layout, m)?)
}
