//! Thin adapters for `rgbd_fusion::clues` and `rgbd_fusion::agree`; `python/rgbd_rs/fusion/clues.py` validates and
//! documents.

use numpy::prelude::*;
use numpy::{PyArray2, PyArray3, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use rgbd_fusion::ClueScales;

use crate::errors::{borrow, run, shape_err};
use crate::geom::to_numpy;

/// `(height, width)` of a 2-D map (the binding's 2-D type guarantees two axes).
fn dims(m: &PyReadonlyArray2<'_, f32>) -> (usize, usize) {
    let s = m.shape();
    (s[0], s[1])
}

/// Two `H x W` maps.
type Maps<'py> = (Bound<'py, PyArray2<f32>>, Bound<'py, PyArray2<f32>>);

/// The warp maps `(columns, rows)` of a stereo map (see `rgbd_fusion::warp_maps`).
#[pyfunction]
pub fn clue_warp_maps<'py>(
    py: Python<'py>,
    stereo_disparity: PyReadonlyArray2<'py, f32>,
    sign: f32,
) -> PyResult<Maps<'py>> {
    let (h, w) = dims(&stereo_disparity);
    let d = borrow("stereo_disparity", &stereo_disparity)?;
    let (xs, ys) = run(py, || rgbd_fusion::warp_maps(d, w, h, sign))?;
    Ok((to_numpy(py, (h, w), xs)?, to_numpy(py, (h, w), ys)?))
}

/// The raw clues `4 x H x W` (see `rgbd_fusion::clue_maps`).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub fn clue_maps<'py>(
    py: Python<'py>,
    grey_reference: PyReadonlyArray2<'py, f32>,
    warped: PyReadonlyArray2<'py, f32>,
    columns: PyReadonlyArray2<'py, f32>,
    tof_disparity: PyReadonlyArray2<'py, f32>,
    tof_amplitude: PyReadonlyArray2<'py, f32>,
    stereo_disparity: PyReadonlyArray2<'py, f32>,
    mu_reference: f32,
    mu_target: f32,
    amplitude: f32,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let (h, w) = dims(&grey_reference);
    for (arg, m) in [
        ("warped", &warped),
        ("columns", &columns),
        ("tof_disparity", &tof_disparity),
        ("tof_amplitude", &tof_amplitude),
        ("stereo_disparity", &stereo_disparity),
    ] {
        if dims(m) != (h, w) {
            return Err(shape_err(format!(
                "{arg}: got shape {:?}, expected ({h}, {w}) (the reference image's)",
                m.shape()
            )));
        }
    }
    let g = borrow("grey_reference", &grey_reference)?;
    let wp = borrow("warped", &warped)?;
    let cols = borrow("columns", &columns)?;
    let dt = borrow("tof_disparity", &tof_disparity)?;
    let at = borrow("tof_amplitude", &tof_amplitude)?;
    let ds = borrow("stereo_disparity", &stereo_disparity)?;
    let scales = ClueScales {
        mu_reference,
        mu_target,
        amplitude,
    };
    let out = run(py, || {
        rgbd_fusion::clue_maps(g, wp, cols, dt, at, ds, w, h, scales)
    })?;
    to_numpy(py, (4, h, w), out)
}

/// `maps / sigmas`, 0 where not finite (see `rgbd_fusion::normalise_clues`).
#[pyfunction]
pub fn normalise_clues<'py>(
    py: Python<'py>,
    maps: PyReadonlyArray3<'py, f32>,
    sigmas: PyReadonlyArray1<'py, f32>,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let shape = match maps.shape() {
        &[k, h, w] if k == sigmas.len() => (k, h, w),
        s => {
            return Err(shape_err(format!(
                "maps: got shape {s:?}, expected ({}, H, W): one map per sigma",
                sigmas.len()
            )))
        }
    };
    let m = borrow("maps", &maps)?;
    let s = borrow("sigmas", &sigmas)?;
    let out = run(py, || rgbd_fusion::normalise_clues(m, s))?;
    to_numpy(py, shape, out)
}

/// `(both, within)` of two maps (see `rgbd_fusion::agreement`).
#[pyfunction]
pub fn agreement<'py>(
    py: Python<'py>,
    a: PyReadonlyArray2<'py, f32>,
    b: PyReadonlyArray2<'py, f32>,
    tol: f32,
) -> PyResult<(u64, u64)> {
    if a.shape() != b.shape() {
        return Err(shape_err(format!(
            "stereo_disparity: got shape {:?}, expected {:?} (the ToF map's)",
            b.shape(),
            a.shape()
        )));
    }
    let (x, y) = (
        borrow("tof_disparity", &a)?,
        borrow("stereo_disparity", &b)?,
    );
    run(py, || rgbd_fusion::agreement(x, y, tol))
}
