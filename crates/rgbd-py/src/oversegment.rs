//! Adapters for Normalized-cuts over-segmentation (rgbd-segment::nystrom, kmeans).

use pyo3::prelude::*;

/// Adds this module's functions and classes to the native module.
pub fn register(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
