//! B-spline (NURBS with unit weights) surfaces on a knot grid anchored to the image lattice
//! (thesis §4.5, §5.3.3). Work in progress (issue 5): the uniform basis with derivatives and the
//! regularised least-squares fit of a whole view, principal curvatures; segment fits and the Python
//! API are still to come.

pub mod basis;
pub mod curvature;
pub mod grid;

pub use basis::{uniform_basis, Basis, BasisError, MAX_DEGREE};
pub use curvature::{curvature, Curvature};
pub use grid::{fit_grid, GridSurface, Jet, KnotGrid, DEFAULT_LAMBDA};

use std::fmt::Display;

/// Errors of the spline kernels; each names the argument, what it got and what it expected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SplineError {
    #[error("{arg}: got {got}, expected {expected}")]
    InvalidArgument {
        arg: &'static str,
        got: String,
        expected: String,
    },
}

impl SplineError {
    pub(crate) fn invalid(
        arg: &'static str,
        got: impl Display,
        expected: impl Into<String>,
    ) -> Self {
        Self::InvalidArgument {
            arg,
            got: got.to_string(),
            expected: expected.into(),
        }
    }
}
