//! Adapters for rgbd-spline: surface fits of organised point clouds and per-segment fits.

use numpy::{PyArray2, PyArray3, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods};
use pyo3::prelude::*;
use rgbd_spline::{fit_mask, Criterion, FitKind, KnotGrid, SegmentFits, SurfaceMaps};

use crate::errors::{contiguous, run, to_py, InvalidArgumentError};
use crate::geom::{shape_err, to_numpy};

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
        InvalidArgumentError::new_err(format!("{arg}: got {i}, expected a segment id >= 0"))
    })
}

/// Fits one surface to the points (where `mask`, if given) and evaluates it at every pixel:
/// `(fitted, error, k1, k2, mean, gaussian, n, sse, dof, linear)`.
#[pyfunction]
#[pyo3(signature = (points, mask, spacing, degree, lam, with_dof))]
#[allow(clippy::type_complexity)]
pub fn fit_surface<'py>(
    py: Python<'py>,
    points: PyReadonlyArray3<'py, f32>,
    mask: Option<PyReadonlyArray2<'py, bool>>,
    spacing: f64,
    degree: usize,
    lam: f64,
    with_dof: bool,
) -> PyResult<(MapsOut<'py>, usize, f64, Option<f64>, bool)> {
    let (h, w) = points_shape(&points)?;
    let p = contiguous("points", points.as_slice())?;
    let m = match &mask {
        Some(m) => {
            same_size("mask", m.shape(), h, w)?;
            Some(contiguous("mask", m.as_slice())?)
        }
        None => None,
    };
    let (fit, maps) = run(py, || {
        let grid = KnotGrid::new(w, h, spacing, degree)?;
        let fit = fit_mask(p, w, h, 3, m, &grid, lam, with_dof)?;
        // Outside the mask every map is NaN: evaluate only the fit's cell box.
        let region = m.map(|_| fit.surface.pixel_region(w, h));
        let maps = rgbd_spline::surface_maps(p, w, h, 3, region, |i| {
            m.is_none_or(|m| m[i]).then_some(&fit)
        });
        Ok::<_, rgbd_spline::SplineError>((fit, maps))
    })?;
    let linear = fit.kind == FitKind::Linear;
    Ok((maps_out(py, h, w, maps)?, fit.n, fit.sse, fit.dof, linear))
}

/// Per-segment spline fits of a labelled point cloud with cheap unions and merges.
#[pyclass(module = "rgbd_rs._rgbd_rs", name = "SegmentFits")]
pub struct PySegmentFits {
    inner: SegmentFits,
}

#[pymethods]
impl PySegmentFits {
    #[new]
    #[pyo3(signature = (points, labels, spacing, degree, lam, criterion))]
    fn new(
        py: Python<'_>,
        points: PyReadonlyArray3<'_, f32>,
        labels: PyReadonlyArray2<'_, i32>,
        spacing: f64,
        degree: usize,
        lam: f64,
        criterion: &str,
    ) -> PyResult<Self> {
        let (h, w) = points_shape(&points)?;
        same_size("labels", labels.shape(), h, w)?;
        let criterion = match criterion {
            "gcv" => Criterion::Gcv,
            "mse" => Criterion::Mse,
            other => {
                return Err(InvalidArgumentError::new_err(format!(
                    "criterion: got {other:?}, expected 'gcv' or 'mse'"
                )))
            }
        };
        let p = contiguous("points", points.as_slice())?;
        let l = contiguous("labels", labels.as_slice())?;
        let inner = run(py, || {
            let grid = KnotGrid::new(w, h, spacing, degree)?;
            SegmentFits::new(p, w, h, 3, l, &grid, lam, criterion)
        })?;
        Ok(Self { inner })
    }

    /// Number of labels (merged ones included).
    #[getter]
    fn n_labels(&self) -> usize {
        self.inner.n_labels()
    }

    /// 'gcv' or 'mse'.
    #[getter]
    fn criterion(&self) -> &'static str {
        match self.inner.criterion {
            Criterion::Gcv => "gcv",
            Criterion::Mse => "mse",
        }
    }

    fn size(&self, i: i64) -> PyResult<usize> {
        self.inner.size(index("i", i)?).map_err(to_py)
    }

    fn fit_error(&self, i: i64) -> PyResult<f64> {
        self.inner.fit_error(index("i", i)?).map_err(to_py)
    }

    fn mse(&self, i: i64) -> PyResult<f64> {
        Ok(self.inner.fit(index("i", i)?).map_err(to_py)?.mse())
    }

    fn union_error(&self, py: Python<'_>, i: i64, j: i64) -> PyResult<f64> {
        let (i, j) = (index("i", i)?, index("j", j)?);
        run(py, || self.inner.union_error(i, j))
    }

    fn should_merge(&self, py: Python<'_>, i: i64, j: i64) -> PyResult<bool> {
        let (i, j) = (index("i", i)?, index("j", j)?);
        run(py, || self.inner.should_merge(i, j))
    }

    fn merge(&mut self, py: Python<'_>, i: i64, j: i64) -> PyResult<f64> {
        let (i, j) = (index("i", i)?, index("j", j)?);
        let inner = &mut self.inner;
        run(py, move || inner.merge(i, j))
    }

    fn find(&self, label: i64) -> PyResult<usize> {
        let l = index("label", label)?;
        if l >= self.inner.n_labels() {
            return Err(InvalidArgumentError::new_err(format!(
                "label: got {l}, expected < {}",
                self.inner.n_labels()
            )));
        }
        Ok(self.inner.find(l))
    }

    fn labels<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<i32>>> {
        to_numpy(
            py,
            (self.inner.height, self.inner.width),
            self.inner.current_labels(),
        )
    }

    fn maps<'py>(
        &self,
        py: Python<'py>,
        points: PyReadonlyArray3<'py, f32>,
    ) -> PyResult<MapsOut<'py>> {
        let (h, w) = points_shape(&points)?;
        same_size("points", &[h, w], self.inner.height, self.inner.width)?;
        let p = contiguous("points", points.as_slice())?;
        let m = run(py, || self.inner.maps(p))?;
        maps_out(py, h, w, m)
    }
}
