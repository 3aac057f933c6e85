//! ToF–stereo fusion kernels for rgbd_rs (thesis ch. 2.4.2 and ch. 3):
//!
//! - [`upsample_depth`]: sparse reprojected ToF depth → dense depth on the colour lattice with
//!   the extended cross bilateral filter of Dal Mutto et al. (spatial, colour, depth-range and
//!   segmentation terms);
//! - [`label_regions`] (re-exported from rgbd-segment): connected regions of (mean-shift
//!   filtered) colour, the segmentation the filter uses;
//! - [`lc_fuse`]: the locally consistent accumulation of eq. 2.16–2.19, extended to several
//!   confidence-weighted disparity sources (eq. 3.1); with one source it is Mattoccia's LC
//!   refinement.
//!
//! Images are `H x W x 3` row-major `u8`; maps are `H x W` `f32` with NaN for "no value".
//! Errors are the workspace's one enum, `rgbd_error::RgbdError`.

mod check;
pub mod color;
pub mod lc;
pub mod upsample;

pub use check::MAX_RADIUS;
pub use lc::{lc_fuse, LcOutput, LcParams, Source};
pub use rgbd_segment::label_regions;
pub use upsample::{upsample_depth, UpsampleParams, Upsampled};
