//! Pinhole intrinsics (thesis eq. 2.3-2.6) and rigid poses (eq. 2.7).

use nalgebra::{Matrix3, Vector3};

use crate::error::{invalid, Result};

/// Pinhole intrinsics. Pixel centres sit at integer coordinates (OpenCV convention).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub width: usize,
    pub height: usize,
}

impl Intrinsics {
    /// Validated constructor: focal lengths finite and > 0, principal point finite, size > 0.
    pub fn new(fx: f64, fy: f64, cx: f64, cy: f64, width: usize, height: usize) -> Result<Self> {
        for (arg, v) in [("fx", fx), ("fy", fy)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(invalid(arg, v, "a finite focal length > 0 (pixels)"));
            }
        }
        for (arg, v) in [("cx", cx), ("cy", cy)] {
            if !v.is_finite() {
                return Err(invalid(arg, v, "a finite principal point coordinate"));
            }
        }
        // Bounded here, so every map or image made for this camera has a sane size.
        rgbd_error::image_len("size", width, height)?;
        Ok(Self {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
        })
    }

    /// Normalised image-plane coordinates to pixels (eq. 2.5 without the depth).
    #[inline]
    pub fn to_pixel(&self, x: f64, y: f64) -> [f64; 2] {
        [self.fx * x + self.cx, self.fy * y + self.cy]
    }

    /// Pixels to normalised image-plane coordinates (inverse of [`Self::to_pixel`]).
    #[inline]
    pub fn to_normalized(&self, u: f64, v: f64) -> [f64; 2] {
        [(u - self.cx) / self.fx, (v - self.cy) / self.fy]
    }

    /// Number of pixels of the lattice.
    #[inline]
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// Always false for a validated camera; present for clippy's `len_without_is_empty`.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Rigid transform mapping points of a source frame into this camera's frame: `X_c = R X + t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub rotation: Matrix3<f64>,
    pub translation: Vector3<f64>,
}

/// Tolerance on `|R^T R - I|` (max abs entry). Factory calibrations store rotations in f32
/// (about 1e-7 error), so 1e-5 accepts them and still rejects non-rotations.
pub const ROTATION_TOL: f64 = 1e-5;

impl Pose {
    /// The identity transform.
    pub fn identity() -> Self {
        Self {
            rotation: Matrix3::identity(),
            translation: Vector3::zeros(),
        }
    }

    /// Validated constructor from a row-major 3x3 rotation and a translation.
    pub fn new(rotation_row_major: [f64; 9], translation: [f64; 3]) -> Result<Self> {
        if rotation_row_major
            .iter()
            .chain(&translation)
            .any(|v| !v.is_finite())
        {
            return Err(invalid("pose", "non-finite values", "finite R and t"));
        }
        let r = Matrix3::from_row_slice(&rotation_row_major);
        let err = (r.transpose() * r - Matrix3::identity()).abs().max();
        if err > ROTATION_TOL || r.determinant() <= 0.0 {
            return Err(invalid(
                "rotation",
                format!("|R^T R - I| = {err:.2e}, det = {:.4}", r.determinant()),
                format!("a rotation matrix (orthonormal within {ROTATION_TOL:e}, det = +1)"),
            ));
        }
        Ok(Self {
            rotation: r,
            translation: Vector3::from(translation),
        })
    }

    /// True when this is exactly the identity (lets kernels skip the transform).
    pub fn is_identity(&self) -> bool {
        self.rotation == Matrix3::identity() && self.translation == Vector3::zeros()
    }

    /// Applies the transform to one point.
    #[inline]
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let q = self.rotation * Vector3::from(p) + self.translation;
        [q.x, q.y, q.z]
    }

    /// The inverse transform (`X = R^T (X_c - t)`).
    pub fn inverse(&self) -> Self {
        let rt = self.rotation.transpose();
        Self {
            rotation: rt,
            translation: -(rt * self.translation),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_focal() {
        assert!(Intrinsics::new(0.0, 1.0, 0.0, 0.0, 1, 1).is_err());
        assert!(Intrinsics::new(1.0, f64::NAN, 0.0, 0.0, 1, 1).is_err());
        assert!(Intrinsics::new(1.0, 1.0, 0.0, 0.0, 0, 1).is_err());
        assert!(Intrinsics::new(1.0, 1.0, 0.0, 0.0, 1, 1).is_ok());
    }

    #[test]
    fn pose_inverse_round_trip() {
        let (s, c) = 0.3f64.sin_cos();
        let pose = Pose::new([c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0], [0.1, -0.2, 0.3]).unwrap();
        let p = [1.0, 2.0, 3.0];
        let q = pose.inverse().apply(pose.apply(p));
        for i in 0..3 {
            assert!((p[i] - q[i]).abs() < 1e-12);
        }
    }

    #[test]
    fn rejects_reflection_and_shear() {
        assert!(Pose::new([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0], [0.0; 3]).is_err());
        assert!(Pose::new([1.0, 0.1, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0], [0.0; 3]).is_err());
    }
}
