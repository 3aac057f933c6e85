//! Per-segment fits for region merging (thesis §4.7, eq. 4.8): each segment keeps its normal
//! equations, so the fit of a union is one sum and one band solve, never a pass over pixels.

use rayon::prelude::*;

use crate::fit::{solve, Fit};
use crate::grid::{check_grid, check_pixels, check_values, valid_mean, KnotGrid};
use crate::local::{box_union, cell_box, local_union_delta, CellBox};
use crate::maps::{surface_maps, SurfaceMaps};
use crate::normal::{accumulate, Normal, Region};
use crate::seam::{seam_pixels, SeamTest};
use crate::union::{solve_one_channel, solve_union};
use rgbd_error::{invalid, RgbdError};

/// Which number `fit_error` reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
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
    /// The seam test of [`crate::seam`] (default): `fit_error` is the segment's χ² per pixel
    /// against its surface of variance-stabilised depth (in noise variances), `union_error` the
    /// union's χ² less `tolerance` per seam pixel, per pixel (infinite when the two segments have
    /// no seam, i.e. do not meet). Eq. 4.8 then merges when the union
    /// fits its seam to within the sensor noise, and the improvement
    /// `e_i|S_i| + e_j|S_j| - e_ij(|S_i| + |S_j|) = tolerance·|seam| - Δχ²` orders pairs by how
    /// long and how continuous their seam is. Parameters: [`SeamTest`].
    #[default]
    Seam,
}

/// The fits of the seam test: one channel (variance-stabilised depth) on the test grid.
#[derive(Debug, Clone)]
struct TestFits {
    spec: SeamTest,
    grid: KnotGrid,
    offset: Vec<f64>,
    normals: Vec<Normal>,
    fits: Vec<Result<Fit, RgbdError>>,
    /// Cell box of each slot's test cells (`None`: no cell).
    boxes: Vec<Option<CellBox>>,
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
    /// The seam test's fits (`criterion == Seam` only).
    test: Option<TestFits>,
    /// False when built by [`SegmentFits::test_only`]: no surface fits, only the seam test.
    surfaces: bool,
    /// Merges applied so far (a [`PreparedMerge`] is valid for one generation).
    generation: usize,
}

/// The union fits of a merge, solved by [`SegmentFits::prepare_merge`] and applied by
/// [`SegmentFits::apply_merge`].
#[derive(Debug, Clone)]
pub struct PreparedMerge {
    slots: (usize, usize),
    /// The label of the absorbed segment (for the error its slot reports afterwards).
    absorbed: usize,
    generation: usize,
    surface: Option<(Normal, Fit)>,
    tested: Option<(Normal, Fit)>,
}

impl SegmentFits {
    /// Fits every distinct label >= 0 (negative: unlabelled) of `values`
    /// (`height x width x channels`), in parallel. [`Criterion::Seam`] uses the default
    /// [`SeamTest`] (Kinect v1 noise, 16-pixel test grid, tolerance 1); see [`Self::with_test`].
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
        Self::with_test(
            values,
            width,
            height,
            channels,
            labels,
            grid,
            lambda,
            criterion,
            &SeamTest::default(),
        )
    }

    /// As [`Self::new`] with the parameters of the seam test (used when `criterion` is
    /// [`Criterion::Seam`]). The depth the test reads is the last channel of `values` (`Z` of an
    /// `X, Y, Z` point cloud, or a one-channel depth map), in the unit of `test.noise`.
    #[allow(clippy::too_many_arguments)]
    pub fn with_test<T: Copy + Into<f64> + Sync>(
        values: &[T],
        width: usize,
        height: usize,
        channels: usize,
        labels: &[i32],
        grid: &KnotGrid,
        lambda: f64,
        criterion: Criterion,
        test: &SeamTest,
    ) -> Result<Self, RgbdError> {
        Self::build(
            values, width, height, channels, labels, grid, lambda, criterion, test, true,
        )
    }

    /// The seam test alone ([`Criterion::Seam`], `test`), without surface fits of `values`: about
    /// a third of the cost of [`Self::with_test`]. `fit_error`, `union_error`, `should_merge`,
    /// `merge`, `size` (valid depth pixels here), `find` and `current_labels` work; `fit` and
    /// `maps` report that there are no surfaces. `grid` is the test grid.
    pub fn test_only<T: Copy + Into<f64> + Sync>(
        values: &[T],
        width: usize,
        height: usize,
        channels: usize,
        labels: &[i32],
        lambda: f64,
        test: &SeamTest,
    ) -> Result<Self, RgbdError> {
        test.validate()?;
        let grid = KnotGrid::new(width, height, test.spacing, 3)?;
        Self::build(
            values,
            width,
            height,
            channels,
            labels,
            &grid,
            lambda,
            Criterion::Seam,
            test,
            false,
        )
    }

    #[allow(clippy::too_many_arguments)]
    fn build<T: Copy + Into<f64> + Sync>(
        values: &[T],
        width: usize,
        height: usize,
        channels: usize,
        labels: &[i32],
        grid: &KnotGrid,
        lambda: f64,
        criterion: Criterion,
        test: &SeamTest,
        surfaces: bool,
    ) -> Result<Self, RgbdError> {
        test.validate()?;
        check_values(values, width, height, channels, lambda)?;
        check_grid(grid, width, height)?;
        check_pixels("labels", labels.len(), width, height)?;
        let (ids, table) = distinct_labels(labels);
        if ids.is_empty() {
            return Err(invalid(
                "labels",
                "no label >= 0",
                "at least one labelled pixel",
            ));
        }
        let n_labels = ids.len();
        let slots = label_slots(labels, &ids, table.as_deref());
        let labels = &slots[..];
        let full = Region::full(width, height);
        let (offset, normals, fits) = if surfaces {
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
            (offset, normals, fits)
        } else {
            (vec![0.0; channels], Vec::new(), Vec::new())
        };
        let test = (criterion == Criterion::Seam)
            .then(|| {
                TestFits::new(
                    values, width, height, channels, labels, n_labels, lambda, test,
                )
            })
            .transpose()?;
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
            test,
            surfaces,
            generation: 0,
        })
    }

    /// Number of distinct labels the fits were built with (merged ones included).
    pub fn n_labels(&self) -> usize {
        self.parent.len()
    }

    /// Merges applied so far.
    pub fn merges(&self) -> usize {
        self.generation
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

    /// Valid pixels of slot `s` (of the test when there are no surfaces).
    fn count(&self, s: usize) -> usize {
        match (&self.test, self.surfaces) {
            (Some(t), false) => t.normals[s].moments.n,
            _ => self.normals[s].moments.n,
        }
    }

    /// Valid pixels of live segment `i` ([`Self::test_only`]: pixels with a valid depth).
    pub fn size(&self, i: usize) -> Result<usize, RgbdError> {
        Ok(self.count(self.live("i", i)?))
    }

    /// The fit of live segment `i`.
    pub fn fit(&self, i: usize) -> Result<&Fit, RgbdError> {
        let s = self.live("i", i)?;
        if !self.surfaces {
            return Err(no_surfaces());
        }
        self.fits[s].as_ref().map_err(Clone::clone)
    }

    fn error_of(&self, fit: &Fit) -> f64 {
        match self.criterion {
            Criterion::Mse => fit.mse(),
            Criterion::Gcv | Criterion::Seam => fit.gcv(),
        }
    }

    /// Fitting error of live segment `i` under the chosen [`Criterion`].
    pub fn fit_error(&self, i: usize) -> Result<f64, RgbdError> {
        match &self.test {
            Some(t) => {
                let s = self.live("i", i)?;
                let fit = t.fits[s].as_ref().map_err(Clone::clone)?;
                Ok(fit.sse / self.count(s) as f64)
            }
            None => Ok(self.error_of(self.fit(i)?)),
        }
    }

    /// The seam test's union of live segments `i` and `j`: its test normal equations and fit.
    fn test_union(&self, i: usize, j: usize) -> Result<Option<(Normal, Fit)>, RgbdError> {
        let (si, sj) = (self.live("i", i)?, self.live("j", j)?);
        if i == j {
            return Err(invalid("j", j, "a segment other than i"));
        }
        let Some(t) = &self.test else { return Ok(None) };
        let (a, b) = (&t.normals[si], &t.normals[sj]);
        let u = a.union(b);
        let fit = solve_one_channel(&u, &t.grid, self.lambda, &t.offset)?;
        Ok(Some((u, fit)))
    }

    /// Pixels of the union of live segments `i` and `j` whose test fit the union couples (the
    /// seam of [`Criterion::Seam`]; 0 under the other criteria).
    pub fn seam(&self, i: usize, j: usize) -> Result<usize, RgbdError> {
        let (si, sj) = (self.live("i", i)?, self.live("j", j)?);
        if i == j {
            return Err(invalid("j", j, "a segment other than i"));
        }
        Ok(self
            .test
            .as_ref()
            .map_or(0, |t| seam_pixels(&t.normals[si], &t.normals[sj], &t.grid)))
    }

    /// The seam test's `(χ²(S_i ∪ S_j), |seam|)` for live segments `i`, `j`, with the union fit
    /// chosen by [`SeamTest::window`] (local: the parts' χ² plus the local `Δχ²`; `None` when
    /// the local fit does not apply, e.g. a part without a fit). `None` without a seam test.
    fn test_chi2(&self, i: usize, j: usize) -> Result<Option<(f64, usize)>, RgbdError> {
        let (si, sj) = (self.live("i", i)?, self.live("j", j)?);
        if i == j {
            return Err(invalid("j", j, "a segment other than i"));
        }
        let Some(t) = &self.test else { return Ok(None) };
        let (a, b) = (&t.normals[si], &t.normals[sj]);
        let (Some(ba), Some(bb)) = (t.boxes[si], t.boxes[sj]) else {
            return Ok(Some((f64::NAN, 0)));
        };
        if let (Some(r), Ok(fa), Ok(fb)) = (t.spec.window, &t.fits[si], &t.fits[sj]) {
            let local = local_union_delta(
                [(a, fa), (b, fb)],
                [ba, bb],
                &t.grid,
                self.lambda,
                t.offset[0],
                r,
            )?;
            return Ok(Some(match local {
                Some((delta, seam)) => (fa.sse + fb.sse + delta, seam),
                None => (f64::NAN, 0),
            }));
        }
        let seam = seam_pixels(a, b, &t.grid);
        if seam == 0 {
            return Ok(Some((f64::NAN, 0)));
        }
        let u = a.union(b);
        let fit = solve(&u, &t.grid, self.lambda, &t.offset, false)?;
        Ok(Some((fit.sse, seam)))
    }

    /// The normal equations of the union of live segments `i` and `j`, and their fit.
    fn union_fit(&self, i: usize, j: usize) -> Result<(Normal, Fit), RgbdError> {
        let (si, sj) = (self.live("i", i)?, self.live("j", j)?);
        if i == j {
            return Err(invalid("j", j, "a segment other than i"));
        }
        if !self.surfaces {
            return Err(no_surfaces());
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

    /// Fitting error of the union of live segments `i` and `j` (nothing is changed). Under
    /// [`Criterion::Seam`]: `(χ²_ij - tolerance·|seam|) / (|S_i| + |S_j|)`, so eq. 4.8 is the
    /// seam test; infinite (never merged) when the segments have no seam.
    pub fn union_error(&self, i: usize, j: usize) -> Result<f64, RgbdError> {
        // Both checked first, each under its own name (the helpers below name theirs `i`).
        self.live("i", i)?;
        self.live("j", j)?;
        match (self.test_chi2(i, j)?, &self.test) {
            // No seam: the parts do not meet, nothing says they are one surface (and the χ² of
            // the union equals the parts' up to rounding, which must not decide).
            (Some((_, 0)), Some(_)) => Ok(f64::INFINITY),
            (Some((chi2, seam)), Some(t)) => {
                let n = (self.size(i)? + self.size(j)?) as f64;
                Ok((chi2 - t.spec.tolerance * seam as f64) / n)
            }
            _ => Ok(self.error_of(&self.union_fit(i, j)?.1)),
        }
    }

    /// Eq. 4.8: whether `e_i|S_i| + e_j|S_j| > e_ij (|S_i| + |S_j|)`.
    pub fn should_merge(&self, i: usize, j: usize) -> Result<bool, RgbdError> {
        self.live("i", i)?;
        self.live("j", j)?;
        let (ni, nj) = (self.size(i)? as f64, self.size(j)? as f64);
        let lhs = self.fit_error(i)? * ni + self.fit_error(j)? * nj;
        Ok(lhs > self.union_error(i, j)? * (ni + nj))
    }

    /// Merges live segment `j` into `i`; returns the error of the merged segment
    /// ([`Self::fit_error`] of `i` afterwards).
    pub fn merge(&mut self, i: usize, j: usize) -> Result<f64, RgbdError> {
        if self.surfaces || self.test.is_none() {
            let prepared = self.prepare_merge(i, j)?;
            return self.apply_merge(prepared);
        }
        // The seam test alone ([`Self::test_only`]): as `apply_merge(prepare_merge(..))`, but the
        // union is fitted from its parts and then joined into the kept segment's system in place
        // (no copy of the kept segment's blocks per merge; same fit and system bit for bit).
        let (si, sj) = (self.live("i", i)?, self.live("j", j)?);
        if i == j {
            return Err(invalid("j", j, "a segment other than i"));
        }
        let n = (self.count(si) + self.count(sj)) as f64;
        let Some(t) = self.test.as_mut() else {
            // Not reached (checked above); an error rather than a panic across the boundary.
            return Err(invalid(
                "fits",
                "no seam test",
                "fits built with a seam test",
            ));
        };
        let tfit = solve_union(
            &t.normals[si],
            &t.normals[sj],
            (t.boxes[si], t.boxes[sj]),
            &t.grid,
            self.lambda,
            &t.offset,
        )?;
        let e = tfit.sse / n;
        let k = t.normals[sj].k;
        let absorbed = std::mem::replace(&mut t.normals[sj], Normal::empty(k, 1));
        t.normals[si].absorb(&absorbed);
        t.join(si, sj, j, tfit);
        self.parent[sj] = si;
        self.generation += 1;
        Ok(e)
    }

    /// The solving half of [`Self::merge`] (`&self`: other queries, e.g. union tests of other
    /// segments, may run beside it): the normal equations and fits of the union of live segments
    /// `i` and `j`. [`Self::apply_merge`] then joins them.
    pub fn prepare_merge(&self, i: usize, j: usize) -> Result<PreparedMerge, RgbdError> {
        let surface = if self.surfaces {
            Some(self.union_fit(i, j)?)
        } else {
            None
        };
        let tested = self.test_union(i, j)?;
        let (si, sj) = (self.live("i", i)?, self.live("j", j)?);
        Ok(PreparedMerge {
            slots: (si, sj),
            absorbed: j,
            generation: self.generation,
            surface,
            tested,
        })
    }

    /// Joins the segments of `prepared` (made by [`Self::prepare_merge`] on these fits with no
    /// merge since); returns the error of the merged segment, as [`Self::merge`].
    pub fn apply_merge(&mut self, prepared: PreparedMerge) -> Result<f64, RgbdError> {
        let PreparedMerge {
            slots: (si, sj),
            absorbed: j,
            generation,
            surface,
            tested,
        } = prepared;
        if generation != self.generation {
            return Err(invalid(
                "prepared",
                format!(
                    "a merge prepared before {} other merges",
                    self.generation - generation
                ),
                "a merge prepared on the current fits",
            ));
        }
        let n = (self.count(si) + self.count(sj)) as f64;
        let mut e = f64::NAN;
        if let (Some((tu, tfit)), Some(t)) = (tested, self.test.as_mut()) {
            e = tfit.sse / n;
            let k = tu.k;
            t.normals[si] = tu;
            t.normals[sj] = Normal::empty(k, 1);
            t.join(si, sj, j, tfit);
        }
        if let Some((union, fit)) = surface {
            if self.test.is_none() {
                e = self.error_of(&fit);
            }
            let empty = Normal::empty(union.k, union.channels);
            self.normals[si] = union;
            self.normals[sj] = empty;
            self.fits[si] = Ok(fit);
            self.fits[sj] = Err(invalid("j", format!("segment {j}"), "a live segment"));
        }
        self.parent[sj] = si;
        self.generation += 1;
        Ok(e)
    }

    /// The seam test's parameters (`None` unless the criterion is [`Criterion::Seam`]).
    pub fn seam_test(&self) -> Option<&SeamTest> {
        self.test.as_ref().map(|t| &t.spec)
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
        if !self.surfaces {
            return Err(no_surfaces());
        }
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

/// Each pixel's slot among `ids` (from [`distinct_labels`], with its `table` when it gave one);
/// negative labels are kept as they are.
pub fn label_slots(labels: &[i32], ids: &[i32], table: Option<&[i32]>) -> Vec<i32> {
    match table {
        Some(slot_of) => labels
            .par_iter()
            .map(|&l| if l < 0 { l } else { slot_of[l as usize] })
            .collect(),
        None => labels
            .par_iter()
            .map(|&l| {
                if l < 0 {
                    l
                } else {
                    ids.binary_search(&l).map_or(-1, |s| s as i32)
                }
            })
            .collect(),
    }
}

/// The distinct labels >= 0 of `labels`, sorted, and (when the largest is at most a few times
/// the pixel count) a table of each label's slot among them, `-1` for absent labels: a presence
/// scan instead of sorting every pixel's label.
pub fn distinct_labels(labels: &[i32]) -> (Vec<i32>, Option<Vec<i32>>) {
    let max = labels.iter().copied().fold(-1, i32::max);
    if max < 0 {
        return (Vec::new(), None);
    }
    let max = max as usize;
    if max > 4 * labels.len() + 1024 {
        // Sparse labels (e.g. 2^31 - 2): sort them.
        let mut ids: Vec<i32> = labels.iter().copied().filter(|&l| l >= 0).collect();
        ids.par_sort_unstable();
        ids.dedup();
        return (ids, None);
    }
    let mut slot_of = vec![-1i32; max + 1];
    for &l in labels {
        if l >= 0 {
            slot_of[l as usize] = 0;
        }
    }
    let mut ids = Vec::new();
    for (l, s) in slot_of.iter_mut().enumerate() {
        if *s == 0 {
            *s = ids.len() as i32;
            ids.push(l as i32);
        }
    }
    (ids, Some(slot_of))
}

fn no_surfaces() -> RgbdError {
    invalid(
        "fits",
        "built with test_only (no surface fits)",
        "SegmentFits::new or with_test",
    )
}

impl TestFits {
    /// After slot `sj` (label `j`) joined slot `si`: `si` takes the union's fit and both cell
    /// boxes, `sj` is retired (its normal equations are the caller's business).
    fn join(&mut self, si: usize, sj: usize, j: usize, union_fit: Fit) {
        self.fits[si] = Ok(union_fit);
        self.fits[sj] = Err(invalid("j", format!("segment {j}"), "a live segment"));
        self.boxes[si] = match (self.boxes[si], self.boxes[sj]) {
            (Some(x), Some(y)) => Some(box_union(x, y)),
            (x, y) => x.or(y),
        };
        self.boxes[sj] = None;
    }

    /// Fits the variance-stabilised depth (last channel of `values`) of every slot on the test
    /// grid. `labels` are slots.
    #[allow(clippy::too_many_arguments)]
    fn new<T: Copy + Into<f64> + Sync>(
        values: &[T],
        width: usize,
        height: usize,
        channels: usize,
        labels: &[i32],
        n_labels: usize,
        lambda: f64,
        spec: &SeamTest,
    ) -> Result<Self, RgbdError> {
        let grid = KnotGrid::new(width, height, spec.spacing, 3)?;
        let noise = spec.noise;
        // One pass per row: the stabilised depth and its sum (for the offset).
        let mut g = vec![f64::NAN; width * height];
        // Rows in parallel, their sums added in row order: the same offset whatever the threads.
        let rows: Vec<(f64, usize)> = g
            .par_chunks_mut(width)
            .zip(values.par_chunks(width * channels))
            .zip(labels.par_chunks(width))
            .map(|((out, row), lab)| {
                let (mut sum, mut n) = (0.0, 0usize);
                for ((o, px), &l) in out.iter_mut().zip(row.chunks_exact(channels)).zip(lab) {
                    if l >= 0 && px.iter().all(|&x| x.into().is_finite()) {
                        let x = noise.stabilize(px[channels - 1].into());
                        if x.is_finite() {
                            *o = x;
                            sum += x;
                            n += 1;
                        }
                    }
                }
                (sum, n)
            })
            .collect();
        let (sum, n) = rows.iter().fold((0.0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        let full = Region::full(width, height);
        let offset = vec![if n > 0 { sum / n as f64 } else { 0.0 }];
        let normals = accumulate(
            &g,
            width,
            height,
            1,
            Some(labels),
            n_labels,
            &grid,
            &offset,
            full,
        );
        let fits = normals
            .par_iter()
            .map(|n| solve(n, &grid, lambda, &offset, false))
            .collect();
        let boxes = normals
            .iter()
            .map(|n| (!n.cells.is_empty()).then(|| cell_box(n, &grid)))
            .collect();
        Ok(Self {
            spec: *spec,
            grid,
            offset,
            normals,
            fits,
            boxes,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::{distinct_labels, Criterion, KnotGrid, SegmentFits};

    /// The seam test's offset is a sum over rows: the same bits in a pool of 1 or 4 threads.
    #[test]
    fn seam_fits_are_the_same_bits_for_any_thread_count() {
        let (w, h) = (160usize, 480usize);
        let mut state = 12345u64;
        let mut noise = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut points = Vec::with_capacity(w * h * 3);
        for v in 0..h {
            for u in 0..w {
                // depths from 0.5 to 8 m: stabilised values of many magnitudes, whose sum
                // depends on the order they are added in
                let z = 4.25 + 7.5 * noise() + 0.001 * u as f64;
                points.extend([
                    (u as f64 - 100.0) * z / 300.0,
                    (v as f64 - 80.0) * z / 300.0,
                    z,
                ]);
            }
        }
        let labels: Vec<i32> = (0..w * h)
            .map(|i| ((i / w) / 96 * 4 + (i % w) / 40) as i32)
            .collect();
        let grid = KnotGrid::new(w, h, 16.0, 3).unwrap();
        let errors = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let fits =
                    SegmentFits::new(&points, w, h, 3, &labels, &grid, 1e-3, Criterion::Seam)
                        .unwrap();
                (0..20)
                    .map(|i| fits.fit_error(i).unwrap().to_bits())
                    .collect::<Vec<u64>>()
            })
        };
        let one = errors(1);
        for _ in 0..5 {
            assert_eq!(errors(4), one);
        }
    }

    #[test]
    fn distinct_labels_match_a_sort() {
        let cases: [Vec<i32>; 5] = [
            vec![5, -1, 3, 3, 0, 7, -3, 5],
            vec![-1, -2],
            vec![2_147_483_646, 4, -1, 4],
            (0..500).map(|i| (i * 37 % 101) - 3).collect(),
            vec![0],
        ];
        for labels in cases {
            let mut want: Vec<i32> = labels.iter().copied().filter(|&l| l >= 0).collect();
            want.sort_unstable();
            want.dedup();
            let (ids, table) = distinct_labels(&labels);
            assert_eq!(ids, want, "{labels:?}");
            if let Some(t) = table {
                for &l in labels.iter().filter(|&&l| l >= 0) {
                    assert_eq!(ids[t[l as usize] as usize], l);
                }
                assert!(t
                    .iter()
                    .all(|&s| s == -1 || ids[s as usize] as usize <= t.len()));
            }
        }
    }
}
