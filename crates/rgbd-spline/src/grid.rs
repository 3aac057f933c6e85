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

use crate::basis::{uniform_basis, Basis, MAX_DEGREE};
use crate::fit::{solve, Fit};
use crate::normal::{accumulate_by, Region};
use crate::surface::MAX_CHANNELS;
use rayon::prelude::*;
use rgbd_error::{invalid, RgbdError};

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
    ) -> Result<Self, RgbdError> {
        if !(1..=MAX_DEGREE).contains(&degree) {
            return Err(invalid("degree", degree, format!("1..={MAX_DEGREE}")));
        }
        if !(spacing.is_finite() && spacing >= 1.0) {
            return Err(invalid("spacing", spacing, "a knot spacing >= 1 pixel"));
        }
        if width == 0 || height == 0 {
            return Err(invalid(
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

    /// The cell and basis of pixel coordinate `x` along u (`along_u`) or v.
    #[inline]
    pub fn axis(&self, x: f64, along_u: bool) -> (usize, Basis) {
        let (c, t) = self.locate(x, if along_u { self.cells_u } else { self.cells_v });
        // Degree was validated in `new`, t is clamped to [0, 1]: the basis cannot fail.
        (
            c,
            uniform_basis(self.degree, t).unwrap_or_else(|_| unreachable!()),
        )
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

/// Per-channel mean of the valid pixels (all channels finite, `keep` true) inside `region`: the
/// offset the normal equations are accumulated against, so sums of squares stay well-conditioned.
pub fn valid_mean<T: Copy + Into<f64> + Sync>(
    values: &[T],
    width: usize,
    channels: usize,
    region: Region,
    keep: impl Fn(usize) -> bool + Sync,
) -> Vec<f64> {
    match channels {
        1 => mean_of::<T, 1>(values, width, region, keep),
        2 => mean_of::<T, 2>(values, width, region, keep),
        3 => mean_of::<T, 3>(values, width, region, keep),
        _ => mean_of::<T, 4>(values, width, region, keep),
    }
}

/// [`valid_mean`] of `C` channels.
fn mean_of<T: Copy + Into<f64> + Sync, const C: usize>(
    values: &[T],
    width: usize,
    region: Region,
    keep: impl Fn(usize) -> bool + Sync,
) -> Vec<f64> {
    let row_sums = |v: usize| {
        let mut sum = [0.0; C];
        let mut n = 0usize;
        let i0 = v * width + region.u0;
        let px = &values[i0 * C..(v * width + region.u1) * C];
        for (i, p) in (i0..).zip(px.chunks_exact(C)) {
            let x: [f64; C] = std::array::from_fn(|c| p[c].into());
            if x.iter().all(|x| x.is_finite()) && keep(i) {
                n += 1;
                for (s, x) in sum.iter_mut().zip(x) {
                    *s += x;
                }
            }
        }
        (sum, n)
    };
    // Rows in parallel, their sums added in row order: the same offset whatever the threads.
    let rows: Vec<([f64; C], usize)> = (region.v0..region.v1)
        .into_par_iter()
        .with_min_len(32)
        .map(row_sums)
        .collect();
    let (mut sum, mut n) = ([0.0; C], 0);
    for (s, k) in rows {
        for (a, b) in sum.iter_mut().zip(s) {
            *a += b;
        }
        n += k;
    }
    sum.iter()
        .map(|s| if n > 0 { s / n as f64 } else { 0.0 })
        .collect()
}

pub(crate) fn check_values<T>(
    values: &[T],
    width: usize,
    height: usize,
    channels: usize,
    lambda: f64,
) -> Result<(), RgbdError> {
    if !(1..=MAX_CHANNELS).contains(&channels) {
        return Err(invalid("channels", channels, format!("1..={MAX_CHANNELS}")));
    }
    if values.len() != width * height * channels {
        return Err(invalid(
            "values",
            format!("{} values", values.len()),
            format!("height * width * channels = {}", width * height * channels),
        ));
    }
    if !(lambda.is_finite() && lambda > 0.0) {
        return Err(invalid("lambda", lambda, "a smoothness weight > 0"));
    }
    Ok(())
}

/// Least-squares fit of `channels` values per pixel (`height x width x channels`, row-major; a
/// pixel with any non-finite channel is skipped) on `grid` with smoothness weight `lambda`.
/// Fewer than `(p+1)²` valid pixels fall back to a linear fit ([`FitKind::Linear`]).
/// `with_dof` also computes the effective degrees of freedom (for [`Fit::gcv`]), which costs
/// about as much again as the solve.
pub fn fit_grid<T: Copy + Into<f64> + Sync>(
    values: &[T],
    width: usize,
    height: usize,
    channels: usize,
    grid: &KnotGrid,
    lambda: f64,
    with_dof: bool,
) -> Result<Fit, RgbdError> {
    fit_mask(
        values, width, height, channels, None, grid, lambda, with_dof,
    )
}

/// As [`fit_grid`] on the pixels where `mask` is true (`None`: all pixels).
#[allow(clippy::too_many_arguments)]
pub fn fit_mask<T: Copy + Into<f64> + Sync>(
    values: &[T],
    width: usize,
    height: usize,
    channels: usize,
    mask: Option<&[bool]>,
    grid: &KnotGrid,
    lambda: f64,
    with_dof: bool,
) -> Result<Fit, RgbdError> {
    Ok(fit_mask_box(
        values, width, height, channels, mask, grid, lambda, with_dof,
    )?
    .0)
}

/// As [`fit_mask`], also returning the bounding box of the mask's pixels (the whole image
/// without a mask), which the fit found anyway.
#[allow(clippy::too_many_arguments)]
pub fn fit_mask_box<T: Copy + Into<f64> + Sync>(
    values: &[T],
    width: usize,
    height: usize,
    channels: usize,
    mask: Option<&[bool]>,
    grid: &KnotGrid,
    lambda: f64,
    with_dof: bool,
) -> Result<(Fit, Region), RgbdError> {
    check_values(values, width, height, channels, lambda)?;
    check_grid(grid, width, height)?;
    if let Some(m) = mask {
        check_pixels("mask", m.len(), width, height)?;
    }
    let region = match mask {
        Some(m) => Region::of_mask(width, m),
        None => Some(Region::full(width, height)),
    };
    let Some(region) = region else {
        return Err(invalid(
            "mask",
            "no pixel selected",
            "at least one true pixel",
        ));
    };
    let offset = valid_mean(values, width, channels, region, |i| {
        mask.is_none_or(|m| m[i])
    });
    let normals = accumulate_by(
        values,
        width,
        height,
        channels,
        |i| mask.map_or(0, |m| if m[i] { 0 } else { -1 }),
        1,
        grid,
        &offset,
        region,
    );
    if normals[0].moments.n == 0 {
        return Err(invalid(
            "values",
            "no valid pixel (all NaN or masked out)",
            "at least one pixel with finite values",
        ));
    }
    Ok((solve(&normals[0], grid, lambda, &offset, with_dof)?, region))
}

/// A per-pixel array (`arg`) must hold one value per pixel.
pub(crate) fn check_pixels(
    arg: &'static str,
    len: usize,
    width: usize,
    height: usize,
) -> Result<(), RgbdError> {
    if len != width * height {
        return Err(invalid(
            arg,
            format!("{len} values"),
            format!("height * width = {}", width * height),
        ));
    }
    Ok(())
}

/// The grid must have been made for an image of this size.
pub(crate) fn check_grid(grid: &KnotGrid, width: usize, height: usize) -> Result<(), RgbdError> {
    let expect = KnotGrid::new(width, height, grid.spacing, grid.degree)?;
    if expect != *grid {
        return Err(invalid(
            "grid",
            format!("{}x{} cells", grid.cells_u, grid.cells_v),
            format!("the grid of a {width}x{height} image"),
        ));
    }
    Ok(())
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
        let s = fit_grid(&vals, w, h, 1, &grid, DEFAULT_LAMBDA, false).unwrap();
        for (u, v) in [(0.0, 0.0), (39.0, 29.0), (13.5, 7.25), (20.0, 3.0)] {
            let j = s.surface.jet(u, v).unwrap();
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
        let s = fit_grid(&vals, w, h, 1, &grid, DEFAULT_LAMBDA, false).unwrap();
        assert!(s.surface.ctrl.iter().all(|c| c.is_finite()));
        assert!((s.surface.jet(5.0, 5.0).unwrap().value[0] - 1.05).abs() < 1e-6);
    }

    #[test]
    fn bad_arguments() {
        assert!(KnotGrid::new(10, 10, 0.5, 3).is_err());
        assert!(KnotGrid::new(10, 10, 4.0, 0).is_err());
        assert!(KnotGrid::new(10, 10, 4.0, 6).is_err());
        let grid = KnotGrid::new(10, 10, 4.0, 3).unwrap();
        assert!(fit_grid(&[1.0; 99], 10, 10, 1, &grid, 1e-6, false).is_err());
        assert!(fit_grid(&[f64::NAN; 100], 10, 10, 1, &grid, 1e-6, false).is_err());
        assert!(fit_grid(&[1.0; 100], 10, 10, 1, &grid, 0.0, false).is_err());
    }
}
