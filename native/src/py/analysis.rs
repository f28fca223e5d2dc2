//! Binding of [`crate::analysis::analyze_rig`].

use numpy::{PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;

use super::arrays;
use super::errors::py_err;
use super::run::detached;
use crate::analysis::{analyze_rig as analyze, AnalysisParams};
use crate::geometry::mirror::SymmetryParams;
use crate::rig::RigView;

/// analyze_rig(neutral, deltas, triangles, names, *, axis=0, mirror_tolerance=1e-3,
///             pair_tolerance=0.25, antagonist_iou=0.6, mu=0.3, use_names=True) -> dict
#[pyfunction]
#[pyo3(signature = (neutral, deltas, triangles, names, *, axis=0, mirror_tolerance=1e-3,
                    pair_tolerance=0.25, antagonist_iou=0.6, mu=0.3, use_names=true))]
#[allow(clippy::too_many_arguments)]
fn analyze_rig<'py>(
    py: Python<'py>,
    neutral: PyReadonlyArray2<'py, f32>,
    deltas: PyReadonlyArray3<'py, f32>,
    triangles: PyReadonlyArray2<'py, i32>,
    names: Vec<String>,
    axis: usize,
    mirror_tolerance: f64,
    pair_tolerance: f64,
    antagonist_iou: f64,
    mu: f64,
    use_names: bool,
) -> PyResult<Bound<'py, PyAny>> {
    let points = arrays::points(&neutral, "neutral").map_err(py_err(py))?;
    let (delta_rows, _) = arrays::deltas(&deltas, points.len()).map_err(py_err(py))?;
    let tris = arrays::triangles(&triangles).map_err(py_err(py))?;
    let params = AnalysisParams {
        axis,
        mirror_tolerance,
        symmetry: SymmetryParams { pair_tolerance, antagonist_iou, mu, use_names },
    };
    let report = detached(py, || {
        let rig = RigView::new(points, delta_rows, &tris, &names)?;
        analyze(&rig, &params)
    })?;
    arrays::to_python(py, &report)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(analyze_rig, m)?)
}
