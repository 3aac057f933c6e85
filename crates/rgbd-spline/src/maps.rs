//! Per-pixel maps of fitted surfaces: the surface point, the fitting error (3-D distance between
//! the measured point and the surface at the same (u, v), thesis §4.5) and the curvatures.
//!
//! Evaluation is separable: for each image row the control grid is first contracted with the
//! row's v-basis (and its derivatives), once per surface met in that row; each pixel then needs
//! only `p + 1` terms per output instead of `(p + 1)²`.

use rayon::prelude::*;

use crate::basis::Basis;
use crate::curvature::curvature;
use crate::fit::Fit;
use crate::normal::{axis_table, Region};
use crate::surface::{Jet, MAX_CHANNELS};

/// Per-pixel outputs (float32, as every image the library returns), NaN where a pixel has no
/// surface (or no finite measurement, for `error`).
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceMaps {
    /// `height x width x channels`.
    pub fitted: Vec<f32>,
    /// Distance between the measured and the fitted point.
    pub error: Vec<f32>,
    /// Principal curvatures `k1 >= k2`, mean and Gaussian curvature (3-channel surfaces only).
    pub k1: Vec<f32>,
    pub k2: Vec<f32>,
    pub mean: Vec<f32>,
    pub gaussian: Vec<f32>,
}

/// A surface's control grid contracted with one row's v-basis: per local column, value, ∂v and
/// ∂²v of each channel.
struct RowContraction<'a> {
    fit: &'a Fit,
    cols: Vec<[[f64; MAX_CHANNELS]; 3]>,
}

impl<'a> RowContraction<'a> {
    /// `None` when row `cv` is outside the surface's control rectangle.
    fn new(fit: &'a Fit, cv: usize, bv: &Basis) -> Option<Self> {
        let s = &fit.surface;
        let p = s.grid.degree;
        let cv = s.local_v(cv)?;
        let c = s.channels;
        let inv = 1.0 / s.grid.spacing;
        let mut cols = vec![[[0.0; MAX_CHANNELS]; 3]; s.shape.0];
        for (i, out) in cols.iter_mut().enumerate() {
            for j in 0..=p {
                let q = &s.ctrl[((cv + j) * s.shape.0 + i) * c..][..c];
                let w = [bv.value[j], bv.d1[j] * inv, bv.d2[j] * inv * inv];
                for (d, o) in out.iter_mut().enumerate() {
                    for ch in 0..c {
                        o[ch] += w[d] * q[ch];
                    }
                }
            }
        }
        Some(Self { fit, cols })
    }

    fn jet(&self, cu: usize, bu: &Basis) -> Option<Jet> {
        let s = &self.fit.surface;
        let p = s.grid.degree;
        let cu = s.local_u(cu)?;
        let inv = 1.0 / s.grid.spacing;
        let mut jet = Jet::zero(s.channels);
        for i in 0..=p {
            let [r0, r1, r2] = &self.cols[cu + i];
            let (b0, b1, b2) = (bu.value[i], bu.d1[i] * inv, bu.d2[i] * inv * inv);
            for ch in 0..s.channels {
                jet.value[ch] += b0 * r0[ch];
                jet.du[ch] += b1 * r0[ch];
                jet.duu[ch] += b2 * r0[ch];
                jet.dv[ch] += b0 * r1[ch];
                jet.duv[ch] += b1 * r1[ch];
                jet.dvv[ch] += b0 * r2[ch];
            }
        }
        Some(jet)
    }
}

/// Evaluates, for every pixel of `region` (`None`: the whole image), the fit
/// `fit_of(pixel index)` at that pixel. All fits must share one knot grid (they come from one
/// image).
pub fn surface_maps<'a, T: Copy + Into<f64> + Sync>(
    values: &[T],
    width: usize,
    height: usize,
    channels: usize,
    region: Option<Region>,
    fit_of: impl Fn(usize) -> Option<&'a Fit> + Sync,
) -> SurfaceMaps {
    let n = width * height;
    let region = region.unwrap_or(Region::full(width, height));
    let mut fitted = vec![f32::NAN; n * channels];
    let mut scalar = vec![[f32::NAN; 5]; n];
    let grid = (region.v0..region.v1)
        .flat_map(|v| (region.u0..region.u1).map(move |u| v * width + u))
        .find_map(&fit_of)
        .map(|f| f.surface.grid);
    if let Some(grid) = grid {
        let cols = axis_table(&grid, width, true);
        let rows = axis_table(&grid, height, false);
        fitted
            .par_chunks_mut(width * channels)
            .zip(scalar.par_chunks_mut(width))
            .enumerate()
            .for_each(|(v, (frow, srow))| {
                if v < region.v0 || v >= region.v1 {
                    return;
                }
                let (cv, bv) = &rows[v];
                let mut cache: Option<RowContraction> = None;
                for u in region.u0..region.u1 {
                    let px = v * width + u;
                    let Some(fit) = fit_of(px) else { continue };
                    if !cache.as_ref().is_some_and(|c| std::ptr::eq(c.fit, fit)) {
                        cache = RowContraction::new(fit, *cv, bv);
                    }
                    let Some(jet) = cache.as_ref().and_then(|c| c.jet(cols[u].0, &cols[u].1))
                    else {
                        continue;
                    };
                    let meas = &values[px * channels..][..channels];
                    for (o, x) in frow[u * channels..][..channels].iter_mut().zip(&jet.value) {
                        *o = *x as f32;
                    }
                    let d2: f64 = meas
                        .iter()
                        .zip(&jet.value)
                        .map(|(&m, f)| (m.into() - f) * (m.into() - f))
                        .sum();
                    srow[u][0] = d2.sqrt() as f32;
                    if let Some(c) = curvature(&jet) {
                        srow[u][1..].copy_from_slice(&[
                            c.k1 as f32,
                            c.k2 as f32,
                            c.mean as f32,
                            c.gaussian as f32,
                        ]);
                    }
                }
            });
    }
    let col = |i: usize| scalar.iter().map(|s| s[i]).collect::<Vec<f32>>();
    SurfaceMaps {
        fitted,
        error: col(0),
        k1: col(1),
        k2: col(2),
        mean: col(3),
        gaussian: col(4),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{fit_grid, KnotGrid};

    #[test]
    fn separable_evaluation_equals_the_direct_jet() {
        let (w, h) = (37, 29);
        let vals: Vec<f64> = (0..w * h * 3)
            .map(|i| ((i * 7919) % 101) as f64 / 101.0)
            .collect();
        for p in 1..=5 {
            let grid = KnotGrid::new(w, h, 5.5, p).unwrap();
            let fit = fit_grid(&vals, w, h, 3, &grid, 1e-3, false).unwrap();
            let maps = surface_maps(&vals, w, h, 3, None, |_| Some(&fit));
            for px in [0, 5, 100, 517, w * h - 1] {
                let j = fit.surface.jet((px % w) as f64, (px / w) as f64).unwrap();
                for c in 0..3 {
                    assert_eq!(maps.fitted[px * 3 + c], j.value[c] as f32);
                }
                let k = curvature(&j).unwrap();
                let close = |a: f32, b: f64| (a as f64 - b).abs() <= 1e-6 * (1.0 + b.abs());
                assert!(close(maps.k1[px], k.k1) && close(maps.gaussian[px], k.gaussian));
            }
        }
    }
}
