//! Thin adapters for `rgbd-fusion`; `python/rgbd_rs/fusion/` validates and documents.

use numpy::prelude::*;
use numpy::{PyArray2, PyReadonlyArray2, PyReadonlyArray3};
use pyo3::prelude::*;
use rgbd_fusion::{LcParams, Source, UpsampleParams};

use crate::errors::{contiguous, run};
use crate::geom::{shape_err, to_numpy};

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
    let img = contiguous("image", image.as_slice())?;
    let (labels, n) = run(py, || rgbd_fusion::label_regions(img, w, h, tolerance))?;
    Ok((to_numpy(py, (h, w), labels)?, n))
}

/// Extended cross bilateral upsampling of a sparse depth map.
#[pyfunction]
#[pyo3(signature = (sparse, image, labels, radius, sigma_s, sigma_c, sigma_r))]
#[allow(clippy::too_many_arguments)]
pub fn upsample_depth<'py>(
    py: Python<'py>,
    sparse: PyReadonlyArray2<'py, f32>,
    image: PyReadonlyArray3<'py, u8>,
    labels: Option<PyReadonlyArray2<'py, i32>>,
    radius: usize,
    sigma_s: f32,
    sigma_c: f32,
    sigma_r: f32,
) -> PyResult<Bound<'py, PyArray2<f32>>> {
    let (h, w) = rgb_shape("image", &image)?;
    let s = contiguous("sparse", sparse.as_slice())?;
    let img = contiguous("image", image.as_slice())?;
    let lab = labels
        .as_ref()
        .map(|l| contiguous("labels", l.as_slice()))
        .transpose()?;
    let p = UpsampleParams {
        radius,
        sigma_s,
        sigma_c,
        sigma_r,
    };
    let out = run(py, || rgbd_fusion::upsample_depth(s, img, lab, w, h, &p))?;
    to_numpy(py, (h, w), out)
}

/// LC fusion of disparity sources: `(disparity, plausibility)`.
#[pyfunction]
#[pyo3(signature = (reference, target, disparities, confidences, radius, gamma_s, gamma_c, gamma_t, truncation, bin_width, stride, target_sign))]
#[allow(clippy::too_many_arguments, clippy::type_complexity)]
pub fn lc_fuse<'py>(
    py: Python<'py>,
    reference: PyReadonlyArray3<'py, u8>,
    target: PyReadonlyArray3<'py, u8>,
    disparities: Vec<PyReadonlyArray2<'py, f32>>,
    confidences: Vec<Option<PyReadonlyArray2<'py, f32>>>,
    radius: usize,
    gamma_s: f32,
    gamma_c: f32,
    gamma_t: f32,
    truncation: f32,
    bin_width: f32,
    stride: usize,
    target_sign: i8,
) -> PyResult<(Bound<'py, PyArray2<f32>>, Bound<'py, PyArray2<f32>>)> {
    let (h, w) = rgb_shape("reference", &reference)?;
    if disparities.len() != confidences.len() {
        return Err(shape_err(format!(
            "confidences: got {} maps, expected one (or None) per disparity map ({})",
            confidences.len(),
            disparities.len()
        )));
    }
    let r = contiguous("reference", reference.as_slice())?;
    let t = contiguous("target", target.as_slice())?;
    let mut sources = Vec::with_capacity(disparities.len());
    for (d, c) in disparities.iter().zip(&confidences) {
        sources.push(Source {
            disparity: contiguous("disparity", d.as_slice())?,
            confidence: c
                .as_ref()
                .map(|c| contiguous("confidence", c.as_slice()))
                .transpose()?,
        });
    }
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
    let out = run(py, || rgbd_fusion::lc_fuse(r, t, w, h, &sources, &p))?;
    Ok((
        to_numpy(py, (h, w), out.disparity)?,
        to_numpy(py, (h, w), out.plausibility)?,
    ))
}
