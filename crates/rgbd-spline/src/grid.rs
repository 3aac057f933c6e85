//! A uniform knot grid anchored to the image lattice and least-squares fits on it.
//!
//! Pixel `(u, v)` lies in cell `(floor(u / s), floor(v / s))` of a grid with spacing `s`
//! pixels; the `(p + 1)²` control points `(cu + i, cv + j)` are active there. Because the grid
//! is anchored to the image, any set of pixels (a whole view or a segment) touches a number of
//! control points proportional to its area (thesis §4.5: degrees of freedom proportional to the
//! segment size), and normal equations of disjoint pixel sets add up.
//!
//! A second-difference (P-spline) penalty `lambda · Σ (Δ² c)²` along both grid axes keeps spans
//! without data well-posed: the system is positive definite for `lambda > 0` whenever the data
//! fix a plane, so no rank deficiency and no NaN surface.

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};

use crate::basis::{uniform_basis, Basis, MAX_DEGREE};
use crate::SplineError;

/// Default smoothness weight (relative to one data point's weight). Chosen small enough that a
/// noise-free quadric is reproduced to < 1e-6 relative error and large enough that an empty span
/// is interpolated smoothly; see the tests.
pub const DEFAULT_LAMBDA: f64 = 1e-6;

/// The knot grid of an image of `width x height` pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KnotGrid {
    pub degree: usize,
    pub spacing: f64,
    pub cells_u: usize,
    pub cells_v: usize,
}

impl KnotGrid {
    /// Grid covering pixel coordinates `[0, width-1] x [0, height-1]`.
    pub fn new(
        width: usize,
        height: usize,
        spacing: f64,
        degree: usize,
    ) -> Result<Self, SplineError> {
        if !(1..=MAX_DEGREE).contains(&degree) {
            return Err(SplineError::invalid(
                "degree",
                degree,
                format!("1..={MAX_DEGREE}"),
            ));
        }
        if !(spacing.is_finite() && spacing >= 1.0) {
            return Err(SplineError::invalid(
                "spacing",
                spacing,
                "a knot spacing >= 1 pixel",
            ));
        }
        if width == 0 || height == 0 {
            return Err(SplineError::invalid(
                "size",
                format!("{width}x{height}"),
                "a non-empty image",
            ));
        }
        let cells = |n: usize| ((n as f64 / spacing).ceil() as usize).max(1);
        Ok(Self {
            degree,
            spacing,
            cells_u: cells(width),
            cells_v: cells(height),
        })
    }

    /// Control points along u and v.
    pub fn ctrl_shape(&self) -> (usize, usize) {
        (self.cells_u + self.degree, self.cells_v + self.degree)
    }

    /// Total number of control points.
    pub fn n_ctrl(&self) -> usize {
        let (a, b) = self.ctrl_shape();
        a * b
    }

    /// Cell index and local parameter of a pixel coordinate along one axis.
    #[inline]
    fn locate(&self, x: f64, cells: usize) -> (usize, f64) {
        let g = x / self.spacing;
        let c = (g.floor().max(0.0) as usize).min(cells - 1);
        (c, (g - c as f64).clamp(0.0, 1.0))
    }

    /// The active control points (row-major indices) and basis of pixel `(u, v)`.
    #[inline]
    pub fn support(&self, u: f64, v: f64) -> (usize, usize, Basis, Basis) {
        let (cu, tu) = self.locate(u, self.cells_u);
        let (cv, tv) = self.locate(v, self.cells_v);
        // Degree was validated in `new`, t is clamped to [0, 1]: the basis cannot fail.
        let bu = uniform_basis(self.degree, tu).unwrap_or_else(|_| unreachable!());
        let bv = uniform_basis(self.degree, tv).unwrap_or_else(|_| unreachable!());
        (cu, cv, bu, bv)
    }
}

/// A fitted surface: `channels` control-point grids on a [`KnotGrid`].
#[derive(Debug, Clone, PartialEq)]
pub struct GridSurface {
    pub grid: KnotGrid,
    pub channels: usize,
    /// Row-major `(ctrl_v, ctrl_u, channels)`.
    pub ctrl: Vec<f64>,
}

/// Value and derivatives (per pixel, all channels) of a surface at one point.
#[derive(Debug, Clone, PartialEq)]
pub struct Jet {
    pub value: Vec<f64>,
    pub du: Vec<f64>,
    pub dv: Vec<f64>,
    pub duu: Vec<f64>,
    pub duv: Vec<f64>,
    pub dvv: Vec<f64>,
}

impl GridSurface {
    /// Evaluates the surface and its first and second derivatives (per pixel) at `(u, v)`.
    pub fn jet(&self, u: f64, v: f64) -> Jet {
        let (cu, cv, bu, bv) = self.grid.support(u, v);
        let (nu, _) = self.grid.ctrl_shape();
        let c = self.channels;
        let s = self.grid.spacing;
        let mut jet = Jet {
            value: vec![0.0; c],
            du: vec![0.0; c],
            dv: vec![0.0; c],
            duu: vec![0.0; c],
            duv: vec![0.0; c],
            dvv: vec![0.0; c],
        };
        let p = self.grid.degree;
        for j in 0..=p {
            for i in 0..=p {
                let base = ((cv + j) * nu + cu + i) * c;
                let w = [
                    bu.value[i] * bv.value[j],
                    bu.d1[i] * bv.value[j] / s,
                    bu.value[i] * bv.d1[j] / s,
                    bu.d2[i] * bv.value[j] / (s * s),
                    bu.d1[i] * bv.d1[j] / (s * s),
                    bu.value[i] * bv.d2[j] / (s * s),
                ];
                for ch in 0..c {
                    let q = self.ctrl[base + ch];
                    jet.value[ch] += w[0] * q;
                    jet.du[ch] += w[1] * q;
                    jet.dv[ch] += w[2] * q;
                    jet.duu[ch] += w[3] * q;
                    jet.duv[ch] += w[4] * q;
                    jet.dvv[ch] += w[5] * q;
                }
            }
        }
        jet
    }
}

/// Least-squares fit of `channels` values per pixel (`height x width x channels`, row-major;
/// a pixel with any non-finite channel is skipped) on `grid`, with smoothness weight `lambda`.
pub fn fit_grid(
    values: &[f64],
    width: usize,
    height: usize,
    channels: usize,
    grid: &KnotGrid,
    lambda: f64,
) -> Result<GridSurface, SplineError> {
    if channels == 0 || values.len() != width * height * channels {
        return Err(SplineError::invalid(
            "values",
            format!("{} values", values.len()),
            format!("height * width * channels = {}", width * height * channels),
        ));
    }
    if !(lambda.is_finite() && lambda > 0.0) {
        return Err(SplineError::invalid(
            "lambda",
            lambda,
            "a smoothness weight > 0",
        ));
    }
    let n = grid.n_ctrl();
    let (nu, nv) = grid.ctrl_shape();
    let p = grid.degree;
    let k = (p + 1) * (p + 1);
    let mut ata = Mat::<f64>::zeros(n, n);
    let mut atb = Mat::<f64>::zeros(n, channels);
    let mut used = 0usize;
    let mut idx = vec![0usize; k];
    let mut w = vec![0.0f64; k];
    for v in 0..height {
        for u in 0..width {
            let px = &values[(v * width + u) * channels..(v * width + u + 1) * channels];
            if px.iter().any(|x| !x.is_finite()) {
                continue;
            }
            used += 1;
            let (cu, cv, bu, bv) = grid.support(u as f64, v as f64);
            for j in 0..=p {
                for i in 0..=p {
                    idx[j * (p + 1) + i] = (cv + j) * nu + cu + i;
                    w[j * (p + 1) + i] = bu.value[i] * bv.value[j];
                }
            }
            for a in 0..k {
                for b in 0..k {
                    ata[(idx[a], idx[b])] += w[a] * w[b];
                }
                for (ch, &x) in px.iter().enumerate() {
                    atb[(idx[a], ch)] += w[a] * x;
                }
            }
        }
    }
    if used < (p + 1) * (p + 1) {
        return Err(SplineError::invalid(
            "values",
            format!("{used} valid pixels"),
            format!("at least (degree+1)^2 = {}", (p + 1) * (p + 1)),
        ));
    }
    add_second_difference_penalty(&mut ata, nu, nv, lambda);
    let llt = ata
        .llt(Side::Lower)
        .map_err(|e| SplineError::invalid("values", format!("{e:?}"), "a well-posed fit"))?;
    let sol = llt.solve(&atb);
    let mut ctrl = vec![0.0; n * channels];
    for i in 0..n {
        for ch in 0..channels {
            ctrl[i * channels + ch] = sol[(i, ch)];
        }
    }
    Ok(GridSurface {
        grid: *grid,
        channels,
        ctrl,
    })
}

/// Adds `lambda (D_u^T D_u + D_v^T D_v)` with second differences along each grid axis.
fn add_second_difference_penalty(m: &mut Mat<f64>, nu: usize, nv: usize, lambda: f64) {
    let stencil = [1.0, -2.0, 1.0];
    let mut add = |ids: [usize; 3]| {
        for (a, &ia) in ids.iter().enumerate() {
            for (b, &ib) in ids.iter().enumerate() {
                m[(ia, ib)] += lambda * stencil[a] * stencil[b];
            }
        }
    };
    for row in 0..nv {
        for col in 1..nu.saturating_sub(1) {
            let c = row * nu + col;
            add([c - 1, c, c + 1]);
        }
    }
    for row in 1..nv.saturating_sub(1) {
        for col in 0..nu {
            let c = row * nu + col;
            add([c - nu, c, c + nu]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample(w: usize, h: usize, f: impl Fn(f64, f64) -> f64) -> Vec<f64> {
        (0..w * h)
            .map(|i| f((i % w) as f64, (i / w) as f64))
            .collect()
    }

    #[test]
    fn plane_is_reproduced_to_machine_precision() {
        let (w, h) = (40, 30);
        let plane = |u: f64, v: f64| 2.0 + 0.01 * u - 0.02 * v;
        let mut vals = sample(w, h, plane);
        vals[100] = f64::NAN;
        let grid = KnotGrid::new(w, h, 8.0, 3).unwrap();
        let s = fit_grid(&vals, w, h, 1, &grid, DEFAULT_LAMBDA).unwrap();
        for (u, v) in [(0.0, 0.0), (39.0, 29.0), (13.5, 7.25), (20.0, 3.0)] {
            let j = s.jet(u, v);
            assert!(
                (j.value[0] - plane(u, v)).abs() < 1e-9,
                "{u} {v} {}",
                j.value[0]
            );
            assert!((j.du[0] - 0.01).abs() < 1e-9 && (j.dv[0] + 0.02).abs() < 1e-9);
            assert!(j.duu[0].abs() < 1e-9 && j.dvv[0].abs() < 1e-9);
        }
    }

    #[test]
    fn empty_spans_stay_finite() {
        // Data only in two corners: the regulariser must keep the system well-posed.
        let (w, h) = (48, 48);
        let vals = sample(w, h, |u, v| {
            if (u < 10.0 && v < 10.0) || (u > 38.0 && v > 38.0) {
                1.0 + 0.01 * u
            } else {
                f64::NAN
            }
        });
        let grid = KnotGrid::new(w, h, 8.0, 3).unwrap();
        let s = fit_grid(&vals, w, h, 1, &grid, DEFAULT_LAMBDA).unwrap();
        assert!(s.ctrl.iter().all(|c| c.is_finite()));
        assert!((s.jet(5.0, 5.0).value[0] - 1.05).abs() < 1e-6);
    }

    #[test]
    fn bad_arguments() {
        assert!(KnotGrid::new(10, 10, 0.5, 3).is_err());
        assert!(KnotGrid::new(10, 10, 4.0, 0).is_err());
        assert!(KnotGrid::new(10, 10, 4.0, 6).is_err());
        let grid = KnotGrid::new(10, 10, 4.0, 3).unwrap();
        assert!(fit_grid(&[1.0; 99], 10, 10, 1, &grid, 1e-6).is_err());
        assert!(fit_grid(&[f64::NAN; 100], 10, 10, 1, &grid, 1e-6).is_err());
        assert!(fit_grid(&[1.0; 100], 10, 10, 1, &grid, 0.0).is_err());
    }
}
