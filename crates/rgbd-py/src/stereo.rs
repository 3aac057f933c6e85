//! Thin adapters for `rgbd-stereo` (census SGM); `python/rgbd_rs/fusion/census.py` validates
//! and documents.

use numpy::prelude::*;
use numpy::{PyArray2, PyReadonlyArray2};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rgbd_stereo::{CensusReference, Paths, Reference, SgmParams, Subpixel};

use crate::errors::{borrow, run_interruptible, shape_err, to_py};
use crate::geom::to_numpy;

fn invalid(msg: String) -> PyErr {
    crate::errors::InvalidArgumentError::new_err(msg)
}

fn paths_of(n: usize) -> PyResult<Paths> {
    match n {
        4 => Ok(Paths::Four),
        5 => Ok(Paths::Five),
        8 => Ok(Paths::Eight),
        _ => Err(invalid(format!("paths: got {n}, expected 4, 5 or 8"))),
    }
}

fn subpixel_of(s: &str) -> PyResult<Subpixel> {
    match s {
        "parabola" => Ok(Subpixel::Parabola),
        "equiangular" => Ok(Subpixel::Equiangular),
        "off" => Ok(Subpixel::Off),
        _ => Err(invalid(format!(
            "subpixel: got {s:?}, expected 'parabola', 'equiangular' or 'off'"
        ))),
    }
}

fn census_of(s: &str) -> PyResult<CensusReference> {
    match s {
        "center" => Ok(CensusReference::Center),
        "mean" => Ok(CensusReference::Mean),
        _ => Err(invalid(format!(
            "census_reference: got {s:?}, expected 'center' or 'mean'"
        ))),
    }
}

/// Parameters of the census SGM, validated once when built (the image width is checked at the
/// call).
#[pyclass(module = "rgbd_rs._rgbd_rs", name = "SgmConfig", frozen)]
#[derive(Clone)]
pub struct PySgmConfig(SgmParams);

#[pymethods]
impl PySgmConfig {
    #[new]
    #[pyo3(signature = (min_disparity, max_disparity, census_width, census_height,
        census_reference, p1, p2, p2_contrast, paths, subpixel, lr_tolerance, uniqueness,
        median, speckle_size, speckle_range, vertical_tolerance, stats))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        min_disparity: usize,
        max_disparity: usize,
        census_width: usize,
        census_height: usize,
        census_reference: &str,
        p1: u16,
        p2: u16,
        p2_contrast: f32,
        paths: usize,
        subpixel: &str,
        lr_tolerance: Option<u16>,
        uniqueness: u8,
        median: usize,
        speckle_size: usize,
        speckle_range: f32,
        vertical_tolerance: usize,
        stats: bool,
    ) -> PyResult<Self> {
        let p = SgmParams {
            min_disparity,
            max_disparity,
            census_width,
            census_height,
            census_reference: census_of(census_reference)?,
            p1,
            p2,
            p2_contrast,
            paths: paths_of(paths)?,
            subpixel: subpixel_of(subpixel)?,
            lr_tolerance,
            uniqueness,
            median,
            speckle_size,
            speckle_range,
            vertical_tolerance,
            stats,
        };
        p.validate(usize::MAX).map_err(to_py)?;
        Ok(Self(p))
    }
}

/// The defaults of every census SGM parameter (defined once, in `rgbd_stereo::SgmParams::new`).
#[pyfunction]
fn sgm_defaults(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let p = SgmParams::new(1);
    let d = PyDict::new(py);
    d.set_item("census_width", p.census_width)?;
    d.set_item("census_height", p.census_height)?;
    d.set_item(
        "census_reference",
        match p.census_reference {
            CensusReference::Center => "center",
            CensusReference::Mean => "mean",
        },
    )?;
    d.set_item("p1", p.p1)?;
    d.set_item("p2", p.p2)?;
    d.set_item("p2_contrast", p.p2_contrast)?;
    d.set_item("paths", p.paths.count())?;
    d.set_item(
        "subpixel",
        match p.subpixel {
            Subpixel::Parabola => "parabola",
            Subpixel::Equiangular => "equiangular",
            Subpixel::Off => "off",
        },
    )?;
    d.set_item("lr_tolerance", p.lr_tolerance)?;
    d.set_item("uniqueness", p.uniqueness)?;
    d.set_item("median", p.median)?;
    d.set_item("speckle_size", p.speckle_size)?;
    d.set_item("speckle_range", p.speckle_range)?;
    d.set_item("vertical_tolerance", p.vertical_tolerance)?;
    d.set_item("max_vertical", rgbd_stereo::MAX_VERTICAL)?;
    d.set_item("max_p2", rgbd_stereo::MAX_P2)?;
    d.set_item("max_median", rgbd_stereo::MAX_MEDIAN)?;
    Ok(d)
}

/// Census SGM of a grey pair on `reference` (`"left"` / `"right"`):
/// `(disparity, best or None, second or None)`.
#[pyfunction]
#[pyo3(signature = (left, right, reference, config))]
#[allow(clippy::type_complexity)]
fn census_sgm<'py>(
    py: Python<'py>,
    left: PyReadonlyArray2<'py, u8>,
    right: PyReadonlyArray2<'py, u8>,
    reference: &str,
    config: &PySgmConfig,
) -> PyResult<(
    Bound<'py, PyArray2<f32>>,
    Option<Bound<'py, PyArray2<f32>>>,
    Option<Bound<'py, PyArray2<f32>>>,
)> {
    let (h, w) = match left.shape() {
        &[h, w] => (h, w),
        s => return Err(shape_err(format!("left: got shape {s:?}, expected (H, W)"))),
    };
    let reference = match reference {
        "left" => Reference::Left,
        "right" => Reference::Right,
        _ => {
            return Err(invalid(format!(
                "reference: got {reference:?}, expected 'left' or 'right'"
            )))
        }
    };
    let l = borrow("left", &left)?;
    let r = borrow("right", &right)?;
    let p = config.0.clone();
    let out = run_interruptible(py, || rgbd_stereo::sgm(l, r, w, h, reference, &p))?;
    let best = out.best.map(|b| to_numpy(py, (h, w), b)).transpose()?;
    let second = out.second.map(|s| to_numpy(py, (h, w), s)).transpose()?;
    Ok((to_numpy(py, (h, w), out.disparity)?, best, second))
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PySgmConfig>()?;
    m.add_function(wrap_pyfunction!(sgm_defaults, m)?)?;
    m.add_function(wrap_pyfunction!(census_sgm, m)?)?;
    Ok(())
}
