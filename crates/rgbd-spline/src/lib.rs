//! B-spline (NURBS with unit weights) surfaces on a knot grid anchored to the image lattice
//! (thesis §4.5, §5.3.3): regularised least-squares fits of whole views and of arbitrary pixel
//! sets, principal curvatures, and per-segment normal equations whose unions are sums, so region
//! merging (eq. 4.8) asks "does the union fit better?" with one band solve; the default test
//! ([`seam`]) asks it in sensor-noise units along the seam of the two segments.

pub mod band;
pub mod basis;
pub mod curvature;
pub mod fit;
pub mod grid;
pub mod height;
pub mod local;
pub mod maps;
pub mod normal;
pub mod seam;
pub mod segments;
pub mod surface;
pub mod union;

pub use basis::{uniform_basis, Basis, BasisError, MAX_DEGREE};
pub use curvature::{curvature, Curvature};
pub use fit::{Fit, FitKind};
pub use grid::{fit_grid, fit_mask, KnotGrid, DEFAULT_LAMBDA};
pub use height::{depth_curvatures, fit_height, view_curvatures, HeightGrid, HeightSpline};
pub use maps::{surface_maps, SurfaceMaps};
pub use normal::Region;
pub use seam::{NoiseModel, SeamTest, KINECT_V1_NOISE};
pub use segments::{distinct_labels, label_slots, Criterion, PreparedMerge, SegmentFits};
pub use surface::{GridSurface, Jet, MAX_CHANNELS};

/// Errors of the spline kernels: the workspace's one error enum (`rgbd-error`).
pub use rgbd_error::RgbdError;
