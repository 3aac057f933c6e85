//! RGB-D segmentation kernels for rgbd_rs (thesis ch. 4):
//!
//! - [`label_regions`]: connected regions of similar colour (also the segmentation the ToF
//!   upsampling filter uses);
//! - [`hha`]: HHA encoding of a depth map (Gupta et al. 2014) and the normals/gravity it needs;
//! - [`nystrom`] and [`kmeans`]: the normalized-cuts over-segmentation of §4.4;
//! - [`adjacency`] and [`merge`]: the region merging of §4.7 (Algorithm 1).
//!
//! Images are `H x W x C` row-major; label images are `H x W` `i32` with negative values for
//! "no segment". Errors are the workspace's one enum, `rgbd_error::RgbdError`.

pub mod adjacency;
pub mod compact;
pub mod hha;
pub mod kmeans;
pub mod labels;
pub mod merge;
pub mod nystrom;
pub mod workspace;

pub use labels::label_regions;
