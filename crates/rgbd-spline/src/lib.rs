//! B-spline (NURBS with unit weights) surfaces on a knot grid anchored to the image lattice
//! (thesis §4.5, §5.3.3): regularised least-squares fits of whole views and of arbitrary pixel
//! sets, principal curvatures, and per-segment normal equations whose unions are sums, so region
//! merging (eq. 4.8) asks "does the union fit better?" with one band solve.

pub mod band;
pub mod basis;
pub mod curvature;
pub mod fit;
pub mod grid;
pub mod maps;
pub mod normal;
pub mod segments;
pub mod surface;

pub use basis::{uniform_basis, Basis, BasisError, MAX_DEGREE};
pub use curvature::{curvature, Curvature};
pub use fit::{Fit, FitKind};
pub use grid::{fit_grid, fit_mask, KnotGrid, DEFAULT_LAMBDA};
pub use maps::{surface_maps, SurfaceMaps};
pub use normal::Region;
pub use segments::{Criterion, SegmentFits};
pub use surface::{GridSurface, Jet, MAX_CHANNELS};

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
