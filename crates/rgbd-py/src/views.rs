//! Adapters for the six depth views of a shape (rgbd-render's `views`);
//! `python/rgbd_rs/shapes/views.py` validates and documents.

use numpy::prelude::*;
use numpy::{PyArray1, PyArray3, PyArray4, PyReadonlyArray2};
use pyo3::prelude::*;
use rgbd_render::views::{self, VIEWS};

use crate::errors::{borrow, run, run_interruptible, shape_err};
use crate::geom::to_numpy;

/// `(views (B, 6, R, R), median splat radius per cloud (B,))`.
type Batch<'py> = (Bound<'py, PyArray4<f32>>, Bound<'py, PyArray1<f32>>);

fn n3(arg: &str, a: &PyReadonlyArray2<'_, impl numpy::Element>) -> PyResult<()> {
    match a.shape() {
        [_, 3] => Ok(()),
        s => Err(shape_err(format!(
            "{arg}: got shape {s:?}, expected (N, 3)"
        ))),
    }
}

/// The six views of a mesh: `(6, R, R)` depths in cube sides, NaN where empty.
#[pyfunction]
pub fn mesh_depth_views<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f32>,
    faces: PyReadonlyArray2<'py, u32>,
    resolution: usize,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    n3("vertices", &vertices)?;
    n3("faces", &faces)?;
    let (v, f) = (borrow("vertices", &vertices)?, borrow("faces", &faces)?);
    let d = run_interruptible(py, || views::mesh_views(v, f, resolution))?;
    to_numpy(py, (VIEWS, resolution, resolution), d)
}

/// [`mesh_depth_views`] by BVH ray casting (the reference; slower).
#[pyfunction]
pub fn mesh_depth_views_raycast<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f32>,
    faces: PyReadonlyArray2<'py, u32>,
    resolution: usize,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    n3("vertices", &vertices)?;
    n3("faces", &faces)?;
    let (v, f) = (borrow("vertices", &vertices)?, borrow("faces", &faces)?);
    let d = run_interruptible(py, || views::mesh_views_raycast(v, f, resolution))?;
    to_numpy(py, (VIEWS, resolution, resolution), d)
}

/// The six views of a point cloud: `((6, R, R) depths, splat radius in pixels)`.
#[pyfunction]
#[pyo3(signature = (points, resolution, splat_radius=None))]
pub fn point_depth_views<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f32>,
    resolution: usize,
    splat_radius: Option<f32>,
) -> PyResult<(Bound<'py, PyArray3<f32>>, f32)> {
    n3("points", &points)?;
    let p = borrow("points", &points)?;
    let (d, r) = run(py, || views::point_views(p, resolution, splat_radius))?;
    Ok((to_numpy(py, (VIEWS, resolution, resolution), d)?, r))
}

/// The automatic per-point splat radii (pixels) of a cloud at `resolution`.
#[pyfunction]
pub fn point_splat_radii<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f32>,
    resolution: usize,
) -> PyResult<Bound<'py, PyArray1<f32>>> {
    n3("points", &points)?;
    let p = borrow("points", &points)?;
    Ok(run(py, || views::splat_radii(p, resolution))?.into_pyarray(py))
}

/// The six views of each cloud, in parallel over the clouds: `((B, 6, R, R), radii (B,))`.
#[pyfunction]
#[pyo3(signature = (clouds, resolution, splat_radius=None))]
pub fn point_depth_views_batch<'py>(
    py: Python<'py>,
    clouds: Vec<PyReadonlyArray2<'py, f32>>,
    resolution: usize,
    splat_radius: Option<f32>,
) -> PyResult<Batch<'py>> {
    for c in &clouds {
        n3("clouds", c)?;
    }
    let slices = clouds
        .iter()
        .map(|c| borrow("clouds", c))
        .collect::<PyResult<Vec<&[f32]>>>()?;
    let (d, radii) = run_interruptible(py, || {
        views::point_views_batch(&slices, resolution, splat_radius)
    })?;
    Ok((
        to_numpy(py, (clouds.len(), VIEWS, resolution, resolution), d)?,
        radii.into_pyarray(py),
    ))
}

/// Local contrast normalisation of each `H x W` map of a `(B, H, W)` float32 stack, in place.
#[pyfunction]
pub fn local_contrast_normalize(
    py: Python<'_>,
    maps: &Bound<'_, PyArray3<f32>>,
    window: usize,
    eps: f64,
) -> PyResult<()> {
    let (h, w) = (maps.shape()[1], maps.shape()[2]);
    let mut rw = maps.try_readwrite()?;
    let data = rw.as_slice_mut().map_err(|_| {
        crate::errors::InvalidArgumentError::new_err(
            "maps: got a non-contiguous array, expected a C-contiguous one",
        )
    })?;
    run(py, || {
        views::local_contrast_normalize(data, h, w, window, eps)
    })
}

/// Adds this module's functions to the native module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(mesh_depth_views, m)?)?;
    m.add_function(wrap_pyfunction!(mesh_depth_views_raycast, m)?)?;
    m.add_function(wrap_pyfunction!(point_depth_views, m)?)?;
    m.add_function(wrap_pyfunction!(point_depth_views_batch, m)?)?;
    m.add_function(wrap_pyfunction!(point_splat_radii, m)?)?;
    m.add_function(wrap_pyfunction!(local_contrast_normalize, m)?)?;
    m.add("VIEWS_MAX_RESOLUTION", views::MAX_RESOLUTION)?;
    m.add("VIEWS_MAX_SPLAT_PX", views::MAX_SPLAT_PX)?;
    m.add("VIEWS_MIN_SPLAT_PX", views::MIN_SPLAT_PX)?;
    m.add("VIEWS_SPLAT_KNN_FACTOR", views::SPLAT_KNN_FACTOR)?;
    m.add("VIEWS_SPLAT_NEIGHBOURS", views::SPLAT_NEIGHBOURS)?;
    m.add("VIEWS_SPLAT_MEDIAN_CAP", views::SPLAT_MEDIAN_CAP)?;
    Ok(())
}
