//! Each tool's `settings` argument: a dict (or None for the defaults) mapped onto the core's
//! `*Params` struct through JSON ([`crate::settings`]), and `default_settings(tool)`, the
//! core's defaults as Python sees them (the add-on's dataclasses are tested against them).

use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyInt, PyList, PyString, PyTuple};
use serde::de::DeserializeOwned;
use serde_json::Value;

use super::arrays;
use super::errors::py_err;
use crate::invalid;
use crate::settings::{settings_from_json, settings_to_json};

/// The tools whose settings `default_settings` knows, each with its core struct's defaults.
fn defaults(tool: &str) -> Option<Value> {
    Some(match tool {
        "analyze" => settings_to_json(&crate::analysis::AnalysisParams::default()),
        "pack" => settings_to_json(&crate::packing::PackingParams::default()),
        "landmarks" => settings_to_json(&crate::landmarks::LandmarkParams::default()),
        "score" => settings_to_json(&crate::landmarks::ScoreParams::default()),
        "transfer" => settings_to_json(&crate::transfer::TransferShapesParams::default()),
        "virtual_edges" => settings_to_json(&crate::transfer::VirtualEdgeParams::default()),
        "performance" => settings_to_json(&crate::performance::PerformanceParams::default()),
        "wrap" => settings_to_json(&crate::wrap::WrapParams::default()),
        "carry" => settings_to_json(&crate::wrap::CarryParams::default()),
        _ => return None,
    })
}

const TOOLS: &str = "analyze, pack, landmarks, score, transfer, virtual_edges, performance, wrap, carry";

/// `T` from the Python `settings` of `tool` (None: the defaults); InvalidInputError naming
/// the key for an unknown option, a value of the wrong type or a number that is not finite.
pub fn settings<T: DeserializeOwned + Default>(py: Python<'_>, given: Option<&Bound<'_, PyAny>>, tool: &str) -> PyResult<T> {
    let Some(given) = given.filter(|g| !g.is_none()) else { return Ok(T::default()) };
    let value = json_of(given, &mut Vec::new()).map_err(|problem| py_err(py)(invalid!("{tool} settings: {problem}")))?;
    settings_from_json(value, tool).map_err(py_err(py))
}

/// The Python value as JSON (dicts with string keys, lists or tuples, strings, booleans,
/// numbers), or what is wrong with it and where (`path`, the keys above it).
fn json_of(value: &Bound<'_, PyAny>, path: &mut Vec<String>) -> Result<Value, String> {
    let here = |path: &[String]| if path.is_empty() { "the settings".to_string() } else { format!("`{}`", path.join(".")) };
    if value.is_none() {
        return Ok(Value::Null);
    }
    if let Ok(flag) = value.cast::<PyBool>() {
        return Ok(Value::Bool(flag.is_true()));
    }
    if value.is_instance_of::<PyInt>() {
        return match value.extract::<i64>() {
            Ok(integer) => Ok(Value::from(integer)),
            Err(_) => Err(format!("{} is too large an integer", here(path))),
        };
    }
    if let Ok(text) = value.cast::<PyString>() {
        return Ok(Value::String(text.to_string()));
    }
    if let Ok(dict) = value.cast::<PyDict>() {
        let mut map = serde_json::Map::new();
        for (key, inner) in dict.iter() {
            let key: String = key.extract().map_err(|_| format!("{} has a key that is not a string: {key}", here(path)))?;
            path.push(key.clone());
            let converted = json_of(&inner, path)?;
            path.pop();
            map.insert(key, converted);
        }
        return Ok(Value::Object(map));
    }
    if value.cast::<PyList>().is_ok() || value.cast::<PyTuple>().is_ok() {
        let mut items = Vec::new();
        for (index, inner) in value.try_iter().map_err(|e| e.to_string())?.enumerate() {
            path.push(index.to_string());
            items.push(json_of(&inner.map_err(|e| e.to_string())?, path)?);
            path.pop();
        }
        return Ok(Value::Array(items));
    }
    // Python floats, and numpy's scalars, which convert to one.
    match value.extract::<f64>() {
        Ok(number) => serde_json::Number::from_f64(number)
            .map(Value::Number)
            .ok_or_else(|| format!("{} must be a finite number, got {number}", here(path))),
        Err(_) => Err(format!(
            "{} must be a number, a boolean, a string, a list or a dict, got {}",
            here(path),
            value.get_type().name().map_or_else(|_| "?".to_string(), |n| n.to_string())
        )),
    }
}

/// default_settings(tool) -> dict
///
/// The core's defaults of one tool's settings (`tool`: analyze, pack, landmarks, score,
/// transfer, virtual_edges, performance, wrap, carry), keyed as the tool's `settings`
/// argument takes them.
#[pyfunction]
fn default_settings<'py>(py: Python<'py>, tool: &str) -> PyResult<Bound<'py, PyAny>> {
    let value = defaults(tool).ok_or_else(|| py_err(py)(invalid!("no tool named '{tool}': one of {TOOLS}")))?;
    arrays::to_python(py, &value)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(default_settings, m)?)
}
