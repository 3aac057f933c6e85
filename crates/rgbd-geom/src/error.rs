//! Errors of `rgbd-geom`: the workspace's one error enum (`rgbd-error`), re-exported so the
//! kernels here and the crates built on this one say `rgbd_geom::error::invalid`.

pub use rgbd_error::{check_len, invalid, mismatch, Result, RgbdError};
