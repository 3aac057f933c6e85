//! Rendering for rgbd_rs: a BVH ray caster over triangle meshes with perspective and
//! orthographic cameras (first-hit depth, normals, ids, barycentrics), point-cloud splatting,
//! Lambertian colour rendering with textures and shadows, and a continuous-wave ToF simulator
//! with mixed pixels, multipath, shot/read noise and low-amplitude dropout (thesis ch. 3 data,
//! ch. 5 depth views).
//!
//! Conventions follow rgbd-geom: x right, y down, z forward; pixel centres at integer
//! coordinates; depth is z in metres; misses are NaN. Results are deterministic: all randomness
//! is a hash of `(seed, pixel, purpose)`.

pub mod bvh;
pub mod gbuffer;
pub mod material;
pub mod math;
#[cfg(target_arch = "x86_64")]
mod packet;
pub mod rng;
pub mod scene;
pub mod shade;
mod simd4;
pub mod splat;
pub mod tof;
pub mod view;
pub mod views;
mod wide;

pub use bvh::{Bvh, Hit};
pub use gbuffer::{render_depth, render_gbuffer, GBuffer};
pub use material::{Material, Pattern};
pub use scene::{PointLight, Scene};
pub use shade::render_color;
pub use splat::render_points;
pub use tof::{simulate_tof, TofFrame, TofOptions, SPEED_OF_LIGHT};
pub use view::{Projection, View};
pub use views::{mesh_views, point_views, point_views_batch, Cube};
