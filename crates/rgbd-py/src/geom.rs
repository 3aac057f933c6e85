//! Thin adapters for `rgbd-geom`: validate, borrow, run without the GIL, return without copies.

use nalgebra::Matrix3;
use numpy::ndarray::{Array, Dimension, ShapeBuilder};
use numpy::prelude::*;
use numpy::{
    Element, PyArray, PyArray1, PyArray2, PyArray3, PyArrayDyn, PyReadonlyArray2, PyReadonlyArray3,
    PyReadonlyArrayDyn,
};
use pyo3::prelude::*;
use rgbd_geom::{Camera, Distortion, ImageRef, Interpolation, Intrinsics, Pose, ReprojectOptions};

use crate::errors::{borrow, run, shape_err, to_py, InvalidArgumentError};

/// `(fx, fy, cx, cy, width, height, [k1, k2, p1, p2, k3, k4, k5, k6])`, as `PinholeCamera._native()`.
type CameraArgs = (f64, f64, f64, f64, usize, usize, [f64; 8]);
/// `(row-major rotation, translation)`, as `Pose._native()`.
pub(crate) type PoseArgs = ([f64; 9], [f64; 3]);

fn camera(c: CameraArgs) -> PyResult<Camera> {
    let k = Intrinsics::new(c.0, c.1, c.2, c.3, c.4, c.5).map_err(to_py)?;
    Ok(Camera::new(
        k,
        Distortion::from_opencv(&c.6).map_err(to_py)?,
    ))
}

pub(crate) fn pose(p: PoseArgs) -> PyResult<Pose> {
    Pose::new(p.0, p.1).map_err(to_py)
}

/// Hands a result buffer to numpy as an array of `shape`, without copying it.
pub(crate) fn to_numpy<'py, T: Element, D: Dimension>(
    py: Python<'py>,
    shape: impl ShapeBuilder<Dim = D>,
    values: Vec<T>,
) -> PyResult<Bound<'py, PyArray<T, D>>> {
    Ok(Array::from_shape_vec(shape, values)
        .map_err(|e| shape_err(e.to_string()))?
        .into_pyarray(py))
}

/// An optional row-major rectifying rotation, validated like a pose's.
fn rotation_arg(rotation: Option<[f64; 9]>) -> PyResult<Option<Matrix3<f64>>> {
    rotation
        .map(|r| Ok(pose((r, [0.0; 3]))?.rotation))
        .transpose()
}

/// Projects `N x 3` points through `pose` into `camera`; returns `N x 2` pixels (NaN behind).
#[pyfunction]
pub fn project_points<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    cam: CameraArgs,
    pose_args: PoseArgs,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let n = points.shape()[0];
    let (cam, pose) = (camera(cam)?, pose(pose_args)?);
    let pts = borrow("points", &points)?;
    let out = run(py, || cam.project_points(pts, &pose))?;
    to_numpy(py, (n, 2), out)
}

/// Lands `N x 3` camera-frame points on an `H x W` map (see `rgbd_geom::land_points`):
/// `(disparity, map value, both finite and inside)`, each `N`.
#[pyfunction]
pub fn land_points<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f64>,
    cam: CameraArgs,
    map: PyReadonlyArray2<'py, f32>,
    bf: f64,
) -> PyResult<Landed<'py>> {
    let n = match points.shape() {
        &[n, 3] => n,
        s => {
            return Err(shape_err(format!(
                "points: got shape {s:?}, expected (N, 3)"
            )))
        }
    };
    let (h, w) = (map.shape()[0], map.shape()[1]);
    let cam = camera(cam)?;
    let pts = borrow("points", &points)?;
    let values = borrow("map", &map)?;
    let out = run(py, || rgbd_geom::land_points(&cam, pts, values, w, h, bf))?;
    Ok((
        to_numpy(py, n, out.disparity)?,
        to_numpy(py, n, out.map)?,
        to_numpy(py, n, out.both)?,
    ))
}

type Landed<'py> = (
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<f64>>,
    Bound<'py, PyArray1<bool>>,
);

/// Undistorts `N x 2` pixels (to ideal pixels, or normalised coordinates).
#[pyfunction]
pub fn undistort_pixels<'py>(
    py: Python<'py>,
    pixels: PyReadonlyArray2<'py, f64>,
    cam: CameraArgs,
    normalized: bool,
    max_iter: usize,
    tol: f64,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let n = pixels.shape()[0];
    let cam = camera(cam)?;
    let px = borrow("pixels", &pixels)?;
    let out = run(py, || cam.undistort_pixels(px, normalized, max_iter, tol))?;
    to_numpy(py, (n, 2), out)
}

/// Distorts `N x 2` ideal pixels.
#[pyfunction]
pub fn distort_pixels<'py>(
    py: Python<'py>,
    pixels: PyReadonlyArray2<'py, f64>,
    cam: CameraArgs,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let n = pixels.shape()[0];
    let cam = camera(cam)?;
    let px = borrow("pixels", &pixels)?;
    let out = run(py, || cam.distort_pixels(px))?;
    to_numpy(py, (n, 2), out)
}

/// Back-projects an `H x W` depth map to an `H x W x 3` point cloud.
#[pyfunction]
pub fn depth_to_points<'py>(
    py: Python<'py>,
    depth: PyReadonlyArray2<'py, f32>,
    cam: CameraArgs,
    max_iter: usize,
    tol: f64,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let cam = camera(cam)?;
    let (h, w) = (cam.intrinsics.height, cam.intrinsics.width);
    let d = borrow("depth", &depth)?;
    let out = run(py, || cam.depth_to_points(d, max_iter, tol))?;
    to_numpy(py, (h, w, 3), out)
}

/// Source-pixel map (`H_dst x W_dst x 2`) for undistorting/rectifying `src` onto `dst`.
#[pyfunction]
#[pyo3(signature = (src, dst, rotation=None))]
pub fn undistort_map<'py>(
    py: Python<'py>,
    src: CameraArgs,
    dst: CameraArgs,
    rotation: Option<[f64; 9]>,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let (src, dst) = (camera(src)?, camera(dst)?.intrinsics);
    let rot = rotation_arg(rotation)?;
    let map = run(py, || {
        Ok::<_, rgbd_geom::RgbdError>(rgbd_geom::undistort_map(&src, &dst, rot.as_ref()))
    })?;
    to_numpy(py, (dst.height, dst.width, 2), map)
}

/// Samples an `H x W x C` image at an `H' x W' x 2` map with `"nearest"` or `"linear"`.
#[pyfunction]
pub fn remap<'py>(
    py: Python<'py>,
    image: PyReadonlyArray3<'py, f32>,
    map: PyReadonlyArray3<'py, f32>,
    interpolation: &str,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let interp = interpolation_arg(interpolation)?;
    let &[h, w, c] = image.shape() else {
        unreachable!("3-D array")
    };
    let &[mh, mw, two] = map.shape() else {
        unreachable!("3-D array")
    };
    if two != 2 {
        return Err(shape_err(format!(
            "map: got shape ({mh}, {mw}, {two}), expected (H, W, 2)"
        )));
    }
    let img = borrow("image", &image)?;
    let m = borrow("map", &map)?;
    let out = run(py, || {
        rgbd_geom::remap(ImageRef::new(img, w, h, c)?, m, mw, interp)
    })?;
    to_numpy(py, (mh, mw, c), out)
}

fn interpolation_arg(name: &str) -> PyResult<Interpolation> {
    match name {
        "nearest" => Ok(Interpolation::Nearest),
        "linear" => Ok(Interpolation::Linear),
        other => Err(InvalidArgumentError::new_err(format!(
            "interpolation: got {other:?}, expected 'nearest' or 'linear'"
        ))),
    }
}

/// Undistorts (optionally rectifies) an `H x W x C` image of `src` onto the ideal camera `dst`.
#[pyfunction]
#[pyo3(signature = (image, src, dst, interpolation, rotation=None))]
pub fn undistort_image<'py>(
    py: Python<'py>,
    image: PyReadonlyArray3<'py, f32>,
    src: CameraArgs,
    dst: CameraArgs,
    interpolation: &str,
    rotation: Option<[f64; 9]>,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let interp = interpolation_arg(interpolation)?;
    let (src, dst) = (camera(src)?, camera(dst)?.intrinsics);
    let rot = rotation_arg(rotation)?;
    let &[h, w, c] = image.shape() else {
        unreachable!("3-D array")
    };
    let img = borrow("image", &image)?;
    let out = run(py, || {
        rgbd_geom::undistort_image(
            ImageRef::new(img, w, h, c)?,
            &src,
            &dst,
            rot.as_ref(),
            interp,
        )
    })?;
    to_numpy(py, (dst.height, dst.width, c), out)
}

/// `baseline * focal / values`, elementwise, NaN for invalid (depth <-> disparity, eq. 2.15).
#[pyfunction]
pub fn depth_disparity<'py>(
    py: Python<'py>,
    values: PyReadonlyArrayDyn<'py, f32>,
    baseline: f64,
    focal: f64,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let shape = values.shape().to_vec();
    let v = borrow("values", &values)?;
    let out = run(py, || rgbd_geom::depth_disparity(v, baseline, focal))?;
    to_numpy(py, shape, out)
}

type Reprojected<'py> = (
    Bound<'py, PyArray2<f32>>,
    Option<Bound<'py, PyArray3<f32>>>,
    Bound<'py, PyArray2<i64>>,
);

/// Z-buffered forward splatting of a depth map (and carried channels) into another camera.
#[pyfunction]
#[pyo3(signature = (depth, src, dst, pose_args, channels=None, splat_radius=0, max_iter=20, tol=1e-12))]
#[allow(clippy::too_many_arguments)]
pub fn reproject_depth<'py>(
    py: Python<'py>,
    depth: PyReadonlyArray2<'py, f32>,
    src: CameraArgs,
    dst: CameraArgs,
    pose_args: PoseArgs,
    channels: Option<PyReadonlyArray3<'py, f32>>,
    splat_radius: usize,
    max_iter: usize,
    tol: f64,
) -> PyResult<Reprojected<'py>> {
    let (src, dst, pose) = (camera(src)?, camera(dst)?, pose(pose_args)?);
    let d = borrow("depth", &depth)?;
    let ch = match &channels {
        Some(c) => Some((borrow("channels", c)?, c.shape()[2])),
        None => None,
    };
    let opts = ReprojectOptions {
        splat_radius,
        max_iter,
        tol,
    };
    let out = run(py, || {
        rgbd_geom::reproject_depth(d, &src, &dst, &pose, ch, opts)
    })?;
    let (h, w) = (dst.intrinsics.height, dst.intrinsics.width);
    let depth = to_numpy(py, (h, w), out.depth)?;
    let chans = match ch {
        Some((_, n)) => Some(to_numpy(py, (h, w, n), out.channels)?),
        None => None,
    };
    let idx = to_numpy(py, (h, w), out.source_index)?;
    Ok((depth, chans, idx))
}

/// Unit normals (towards the camera) of an organised `H x W x 3` point cloud.
#[pyfunction]
pub fn normals_from_points<'py>(
    py: Python<'py>,
    points: PyReadonlyArray3<'py, f32>,
    max_depth_jump: f32,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let &[h, w, c] = points.shape() else {
        unreachable!("3-D array")
    };
    if c != 3 {
        return Err(shape_err(format!(
            "points: got shape ({h}, {w}, {c}), expected (H, W, 3)"
        )));
    }
    let p = borrow("points", &points)?;
    let out = run(py, || {
        rgbd_geom::normals_from_points(p, w, h, max_depth_jump)
    })?;
    to_numpy(py, (h, w, 3), out)
}
