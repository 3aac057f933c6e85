//! ToF–stereo fusion kernels for rgbd_rs (thesis ch. 2.4.2 and ch. 3):
//!
//! - [`upsample_depth`]: sparse reprojected ToF depth → dense depth on the colour lattice with
//!   the extended cross bilateral filter of Dal Mutto et al. (spatial, colour, depth-range and
//!   segmentation terms);
//! - [`label_regions`] (re-exported from rgbd-segment): connected regions of (mean-shift
//!   filtered) colour, the segmentation the filter uses;
//! - [`mean_shift_filter`]: OpenCV's `pyrMeanShiftFiltering`, bit-exact, in parallel rows (the
//!   colour smoothing the segmentation is labelled on);
//! - [`cost_curve_stats`]: minimum, second minimum and chosen value of the pointwise stereo
//!   cost curve (the heuristic stereo confidence's input);
//! - [`lc_fuse`]: the locally consistent accumulation of eq. 2.16–2.19, extended to several
//!   confidence-weighted disparity sources (eq. 3.1); with one source it is Mattoccia's LC
//!   refinement.
//!
//! Images are `H x W x 3` row-major `u8`; maps are `H x W` `f32` with NaN for "no value".
//! Errors are the workspace's one enum, `rgbd_error::RgbdError`.

pub mod agree;
mod check;
pub mod clues;
pub mod color;
pub mod costcurve;
pub mod lc;
pub mod meanshift;
pub mod sources;
pub mod upsample;

pub use agree::agreement;
pub use check::MAX_RADIUS;
pub use clues::{clue_maps, normalise_clues, warp_maps, ClueScales};
pub use costcurve::{cost_curve_stats, CostCurveStats};
pub use lc::{lc_fuse, LcOutput, LcParams, Source};
pub use meanshift::{mean_shift_filter, MeanShiftParams};
pub use rgbd_segment::label_regions;
pub use upsample::{upsample_depth, UpsampleParams, Upsampled};
