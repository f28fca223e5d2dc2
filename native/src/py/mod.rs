//! The `shapesmith_native` Python module: a thin layer that extracts arrays under the GIL,
//! runs the core with the GIL released (`run`), and converts results back. No numerics here.
//! Each tool function takes its arrays, then one `settings` dict onto the tool's `*Params`
//! (`settings`).

mod analysis;
mod arrays;
mod errors;
mod landmarks;
mod packing;
mod performance;
mod run;
mod settings;
mod transfer;
mod wrap;

use pyo3::prelude::*;

#[pymodule]
fn shapesmith_native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    errors::register(m)?;
    settings::register(m)?;
    analysis::register(m)?;
    packing::register(m)?;
    landmarks::register(m)?;
    performance::register(m)?;
    transfer::register(m)?;
    wrap::register(m)?;
    Ok(())
}
