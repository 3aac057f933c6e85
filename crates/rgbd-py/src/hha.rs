//! Adapters for HHA encoding and square-window normals (`rgbd_segment::hha`);
//! `python/rgbd_rs/segmentation/hha.py` validates and documents.

use numpy::prelude::*;
use numpy::{PyArray1, PyArray2, PyArray3, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use rgbd_segment::hha::{self, Pinhole};

use crate::errors::{borrow, run, shape_err};
use crate::geom::to_numpy;

/// `(fx, fy, cx, cy)` of an ideal pinhole (pixel centres at integer coordinates from 0).
type PinholeArgs = (f64, f64, f64, f64);

fn pinhole(c: PinholeArgs) -> Pinhole {
    Pinhole {
        fx: c.0,
        fy: c.1,
        cx: c.2,
        cy: c.3,
    }
}

fn same_shape(
    depth: &PyReadonlyArray2<'_, f32>,
    raw: Option<&PyReadonlyArray2<'_, f32>>,
) -> PyResult<(usize, usize)> {
    let (h, w) = (depth.shape()[0], depth.shape()[1]);
    if let Some(r) = raw {
        if r.shape() != depth.shape() {
            return Err(shape_err(format!(
                "raw_depth: got shape {:?}, expected {:?} (the depth's)",
                r.shape(),
                depth.shape()
            )));
        }
    }
    Ok((h, w))
}

/// HHA of a metric depth map: `(image H x W x 3 u8, gravity (3,), floor_cm, normals H x W x 3
/// f32 toward the camera)`.
#[pyfunction]
#[pyo3(signature = (depth, raw_depth, camera))]
#[allow(clippy::type_complexity)]
pub fn hha_encode<'py>(
    py: Python<'py>,
    depth: PyReadonlyArray2<'py, f32>,
    raw_depth: Option<PyReadonlyArray2<'py, f32>>,
    camera: PinholeArgs,
) -> PyResult<(
    Bound<'py, PyArray3<u8>>,
    Bound<'py, PyArray1<f64>>,
    f64,
    Bound<'py, PyArray3<f32>>,
)> {
    let (h, w) = same_shape(&depth, raw_depth.as_ref())?;
    let d = borrow("depth", &depth)?;
    let r = raw_depth
        .as_ref()
        .map(|r| borrow("raw_depth", r))
        .transpose()?;
    let cam = pinhole(camera);
    let out = run(py, || hha::hha(d, r, w, h, &cam))?;
    Ok((
        to_numpy(py, (h, w, 3), out.image)?,
        out.gravity.to_vec().into_pyarray(py),
        out.floor_cm,
        to_numpy(py, (h, w, 3), out.normals)?,
    ))
}

/// Unit normals (`H x W x 3` f32, NaN where undefined) from least-squares planes in square
/// windows of half-size `radius`.
#[pyfunction]
#[pyo3(signature = (depth, raw_depth, camera, radius, toward_camera))]
pub fn square_normals<'py>(
    py: Python<'py>,
    depth: PyReadonlyArray2<'py, f32>,
    raw_depth: Option<PyReadonlyArray2<'py, f32>>,
    camera: PinholeArgs,
    radius: usize,
    toward_camera: bool,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let (h, w) = same_shape(&depth, raw_depth.as_ref())?;
    let d = borrow("depth", &depth)?;
    let r = raw_depth
        .as_ref()
        .map(|r| borrow("raw_depth", r))
        .transpose()?;
    let cam = pinhole(camera);
    let out = run(py, || hha::normals(d, r, w, h, &cam, radius, toward_camera))?;
    to_numpy(py, (h, w, 3), out)
}

/// The eq. 4.1 vectors: `(vectors H x W x 9, points H x W x 3, valid H x W, (σc, σg, σn))`.
#[pyfunction]
#[pyo3(signature = (lab, depth, normals, camera))]
#[allow(clippy::type_complexity)]
pub fn pixel_features<'py>(
    py: Python<'py>,
    lab: PyReadonlyArray3<'py, f32>,
    depth: PyReadonlyArray2<'py, f32>,
    normals: PyReadonlyArray3<'py, f32>,
    camera: PinholeArgs,
) -> PyResult<(
    Bound<'py, PyArray3<f32>>,
    Bound<'py, PyArray3<f32>>,
    Bound<'py, PyArray2<bool>>,
    (f64, f64, f64),
)> {
    let (h, w) = (depth.shape()[0], depth.shape()[1]);
    for (arg, shape) in [("lab", lab.shape()), ("normals", normals.shape())] {
        if shape != [h, w, 3] {
            return Err(shape_err(format!(
                "{arg}: got shape {shape:?}, expected [{h}, {w}, 3] (the depth's size)"
            )));
        }
    }
    let (l, d, n) = (
        borrow("lab", &lab)?,
        borrow("depth", &depth)?,
        borrow("normals", &normals)?,
    );
    let cam = pinhole(camera);
    let out = run(py, || hha::features(l, d, n, w, h, &cam))?;
    let [sc, sg, sn] = out.sigmas;
    Ok((
        to_numpy(py, (h, w, hha::FEATURE_DIM), out.vectors)?,
        to_numpy(py, (h, w, 3), out.points)?,
        to_numpy(py, (h, w), out.valid)?,
        (sc, sg, sn),
    ))
}

/// Checks a depth map as the HHA kernels do (some valid depth, metres not millimetres).
#[pyfunction]
pub fn check_metric_depth(py: Python<'_>, depth: PyReadonlyArray2<'_, f32>) -> PyResult<()> {
    let (h, w) = (depth.shape()[0], depth.shape()[1]);
    let d = borrow("depth", &depth)?;
    run(py, || hha::check_depth("depth", d, w, h))
}

/// Adds this module's functions and classes to the native module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(hha_encode, m)?)?;
    m.add_function(wrap_pyfunction!(square_normals, m)?)?;
    m.add_function(wrap_pyfunction!(check_metric_depth, m)?)?;
    m.add_function(wrap_pyfunction!(pixel_features, m)?)?;
    m.add("HHA_ANGLE_RADIUS", hha::ANGLE_RADIUS)?;
    m.add("HHA_GRAVITY_RADIUS", hha::GRAVITY_RADIUS)?;
    m.add("HHA_MAX_MEDIAN_DEPTH_M", hha::MAX_MEDIAN_DEPTH_M)?;
    Ok(())
}
