//! Bindings of [`crate::analysis::analyze_rig`], of the rig's front
//! ([`crate::geometry::front::find_front`]) and of the mesh's parts (for the reports).

use numpy::{PyArray1, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;

use super::arrays;
use super::errors::py_err;
use super::run::detached;
use super::settings::settings as read_settings;
use crate::analysis::{analyze_rig as analyze, AnalysisParams};
use crate::geometry::front::find_front as front_of;
use crate::geometry::mesh_faults::find_mesh_faults;
use crate::geometry::topology::{boundary_edges, connected_components};
use crate::geometry::weld::Weld;
use crate::rig::RigView;

/// analyze_rig(neutral, deltas, triangles, names, settings=None) -> dict
///
/// `settings`: a dict onto [`AnalysisParams`] (None: `default_settings("analyze")`): axis,
/// mirror_tolerance, symmetry (pair_tolerance, antagonist_iou, mu, use_names); an unknown key
/// is an InvalidInputError naming it.
#[pyfunction]
#[pyo3(signature = (neutral, deltas, triangles, names, settings=None))]
fn analyze_rig<'py>(
    py: Python<'py>,
    neutral: PyReadonlyArray2<'py, f32>,
    deltas: PyReadonlyArray3<'py, f32>,
    triangles: PyReadonlyArray2<'py, i32>,
    names: Vec<String>,
    settings: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let params: AnalysisParams = read_settings(py, settings.as_ref(), "analyze")?;
    let points = arrays::points(&neutral, "neutral").map_err(py_err(py))?;
    let (delta_rows, _) = arrays::deltas(&deltas, points.len()).map_err(py_err(py))?;
    let tris = arrays::triangles(&triangles).map_err(py_err(py))?;
    let report = detached(py, || {
        let rig = RigView::new(points, delta_rows, &tris, &names)?;
        analyze(&rig, &params)
    })?;
    arrays::to_python(py, &report)
}

/// find_front(neutral, deltas, triangles, names, *, axis=0) -> dict
///
/// The rig's front and up in mesh coordinates (`front`, `up`: unit 3-lists; `lateral_axis`:
/// the symmetry plane's axis or None; `up_source`: "names" or "assumed"; `snapped`,
/// `snap_degrees`). `axis` is the symmetry axis tried first.
#[pyfunction]
#[pyo3(signature = (neutral, deltas, triangles, names, *, axis=0))]
fn find_front<'py>(
    py: Python<'py>,
    neutral: PyReadonlyArray2<'py, f32>,
    deltas: PyReadonlyArray3<'py, f32>,
    triangles: PyReadonlyArray2<'py, i32>,
    names: Vec<String>,
    axis: usize,
) -> PyResult<Bound<'py, PyAny>> {
    let points = arrays::points(&neutral, "neutral").map_err(py_err(py))?;
    let (delta_rows, _) = arrays::deltas(&deltas, points.len()).map_err(py_err(py))?;
    let tris = arrays::triangles(&triangles).map_err(py_err(py))?;
    let front = detached(py, || {
        let rig = RigView::new(points, delta_rows, &tris, &names)?;
        crate::rig::validate_triangle_indices(points.len(), &tris)?;
        front_of(&rig, axis)
    })?;
    arrays::to_python(py, &front)
}

/// mesh_faults(neutral, triangles) -> dict
///
/// Non-manifold edges, loose vertices, zero-area and duplicate triangles, each as
/// `{"count", "first"}` (see `geometry::mesh_faults`).
#[pyfunction]
fn mesh_faults<'py>(py: Python<'py>, neutral: PyReadonlyArray2<'py, f32>, triangles: PyReadonlyArray2<'py, i32>) -> PyResult<Bound<'py, PyAny>> {
    let points = arrays::points(&neutral, "neutral").map_err(py_err(py))?;
    let tris = arrays::triangles(&triangles).map_err(py_err(py))?;
    let faults = detached(py, || find_mesh_faults(points, &tris))?;
    arrays::to_python(py, &faults)
}

/// mesh_parts(vertex_count, triangles, neutral=None) -> (part int32 (N,), parts, boundary_edges)
///
/// The connected part of each vertex (0..parts; a vertex in no triangle is a part of its
/// own), the number of parts, and the number of open boundary edges (edges of one triangle).
/// With `neutral` (N x 3), of the welded surface: a head split along UV seams is one part,
/// and a seam is no boundary.
#[pyfunction]
#[pyo3(signature = (vertex_count, triangles, neutral=None))]
fn mesh_parts<'py>(
    py: Python<'py>,
    vertex_count: usize,
    triangles: PyReadonlyArray2<'py, i32>,
    neutral: Option<PyReadonlyArray2<'py, f32>>,
) -> PyResult<(Bound<'py, PyArray1<i32>>, usize, usize)> {
    let tris = arrays::triangles(&triangles).map_err(py_err(py))?;
    let points = neutral.as_ref().map(|n| arrays::points(n, "neutral")).transpose().map_err(py_err(py))?;
    let (labels, count, boundary) = detached(py, || {
        crate::rig::validate_triangle_indices(vertex_count, &tris)?;
        let weld = match points {
            Some(points) if points.len() == vertex_count => Weld::new(points, &tris),
            Some(points) => return Err(crate::invalid!("neutral has {} vertices, vertex_count is {vertex_count}", points.len())),
            None => Weld::identity(vertex_count, &tris),
        };
        let (labels, count) = connected_components(weld.n_welded(), &weld.triangles);
        Ok((weld.scatter(labels), count, boundary_edges(&weld.triangles).len()))
    })?;
    Ok((PyArray1::from_vec(py, labels.into_iter().map(|l| l as i32).collect()), count, boundary))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(analyze_rig, m)?)?;
    m.add_function(wrap_pyfunction!(find_front, m)?)?;
    m.add_function(wrap_pyfunction!(mesh_faults, m)?)?;
    m.add_function(wrap_pyfunction!(mesh_parts, m)?)
}
