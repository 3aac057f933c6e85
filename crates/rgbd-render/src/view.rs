//! Ray-generating cameras: pinhole perspective and orthographic, each with a pose.
//!
//! Rays are generated in the camera frame (x right, y down, z forward; pixel centres at integer
//! coordinates) with direction `((u - cx)/fx, (v - cy)/fy, 1)`, i.e. *not* normalised: the
//! hit parameter `t` of a ray is then directly the depth z of the hit in the camera frame, for
//! both projections. Lens distortion is not modelled (rendered images are ideal pinhole images;
//! distort them afterwards with rgbd-geom's remap if a lens is wanted).

use rgbd_geom::error::invalid;
use rgbd_geom::{Pose, Result};

use crate::math::{add, V3};

/// The projection of a [`View`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Projection {
    /// Pinhole: focal lengths and principal point in pixels.
    Perspective { fx: f64, fy: f64, cx: f64, cy: f64 },
    /// Orthographic: `sx`, `sy` pixels per metre; the principal point is the pixel the camera's
    /// optical axis passes through. Rays start on the camera's z = 0 plane.
    Orthographic { sx: f64, sy: f64, cx: f64, cy: f64 },
}

/// A camera that renders: projection, image size and pose.
#[derive(Debug, Clone, Copy)]
pub struct View {
    pub projection: Projection,
    pub width: usize,
    pub height: usize,
    /// Camera-to-world rotation (row-major, f32) and camera centre in the world.
    rot: [f32; 9],
    centre: V3,
}

/// A ray: origin and (unnormalised) direction in the world frame.
#[derive(Debug, Clone, Copy)]
pub struct Ray {
    pub o: V3,
    pub d: V3,
}

impl View {
    /// A view from its projection, size and world-to-camera pose (`X_c = R X_w + t`, the
    /// extrinsics convention of rgbd-geom).
    pub fn new(
        projection: Projection,
        width: usize,
        height: usize,
        world_to_camera: &Pose,
    ) -> Result<Self> {
        // Bounded before anything of this size is allocated (rgbd-error's limits).
        rgbd_error::image_len("view", width, height)?;
        let (a, b, c, d) = match projection {
            Projection::Perspective { fx, fy, cx, cy } => (fx, fy, cx, cy),
            Projection::Orthographic { sx, sy, cx, cy } => (sx, sy, cx, cy),
        };
        if !(a > 0.0 && b > 0.0 && a.is_finite() && b.is_finite()) {
            return Err(invalid(
                "focal",
                format!("({a}, {b})"),
                "finite positive focal lengths / scales",
            ));
        }
        if !(c.is_finite() && d.is_finite()) {
            return Err(invalid(
                "principal point",
                format!("({c}, {d})"),
                "finite values",
            ));
        }
        let inv = world_to_camera.inverse();
        let r = inv.rotation;
        let mut rot = [0.0f32; 9];
        for i in 0..3 {
            for j in 0..3 {
                rot[3 * i + j] = r[(i, j)] as f32;
            }
        }
        let t = inv.translation;
        Ok(Self {
            projection,
            width,
            height,
            rot,
            centre: [t.x as f32, t.y as f32, t.z as f32],
        })
    }

    /// The camera centre in the world (perspective) or the origin of the camera frame.
    pub fn centre(&self) -> V3 {
        self.centre
    }

    /// Rotates a camera-frame vector into the world frame.
    #[inline]
    pub fn to_world(&self, v: V3) -> V3 {
        let r = &self.rot;
        [
            r[0] * v[0] + r[1] * v[1] + r[2] * v[2],
            r[3] * v[0] + r[4] * v[1] + r[5] * v[2],
            r[6] * v[0] + r[7] * v[1] + r[8] * v[2],
        ]
    }

    /// Rotates a world-frame vector into the camera frame.
    #[inline]
    pub fn to_camera(&self, v: V3) -> V3 {
        let r = &self.rot;
        [
            r[0] * v[0] + r[3] * v[1] + r[6] * v[2],
            r[1] * v[0] + r[4] * v[1] + r[7] * v[2],
            r[2] * v[0] + r[5] * v[1] + r[8] * v[2],
        ]
    }

    /// The ray through the continuous pixel position `(u, v)` (column, row).
    #[inline]
    pub fn ray(&self, u: f64, v: f64) -> Ray {
        self.ray_at(self.plane_x(u), self.plane_y(v))
    }

    /// The camera-frame x of column `u` on the image plane (z = 1) or, orthographic, on the
    /// z = 0 plane: what [`View::ray`] computes per pixel, hoisted out of pixel loops.
    #[inline]
    pub fn plane_x(&self, u: f64) -> f32 {
        match self.projection {
            Projection::Perspective { fx, cx, .. } => ((u - cx) / fx) as f32,
            Projection::Orthographic { sx, cx, .. } => ((u - cx) / sx) as f32,
        }
    }

    /// The camera-frame y of row `v` (see [`View::plane_x`]).
    #[inline]
    pub fn plane_y(&self, v: f64) -> f32 {
        match self.projection {
            Projection::Perspective { fy, cy, .. } => ((v - cy) / fy) as f32,
            Projection::Orthographic { sy, cy, .. } => ((v - cy) / sy) as f32,
        }
    }

    /// The ray through the plane point `(x, y)` of [`View::plane_x`] / [`View::plane_y`].
    #[inline]
    pub fn ray_at(&self, x: f32, y: f32) -> Ray {
        match self.projection {
            Projection::Perspective { .. } => Ray {
                o: self.centre,
                d: self.to_world([x, y, 1.0]),
            },
            Projection::Orthographic { .. } => Ray {
                o: add(self.centre, self.to_world([x, y, 0.0])),
                d: self.to_world([0.0, 0.0, 1.0]),
            },
        }
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// Never true for a constructed view (both sides are >= 1); present for clippy's sake.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rays_have_unit_z_in_camera_frame() {
        let (s, c) = 0.4f64.sin_cos();
        let pose = Pose::new([c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c], [0.1, 0.2, 0.3]).unwrap();
        let v = View::new(
            Projection::Perspective {
                fx: 100.0,
                fy: 90.0,
                cx: 10.0,
                cy: 8.0,
            },
            20,
            16,
            &pose,
        )
        .unwrap();
        let r = v.ray(13.0, 2.0);
        let dc = v.to_camera(r.d);
        assert!((dc[2] - 1.0).abs() < 1e-6);
        assert!((dc[0] - 0.03).abs() < 1e-6 && (dc[1] + 6.0 / 90.0).abs() < 1e-6);
        // The centre maps to the camera origin.
        let back = pose.apply([r.o[0] as f64, r.o[1] as f64, r.o[2] as f64]);
        assert!(back.iter().all(|x| x.abs() < 1e-6));
        assert!(View::new(
            Projection::Perspective {
                fx: 0.0,
                fy: 1.0,
                cx: 0.0,
                cy: 0.0
            },
            1,
            1,
            &pose
        )
        .is_err());
    }
}
