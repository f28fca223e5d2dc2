//! Bindings of [`crate::transfer`]: `transfer_shapes`, `find_virtual_edges`,
//! `measure_penetration`, `intersecting_triangles`.

use numpy::{PyArray1, PyArrayMethods, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;

use super::arrays;
use super::errors::py_err;
use super::run::{detached, detached_with_progress};
use super::settings::settings as read_settings;
use crate::geometry::penetration::intersecting_triangles as find_intersecting_triangles;
use crate::geometry::weld::{weld_tolerance, Weld};
use crate::invalid;
use crate::transfer::{
    find_virtual_edges as find_edges, measure_rig_penetration, transfer_shapes as run_transfer, RigPenetration, TrainingExpressions,
    TransferShapesParams, VirtualEdgeParams,
};

/// transfer_shapes(source_neutral, source_deltas, target_neutral, triangles, names,
///                 settings=None, *, examples=None, example_weights=None,
///                 template_penetration=None, progress=None)
///     -> (deltas float32 (K, N, 3), report dict)
///
/// `settings`: a dict onto [`TransferShapesParams`] (None: the defaults,
/// `default_settings("transfer")`): `transfer` (`virtual_edges`: `tau_d`, `tau_r`,
/// `max_per_vertex`, or None for none; `edge_weight`, `static_fraction`, `align_rotation`;
/// `contact`: `distance`, or None for no
/// contact solve), `personalise` (`beta_reg`, `refine_weights`), `compare_plain`,
/// `measure_penetration`. A key left out keeps its default; an unknown one is an
/// InvalidInputError naming it. The report's `params` echoes the settings used.
///
/// `template_penetration` is `measure_penetration(template_neutral, template_deltas,
/// triangles)` when already measured (a batch over many targets), else it is measured here.
///
/// `progress(fraction)` is called on the calling thread as the shapes are solved; returning
/// `False` stops the work (`CancelledError`).
///
/// `examples` are J training expressions of the target, float32 (J, N, 3) positions;
/// `example_weights` their J x K blend weights (packed expressions are 0/1 rows).
#[pyfunction]
#[pyo3(signature = (source_neutral, source_deltas, target_neutral, triangles, names, settings=None, *, examples=None,
                    example_weights=None, template_penetration=None, progress=None))]
#[allow(clippy::too_many_arguments)]
fn transfer_shapes<'py>(
    py: Python<'py>,
    source_neutral: PyReadonlyArray2<'py, f32>,
    source_deltas: PyReadonlyArray3<'py, f32>,
    target_neutral: PyReadonlyArray2<'py, f32>,
    triangles: PyReadonlyArray2<'py, i32>,
    names: Vec<String>,
    settings: Option<Bound<'py, PyAny>>,
    examples: Option<PyReadonlyArray3<'py, f32>>,
    example_weights: Option<Vec<Vec<f64>>>,
    template_penetration: Option<Bound<'py, PyAny>>,
    progress: Option<Bound<'py, PyAny>>,
) -> PyResult<(Bound<'py, PyAny>, Bound<'py, PyAny>)> {
    let params: TransferShapesParams = read_settings(py, settings.as_ref(), "transfer")?;
    let template_penetration: Option<RigPenetration> = match &template_penetration {
        Some(given) => {
            let text: String = py.import("json")?.call_method1("dumps", (given,))?.extract()?;
            Some(serde_json::from_str(&text).map_err(|e| {
                py_err(py)(invalid!("template_penetration must be what measure_penetration returns ({e})"))
            })?)
        }
        None => None,
    };
    let source = arrays::points(&source_neutral, "source_neutral").map_err(py_err(py))?;
    let target = arrays::points(&target_neutral, "target_neutral").map_err(py_err(py))?;
    let (delta_rows, _) = arrays::deltas(&source_deltas, source.len()).map_err(py_err(py))?;
    let tris = arrays::triangles(&triangles).map_err(py_err(py))?;
    let n = target.len();
    let (example_rows, weights) = match (&examples, &example_weights) {
        (Some(ex), Some(w)) => {
            let shape = ex.shape();
            if shape[1] != n || shape[2] != 3 {
                return Err(py_err(py)(invalid!("examples must have shape (J, {n}, 3) to match the target, got {shape:?}")));
            }
            if w.len() != shape[0] || w.iter().any(|row| row.len() != names.len()) {
                return Err(py_err(py)(invalid!(
                    "example_weights must be {} rows (one per example) of {} weights (one per shape)",
                    shape[0],
                    names.len()
                )));
            }
            let flat = ex
                .as_slice()
                .map_err(|_| py_err(py)(invalid!("examples must be C-contiguous (use numpy.ascontiguousarray)")))?;
            (Some(bytemuck::cast_slice::<f32, [f32; 3]>(flat)), w.concat())
        }
        (None, None) => (None, Vec::new()),
        _ => return Err(py_err(py)(invalid!("give both examples and example_weights, or neither"))),
    };
    let (deltas, report) = detached_with_progress(py, progress.as_ref(), |progress| {
        let training = example_rows.map(|positions| TrainingExpressions { positions, weights: &weights });
        run_transfer(source, delta_rows, target, &tris, &names, training, template_penetration.as_ref(), &params, progress)
    })?;
    let flat: Vec<f32> = deltas.into_iter().flatten().collect();
    let array = PyArray1::from_vec(py, flat).reshape([names.len(), n, 3])?;
    Ok((array.into_any(), arrays::to_python(py, &report)?))
}

/// find_virtual_edges(target_neutral, triangles, settings=None) -> int32 (E, 2)
///
/// `settings`: a dict onto [`VirtualEdgeParams`] (`tau_d`, `tau_r`, `max_per_vertex`; None:
/// `default_settings("virtual_edges")`), the transfer settings' `transfer.virtual_edges`.
#[pyfunction]
#[pyo3(signature = (target_neutral, triangles, settings=None))]
fn find_virtual_edges<'py>(
    py: Python<'py>,
    target_neutral: PyReadonlyArray2<'py, f32>,
    triangles: PyReadonlyArray2<'py, i32>,
    settings: Option<Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    let params: VirtualEdgeParams = read_settings(py, settings.as_ref(), "virtual_edges")?;
    let (tau_d, tau_r) = (params.tau_d, params.tau_r);
    let points = arrays::points(&target_neutral, "target_neutral").map_err(py_err(py))?;
    let tris = arrays::triangles(&triangles).map_err(py_err(py))?;
    let edges = detached(py, || {
        crate::rig::validate_points(points, "target_neutral")?;
        crate::rig::validate_triangle_indices(points.len(), &tris)?;
        if !(tau_d > 0.0 && tau_r > 0.0) {
            return Err(invalid!("tau_d and tau_r must be positive, got tau_d = {tau_d}, tau_r = {tau_r}"));
        }
        // On the welded surface, as the transfer finds them; each end is its point's
        // representative vertex.
        let weld = Weld::new(points, &tris);
        let edges = find_edges(&weld.gather(points), &weld.triangles, &params);
        Ok(edges.into_iter().map(|(i, j)| (weld.vertex(i), weld.vertex(j))).collect::<Vec<_>>())
    })?;
    let flat: Vec<i32> = edges.iter().flat_map(|&(i, j)| [i as i32, j as i32]).collect();
    Ok(PyArray1::from_vec(py, flat).reshape([edges.len(), 2])?.into_any())
}

/// measure_penetration(neutral, deltas, triangles)
///     -> {"neutral": {"length", "pairs", "between_pieces"}, "shapes": [{...}, ...]}
#[pyfunction]
fn measure_penetration<'py>(
    py: Python<'py>,
    neutral: PyReadonlyArray2<'py, f32>,
    deltas: PyReadonlyArray3<'py, f32>,
    triangles: PyReadonlyArray2<'py, i32>,
) -> PyResult<Bound<'py, PyAny>> {
    let points = arrays::points(&neutral, "neutral").map_err(py_err(py))?;
    let (delta_rows, _) = arrays::deltas(&deltas, points.len()).map_err(py_err(py))?;
    let tris = arrays::triangles(&triangles).map_err(py_err(py))?;
    let report = detached(py, || measure_rig_penetration(points, delta_rows, &tris))?;
    arrays::to_python(py, &report)
}

/// intersecting_triangles(positions, triangles, rest=None) -> bool (T,)
///
/// True for each triangle that crosses another one it shares no vertex with (the pairs the
/// penetration metric counts); with `rest` (same shape as `positions`), only pairs that do not
/// already cross at rest.
#[pyfunction]
#[pyo3(signature = (positions, triangles, rest=None))]
fn intersecting_triangles<'py>(
    py: Python<'py>,
    positions: PyReadonlyArray2<'py, f32>,
    triangles: PyReadonlyArray2<'py, i32>,
    rest: Option<PyReadonlyArray2<'py, f32>>,
) -> PyResult<Bound<'py, PyArray1<bool>>> {
    let points = arrays::points(&positions, "positions").map_err(py_err(py))?;
    let rest_points = rest.as_ref().map(|r| arrays::points(r, "rest")).transpose().map_err(py_err(py))?;
    let tris = arrays::triangles(&triangles).map_err(py_err(py))?;
    let crossed = detached(py, || {
        crate::rig::validate_triangle_indices(points.len(), &tris)?;
        crate::rig::validate_points(points, "positions")?;
        if let Some(rest_points) = rest_points {
            if rest_points.len() != points.len() {
                return Err(invalid!("rest has {} vertices, positions {}", rest_points.len(), points.len()));
            }
            crate::rig::validate_points(rest_points, "rest")?;
        }
        // On the welded surface: triangles that meet across a seam are neighbours.
        let rest = rest_points.unwrap_or(points);
        let weld = Weld::new(rest, &tris);
        let weld = weld.split_where_apart(points, weld_tolerance(points), &tris, &[rest]);
        let rest_points = rest_points.map(|r| weld.gather(r));
        let crossed = find_intersecting_triangles(&weld.gather(points), rest_points.as_deref(), &weld.triangles);
        Ok(weld.scatter_triangles(&crossed, tris.len(), false))
    })?;
    Ok(PyArray1::from_vec(py, crossed))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(transfer_shapes, m)?)?;
    m.add_function(wrap_pyfunction!(find_virtual_edges, m)?)?;
    m.add_function(wrap_pyfunction!(measure_penetration, m)?)?;
    m.add_function(wrap_pyfunction!(intersecting_triangles, m)?)
}
