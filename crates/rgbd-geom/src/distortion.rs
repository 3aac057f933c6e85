//! Heikkila / Brown-Conrady lens distortion (thesis eq. 2.8) and its rational extension
//! (k4..k6 in the denominator, OpenCV's `CALIB_RATIONAL_MODEL`, used by the Azure Kinect).
//!
//! Works on normalised image-plane coordinates. The thesis' tangential terms d1, d2 are
//! OpenCV's p1, p2.

use crate::error::{invalid, Result};

/// Distortion coefficients. `k = [k1..k6]` radial (k4..k6 divide), `p = [p1, p2]` tangential.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Distortion {
    pub k: [f64; 6],
    pub p: [f64; 2],
}

/// Default iteration cap of [`Distortion::undistort`].
pub const UNDISTORT_MAX_ITER: usize = 20;
/// Default convergence tolerance of [`Distortion::undistort`] on the residual, in normalised
/// units (1e-12 is about 1e-9 px at f = 1000 px).
pub const UNDISTORT_TOL: f64 = 1e-12;

/// Radial numerator `1 + k1 r² + k2 r⁴ + k3 r⁶`.
#[inline(always)]
fn numerator(k: &[f64; 6], r2: f64) -> f64 {
    1.0 + r2 * (k[0] + r2 * (k[1] + r2 * k[2]))
}

/// Rational denominator `1 + k4 r² + k5 r⁴ + k6 r⁶`.
#[inline(always)]
fn denominator(k: &[f64; 6], r2: f64) -> f64 {
    1.0 + r2 * (k[3] + r2 * (k[4] + r2 * k[5]))
}

/// Radial factor and its derivative with respect to r².
#[inline(always)]
fn radial(k: &[f64; 6], r2: f64) -> (f64, f64) {
    let num = numerator(k, r2);
    let den = denominator(k, r2);
    let dnum = k[0] + r2 * (2.0 * k[1] + 3.0 * r2 * k[2]);
    let dden = k[3] + r2 * (2.0 * k[4] + 3.0 * r2 * k[5]);
    (num / den, (dnum * den - num * dden) / (den * den))
}

impl Distortion {
    /// No distortion.
    pub const NONE: Self = Self {
        k: [0.0; 6],
        p: [0.0; 2],
    };

    /// From OpenCV's coefficient order `(k1, k2, p1, p2[, k3[, k4, k5, k6]])`.
    pub fn from_opencv(c: &[f64]) -> Result<Self> {
        if !matches!(c.len(), 0 | 4 | 5 | 8) {
            return Err(invalid(
                "distortion",
                format!("{} coefficients", c.len()),
                "0, 4, 5 or 8 coefficients (k1, k2, p1, p2[, k3[, k4, k5, k6]])",
            ));
        }
        if let Some(v) = c.iter().find(|v| !v.is_finite()) {
            return Err(invalid("distortion", v, "finite coefficients"));
        }
        let g = |i: usize| c.get(i).copied().unwrap_or(0.0);
        Ok(Self {
            k: [g(0), g(1), g(4), g(5), g(6), g(7)],
            p: [g(2), g(3)],
        })
    }

    /// Coefficients in OpenCV's 8-element order.
    pub fn to_opencv(&self) -> [f64; 8] {
        let (k, p) = (self.k, self.p);
        [k[0], k[1], p[0], p[1], k[2], k[3], k[4], k[5]]
    }

    /// True when every coefficient is zero.
    pub fn is_none(&self) -> bool {
        *self == Self::NONE
    }

    /// True when the rational denominator terms k4..k6 are in use.
    #[inline]
    pub fn is_rational(&self) -> bool {
        self.k[3..] != [0.0; 3]
    }

    /// Distorts an ideal normalised point (eq. 2.8 applied forward, as OpenCV's projectPoints).
    #[inline]
    pub fn distort(&self, x: f64, y: f64) -> [f64; 2] {
        self.distort_with::<true>(x, y)
    }

    /// [`Self::distort`] with the rational denominator compiled in or out (`RATIONAL = false`
    /// is exact only when [`Self::is_rational`] is false); lets pixel loops drop a division.
    #[inline(always)]
    pub fn distort_with<const RATIONAL: bool>(&self, x: f64, y: f64) -> [f64; 2] {
        let k = &self.k;
        let r2 = x * x + y * y;
        let s = if RATIONAL {
            numerator(k, r2) / denominator(k, r2)
        } else {
            numerator(k, r2)
        };
        let [p1, p2] = self.p;
        let xy = x * y;
        [
            x * s + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x),
            y * s + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy,
        ]
    }

    /// Whether the radial mapping r -> r·s(r²) is still increasing at this point. Beyond the
    /// first turning point a polynomial/rational model folds back, so points far outside the
    /// calibrated field of view would land inside the image as ghosts; reprojection drops them.
    #[inline]
    pub fn is_monotonic_at(&self, x: f64, y: f64) -> bool {
        let r2 = x * x + y * y;
        let (s, ds) = radial(&self.k, r2);
        s > 0.0 && s + 2.0 * r2 * ds > 0.0
    }

    /// Jacobian of [`Self::distort`] at (x, y), row-major.
    #[inline]
    fn jacobian(&self, x: f64, y: f64) -> ([f64; 2], [f64; 4]) {
        let r2 = x * x + y * y;
        let (s, ds) = radial(&self.k, r2);
        let [p1, p2] = self.p;
        let xy = x * y;
        let f = [
            x * s + 2.0 * p1 * xy + p2 * (r2 + 2.0 * x * x),
            y * s + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * xy,
        ];
        let cross = 2.0 * xy * ds + 2.0 * p1 * x + 2.0 * p2 * y;
        let j = [
            s + 2.0 * x * x * ds + 2.0 * p1 * y + 6.0 * p2 * x,
            cross,
            cross,
            s + 2.0 * y * y * ds + 6.0 * p1 * y + 2.0 * p2 * x,
        ];
        (f, j)
    }

    /// Inverts [`Self::distort`] by Newton's method started at the distorted point.
    ///
    /// Returns `None` when the residual is still above `tol` after `max_iter` steps (e.g. a point
    /// outside the region where the model is invertible) or the Jacobian is singular.
    pub fn undistort(&self, xd: f64, yd: f64, max_iter: usize, tol: f64) -> Option<[f64; 2]> {
        if !(xd.is_finite() && yd.is_finite()) {
            return None;
        }
        if self.is_none() {
            return Some([xd, yd]);
        }
        let (mut x, mut y) = (xd, yd);
        for _ in 0..=max_iter {
            let (f, j) = self.jacobian(x, y);
            let (ex, ey) = (f[0] - xd, f[1] - yd);
            if ex.abs().max(ey.abs()) <= tol {
                return Some([x, y]);
            }
            let det = j[0] * j[3] - j[1] * j[2];
            if det.abs() < 1e-300 || !det.is_finite() {
                return None;
            }
            x -= (j[3] * ex - j[1] * ey) / det;
            y -= (j[0] * ey - j[2] * ex) / det;
        }
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn kinect_like() -> Distortion {
        // Azure Kinect depth camera factory coefficients (rational model).
        Distortion {
            k: [0.5479, -0.02097, -0.002652, 0.8897, 0.08613, -0.01391],
            p: [2.0557e-5, -7.2104e-5],
        }
    }

    #[test]
    fn opencv_order_round_trip() {
        let c = [0.1, -0.2, 0.001, 0.002, 0.03, 0.4, 0.5, 0.6];
        let d = Distortion::from_opencv(&c).unwrap();
        assert_eq!(d.to_opencv(), c);
        assert!(Distortion::from_opencv(&[0.0; 3]).is_err());
        assert!(Distortion::from_opencv(&[f64::NAN, 0.0, 0.0, 0.0]).is_err());
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let d = kinect_like();
        let (x, y, h) = (0.31, -0.22, 1e-6);
        let (_, j) = d.jacobian(x, y);
        let fx1 = d.distort(x + h, y);
        let fx0 = d.distort(x - h, y);
        let fy1 = d.distort(x, y + h);
        let fy0 = d.distort(x, y - h);
        let num = [
            (fx1[0] - fx0[0]) / (2.0 * h),
            (fy1[0] - fy0[0]) / (2.0 * h),
            (fx1[1] - fx0[1]) / (2.0 * h),
            (fy1[1] - fy0[1]) / (2.0 * h),
        ];
        for i in 0..4 {
            assert!((num[i] - j[i]).abs() < 1e-6, "{i}: {} vs {}", num[i], j[i]);
        }
    }

    proptest! {
        #[test]
        fn undistort_inverts_distort(x in -0.8f64..0.8, y in -0.8f64..0.8) {
            let d = kinect_like();
            let [xd, yd] = d.distort(x, y);
            let [ux, uy] = d.undistort(xd, yd, UNDISTORT_MAX_ITER, UNDISTORT_TOL).unwrap();
            prop_assert!((ux - x).abs() < 1e-9 && (uy - y).abs() < 1e-9);
        }
    }
}
