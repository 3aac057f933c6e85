//! The one error enum every rgbd_rs core crate returns (polars-error style), the size limits
//! that are checked before anything is allocated, and cooperative interruption of long kernels.
//!
//! The binding crate maps each variant to one Python exception: `InvalidArgument` to
//! `InvalidArgumentError`, `ShapeMismatch` to `ShapeMismatchError`, `Interrupted` to the
//! `KeyboardInterrupt` that asked for it.

mod interrupt;
mod limits;

use std::fmt::Display;

pub use interrupt::{
    check_interrupt, interrupt_running, request_interrupt, reset_after_fork, running, Running,
};
pub use limits::{checked_len, image_len, MAX_ELEMENTS, MAX_PIXELS, MAX_SIDE};

/// Errors raised by the core kernels. Every argument-related variant names the argument, what
/// was seen and what was expected, so the Python layer can forward it verbatim.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RgbdError {
    /// A scalar or structured argument is out of its valid range.
    #[error("{arg}: got {got}, expected {expected}")]
    InvalidArgument {
        arg: &'static str,
        got: String,
        expected: String,
    },
    /// A buffer does not have the length or shape its companions imply.
    #[error("{arg}: got {got}, expected {expected}")]
    ShapeMismatch {
        arg: &'static str,
        got: String,
        expected: String,
    },
    /// The caller asked the running kernel to stop (Ctrl-C); nothing was returned.
    #[error("interrupted")]
    Interrupted,
    /// Memory a kernel needs could not be reserved (checked fallibly before the work starts,
    /// so the process does not abort); `bytes` is what was asked for in all.
    #[error("{what}: out of memory: could not reserve {} MiB for {detail}", bytes.div_ceil(1 << 20))]
    OutOfMemory {
        what: &'static str,
        bytes: u64,
        detail: String,
    },
}

/// Result alias used throughout the core crates.
pub type Result<T> = std::result::Result<T, RgbdError>;

/// Builds an [`RgbdError::InvalidArgument`].
pub fn invalid(arg: &'static str, got: impl Display, expected: impl Into<String>) -> RgbdError {
    RgbdError::InvalidArgument {
        arg,
        got: got.to_string(),
        expected: expected.into(),
    }
}

/// Builds an [`RgbdError::ShapeMismatch`].
pub fn mismatch(arg: &'static str, got: impl Display, expected: impl Into<String>) -> RgbdError {
    RgbdError::ShapeMismatch {
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
        Err(mismatch(
            arg,
            format!("{} elements", buf.len()),
            format!("{expected} ({what})"),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn messages_name_the_argument() {
        assert_eq!(
            invalid("radius", 0, "1..=64").to_string(),
            "radius: got 0, expected 1..=64"
        );
        let e = check_len("depth", &[0.0f32; 3], 4, "2 x 2").unwrap_err();
        assert_eq!(e.to_string(), "depth: got 3 elements, expected 4 (2 x 2)");
        assert!(matches!(e, RgbdError::ShapeMismatch { arg: "depth", .. }));
        assert!(check_len("depth", &[0u8; 4], 4, "2 x 2").is_ok());
    }
}
