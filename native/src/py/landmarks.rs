//! Bindings of [`crate::landmarks::place_landmarks`] and [`crate::landmarks::score_layout`].
//! Shapes are reported by name.

use numpy::{PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use serde::Serialize;

use super::arrays;
use super::errors::py_err;
use super::run::detached_with_progress;
use crate::ilp::SolveStatus;
use crate::invalid;
use crate::landmarks::{
    place_landmarks as place, score_layout_reporting as score, Criterion, CurvePoint, DesignStop, LandmarkLayout, LandmarkParams, ScoreParams,
};
use crate::rig::RigView;

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
struct EchoedParams {
    epsilon: f64,
    alpha: f64,
    gamma: f64,
    rays: usize,
    cameras: usize,
    symmetric: bool,
    max_per_shape: usize,
    radius: f64,
    share_limit: f64,
    min_visibility: f64,
    axis: usize,
    seed: u64,
    time_limit: Option<f64>,
    landmarks: Option<usize>,
    target_error: Option<f64>,
    criterion: Criterion,
    pool_epsilon: f64,
    pool_visibility: f64,
    noise: f64,
    curve_to: usize,
    reuse_visibility: bool,
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
    params: EchoedParams,
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
        params: EchoedParams {
            epsilon: params.epsilon,
            alpha: params.alpha,
            gamma: params.gamma,
            rays: params.rays,
            cameras: params.cameras.as_ref().map_or(0, Vec::len),
            symmetric: params.symmetric,
            max_per_shape: params.max_per_shape,
            radius: params.radius,
            share_limit: params.share_limit,
            min_visibility: params.min_visibility,
            axis: params.axis,
            seed: params.seed,
            time_limit: params.time_limit,
            landmarks: params.landmarks,
            target_error: params.target_error,
            criterion: params.criterion,
            pool_epsilon: params.pool_epsilon,
            pool_visibility: params.pool_visibility,
            noise: params.noise,
            curve_to: params.curve_to,
            reuse_visibility: params.reuse_visibility,
        },
    }
}

/// place_landmarks(neutral, deltas, triangles, names, *, epsilon=0.5, alpha=0.5, gamma=0.5,
///                 rays=64, symmetric=False, max_per_shape=2, radius=0.03, cameras=None,
///                 axis=0, seed=0, time_limit=None, share_limit=0.1, min_visibility=0.0,
///                 landmarks=None, target_error=None, criterion="a", pool_epsilon=0.3,
///                 pool_visibility=0.25, noise=0.002, curve_to=68, reuse_visibility=True,
///                 allowed=None, progress=None) -> dict
///
/// `cameras`: optional (C, 3) float32 camera positions in the mesh's local space.
/// `allowed`: optional list of N bools, the vertices a landmark may go on (a face's skin,
/// not its teeth and eyes); every vertex still moves and hides others.
/// `landmarks` / `target_error`: add landmarks after the cover by the design `criterion`
/// ("a": the predicted error, "d": the log-determinant) up to this count in all, or until the
/// predicted error (fraction of the diagonal) reaches the target.
/// `progress(fraction)` is called on the calling thread as the work advances; returning
/// `False` stops it (`CancelledError`).
#[pyfunction]
#[pyo3(signature = (neutral, deltas, triangles, names, *, epsilon=0.5, alpha=0.5, gamma=0.5,
                    rays=64, symmetric=false, max_per_shape=2, radius=0.03, cameras=None,
                    axis=0, seed=0, time_limit=None, share_limit=0.1, min_visibility=0.0, landmarks=None,
                    target_error=None, criterion="a", pool_epsilon=0.3, pool_visibility=0.25, noise=0.002,
                    curve_to=68, reuse_visibility=true, allowed=None, progress=None))]
#[allow(clippy::too_many_arguments)]
fn place_landmarks<'py>(
    py: Python<'py>,
    neutral: PyReadonlyArray2<'py, f32>,
    deltas: PyReadonlyArray3<'py, f32>,
    triangles: PyReadonlyArray2<'py, i32>,
    names: Vec<String>,
    epsilon: f64,
    alpha: f64,
    gamma: f64,
    rays: usize,
    symmetric: bool,
    max_per_shape: usize,
    radius: f64,
    cameras: Option<PyReadonlyArray2<'py, f32>>,
    axis: usize,
    seed: u64,
    time_limit: Option<f64>,
    share_limit: f64,
    min_visibility: f64,
    landmarks: Option<i64>,
    target_error: Option<f64>,
    criterion: &str,
    pool_epsilon: f64,
    pool_visibility: f64,
    noise: f64,
    curve_to: usize,
    reuse_visibility: bool,
    allowed: Option<Vec<bool>>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let criterion = match criterion.to_ascii_lowercase().as_str() {
        "a" => Criterion::A,
        "d" => Criterion::D,
        other => return Err(py_err(py)(invalid!("criterion must be 'a' (predicted error) or 'd' (log-determinant), got '{other}'"))),
    };
    let landmarks = match landmarks {
        Some(m) if m < 1 => return Err(py_err(py)(invalid!("landmarks must be at least 1, got {m}"))),
        other => other.map(|m| m as usize),
    };
    let points = arrays::points(&neutral, "neutral").map_err(py_err(py))?;
    let (delta_rows, _) = arrays::deltas(&deltas, points.len()).map_err(py_err(py))?;
    let tris = arrays::triangles(&triangles).map_err(py_err(py))?;
    let cameras = match &cameras {
        Some(array) => Some(arrays::points(array, "cameras").map_err(py_err(py))?.iter().map(|c| c.map(f64::from)).collect()),
        None => None,
    };
    let params = LandmarkParams {
        epsilon,
        alpha,
        gamma,
        rays,
        cameras,
        symmetric,
        axis,
        max_per_shape,
        radius,
        share_limit,
        min_visibility,
        seed,
        time_limit,
        landmarks,
        target_error,
        criterion,
        pool_epsilon,
        pool_visibility,
        noise,
        curve_to,
        reuse_visibility,
        allowed,
        ..LandmarkParams::default()
    };
    let layout = detached_with_progress(py, progress.as_ref(), |progress| {
        let rig = RigView::new(points, delta_rows, &tris, &names)?;
        place(&rig, &params, progress)
    })?;
    arrays::to_python(py, &report(layout, &names, &params))
}

/// score_layout(neutral, deltas, triangles, names, vertices, *, noise=0.002, seed=0,
///              extra_poses=None, random_mixes=50, progress=None) -> dict with mean, max,
///              poses, landmarks
///
/// `vertices`: a list or array of vertex indices; `extra_poses`: optional (P, K) float32;
/// `progress(fraction)` is called as the poses are scored (False stops: CancelledError).
#[pyfunction]
#[pyo3(signature = (neutral, deltas, triangles, names, vertices, *, noise=0.002, seed=0,
                    extra_poses=None, random_mixes=50, progress=None))]
#[allow(clippy::too_many_arguments)]
fn score_layout<'py>(
    py: Python<'py>,
    neutral: PyReadonlyArray2<'py, f32>,
    deltas: PyReadonlyArray3<'py, f32>,
    triangles: PyReadonlyArray2<'py, i32>,
    names: Vec<String>,
    vertices: Vec<i64>,
    noise: f64,
    seed: u64,
    extra_poses: Option<PyReadonlyArray2<'py, f32>>,
    random_mixes: usize,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
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
    let params = ScoreParams { noise, seed, extra_poses, random_mixes };
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
