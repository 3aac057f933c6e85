//! Adapters for Region adjacency and merging (rgbd-segment::adjacency, merge).

use pyo3::prelude::*;

/// Adds this module's functions and classes to the native module.
pub fn register(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
