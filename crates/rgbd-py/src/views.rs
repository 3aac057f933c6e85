//! Adapters for the six depth views of a shape (rgbd-render).

use pyo3::prelude::*;

/// Adds this module's functions to the native module.
pub fn register(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
