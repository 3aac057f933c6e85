//! Per-pixel maps of fitted surfaces: the surface point, the fitting error (3-D distance between
//! the measured point and the surface at the same (u, v), thesis §4.5) and the curvatures.

use rayon::prelude::*;

use crate::curvature::curvature;
use crate::fit::Fit;

/// Per-pixel outputs, NaN where a pixel has no surface (or no finite measurement, for `error`).
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceMaps {
    /// `height x width x channels`.
    pub fitted: Vec<f64>,
    /// Distance between the measured and the fitted point.
    pub error: Vec<f64>,
    /// Principal curvatures `k1 >= k2`, mean and Gaussian curvature (3-channel surfaces only).
    pub k1: Vec<f64>,
    pub k2: Vec<f64>,
    pub mean: Vec<f64>,
    pub gaussian: Vec<f64>,
}

/// Evaluates, for every pixel, the fit `fit_of(pixel index)` at that pixel.
pub fn surface_maps<'a>(
    values: &[f64],
    width: usize,
    height: usize,
    channels: usize,
    fit_of: impl Fn(usize) -> Option<&'a Fit> + Sync,
) -> SurfaceMaps {
    let n = width * height;
    let mut fitted = vec![f64::NAN; n * channels];
    let mut scalar = vec![[f64::NAN; 5]; n];
    fitted
        .par_chunks_mut(width * channels)
        .zip(scalar.par_chunks_mut(width))
        .enumerate()
        .for_each(|(v, (frow, srow))| {
            for u in 0..width {
                let px = v * width + u;
                let Some(jet) = fit_of(px).and_then(|f| f.surface.jet(u as f64, v as f64)) else {
                    continue;
                };
                let meas = &values[px * channels..][..channels];
                frow[u * channels..][..channels].copy_from_slice(&jet.value[..channels]);
                let d2: f64 = meas
                    .iter()
                    .zip(&jet.value)
                    .map(|(m, f)| (m - f) * (m - f))
                    .sum();
                srow[u][0] = d2.sqrt();
                if let Some(c) = curvature(&jet) {
                    srow[u][1..].copy_from_slice(&[c.k1, c.k2, c.mean, c.gaussian]);
                }
            }
        });
    let col = |i: usize| scalar.iter().map(|s| s[i]).collect::<Vec<f64>>();
    SurfaceMaps {
        fitted,
        error: col(0),
        k1: col(1),
        k2: col(2),
        mean: col(3),
        gaussian: col(4),
    }
}
