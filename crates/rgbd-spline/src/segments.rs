//! Per-segment fits for region merging (thesis §4.7, eq. 4.8): each segment keeps its normal
//! equations, so the fit of a union is one sum and one band solve, never a pass over pixels.

use rayon::prelude::*;

use crate::fit::{solve, Fit};
use crate::grid::{check_grid, check_pixels, check_values, valid_mean, KnotGrid};
use crate::maps::{surface_maps, SurfaceMaps};
use crate::normal::{accumulate, Normal, Region};
use rgbd_error::{invalid, RgbdError};

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
    /// Per pixel: the slot of its label in `ids`, -1 unlabelled (labels are compacted, never
    /// used as indices: a label of 2^31 - 2 costs one slot, not 2^31).
    slots: Vec<i32>,
    /// The distinct labels >= 0, sorted; slot `s` holds label `ids[s]`.
    ids: Vec<i32>,
    normals: Vec<Normal>,
    fits: Vec<Result<Fit, RgbdError>>,
    /// `parent[s] == s` for live segments; a merged segment points at the one it joined (slots).
    parent: Vec<usize>,
}

impl SegmentFits {
    /// Fits every distinct label >= 0 (negative: unlabelled) of `values`
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
    ) -> Result<Self, RgbdError> {
        check_values(values, width, height, channels, lambda)?;
        check_grid(grid, width, height)?;
        check_pixels("labels", labels.len(), width, height)?;
        let mut ids: Vec<i32> = labels.iter().copied().filter(|&l| l >= 0).collect();
        ids.par_sort_unstable();
        ids.dedup();
        if ids.is_empty() {
            return Err(invalid(
                "labels",
                "no label >= 0",
                "at least one labelled pixel",
            ));
        }
        let n_labels = ids.len();
        let slots: Vec<i32> = labels
            .par_iter()
            .map(|&l| {
                if l < 0 {
                    l
                } else {
                    ids.binary_search(&l).map_or(-1, |s| s as i32)
                }
            })
            .collect();
        let labels = &slots[..];
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
            slots,
            ids,
            normals,
            fits,
            parent: (0..n_labels).collect(),
        })
    }

    /// Number of distinct labels the fits were built with (merged ones included).
    pub fn n_labels(&self) -> usize {
        self.parent.len()
    }

    /// The distinct labels the fits were built with, sorted.
    pub fn label_ids(&self) -> &[i32] {
        &self.ids
    }

    /// The slot of `label`, or an error naming `arg`.
    fn slot(&self, arg: &'static str, label: usize) -> Result<usize, RgbdError> {
        i32::try_from(label)
            .ok()
            .and_then(|l| self.ids.binary_search(&l).ok())
            .ok_or_else(|| invalid(arg, label, "a label present in the label image"))
    }

    fn root(&self, slot: usize) -> usize {
        let mut i = slot;
        while self.parent[i] != i {
            i = self.parent[i];
        }
        i
    }

    /// The live segment (its label) that `label` belongs to now.
    pub fn find(&self, label: usize) -> Result<usize, RgbdError> {
        Ok(self.ids[self.root(self.slot("label", label)?)] as usize)
    }

    /// The slot of live segment `label`, or an error naming `arg`.
    fn live(&self, arg: &'static str, label: usize) -> Result<usize, RgbdError> {
        let s = self.slot(arg, label)?;
        if self.parent[s] != s {
            return Err(invalid(
                arg,
                format!("segment {label}, merged into {}", self.ids[self.root(s)]),
                "a live segment",
            ));
        }
        Ok(s)
    }

    /// Valid pixels of live segment `i`.
    pub fn size(&self, i: usize) -> Result<usize, RgbdError> {
        Ok(self.normals[self.live("i", i)?].moments.n)
    }

    /// The fit of live segment `i`.
    pub fn fit(&self, i: usize) -> Result<&Fit, RgbdError> {
        self.fits[self.live("i", i)?].as_ref().map_err(Clone::clone)
    }

    fn error_of(&self, fit: &Fit) -> f64 {
        match self.criterion {
            Criterion::Mse => fit.mse(),
            Criterion::Gcv => fit.gcv(),
        }
    }

    /// Fitting error of live segment `i` under the chosen [`Criterion`].
    pub fn fit_error(&self, i: usize) -> Result<f64, RgbdError> {
        Ok(self.error_of(self.fit(i)?))
    }

    /// The normal equations of the union of live segments `i` and `j`, and their fit.
    fn union_fit(&self, i: usize, j: usize) -> Result<(Normal, Fit), RgbdError> {
        let (si, sj) = (self.live("i", i)?, self.live("j", j)?);
        if i == j {
            return Err(invalid("j", j, "a segment other than i"));
        }
        let u = self.normals[si].union(&self.normals[sj]);
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
    pub fn union_error(&self, i: usize, j: usize) -> Result<f64, RgbdError> {
        Ok(self.error_of(&self.union_fit(i, j)?.1))
    }

    /// Eq. 4.8: whether `e_i|S_i| + e_j|S_j| > e_ij (|S_i| + |S_j|)`.
    pub fn should_merge(&self, i: usize, j: usize) -> Result<bool, RgbdError> {
        let (ni, nj) = (self.size(i)? as f64, self.size(j)? as f64);
        let lhs = self.fit_error(i)? * ni + self.fit_error(j)? * nj;
        Ok(lhs > self.union_error(i, j)? * (ni + nj))
    }

    /// Merges live segment `j` into `i`; returns the error of the merged segment.
    pub fn merge(&mut self, i: usize, j: usize) -> Result<f64, RgbdError> {
        let (union, fit) = self.union_fit(i, j)?;
        let (si, sj) = (self.live("i", i)?, self.live("j", j)?);
        let e = self.error_of(&fit);
        let empty = Normal::empty(union.k, union.channels);
        self.normals[si] = union;
        self.normals[sj] = empty;
        self.fits[si] = Ok(fit);
        self.fits[sj] = Err(invalid("j", format!("segment {j}"), "a live segment"));
        self.parent[sj] = si;
        Ok(e)
    }

    /// The label image with every label replaced by the live segment it belongs to.
    pub fn current_labels(&self) -> Vec<i32> {
        let root: Vec<i32> = (0..self.parent.len())
            .map(|s| self.ids[self.root(s)])
            .collect();
        self.slots
            .iter()
            .map(|&s| if s < 0 { s } else { root[s as usize] })
            .collect()
    }

    /// Per-pixel maps of `values` (the array the fits were built from) against the surface of
    /// the segment each pixel belongs to now.
    pub fn maps<T: Copy + Into<f64> + Sync>(&self, values: &[T]) -> Result<SurfaceMaps, RgbdError> {
        check_values(values, self.width, self.height, self.channels, self.lambda)?;
        let root: Vec<usize> = (0..self.parent.len()).map(|s| self.root(s)).collect();
        Ok(surface_maps(
            values,
            self.width,
            self.height,
            self.channels,
            None,
            |px| {
                let s = self.slots[px];
                if s < 0 {
                    None
                } else {
                    self.fits[root[s as usize]].as_ref().ok()
                }
            },
        ))
    }
}
