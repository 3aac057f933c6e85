//! The Python exception hierarchy and the single helper that runs core code without the GIL.

use std::panic::{catch_unwind, AssertUnwindSafe};

use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use rgbd_geom::GeomError;
use rgbd_spline::SplineError;

create_exception!(
    _rgbd_rs,
    RgbdError,
    PyValueError,
    "Base class of every rgbd_rs error (a ValueError)."
);
create_exception!(
    _rgbd_rs,
    InvalidArgumentError,
    RgbdError,
    "An argument is out of range or of the wrong kind."
);
create_exception!(
    _rgbd_rs,
    ShapeMismatchError,
    RgbdError,
    "An array does not have the shape its companions or the camera imply."
);

/// A core crate's error enum, mapped variant by variant to the Python hierarchy.
pub trait CoreError {
    fn into_py(self) -> PyErr;
}

impl CoreError for GeomError {
    fn into_py(self) -> PyErr {
        let msg = self.to_string();
        match self {
            GeomError::InvalidArgument { .. } => InvalidArgumentError::new_err(msg),
            GeomError::ShapeMismatch { .. } => ShapeMismatchError::new_err(msg),
        }
    }
}

impl CoreError for SplineError {
    fn into_py(self) -> PyErr {
        let msg = self.to_string();
        match self {
            SplineError::InvalidArgument { .. } => InvalidArgumentError::new_err(msg),
        }
    }
}

/// Maps a core error to its Python exception, message unchanged.
pub fn to_py(err: impl CoreError) -> PyErr {
    err.into_py()
}

/// Runs `f` with the GIL released; a panic becomes `RgbdError` instead of crossing into Python.
pub fn run<T, E, F>(py: Python<'_>, f: F) -> PyResult<T>
where
    T: Send,
    E: CoreError + Send,
    F: FnOnce() -> Result<T, E> + Send,
{
    match py.detach(|| catch_unwind(AssertUnwindSafe(f))) {
        Ok(res) => res.map_err(to_py),
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown panic".into());
            Err(RgbdError::new_err(format!(
                "internal error in the native core (please report): {what}"
            )))
        }
    }
}

/// Borrows a contiguous numpy buffer, or says which argument was not contiguous.
pub fn contiguous<'a, T>(
    arg: &str,
    slice: Result<&'a [T], numpy::AsSliceError>,
) -> PyResult<&'a [T]> {
    slice.map_err(|_| {
        InvalidArgumentError::new_err(format!(
            "{arg}: got a non-contiguous array, expected a C-contiguous array (use np.ascontiguousarray)"
        ))
    })
}
