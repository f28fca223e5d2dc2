//! Binding of [`crate::performance::solve_performance`]. Shapes are reported by name, frames
//! as parallel lists.

use numpy::{PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use serde::Serialize;

use super::arrays;
use super::errors::py_err;
use super::run::detached_with_progress;
use super::settings::settings as read_settings;
use crate::geometry::mat3::{Mat3, Vec3};
use crate::invalid;
use crate::performance::{solve_performance as solve, Camera, Performance, PerformanceParams, Pose, Tracks};
use crate::rig::RigView;

#[derive(Serialize)]
struct Report {
    weights: Vec<Vec<f64>>,
    rotations: Vec<Mat3>,
    /// `(w, x, y, z)`.
    quaternions: Vec<[f64; 4]>,
    translations: Vec<Vec3>,
    scales: Vec<f64>,
    residuals: Vec<Option<f64>>,
    observed: Vec<usize>,
    kept: Vec<usize>,
    iterations: Vec<usize>,
    rigid: Vec<usize>,
    unseen: Vec<String>,
    inert: Vec<String>,
}

fn report(solved: Performance, names: &[String]) -> Report {
    let name = |k: &usize| names[*k].clone();
    let frames = &solved.frames;
    Report {
        weights: frames.iter().map(|f| f.weights.clone()).collect(),
        rotations: frames.iter().map(|f| f.pose.rotation).collect(),
        quaternions: frames.iter().map(|f| f.pose.quaternion()).collect(),
        translations: frames.iter().map(|f| f.pose.translation).collect(),
        scales: frames.iter().map(|f| f.pose.scale).collect(),
        residuals: frames.iter().map(|f| f.residual).collect(),
        observed: frames.iter().map(|f| f.observed).collect(),
        iterations: frames.iter().map(|f| f.iterations).collect(),
        kept: solved.kept,
        rigid: solved.rigid,
        unseen: solved.unseen.iter().map(name).collect(),
        inert: solved.inert.iter().map(name).collect(),
    }
}

fn matrix(value: &Bound<'_, PyAny>, what: &str) -> PyResult<Mat3> {
    let rows: Vec<Vec<f64>> = value.extract()?;
    if rows.len() != 3 || rows.iter().any(|r| r.len() != 3) {
        return Err(py_err(value.py())(invalid!("{what} must be a 3 x 3 matrix")));
    }
    Ok(std::array::from_fn(|r| std::array::from_fn(|c| rows[r][c])))
}

/// The camera dict: focal (fx, fy) and principal (cx, cy) in pixels from the bottom-left
/// corner, distortion (k1, k2, k3), rotation (3 x 3) and translation (3) world to camera.
fn camera_dict(value: &Bound<'_, PyDict>) -> PyResult<Camera> {
    let py = value.py();
    let get = |key: &str| {
        value.get_item(key)?.ok_or_else(|| py_err(py)(invalid!("the camera needs '{key}'")))
    };
    let pair: [f64; 2] = get("focal")?.extract()?;
    Ok(Camera {
        focal: pair,
        principal: get("principal")?.extract()?,
        distortion: get("distortion")?.extract()?,
        rotation: matrix(&get("rotation")?, "the camera's rotation")?,
        translation: get("translation")?.extract()?,
    })
}

/// solve_performance(neutral, deltas, triangles, names, landmarks, tracks, settings=None, *,
///                   camera=None, start_rotation=None, start_translation=None, start_scale=1.0,
///                   progress=None) -> dict
///
/// `settings`: a dict onto [`PerformanceParams`] (None: `default_settings("performance")`):
/// smoothing, noise_points, noise_pixels, huber (None: plain least squares), solve_scale,
/// iterations, rigid_fraction; an unknown key is an InvalidInputError naming it.
/// `landmarks`: the vertex each track follows; `tracks`: float64 (T, L, 3) positions, or
/// (T, L, 2) pixels with `camera` (a dict: focal, principal, distortion, rotation,
/// translation); NaN marks a landmark lost on a frame. The start pose is the head's placement.
/// `progress(fraction)` is called on the calling thread; returning `False` stops the solve
/// (`CancelledError`).
#[pyfunction]
#[pyo3(signature = (neutral, deltas, triangles, names, landmarks, tracks, settings=None, *, camera=None,
                    start_rotation=None, start_translation=None, start_scale=1.0, progress=None))]
#[allow(clippy::too_many_arguments)]
fn solve_performance<'py>(
    py: Python<'py>,
    neutral: PyReadonlyArray2<'py, f32>,
    deltas: PyReadonlyArray3<'py, f32>,
    triangles: PyReadonlyArray2<'py, i32>,
    names: Vec<String>,
    landmarks: Vec<i64>,
    tracks: PyReadonlyArray3<'py, f64>,
    settings: Option<Bound<'py, PyAny>>,
    camera: Option<Bound<'py, PyDict>>,
    start_rotation: Option<Bound<'py, PyAny>>,
    start_translation: Option<[f64; 3]>,
    start_scale: f64,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let settings: PerformanceParams = read_settings(py, settings.as_ref(), "performance")?;
    let points = arrays::points(&neutral, "neutral").map_err(py_err(py))?;
    let (delta_rows, _) = arrays::deltas(&deltas, points.len()).map_err(py_err(py))?;
    let tris = arrays::triangles(&triangles).map_err(py_err(py))?;
    let vertices: Vec<u32> = landmarks
        .iter()
        .map(|&v| u32::try_from(v).map_err(|_| invalid!("landmark vertex {v} does not exist: indices start at 0")))
        .collect::<Result<_, _>>()
        .map_err(py_err(py))?;
    let shape = tracks.shape().to_vec();
    let width = if camera.is_some() { 2 } else { 3 };
    if shape[1] != vertices.len() || shape[2] != width {
        return Err(py_err(py)(invalid!(
            "tracks must have shape (T, {}, {width}) ({}), got {shape:?}",
            vertices.len(),
            if width == 2 { "pixels, with a camera" } else { "positions, without a camera" }
        )));
    }
    let values: Vec<f64> = tracks.as_array().iter().copied().collect();
    let camera = camera.as_ref().map(camera_dict).transpose()?;
    let start = Pose {
        rotation: match &start_rotation {
            Some(value) => matrix(value, "start_rotation")?,
            None => Pose::default().rotation,
        },
        translation: start_translation.unwrap_or([0.0; 3]),
        scale: start_scale,
    };
    let params = PerformanceParams { start, ..settings };
    let solved = detached_with_progress(py, progress.as_ref(), |progress| {
        let rig = RigView::new(points, delta_rows, &tris, &names)?;
        match camera {
            None => solve(&rig, &vertices, &Tracks::Points(bytemuck::cast_slice(&values)), &params, progress),
            Some(camera) => solve(&rig, &vertices, &Tracks::Pixels(bytemuck::cast_slice(&values), camera), &params, progress),
        }
    })?;
    arrays::to_python(py, &report(solved, &names))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(solve_performance, m)?)
}
