//! Adapters for rgbd-spline: surface fits of organised point clouds and per-segment fits.

use numpy::{
    PyArray2, PyArray3, PyArray4, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3,
    PyUntypedArrayMethods,
};
use std::sync::{PoisonError, RwLock, RwLockReadGuard};

use pyo3::prelude::*;
use rgbd_spline::{
    Criterion, FitKind, KnotGrid, NoiseModel, Region, SeamTest, SegmentFits, SurfaceMaps,
};

use crate::errors::{borrow, run, shape_err, InvalidArgumentError};
use crate::geom::to_numpy;

type Map2<'py> = Bound<'py, PyArray2<f32>>;
/// fitted, error, k1, k2, mean, gaussian.
type MapsOut<'py> = (
    Bound<'py, PyArray3<f32>>,
    Map2<'py>,
    Map2<'py>,
    Map2<'py>,
    Map2<'py>,
    Map2<'py>,
);

fn maps_out<'py>(py: Python<'py>, h: usize, w: usize, m: SurfaceMaps) -> PyResult<MapsOut<'py>> {
    Ok((
        to_numpy(py, (h, w, 3), m.fitted)?,
        to_numpy(py, (h, w), m.error)?,
        to_numpy(py, (h, w), m.k1)?,
        to_numpy(py, (h, w), m.k2)?,
        to_numpy(py, (h, w), m.mean)?,
        to_numpy(py, (h, w), m.gaussian)?,
    ))
}

/// `(H, W)` of an `H x W x 3` point array.
fn points_shape(points: &PyReadonlyArray3<'_, f32>) -> PyResult<(usize, usize)> {
    let &[h, w, c] = points.shape() else {
        unreachable!("3-D array")
    };
    if c != 3 {
        return Err(shape_err(format!(
            "points: got shape ({h}, {w}, {c}), expected (H, W, 3)"
        )));
    }
    Ok((h, w))
}

fn same_size(arg: &str, got: &[usize], h: usize, w: usize) -> PyResult<()> {
    if got != [h, w] {
        return Err(shape_err(format!(
            "{arg}: got shape {got:?}, expected ({h}, {w}) like points"
        )));
    }
    Ok(())
}

fn index(arg: &str, i: i64) -> PyResult<usize> {
    usize::try_from(i).map_err(|_| {
        InvalidArgumentError::new_err(format!("{arg}: got {i}, expected a segment label >= 0"))
    })
}

/// One fitted surface (rgbd-spline `Fit`) of a `width x height` image, returned by
/// [`fit_surface`]; its maps are evaluated on request, over a pixel box only.
#[pyclass(module = "rgbd_rs._rgbd_rs", name = "_SplineFit", frozen)]
pub struct PySplineFit {
    fit: rgbd_spline::Fit,
    width: usize,
    height: usize,
}

#[pymethods]
impl PySplineFit {
    /// Maps of the fit over the pixel box whose top-left pixel is `(u0, v0)`: `points` are the
    /// box's measured points (`rows x columns x 3`), `mask` (box-sized) the pixels the fit
    /// belongs to (`None`: all). Box-sized `(fitted, error, k1, k2, mean, gaussian)`.
    fn maps<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray3<'py, f32>,
        mask: Option<PyReadonlyArray2<'py, bool>>,
        u0: usize,
        v0: usize,
    ) -> PyResult<MapsOut<'py>> {
        let (bh, bw) = points_shape(&points)?;
        let p = borrow("points", &points)?;
        let m = match &mask {
            Some(m) => {
                same_size("mask", m.shape(), bh, bw)?;
                Some(borrow("mask", m)?)
            }
            None => None,
        };
        let frame = Region {
            u0,
            u1: u0 + bw,
            v0,
            v1: v0 + bh,
        };
        let maps = run(py, || {
            rgbd_spline::maps::surface_maps_box(p, m, frame, self.width, self.height, &self.fit)
        })?;
        maps_out(py, bh, bw, maps)
    }
}

/// Fits one surface to the points (where `mask`, if given): `(fit, n, sse, dof, linear, box)`,
/// `box = (v0, v1, u0, u1)` the pixel box of the fitted pixels (the mask's bounding box; the
/// whole image without a mask). The maps are computed by `fit.maps` on request.
#[pyfunction]
#[pyo3(signature = (points, mask, spacing, degree, lam, with_dof))]
#[allow(clippy::type_complexity)]
pub fn fit_surface(
    py: Python<'_>,
    points: PyReadonlyArray3<'_, f32>,
    mask: Option<PyReadonlyArray2<'_, bool>>,
    spacing: f64,
    degree: usize,
    lam: f64,
    with_dof: bool,
) -> PyResult<(
    PySplineFit,
    usize,
    f64,
    Option<f64>,
    bool,
    (usize, usize, usize, usize),
)> {
    let (h, w) = points_shape(&points)?;
    let p = borrow("points", &points)?;
    let m = match &mask {
        Some(m) => {
            same_size("mask", m.shape(), h, w)?;
            Some(borrow("mask", m)?)
        }
        None => None,
    };
    let (fit, region) = run(py, || {
        let grid = KnotGrid::new(w, h, spacing, degree)?;
        rgbd_spline::grid::fit_mask_box(p, w, h, 3, m, &grid, lam, with_dof)
    })?;
    let (n, sse, dof, linear) = (fit.n, fit.sse, fit.dof, fit.kind == FitKind::Linear);
    let native = PySplineFit {
        fit,
        width: w,
        height: h,
    };
    let bbox = (region.v0, region.v1, region.u0, region.u1);
    Ok((native, n, sse, dof, linear, bbox))
}

fn criterion_name(c: Criterion) -> &'static str {
    match c {
        Criterion::Seam => "seam",
        Criterion::Gcv => "gcv",
        Criterion::Mse => "mse",
    }
}

/// Per-segment spline fits of a labelled point cloud with cheap unions and merges.
///
/// Safe to share between threads: queries take a read lock, `merge` the write lock, each taken
/// with the GIL released (so a waiting thread never blocks the one holding the lock).
#[pyclass(module = "rgbd_rs._rgbd_rs", name = "SegmentFits", frozen)]
pub struct PySegmentFits {
    /// `pub(crate)`: the region merging (segment.rs) merges these fits in place.
    pub(crate) inner: RwLock<SegmentFits>,
    /// Fixed at construction (merges never change them), so reading them takes no lock.
    ids: Vec<i32>,
    criterion: Criterion,
}

impl PySegmentFits {
    fn read(&self) -> RwLockReadGuard<'_, SegmentFits> {
        // A poisoned lock means a panic mid-merge, which `run` already reported; the fits are
        // still the last consistent state (merge writes only after its solve succeeded).
        self.inner.read().unwrap_or_else(PoisonError::into_inner)
    }

    /// Runs a query on the fits with the GIL released.
    fn query<T: Send>(
        &self,
        py: Python<'_>,
        f: impl FnOnce(&SegmentFits) -> Result<T, rgbd_spline::RgbdError> + Send,
    ) -> PyResult<T> {
        run(py, || f(&self.read()))
    }
}

#[pymethods]
impl PySegmentFits {
    #[new]
    #[pyo3(signature = (
        points, labels, spacing, degree, lam, criterion,
        test_spacing, noise_scale, noise_power, tolerance, surfaces,
        test_window = Some(rgbd_spline::seam::DEFAULT_WINDOW),
    ))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        points: PyReadonlyArray3<'_, f32>,
        labels: PyReadonlyArray2<'_, i32>,
        spacing: f64,
        degree: usize,
        lam: f64,
        criterion: &str,
        test_spacing: f64,
        noise_scale: f64,
        noise_power: f64,
        tolerance: f64,
        surfaces: bool,
        test_window: Option<usize>,
    ) -> PyResult<Self> {
        let (h, w) = points_shape(&points)?;
        same_size("labels", labels.shape(), h, w)?;
        let criterion = match criterion {
            "gcv" => Criterion::Gcv,
            "mse" => Criterion::Mse,
            "seam" => Criterion::Seam,
            other => {
                return Err(InvalidArgumentError::new_err(format!(
                    "criterion: got {other:?}, expected 'seam', 'gcv' or 'mse'"
                )))
            }
        };
        let test = SeamTest {
            spacing: test_spacing,
            noise: NoiseModel {
                scale: noise_scale,
                power: noise_power,
            },
            tolerance,
            window: test_window,
        };
        if !surfaces && criterion != Criterion::Seam {
            return Err(InvalidArgumentError::new_err(format!(
                "surfaces: got False with criterion {:?}, expected criterion 'seam'",
                criterion_name(criterion)
            )));
        }
        let p = borrow("points", &points)?;
        let l = borrow("labels", &labels)?;
        let inner = run(py, || {
            let grid = KnotGrid::new(w, h, spacing, degree)?;
            if surfaces {
                SegmentFits::with_test(p, w, h, 3, l, &grid, lam, criterion, &test)
            } else {
                SegmentFits::test_only(p, w, h, 3, l, lam, &test)
            }
        })?;
        Ok(Self {
            ids: inner.label_ids().to_vec(),
            criterion: inner.criterion,
            inner: RwLock::new(inner),
        })
    }

    /// Defaults of the seam test, defined once in rgbd-spline:
    /// `(test_spacing, noise_scale, noise_power, tolerance, test_window)`.
    #[staticmethod]
    fn seam_defaults() -> (f64, f64, f64, f64, Option<usize>) {
        let t = SeamTest::default();
        (
            t.spacing,
            t.noise.scale,
            t.noise.power,
            t.tolerance,
            t.window,
        )
    }

    /// Number of labels (merged ones included).
    #[getter]
    fn n_labels(&self) -> usize {
        self.ids.len()
    }

    /// The distinct labels the fits were built with, sorted.
    #[getter]
    fn label_ids(&self) -> Vec<i32> {
        self.ids.clone()
    }

    /// Merges applied so far (by `merge` and by `merge_regions`).
    #[getter]
    fn merges(&self, py: Python<'_>) -> PyResult<usize> {
        // Without the GIL (as every query): a merge on another thread may hold the write lock.
        self.query(py, |s| Ok(s.merges()))
    }

    /// 'seam', 'gcv' or 'mse'.
    #[getter]
    fn criterion(&self) -> &'static str {
        criterion_name(self.criterion)
    }

    fn size(&self, py: Python<'_>, i: i64) -> PyResult<usize> {
        let i = index("i", i)?;
        self.query(py, |s| s.size(i))
    }

    fn fit_error(&self, py: Python<'_>, i: i64) -> PyResult<f64> {
        let i = index("i", i)?;
        self.query(py, |s| s.fit_error(i))
    }

    fn mse(&self, py: Python<'_>, i: i64) -> PyResult<f64> {
        let i = index("i", i)?;
        self.query(py, |s| Ok(s.fit(i)?.mse()))
    }

    fn union_error(&self, py: Python<'_>, i: i64, j: i64) -> PyResult<f64> {
        let (i, j) = (index("i", i)?, index("j", j)?);
        self.query(py, |s| s.union_error(i, j))
    }

    fn seam(&self, py: Python<'_>, i: i64, j: i64) -> PyResult<usize> {
        let (i, j) = (index("i", i)?, index("j", j)?);
        self.query(py, |s| s.seam(i, j))
    }

    fn should_merge(&self, py: Python<'_>, i: i64, j: i64) -> PyResult<bool> {
        let (i, j) = (index("i", i)?, index("j", j)?);
        self.query(py, |s| s.should_merge(i, j))
    }

    fn merge(&self, py: Python<'_>, i: i64, j: i64) -> PyResult<f64> {
        let (i, j) = (index("i", i)?, index("j", j)?);
        run(py, || {
            let mut fits = self.inner.write().unwrap_or_else(PoisonError::into_inner);
            fits.merge(i, j)
        })
    }

    fn find(&self, py: Python<'_>, label: i64) -> PyResult<usize> {
        let l = index("label", label)?;
        self.query(py, |s| s.find(l))
    }

    fn labels<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i32>>> {
        let (h, w, labels) = self.query(py, |s| Ok((s.height, s.width, s.current_labels())))?;
        to_numpy(py, (h, w), labels)
    }

    fn maps<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray3<'py, f32>,
    ) -> PyResult<MapsOut<'py>> {
        let (h, w) = points_shape(&points)?;
        let (fh, fw) = self.query(py, |s| Ok((s.height, s.width)))?;
        same_size("points", &[h, w], fh, fw)?;
        let p = borrow("points", &points)?;
        let m = self.query(py, |s| s.maps(p))?;
        maps_out(py, h, w, m)
    }
}

/// Curvature maps of orthographic depth views from height samples (rgbd-spline `height`):
/// `samples` `(N, 3)` `[u, v, z]` in pixels, `view_of` `(N,)` the view of each sample, `eval`
/// `(V, H, W)` the pixels to report. Returns `(V, 2, H, W)` float32 k1, k2 in 1 / pixel, NaN
/// where not reported.
#[pyfunction]
#[pyo3(signature = (samples, view_of, eval, spacing, lam, max_slope))]
pub fn view_curvatures<'py>(
    py: Python<'py>,
    samples: PyReadonlyArray2<'py, f64>,
    view_of: PyReadonlyArray1<'py, u32>,
    eval: PyReadonlyArray3<'py, bool>,
    spacing: f64,
    lam: f64,
    max_slope: f64,
) -> PyResult<Bound<'py, PyArray4<f32>>> {
    let n = match samples.shape() {
        &[n, 3] => n,
        s => {
            return Err(shape_err(format!(
                "samples: got shape {s:?}, expected (N, 3)"
            )))
        }
    };
    if view_of.shape() != [n] {
        return Err(shape_err(format!(
            "view_of: got shape {:?}, expected ({n},) like samples",
            view_of.shape()
        )));
    }
    let &[views, h, w] = eval.shape() else {
        unreachable!("3-D array")
    };
    let (s, v, e) = (
        borrow("samples", &samples)?,
        borrow("view_of", &view_of)?,
        borrow("eval", &eval)?,
    );
    let out = run(py, || {
        rgbd_spline::view_curvatures(views, w, h, s, v, e, spacing, lam, max_slope)
    })?;
    to_numpy(py, (views, 2, h, w), out)
}

/// Curvature maps of orthographic depth views (rgbd-spline `height::depth_curvatures`): `depth`
/// `(V, H, W)` (NaN where empty, times `scale` in pixels). Returns `(V, 2, H, W)` float32 k1, k2
/// in 1 / pixel, NaN where not reported (empty, or steeper than `max_slope`).
#[pyfunction]
#[pyo3(signature = (depth, scale, spacing, lam, max_slope))]
pub fn depth_view_curvatures<'py>(
    py: Python<'py>,
    depth: PyReadonlyArray3<'py, f32>,
    scale: f64,
    spacing: f64,
    lam: f64,
    max_slope: f64,
) -> PyResult<Bound<'py, PyArray4<f32>>> {
    let &[views, h, w] = depth.shape() else {
        unreachable!("3-D array")
    };
    let d = borrow("depth", &depth)?;
    let out = run(py, || {
        rgbd_spline::depth_curvatures(d, views, w, h, scale, spacing, lam, max_slope)
    })?;
    to_numpy(py, (views, 2, h, w), out)
}
