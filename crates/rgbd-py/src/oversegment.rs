//! Adapters for Normalized-cuts over-segmentation (rgbd-segment::nystrom, kmeans).

use numpy::{PyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use rgbd_segment::nystrom::{self, NystromParams, OversegParams};

use crate::errors::{borrow, run_interruptible};
use crate::geom::to_numpy;

/// Nyström normalized-cuts over-segmentation of an `H x W x D` feature image:
/// `(labels, count)`, labels `0..count` and -1 where a channel is not finite.
#[pyfunction]
#[pyo3(signature = (features, n_segments, sigma, n_samples, n_vectors, seed, min_size, spatial_weight, feature_weight, fit_points))]
#[allow(clippy::too_many_arguments)]
pub fn oversegment<'py>(
    py: Python<'py>,
    features: PyReadonlyArray3<'py, f32>,
    n_segments: usize,
    sigma: f32,
    n_samples: usize,
    n_vectors: usize,
    seed: u64,
    min_size: usize,
    spatial_weight: f32,
    feature_weight: f32,
    fit_points: usize,
) -> PyResult<(Bound<'py, PyArray2<i32>>, usize)> {
    let &[h, w, d] = features.shape() else {
        unreachable!("3-D array")
    };
    let f = borrow("features", &features)?;
    let params = OversegParams {
        nystrom: NystromParams {
            sigma,
            n_samples,
            n_vectors,
            seed,
        },
        n_segments,
        min_size,
        spatial_weight,
        feature_weight,
        fit_points,
    };
    let (labels, count) = run_interruptible(py, || nystrom::oversegment(f, w, h, d, &params))?;
    Ok((to_numpy(py, (h, w), labels)?, count))
}

/// Adds this module's functions and classes to the native module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(oversegment, m)?)?;
    // Defaults defined once in rgbd-segment, read by rgbd_rs.segmentation.oversegment.
    m.add("OVERSEG_DEFAULT_SIGMA", nystrom::DEFAULT_SIGMA)?;
    m.add("OVERSEG_DEFAULT_SAMPLES", nystrom::DEFAULT_SAMPLES)?;
    m.add("OVERSEG_DEFAULT_VECTORS", nystrom::DEFAULT_VECTORS)?;
    m.add("OVERSEG_MAX_SAMPLES", nystrom::MAX_SAMPLES)?;
    m.add("OVERSEG_DEFAULT_SEGMENTS", nystrom::DEFAULT_SEGMENTS)?;
    m.add(
        "OVERSEG_DEFAULT_SPATIAL_WEIGHT",
        nystrom::DEFAULT_SPATIAL_WEIGHT,
    )?;
    m.add(
        "OVERSEG_DEFAULT_FEATURE_WEIGHT",
        nystrom::DEFAULT_FEATURE_WEIGHT,
    )?;
    m.add(
        "OVERSEG_DEFAULT_FIT_POINTS",
        rgbd_segment::kmeans::DEFAULT_FIT_POINTS,
    )?;
    Ok(())
}
