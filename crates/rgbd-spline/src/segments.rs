//! Per-segment fits for region merging (thesis §4.7, eq. 4.8): each segment keeps its normal
//! equations, so the fit of a union is one sum and one band solve, never a pass over pixels.

use rayon::prelude::*;

use crate::fit::{solve, Fit};
use crate::grid::{check_grid, check_pixels, check_values, valid_mean, KnotGrid};
use crate::maps::{surface_maps, SurfaceMaps};
use crate::normal::{accumulate, Normal, Region};
use crate::SplineError;

/// Which number `fit_error` reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Criterion {
    /// Mean squared 3-D distance to the surface (the thesis' `e`). On an image-anchored grid the
    /// union's function space is a restriction of the parts', so its MSE is never below their
    /// weighted mean: eq. 4.8 would never merge.
    Mse,
    /// Generalised cross-validation `n·SSE/(n - dof)²` (default): the MSE corrected for the
    /// degrees of freedom the fit spent, an estimate of the error on new points of the same
    /// surface. Two segments of one surface then score better together (fewer degrees of freedom
    /// per pixel), two surfaces across a step score worse.
    Gcv,
}

/// Fits of every segment of a label image, with cheap unions and merges.
#[derive(Debug, Clone)]
pub struct SegmentFits {
    pub grid: KnotGrid,
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub lambda: f64,
    pub criterion: Criterion,
    offset: Vec<f64>,
    labels: Vec<i32>,
    normals: Vec<Normal>,
    fits: Vec<Result<Fit, SplineError>>,
    /// `parent[i] == i` for live segments; a merged segment points at the one it joined.
    parent: Vec<usize>,
}

impl SegmentFits {
    /// Fits every label `0..=max(labels)` (negative: unlabelled) of `values`
    /// (`height x width x channels`), in parallel.
    #[allow(clippy::too_many_arguments)]
    pub fn new<T: Copy + Into<f64> + Sync>(
        values: &[T],
        width: usize,
        height: usize,
        channels: usize,
        labels: &[i32],
        grid: &KnotGrid,
        lambda: f64,
        criterion: Criterion,
    ) -> Result<Self, SplineError> {
        check_values(values, width, height, channels, lambda)?;
        check_grid(grid, width, height)?;
        check_pixels("labels", labels.len(), width, height)?;
        let n_labels = labels.iter().copied().max().unwrap_or(-1) + 1;
        if n_labels <= 0 {
            return Err(SplineError::invalid(
                "labels",
                "no label >= 0",
                "at least one labelled pixel",
            ));
        }
        let n_labels = n_labels as usize;
        let full = Region::full(width, height);
        let offset = valid_mean(values, width, channels, full, |i| labels[i] >= 0);
        let normals = accumulate(
            values,
            width,
            height,
            channels,
            Some(labels),
            n_labels,
            grid,
            &offset,
            full,
        );
        let with_dof = criterion == Criterion::Gcv;
        let fits = normals
            .par_iter()
            .map(|n| solve(n, grid, lambda, &offset, with_dof))
            .collect();
        Ok(Self {
            grid: *grid,
            width,
            height,
            channels,
            lambda,
            criterion,
            offset,
            labels: labels.to_vec(),
            normals,
            fits,
            parent: (0..n_labels).collect(),
        })
    }

    /// Number of labels the fits were built with (merged ones included).
    pub fn n_labels(&self) -> usize {
        self.parent.len()
    }

    /// The live segment a label belongs to now.
    pub fn find(&self, label: usize) -> usize {
        let mut i = label;
        while self.parent[i] != i {
            i = self.parent[i];
        }
        i
    }

    fn live(&self, arg: &'static str, i: usize) -> Result<(), SplineError> {
        if i >= self.parent.len() {
            return Err(SplineError::invalid(
                arg,
                i,
                format!("a segment id < {}", self.parent.len()),
            ));
        }
        if self.parent[i] != i {
            return Err(SplineError::invalid(
                arg,
                format!("segment {i}, merged into {}", self.find(i)),
                "a live segment",
            ));
        }
        Ok(())
    }

    /// Valid pixels of live segment `i`.
    pub fn size(&self, i: usize) -> Result<usize, SplineError> {
        self.live("i", i)?;
        Ok(self.normals[i].moments.n)
    }

    /// The fit of live segment `i`.
    pub fn fit(&self, i: usize) -> Result<&Fit, SplineError> {
        self.live("i", i)?;
        self.fits[i].as_ref().map_err(Clone::clone)
    }

    fn error_of(&self, fit: &Fit) -> f64 {
        match self.criterion {
            Criterion::Mse => fit.mse(),
            Criterion::Gcv => fit.gcv(),
        }
    }

    /// Fitting error of live segment `i` under the chosen [`Criterion`].
    pub fn fit_error(&self, i: usize) -> Result<f64, SplineError> {
        Ok(self.error_of(self.fit(i)?))
    }

    /// The normal equations of the union of live segments `i` and `j`, and their fit.
    fn union_fit(&self, i: usize, j: usize) -> Result<(Normal, Fit), SplineError> {
        self.live("i", i)?;
        self.live("j", j)?;
        if i == j {
            return Err(SplineError::invalid("j", j, "a segment other than i"));
        }
        let u = self.normals[i].union(&self.normals[j]);
        let fit = solve(
            &u,
            &self.grid,
            self.lambda,
            &self.offset,
            self.criterion == Criterion::Gcv,
        )?;
        Ok((u, fit))
    }

    /// Fitting error of the union of live segments `i` and `j` (nothing is changed).
    pub fn union_error(&self, i: usize, j: usize) -> Result<f64, SplineError> {
        Ok(self.error_of(&self.union_fit(i, j)?.1))
    }

    /// Eq. 4.8: whether `e_i|S_i| + e_j|S_j| > e_ij (|S_i| + |S_j|)`.
    pub fn should_merge(&self, i: usize, j: usize) -> Result<bool, SplineError> {
        let (ni, nj) = (self.size(i)? as f64, self.size(j)? as f64);
        let lhs = self.fit_error(i)? * ni + self.fit_error(j)? * nj;
        Ok(lhs > self.union_error(i, j)? * (ni + nj))
    }

    /// Merges live segment `j` into `i`; returns the error of the merged segment.
    pub fn merge(&mut self, i: usize, j: usize) -> Result<f64, SplineError> {
        let (union, fit) = self.union_fit(i, j)?;
        let e = self.error_of(&fit);
        let empty = Normal::empty(union.k, union.channels);
        self.normals[i] = union;
        self.normals[j] = empty;
        self.fits[i] = Ok(fit);
        self.fits[j] = Err(SplineError::invalid(
            "j",
            format!("segment {j}"),
            "a live segment",
        ));
        self.parent[j] = i;
        Ok(e)
    }

    /// The label image with every label replaced by the live segment it belongs to.
    pub fn current_labels(&self) -> Vec<i32> {
        let root: Vec<i32> = (0..self.parent.len())
            .map(|i| self.find(i) as i32)
            .collect();
        self.labels
            .iter()
            .map(|&l| if l < 0 { l } else { root[l as usize] })
            .collect()
    }

    /// Per-pixel maps of `values` (the array the fits were built from) against the surface of
    /// the segment each pixel belongs to now.
    pub fn maps<T: Copy + Into<f64> + Sync>(
        &self,
        values: &[T],
    ) -> Result<SurfaceMaps, SplineError> {
        check_values(values, self.width, self.height, self.channels, self.lambda)?;
        let root: Vec<usize> = (0..self.parent.len()).map(|i| self.find(i)).collect();
        Ok(surface_maps(
            values,
            self.width,
            self.height,
            self.channels,
            None,
            |px| {
                let l = self.labels[px];
                if l < 0 {
                    None
                } else {
                    self.fits[root[l as usize]].as_ref().ok()
                }
            },
        ))
    }
}
