//! Thin adapters for `rgbd-fusion`; `python/rgbd_rs/fusion/` validates and documents.

use numpy::prelude::*;
use numpy::{PyArray2, PyArray3, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use rgbd_fusion::{LcParams, MeanShiftParams, Source, UpsampleParams};

use crate::errors::{borrow, run, run_interruptible, shape_err, to_py};
use crate::geom::to_numpy;

/// `(height, width)` of an `H x W x 3` image.
fn rgb_shape(arg: &str, img: &PyReadonlyArray3<'_, u8>) -> PyResult<(usize, usize)> {
    match img.shape() {
        &[h, w, 3] => Ok((h, w)),
        s => Err(shape_err(format!(
            "{arg}: got shape {s:?}, expected (H, W, 3)"
        ))),
    }
}

/// Connected colour regions: `(labels, count)`.
#[pyfunction]
pub fn label_regions<'py>(
    py: Python<'py>,
    image: PyReadonlyArray3<'py, u8>,
    tolerance: f32,
) -> PyResult<(Bound<'py, PyArray2<i32>>, usize)> {
    let (h, w) = rgb_shape("image", &image)?;
    let img = borrow("image", &image)?;
    let (labels, n) = run(py, || rgbd_fusion::label_regions(img, w, h, tolerance))?;
    Ok((to_numpy(py, (h, w), labels)?, n))
}

/// Mean-shift filtered copy of an RGB image (OpenCV `pyrMeanShiftFiltering`, bit-exact).
#[pyfunction]
#[pyo3(signature = (image, spatial_radius, color_radius, max_level=1, max_iter=5, epsilon=1.0))]
pub fn mean_shift_filter<'py>(
    py: Python<'py>,
    image: PyReadonlyArray3<'py, u8>,
    spatial_radius: f64,
    color_radius: f64,
    max_level: usize,
    max_iter: usize,
    epsilon: f64,
) -> PyResult<Bound<'py, PyArray3<u8>>> {
    let (h, w) = rgb_shape("image", &image)?;
    let img = borrow("image", &image)?;
    let p = MeanShiftParams {
        spatial_radius,
        color_radius,
        max_level,
        max_iter,
        epsilon,
    };
    let out = run_interruptible(py, || rgbd_fusion::mean_shift_filter(img, w, h, &p))?;
    to_numpy(py, (h, w, 3), out)
}

/// Statistics of the pointwise stereo cost curve of grey images: `(c1, c2, c_at)`.
#[pyfunction]
#[pyo3(signature = (reference, target, disparity, target_sign, max_disparity, block))]
#[allow(clippy::type_complexity)]
pub fn cost_curve_stats<'py>(
    py: Python<'py>,
    reference: PyReadonlyArray2<'py, u8>,
    target: PyReadonlyArray2<'py, u8>,
    disparity: PyReadonlyArray2<'py, f32>,
    target_sign: i8,
    max_disparity: usize,
    block: usize,
) -> PyResult<(
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<f32>>,
    Bound<'py, PyArray2<f32>>,
)> {
    let (h, w) = match reference.shape() {
        &[h, w] => (h, w),
        s => {
            return Err(shape_err(format!(
                "reference: got shape {s:?}, expected (H, W)"
            )))
        }
    };
    let r = borrow("reference", &reference)?;
    let t = borrow("target", &target)?;
    let d = borrow("disparity", &disparity)?;
    let out = run_interruptible(py, || {
        rgbd_fusion::cost_curve_stats(r, t, d, w, h, target_sign, max_disparity, block)
    })?;
    Ok((
        to_numpy(py, (h, w), out.best)?,
        to_numpy(py, (h, w), out.second)?,
        to_numpy(py, (h, w), out.at)?,
    ))
}

/// Parameters of the extended cross bilateral upsampling, validated once when built.
#[pyclass(module = "rgbd_rs._rgbd_rs", name = "UpsampleConfig", frozen)]
#[derive(Clone)]
pub struct PyUpsampleConfig(UpsampleParams);

#[pymethods]
impl PyUpsampleConfig {
    #[new]
    #[pyo3(signature = (radius, sigma_s, sigma_c, sigma_r))]
    fn new(radius: usize, sigma_s: f32, sigma_c: f32, sigma_r: f32) -> PyResult<Self> {
        let p = UpsampleParams {
            radius,
            sigma_s,
            sigma_c,
            sigma_r,
        };
        p.validate().map_err(to_py)?;
        Ok(Self(p))
    }
}

/// Extended cross bilateral upsampling of a sparse depth map, carrying an optional channel with
/// the depth's weights: `(depth, channel or None, color_gap)` (`Upsampled::color_gap`).
#[pyfunction]
#[pyo3(signature = (sparse, channel, image, labels, config))]
#[allow(clippy::type_complexity)]
pub fn upsample_depth<'py>(
    py: Python<'py>,
    sparse: PyReadonlyArray2<'py, f32>,
    channel: Option<PyReadonlyArray2<'py, f32>>,
    image: PyReadonlyArray3<'py, u8>,
    labels: Option<PyReadonlyArray2<'py, i32>>,
    config: &PyUpsampleConfig,
) -> PyResult<(
    Bound<'py, PyArray2<f32>>,
    Option<Bound<'py, PyArray2<f32>>>,
    Bound<'py, PyArray2<f32>>,
)> {
    let (h, w) = rgb_shape("image", &image)?;
    let s = borrow("sparse", &sparse)?;
    let img = borrow("image", &image)?;
    let lab = labels.as_ref().map(|l| borrow("labels", l)).transpose()?;
    let ch = channel.as_ref().map(|c| borrow("channel", c)).transpose()?;
    let p = config.0;
    let out = run_interruptible(py, || {
        rgbd_fusion::upsample_depth(s, ch, img, lab, w, h, &p)
    })?;
    let carried = match ch {
        Some(_) => Some(to_numpy(py, (h, w), out.channel)?),
        None => None,
    };
    Ok((
        to_numpy(py, (h, w), out.depth)?,
        carried,
        to_numpy(py, (h, w), out.color_gap)?,
    ))
}

/// The LC parameter set (eq. 2.16 constants, window, bins, view), validated once when built.
/// `LcConfig.for_width(w)` holds the defaults for an image `w` pixels wide.
#[pyclass(module = "rgbd_rs._rgbd_rs", name = "LcConfig", frozen)]
#[derive(Clone)]
pub struct PyLcConfig(LcParams);

#[pymethods]
impl PyLcConfig {
    #[new]
    #[pyo3(signature = (radius, gamma_s, gamma_c, gamma_t, truncation, bin_width, stride, target_sign))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        radius: usize,
        gamma_s: f32,
        gamma_c: f32,
        gamma_t: f32,
        truncation: f32,
        bin_width: f32,
        stride: usize,
        target_sign: i8,
    ) -> PyResult<Self> {
        let p = LcParams {
            radius,
            gamma_s,
            gamma_c,
            gamma_t,
            truncation,
            bin_width,
            stride,
            target_sign,
        };
        p.validate().map_err(to_py)?;
        Ok(Self(p))
    }

    /// The defaults for an image `width` pixels wide.
    #[staticmethod]
    fn for_width(width: usize) -> Self {
        Self(LcParams::for_width(width))
    }

    /// The literature's γs scaled to a window of half-size `radius` (what `for_width` uses).
    #[staticmethod]
    fn gamma_s_for_radius(radius: usize) -> f32 {
        LcParams::gamma_s_for_radius(radius)
    }

    /// The same parameters with `target_sign` replaced (the cross-check's other view).
    fn with_target_sign(&self, target_sign: i8) -> PyResult<Self> {
        Self::new(
            self.0.radius,
            self.0.gamma_s,
            self.0.gamma_c,
            self.0.gamma_t,
            self.0.truncation,
            self.0.bin_width,
            self.0.stride,
            target_sign,
        )
    }

    #[getter]
    fn radius(&self) -> usize {
        self.0.radius
    }
    #[getter]
    fn gamma_s(&self) -> f32 {
        self.0.gamma_s
    }
    #[getter]
    fn gamma_c(&self) -> f32 {
        self.0.gamma_c
    }
    #[getter]
    fn gamma_t(&self) -> f32 {
        self.0.gamma_t
    }
    #[getter]
    fn truncation(&self) -> f32 {
        self.0.truncation
    }
    #[getter]
    fn bin_width(&self) -> f32 {
        self.0.bin_width
    }
    /// The stride as given (the kernel caps it at the radius).
    #[getter]
    fn stride(&self) -> usize {
        self.0.stride
    }
    #[getter]
    fn target_sign(&self) -> i8 {
        self.0.target_sign
    }
}

/// LC fusion of disparity sources: `(disparity, plausibility)`.
#[pyfunction]
#[pyo3(signature = (reference, target, disparities, confidences, config))]
#[allow(clippy::type_complexity)]
pub fn lc_fuse<'py>(
    py: Python<'py>,
    reference: PyReadonlyArray3<'py, u8>,
    target: PyReadonlyArray3<'py, u8>,
    disparities: Vec<PyReadonlyArray2<'py, f32>>,
    confidences: Vec<Option<PyReadonlyArray2<'py, f32>>>,
    config: &PyLcConfig,
) -> PyResult<(Bound<'py, PyArray2<f32>>, Bound<'py, PyArray2<f32>>)> {
    let (h, w) = rgb_shape("reference", &reference)?;
    if disparities.len() != confidences.len() {
        return Err(shape_err(format!(
            "confidences: got {} maps, expected one (or None) per disparity map ({})",
            confidences.len(),
            disparities.len()
        )));
    }
    let r = borrow("reference", &reference)?;
    let t = borrow("target", &target)?;
    let mut sources = Vec::with_capacity(disparities.len());
    for (d, c) in disparities.iter().zip(&confidences) {
        sources.push(Source {
            disparity: borrow("disparities", d)?,
            confidence: c.as_ref().map(|c| borrow("confidences", c)).transpose()?,
        });
    }
    let p = config.0;
    let out = run_interruptible(py, || rgbd_fusion::lc_fuse(r, t, w, h, &sources, &p))?;
    Ok((
        to_numpy(py, (h, w), out.disparity)?,
        to_numpy(py, (h, w), out.plausibility)?,
    ))
}
