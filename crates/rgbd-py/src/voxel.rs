//! Adapters for rgbd-voxel: voxelization of meshes and point clouds, density profiles;
//! `python/rgbd_rs/shapes/voxels.py` validates and documents.

use numpy::prelude::*;
use numpy::{PyArray1, PyArray3, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use rgbd_voxel::{density_profiles as profiles_core, Fill, Grid, Voxels};

use crate::errors::{borrow, run, shape_err};
use crate::geom::to_numpy;

type Out<'py> = (Bound<'py, PyArray3<u8>>, Bound<'py, PyArray1<f64>>, f64);

fn n3(arg: &str, a: &PyReadonlyArray2<'_, impl numpy::Element>) -> PyResult<()> {
    match a.shape() {
        [_, 3] => Ok(()),
        s => Err(shape_err(format!(
            "{arg}: got shape {s:?}, expected (N, 3)"
        ))),
    }
}

fn out(py: Python<'_>, v: Voxels) -> PyResult<Out<'_>> {
    let r = v.grid.res;
    Ok((
        to_numpy(py, (r, r, r), v.filled)?,
        v.grid.min.to_vec().into_pyarray(py),
        v.grid.size,
    ))
}

/// Occupancy of a point cloud: `(filled (R, R, R) [z, y, x], grid min (3,), voxel size)`.
#[pyfunction]
pub fn voxelize_points<'py>(
    py: Python<'py>,
    points: PyReadonlyArray2<'py, f32>,
    resolution: usize,
    dilate: usize,
) -> PyResult<Out<'py>> {
    n3("points", &points)?;
    let p = borrow("points", &points)?;
    let v = run(py, || rgbd_voxel::voxelize_points(p, resolution, dilate))?;
    out(py, v)
}

/// Voxels of a triangle mesh (surface, or solid by the 3-axis vote).
#[pyfunction]
pub fn voxelize_mesh<'py>(
    py: Python<'py>,
    vertices: PyReadonlyArray2<'py, f32>,
    faces: PyReadonlyArray2<'py, u32>,
    resolution: usize,
    solid: bool,
) -> PyResult<Out<'py>> {
    n3("vertices", &vertices)?;
    n3("faces", &faces)?;
    let (v, f) = (borrow("vertices", &vertices)?, borrow("faces", &faces)?);
    let fill = if solid { Fill::Solid } else { Fill::Surface };
    let vox = run(py, || rgbd_voxel::voxelize_mesh(v, f, resolution, fill))?;
    out(py, vox)
}

/// The X, Y, Z density profiles of an `R x R x R` occupancy: `(3, R, R)` counts.
#[pyfunction]
pub fn density_profiles<'py>(
    py: Python<'py>,
    filled: PyReadonlyArray3<'py, u8>,
) -> PyResult<Bound<'py, PyArray3<f32>>> {
    let r = match filled.shape() {
        &[a, b, c] if a == b && b == c && a > 0 => a,
        s => {
            return Err(shape_err(format!(
                "filled: got shape {s:?}, expected (R, R, R)"
            )))
        }
    };
    let data = borrow("filled", &filled)?.to_vec();
    let maps = run(py, || {
        let grid = Grid {
            res: r,
            min: [0.0; 3],
            size: 1.0,
        };
        Ok(profiles_core(&Voxels { grid, filled: data }).concat())
    })?;
    to_numpy(py, (3, r, r), maps)
}

/// Adds this module's functions to the native module.
pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(voxelize_points, m)?)?;
    m.add_function(wrap_pyfunction!(voxelize_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(density_profiles, m)?)?;
    m.add("VOXEL_MAX_RESOLUTION", rgbd_voxel::MAX_RESOLUTION)?;
    Ok(())
}
