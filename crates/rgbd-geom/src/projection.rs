//! A calibrated camera (intrinsics + distortion): projection of 3-D points (eq. 2.7 with the
//! distortion of eq. 2.8), undistortion of pixels, and back-projection of depth maps.

use rayon::prelude::*;

use crate::camera::{Intrinsics, Pose};
use crate::distortion::Distortion;
use crate::error::{check_len, invalid, Result};

/// Points per rayon task: large enough to amortise scheduling, small enough to balance 2+ cores.
const POINT_CHUNK: usize = 8192;

/// Intrinsics plus lens distortion.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub intrinsics: Intrinsics,
    pub distortion: Distortion,
}

impl Camera {
    /// A camera from its parts.
    pub fn new(intrinsics: Intrinsics, distortion: Distortion) -> Self {
        Self {
            intrinsics,
            distortion,
        }
    }

    /// Projects a point given in this camera's frame to (distorted) pixels; NaN if `z <= 0`.
    #[inline]
    pub fn project(&self, p: [f64; 3]) -> [f64; 2] {
        if !(p[2] > 0.0) {
            return [f64::NAN; 2];
        }
        let (x, y) = (p[0] / p[2], p[1] / p[2]);
        let [xd, yd] = self.distortion.distort(x, y);
        self.intrinsics.to_pixel(xd, yd)
    }

    /// Projects `n` points (`pts` row-major `n x 3`, source frame) through `pose`, returning
    /// `n x 2` pixels. Points behind the camera give NaN. Parallel over chunks of points.
    pub fn project_points(&self, pts: &[f64], pose: &Pose) -> Result<Vec<f64>> {
        if !pts.len().is_multiple_of(3) {
            return Err(invalid(
                "points",
                format!("{} values", pts.len()),
                "a multiple of 3 (N x 3)",
            ));
        }
        let mut out = vec![0.0; pts.len() / 3 * 2];
        let identity = pose.is_identity();
        out.par_chunks_mut(2 * POINT_CHUNK)
            .zip(pts.par_chunks(3 * POINT_CHUNK))
            .for_each(|(o, p)| {
                for (o, p) in o.chunks_exact_mut(2).zip(p.chunks_exact(3)) {
                    let q = [p[0], p[1], p[2]];
                    let q = if identity { q } else { pose.apply(q) };
                    o.copy_from_slice(&self.project(q));
                }
            });
        Ok(out)
    }

    /// Maps distorted pixels to the ideal (undistorted) pixels of the same intrinsics, or to
    /// normalised coordinates when `normalized`. Non-convergent points give NaN.
    pub fn undistort_pixels(
        &self,
        px: &[f64],
        normalized: bool,
        max_iter: usize,
        tol: f64,
    ) -> Result<Vec<f64>> {
        let k = &self.intrinsics;
        map_pixels(px, |u, v| {
            let [xd, yd] = k.to_normalized(u, v);
            match self.distortion.undistort(xd, yd, max_iter, tol) {
                None => [f64::NAN; 2],
                Some([x, y]) if normalized => [x, y],
                Some([x, y]) => k.to_pixel(x, y),
            }
        })
    }

    /// Maps ideal pixels to the distorted pixels where the lens actually images them.
    pub fn distort_pixels(&self, px: &[f64]) -> Result<Vec<f64>> {
        let k = &self.intrinsics;
        map_pixels(px, |u, v| {
            let [x, y] = k.to_normalized(u, v);
            let [xd, yd] = self.distortion.distort(x, y);
            k.to_pixel(xd, yd)
        })
    }

    /// The normalised, undistorted ray `(x, y)` (with z = 1) of every pixel of the lattice,
    /// row-major. NaN where the distortion cannot be inverted.
    pub fn pixel_rays(&self, max_iter: usize, tol: f64) -> Vec<[f64; 2]> {
        let k = self.intrinsics;
        let mut rays = vec![[0.0; 2]; k.len()];
        rays.par_chunks_mut(k.width)
            .enumerate()
            .for_each(|(v, row)| {
                for (u, r) in row.iter_mut().enumerate() {
                    let [xd, yd] = k.to_normalized(u as f64, v as f64);
                    *r = self
                        .distortion
                        .undistort(xd, yd, max_iter, tol)
                        .unwrap_or([f64::NAN; 2]);
                }
            });
        rays
    }

    /// Back-projects a depth map (z along the optical axis, `H x W`) into an organised point
    /// cloud (`H x W x 3`, camera frame). Invalid depth (NaN, <= 0) gives NaN points.
    pub fn depth_to_points(&self, depth: &[f32], max_iter: usize, tol: f64) -> Result<Vec<f32>> {
        let k = self.intrinsics;
        check_len("depth", depth, k.len(), "height * width of the camera")?;
        let rays = self.pixel_rays(max_iter, tol);
        let mut out = vec![0.0f32; depth.len() * 3];
        out.par_chunks_mut(3 * k.width)
            .zip(depth.par_chunks(k.width).zip(rays.par_chunks(k.width)))
            .for_each(|(o, (d, r))| {
                for ((o, &z), ray) in o.chunks_exact_mut(3).zip(d).zip(r) {
                    if z > 0.0 && z.is_finite() && ray[0].is_finite() {
                        let z64 = f64::from(z);
                        o[0] = (ray[0] * z64) as f32;
                        o[1] = (ray[1] * z64) as f32;
                        o[2] = z;
                    } else {
                        o.fill(f32::NAN);
                    }
                }
            });
        Ok(out)
    }
}

/// Applies `f` to every `(u, v)` pair of an `N x 2` buffer, in parallel chunks.
fn map_pixels(px: &[f64], f: impl Fn(f64, f64) -> [f64; 2] + Sync) -> Result<Vec<f64>> {
    if !px.len().is_multiple_of(2) {
        return Err(invalid(
            "pixels",
            format!("{} values", px.len()),
            "a multiple of 2 (N x 2)",
        ));
    }
    let mut out = vec![0.0; px.len()];
    out.par_chunks_mut(2 * POINT_CHUNK)
        .zip(px.par_chunks(2 * POINT_CHUNK))
        .for_each(|(o, p)| {
            for (o, p) in o.chunks_exact_mut(2).zip(p.chunks_exact(2)) {
                o.copy_from_slice(&f(p[0], p[1]));
            }
        });
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distortion::{UNDISTORT_MAX_ITER, UNDISTORT_TOL};

    fn cam() -> Camera {
        Camera::new(
            Intrinsics::new(500.0, 510.0, 320.0, 240.0, 640, 480).unwrap(),
            Distortion::from_opencv(&[0.1, -0.05, 0.001, -0.002, 0.01]).unwrap(),
        )
    }

    #[test]
    fn pinhole_projection_is_eq_2_3() {
        let c = Camera::new(cam().intrinsics, Distortion::NONE);
        let [u, v] = c.project([0.2, -0.1, 2.0]);
        assert!((u - (500.0 * 0.1 + 320.0)).abs() < 1e-12);
        assert!((v - (510.0 * -0.05 + 240.0)).abs() < 1e-12);
        assert!(c.project([0.0, 0.0, -1.0])[0].is_nan());
    }

    #[test]
    fn depth_to_points_projects_back_to_its_pixel() {
        let c = cam();
        let depth: Vec<f32> = (0..c.intrinsics.len())
            .map(|i| 1.0 + (i % 7) as f32 * 0.1)
            .collect();
        let pts = c
            .depth_to_points(&depth, UNDISTORT_MAX_ITER, UNDISTORT_TOL)
            .unwrap();
        for &(u, v) in &[(0usize, 0usize), (639, 479), (100, 400), (320, 240)] {
            let i = v * 640 + u;
            let p = [
                pts[3 * i] as f64,
                pts[3 * i + 1] as f64,
                pts[3 * i + 2] as f64,
            ];
            let [pu, pv] = c.project(p);
            assert!(
                (pu - u as f64).abs() < 1e-3 && (pv - v as f64).abs() < 1e-3,
                "{pu} {pv}"
            );
        }
    }

    #[test]
    fn undistort_pixels_inverts_distort_pixels() {
        let c = cam();
        let px = vec![10.0, 20.0, 600.0, 470.0, 320.0, 240.0];
        let d = c.distort_pixels(&px).unwrap();
        let u = c
            .undistort_pixels(&d, false, UNDISTORT_MAX_ITER, UNDISTORT_TOL)
            .unwrap();
        for (a, b) in px.iter().zip(&u) {
            assert!((a - b).abs() < 1e-8);
        }
        assert!(c.undistort_pixels(&[1.0], false, 5, 1e-9).is_err());
    }
}
