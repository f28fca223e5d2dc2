//! Core errors as Python exceptions. Every class derives from `ShapesmithError`; bad input is
//! also a `ValueError` and solver trouble also a `RuntimeError`, so callers can catch either
//! the project's base class or the builtin they expect.

use pyo3::prelude::*;
use pyo3::types::{PyDict, PyType};

use crate::error::ShapesmithError;

const CLASSES: &std::ffi::CStr = c"
class ShapesmithError(Exception):
    '''Base class of every error raised by shapesmith_native.'''
class InvalidInputError(ShapesmithError, ValueError):
    '''The rig or the parameters are unusable as given; the message says what to fix.'''
class InfeasibleError(ShapesmithError, ValueError):
    '''The constraints (e.g. the user's refinements) admit no solution.'''
class SolverError(ShapesmithError, RuntimeError):
    '''A numerical solver failed on valid input.'''
class CancelledError(ShapesmithError):
    '''The caller asked the job to stop.'''
";

const NAMES: [&str; 5] = ["ShapesmithError", "InvalidInputError", "InfeasibleError", "SolverError", "CancelledError"];

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    let scope = PyDict::new(py);
    py.run(CLASSES, Some(&scope), None)?;
    for name in NAMES {
        let class = scope.get_item(name)?.expect("class defined above");
        class.setattr("__module__", "shapesmith_native")?;
        m.add(name, class)?;
    }
    Ok(())
}

/// Converts a core error into the matching exception class of this module.
pub fn to_py_err(py: Python<'_>, err: ShapesmithError) -> PyErr {
    let class = match err {
        ShapesmithError::InvalidInput(_) => "InvalidInputError",
        ShapesmithError::Infeasible(_) => "InfeasibleError",
        ShapesmithError::Solver(_) => "SolverError",
        ShapesmithError::Cancelled => "CancelledError",
    };
    let message = err.to_string();
    match py.import("shapesmith_native").and_then(|m| m.getattr(class)) {
        Ok(class) => match class.cast_into::<PyType>() {
            Ok(class) => PyErr::from_type(class, message),
            Err(_) => pyo3::exceptions::PyRuntimeError::new_err(message),
        },
        Err(_) => pyo3::exceptions::PyRuntimeError::new_err(message),
    }
}

/// `map_err` helper: `result.map_err(py_err(py))`.
pub fn py_err(py: Python<'_>) -> impl Fn(ShapesmithError) -> PyErr + '_ {
    move |e| to_py_err(py, e)
}
