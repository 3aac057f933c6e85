//! Camera geometry for rgbd_rs (thesis chapter 2): pinhole intrinsics and poses, Heikkila /
//! Brown-Conrady (+ rational) distortion, depth <-> disparity, remapping, z-buffered depth
//! reprojection between cameras, and normals of organised point clouds.
//!
//! Conventions: x right, y down, z forward; pixel centres at integer coordinates; depth is z in
//! metres; invalid samples are NaN. Buffers are row-major slices with explicit sizes so the
//! binding crate can pass numpy memory without copies. No function panics on bad input: each
//! returns a [`RgbdError`] naming the argument.

pub mod camera;
pub mod distortion;
pub mod error;
pub mod landing;
pub mod normals;
pub mod projection;
pub mod remap;
pub mod reproject;
pub mod shape;
pub mod stereo;

pub use camera::{Intrinsics, Pose};
pub use distortion::{Distortion, UNDISTORT_MAX_ITER, UNDISTORT_TOL};
pub use error::{Result, RgbdError};
pub use landing::{land_points, Landed};
pub use normals::normals_from_points;
pub use projection::Camera;
pub use remap::{remap, undistort_image, undistort_map, ImageRef, Interpolation};
pub use reproject::{reproject_depth, ReprojectOptions, Reprojected};
pub use stereo::depth_disparity;
