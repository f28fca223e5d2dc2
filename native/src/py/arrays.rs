//! numpy <-> core conversion with explicit shape, dtype and contiguity errors. Positions are
//! C-contiguous float32 (N, 3), deltas float32 (K, N, 3), triangles int32 (T, 3); they are
//! borrowed, not copied (triangles are copied once to unsigned indices).

use numpy::{PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyAny;

use crate::error::ShapesmithError;
use crate::invalid;

/// Borrows an (N, 3) float32 array as points.
pub fn points<'a>(array: &'a PyReadonlyArray2<'_, f32>, what: &str) -> Result<&'a [[f32; 3]], ShapesmithError> {
    let shape = array.shape();
    if shape[1] != 3 {
        return Err(invalid!("{what} must have shape (N, 3), got {shape:?}"));
    }
    Ok(bytemuck::cast_slice(c_contiguous(array.as_slice(), array.is_c_contiguous(), what)?))
}

/// Borrows a (K, N, 3) float32 array as shape-major delta rows; returns them with K.
pub fn deltas<'a>(array: &'a PyReadonlyArray3<'_, f32>, n_vertices: usize) -> Result<(&'a [[f32; 3]], usize), ShapesmithError> {
    let shape = array.shape();
    if shape[1] != n_vertices || shape[2] != 3 {
        return Err(invalid!(
            "deltas must have shape (K, {n_vertices}, 3) to match the neutral, got {shape:?}"
        ));
    }
    let flat = c_contiguous(array.as_slice(), array.is_c_contiguous(), "deltas")?;
    Ok((bytemuck::cast_slice(flat), shape[0]))
}

/// The array's data in C order. `as_slice` alone also accepts Fortran order, whose rows would
/// be read as garbage.
fn c_contiguous<'a, E>(slice: Result<&'a [f32], E>, is_c: bool, what: &str) -> Result<&'a [f32], ShapesmithError> {
    match slice {
        Ok(flat) if is_c => Ok(flat),
        _ => Err(invalid!("{what} must be C-contiguous (use numpy.ascontiguousarray)")),
    }
}

/// Copies an (T, 3) int32 array to unsigned triangle indices; negative indices are an error.
pub fn triangles(array: &PyReadonlyArray2<'_, i32>) -> Result<Vec<[u32; 3]>, ShapesmithError> {
    let shape = array.shape();
    if shape[1] != 3 {
        return Err(invalid!("triangles must have shape (T, 3), got {shape:?}"));
    }
    let view = array.as_array();
    let mut out = Vec::with_capacity(shape[0]);
    for (t, row) in view.outer_iter().enumerate() {
        let mut tri = [0u32; 3];
        for c in 0..3 {
            tri[c] = u32::try_from(row[c])
                .map_err(|_| invalid!("triangle {t} has a negative vertex index {}", row[c]))?;
        }
        out.push(tri);
    }
    Ok(out)
}

/// A serialisable report as a Python object (dicts, lists, numbers, strings) via `json`.
pub fn to_python<'py>(py: Python<'py>, value: &impl serde::Serialize) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value)
        .map_err(|e| pyo3::exceptions::PyRuntimeError::new_err(format!("report serialisation failed: {e}")))?;
    py.import("json")?.call_method1("loads", (text,))
}
