//! Voxelization for rgbd_rs (thesis §5.3.2):
//!
//! - [`Grid`]: a cubic voxel grid over a shape's bounding box (largest side spans the grid, the
//!   other axes centred, so shapes keep their proportions);
//! - [`voxelize_points`]: occupancy of a point cloud (optionally dilated);
//! - [`voxelize_mesh`]: the voxels a triangle mesh's surface touches (exact triangle-box overlap)
//!   and, optionally, its interior by a hole-tolerant scanline vote;
//! - [`density_profiles`]: the three maps of filled-voxel counts along X, Y and Z.
//!
//! Coordinates are `f32` `n x 3` rows, z up (ModelNet's convention). Errors are the workspace's
//! one enum, `rgbd_error::RgbdError`.

pub mod grid;
pub mod mesh;
pub mod points;
pub mod profiles;
mod tribox;

pub use grid::{Grid, Voxels, MAX_RESOLUTION};
pub use mesh::{voxelize_mesh, Fill};
pub use points::voxelize_points;
pub use profiles::density_profiles;
