//! Adapters for HHA encoding (rgbd-segment::hha).

use pyo3::prelude::*;

/// Adds this module's functions and classes to the native module.
pub fn register(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
