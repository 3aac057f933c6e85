//! The one error type of `rgbd-geom`. Every variant names the offending argument, what was seen
//! and what was expected, so the Python layer can forward it verbatim.

use std::fmt::Display;

/// Errors raised by the geometry kernels.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum GeomError {
    /// A scalar or structured argument is out of its valid range.
    #[error("{arg}: got {got}, expected {expected}")]
    InvalidArgument {
        arg: &'static str,
        got: String,
        expected: String,
    },
    /// A buffer does not have the length its declared shape implies.
    #[error("{arg}: got {got} elements, expected {expected}")]
    ShapeMismatch {
        arg: &'static str,
        got: usize,
        expected: String,
    },
}

/// Result alias used throughout the crate.
pub type Result<T> = std::result::Result<T, GeomError>;

/// Builds an [`GeomError::InvalidArgument`] (shared by the crates built on this one).
pub fn invalid(arg: &'static str, got: impl Display, expected: impl Into<String>) -> GeomError {
    GeomError::InvalidArgument {
        arg,
        got: got.to_string(),
        expected: expected.into(),
    }
}

/// Checks that `buf` holds exactly `expected` elements.
pub fn check_len<T>(arg: &'static str, buf: &[T], expected: usize, what: &str) -> Result<()> {
    if buf.len() == expected {
        Ok(())
    } else {
        Err(GeomError::ShapeMismatch {
            arg,
            got: buf.len(),
            expected: format!("{expected} ({what})"),
        })
    }
}
