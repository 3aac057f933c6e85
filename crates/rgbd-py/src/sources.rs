//! Thin adapters for `rgbd_fusion::sources` (the steps after LC, editing the fused maps in
//! place); `python/rgbd_rs/fusion/sources.py` documents them.

use numpy::prelude::*;
use numpy::{PyReadonlyArray2, PyReadwriteArray2};
use pyo3::prelude::*;
use rgbd_fusion::sources::{self, Fused};

use crate::errors::{borrow, run, InvalidArgumentError};

/// A writable C-contiguous `H x W` map as a slice.
fn slice_mut<'a, T: numpy::Element>(
    arg: &str,
    a: &'a mut PyReadwriteArray2<'_, T>,
    shape: [usize; 2],
) -> PyResult<&'a mut [T]> {
    same_shape(arg, a.shape(), shape)?;
    if !a.is_c_contiguous() {
        return Err(InvalidArgumentError::new_err(format!(
            "{arg}: got a non-C-contiguous array, expected a C-contiguous one"
        )));
    }
    a.as_slice_mut().map_err(|_| {
        InvalidArgumentError::new_err(format!(
            "{arg}: got a non-C-contiguous array, expected a C-contiguous one"
        ))
    })
}

/// Refuses a map whose shape is not the fused map's.
fn same_shape(arg: &str, got: &[usize], shape: [usize; 2]) -> PyResult<()> {
    if got != shape {
        return Err(InvalidArgumentError::new_err(format!(
            "{arg}: got shape {got:?}, expected {shape:?} (the fused map's)"
        )));
    }
    Ok(())
}

/// A read-only map of the fused map's shape as a slice.
fn map<'a>(arg: &str, a: &'a PyReadonlyArray2<'_, f32>, shape: [usize; 2]) -> PyResult<&'a [f32]> {
    same_shape(arg, a.shape(), shape)?;
    borrow(arg, a)
}

/// Runs one step on the fused maps, of the `shape` read from `disparity`.
fn with_fused<'py>(
    py: Python<'py>,
    shape: [usize; 2],
    mut disparity: PyReadwriteArray2<'py, f32>,
    mut plausibility: PyReadwriteArray2<'py, f32>,
    mut source: PyReadwriteArray2<'py, u8>,
    step: impl FnOnce(&mut Fused<'_>) -> rgbd_geom::Result<()> + Send,
) -> PyResult<()> {
    let mut fused = Fused {
        disparity: slice_mut("disparity", &mut disparity, shape)?,
        plausibility: slice_mut("plausibility", &mut plausibility, shape)?,
        source: slice_mut("source", &mut source, shape)?,
        width: shape[1],
        height: shape[0],
    };
    run(py, || step(&mut fused))
}

/// An optional confidence map of the fused map's shape as a slice.
fn maybe<'a>(
    arg: &str,
    c: &'a Option<PyReadonlyArray2<'_, f32>>,
    shape: [usize; 2],
) -> PyResult<Option<&'a [f32]>> {
    c.as_ref().map(|c| map(arg, c, shape)).transpose()
}

/// The fused map's `[H, W]` (the binding's 2-D type guarantees two axes).
fn fused_shape(d: &PyReadwriteArray2<'_, f32>) -> [usize; 2] {
    let s = d.shape();
    [s[0], s[1]]
}

/// `_fill_single_source` on LC's maps (copies the caller made).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub fn fill_single_source<'py>(
    py: Python<'py>,
    disparity: PyReadwriteArray2<'py, f32>,
    plausibility: PyReadwriteArray2<'py, f32>,
    source: PyReadwriteArray2<'py, u8>,
    tof: PyReadonlyArray2<'py, f32>,
    stereo: PyReadonlyArray2<'py, f32>,
    tof_confidence: Option<PyReadonlyArray2<'py, f32>>,
    stereo_confidence: Option<PyReadonlyArray2<'py, f32>>,
    keep_out_zero: bool,
    cross_check: bool,
) -> PyResult<()> {
    let shape = fused_shape(&disparity);
    let (t, s) = (map("tof", &tof, shape)?, map("stereo", &stereo, shape)?);
    let ct = maybe("tof_confidence", &tof_confidence, shape)?;
    let cs = maybe("stereo_confidence", &stereo_confidence, shape)?;
    with_fused(py, shape, disparity, plausibility, source, |f| {
        sources::fill_single_source(f, t, s, ct, cs, keep_out_zero, cross_check)
    })
}

/// `_unseen_from_tof`, in place.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub fn unseen_from_tof<'py>(
    py: Python<'py>,
    disparity: PyReadwriteArray2<'py, f32>,
    plausibility: PyReadwriteArray2<'py, f32>,
    source: PyReadwriteArray2<'py, u8>,
    tof: PyReadonlyArray2<'py, f32>,
    stereo: PyReadonlyArray2<'py, f32>,
    tof_confidence: Option<PyReadonlyArray2<'py, f32>>,
    sign: f32,
) -> PyResult<()> {
    let shape = fused_shape(&disparity);
    let (t, s) = (map("tof", &tof, shape)?, map("stereo", &stereo, shape)?);
    let ct = maybe("tof_confidence", &tof_confidence, shape)?;
    with_fused(py, shape, disparity, plausibility, source, |f| {
        sources::unseen_from_tof(f, t, s, ct, sign)
    })
}

/// `_extend_tof_into_band`, in place.
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub fn extend_tof_into_band<'py>(
    py: Python<'py>,
    disparity: PyReadwriteArray2<'py, f32>,
    plausibility: PyReadwriteArray2<'py, f32>,
    source: PyReadwriteArray2<'py, u8>,
    tof: PyReadonlyArray2<'py, f32>,
    tof_confidence: Option<PyReadonlyArray2<'py, f32>>,
    sign: f32,
    chain_step: f32,
    confirm_gap: f32,
) -> PyResult<()> {
    let shape = fused_shape(&disparity);
    let t = map("tof", &tof, shape)?;
    let ct = maybe("tof_confidence", &tof_confidence, shape)?;
    with_fused(py, shape, disparity, plausibility, source, |f| {
        sources::extend_tof_into_band(f, t, ct, sign, (chain_step, confirm_gap))
    })
}

/// `_carry_tof_to_border`, in place.
#[pyfunction]
pub fn carry_tof_to_border<'py>(
    py: Python<'py>,
    disparity: PyReadwriteArray2<'py, f32>,
    plausibility: PyReadwriteArray2<'py, f32>,
    source: PyReadwriteArray2<'py, u8>,
    tof: PyReadonlyArray2<'py, f32>,
    tof_confidence: Option<PyReadonlyArray2<'py, f32>>,
    sign: f32,
) -> PyResult<()> {
    let shape = fused_shape(&disparity);
    let t = map("tof", &tof, shape)?;
    let ct = maybe("tof_confidence", &tof_confidence, shape)?;
    with_fused(py, shape, disparity, plausibility, source, |f| {
        sources::carry_tof_to_border(f, t, ct, sign)
    })
}

/// `_bridge_band_across_dropouts`, in place.
#[pyfunction]
pub fn bridge_band_across_dropouts<'py>(
    py: Python<'py>,
    disparity: PyReadwriteArray2<'py, f32>,
    plausibility: PyReadwriteArray2<'py, f32>,
    source: PyReadwriteArray2<'py, u8>,
    tof: PyReadonlyArray2<'py, f32>,
    sign: f32,
    chain_step: f64,
) -> PyResult<()> {
    let shape = fused_shape(&disparity);
    let t = map("tof", &tof, shape)?;
    with_fused(py, shape, disparity, plausibility, source, |f| {
        sources::bridge_band_across_dropouts(f, t, sign, chain_step)
    })
}
