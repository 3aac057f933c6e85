//! Principal curvatures of a fitted 3-D surface `S(u, v) = (X, Y, Z)(u, v)` from its first and
//! second fundamental forms.
//!
//! Sign convention: the normal is oriented towards the camera (`n · S < 0`), and curvature is
//! positive where the surface bulges towards the viewer (a ball seen from outside has
//! `k1 = k2 = +1/r`), negative in a concave corner or bowl.

use crate::surface::Jet;

/// Curvatures at one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Curvature {
    /// Larger principal curvature (1/metre when S is in metres).
    pub k1: f64,
    /// Smaller principal curvature.
    pub k2: f64,
    /// Mean curvature `(k1 + k2) / 2`.
    pub mean: f64,
    /// Gaussian curvature `k1 · k2`.
    pub gaussian: f64,
}

/// Curvature of a 3-channel jet; `None` where the parametrisation is degenerate.
pub fn curvature(jet: &Jet) -> Option<Curvature> {
    if jet.channels != 3 {
        return None;
    }
    let v3 = |a: &[f64]| [a[0], a[1], a[2]];
    let (s, su, sv) = (v3(&jet.value), v3(&jet.du), v3(&jet.dv));
    let (suu, suv, svv) = (v3(&jet.duu), v3(&jet.duv), v3(&jet.dvv));
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut n = [
        su[1] * sv[2] - su[2] * sv[1],
        su[2] * sv[0] - su[0] * sv[2],
        su[0] * sv[1] - su[1] * sv[0],
    ];
    let len = dot(n, n).sqrt();
    if !(len > 0.0) {
        return None;
    }
    let sign = if dot(n, s) > 0.0 { -1.0 } else { 1.0 };
    for x in &mut n {
        *x *= sign / len;
    }
    let (e, f, g) = (dot(su, su), dot(su, sv), dot(sv, sv));
    // With n towards the viewer a bulge has negative L, N: flip so that bulges are positive.
    let (l, m, nn) = (-dot(suu, n), -dot(suv, n), -dot(svv, n));
    let det = e * g - f * f;
    if !(det > 0.0) {
        return None;
    }
    let gaussian = (l * nn - m * m) / det;
    let mean = (e * nn - 2.0 * f * m + g * l) / (2.0 * det);
    let disc = (mean * mean - gaussian).max(0.0).sqrt();
    Some(Curvature {
        k1: mean + disc,
        k2: mean - disc,
        mean,
        gaussian,
    })
}

/// [`curvature`] of `n` 3-channel jets held as columns, written as f32 (NaN where [`curvature`]
/// gives `None`). `jet[d][ch]` is derivative `d` (value, du, dv, duu, duv, dvv) of channel `ch`
/// at each of the `n` points. The same operations in the same order as [`curvature`] (so the
/// same bits), without branches: the loop vectorises over the points.
#[inline(always)]
#[allow(clippy::needless_range_loop)] // one index into 22 columns
pub(crate) fn curvature_columns(jet: [[&[f64]; 3]; 6], out: [&mut [f32]; 4]) {
    let n = out[0].len();
    let col = |d: usize| -> [&[f64]; 3] { [&jet[d][0][..n], &jet[d][1][..n], &jet[d][2][..n]] };
    let (s, su, sv, suu, suv, svv) = (col(0), col(1), col(2), col(3), col(4), col(5));
    let [k1, k2, mean_out, gauss_out] = out;
    let (k2, mean_out, gauss_out) = (&mut k2[..n], &mut mean_out[..n], &mut gauss_out[..n]);
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    for i in 0..n {
        let at = |c: [&[f64]; 3]| [c[0][i], c[1][i], c[2][i]];
        let (p, pu, pv) = (at(s), at(su), at(sv));
        let (puu, puv, pvv) = (at(suu), at(suv), at(svv));
        let nrm = [
            pu[1] * pv[2] - pu[2] * pv[1],
            pu[2] * pv[0] - pu[0] * pv[2],
            pu[0] * pv[1] - pu[1] * pv[0],
        ];
        let len = dot(nrm, nrm).sqrt();
        let sign = if dot(nrm, p) > 0.0 { -1.0 } else { 1.0 };
        let scale = sign / len;
        let nrm = [nrm[0] * scale, nrm[1] * scale, nrm[2] * scale];
        let (e, f, g) = (dot(pu, pu), dot(pu, pv), dot(pv, pv));
        let (l, m, nn) = (-dot(puu, nrm), -dot(puv, nrm), -dot(pvv, nrm));
        let det = e * g - f * f;
        let gaussian = (l * nn - m * m) / det;
        let mean = (e * nn - 2.0 * f * m + g * l) / (2.0 * det);
        let disc = (mean * mean - gaussian).max(0.0).sqrt();
        let ok = len > 0.0 && det > 0.0;
        let pick = |x: f64| if ok { x as f32 } else { f32::NAN };
        k1[i] = pick(mean + disc);
        k2[i] = pick(mean - disc);
        mean_out[i] = pick(mean);
        gauss_out[i] = pick(gaussian);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::{fit_grid, KnotGrid, DEFAULT_LAMBDA};

    /// Organised point cloud of a pinhole camera (f = 200) looking at `hit(ray) -> depth`.
    fn cloud(w: usize, h: usize, hit: impl Fn([f64; 3]) -> Option<f64>) -> Vec<f64> {
        let mut out = Vec::with_capacity(w * h * 3);
        for v in 0..h {
            for u in 0..w {
                let d = [
                    (u as f64 - w as f64 / 2.0) / 200.0,
                    (v as f64 - h as f64 / 2.0) / 200.0,
                    1.0,
                ];
                match hit(d) {
                    Some(s) => out.extend_from_slice(&[d[0] * s, d[1] * s, s]),
                    None => out.extend_from_slice(&[f64::NAN; 3]),
                }
            }
        }
        out
    }

    #[test]
    fn sphere_curvatures_within_one_percent() {
        // Close enough that the ball fills the view: no silhouette, where depth has an infinite
        // slope that no spline follows (its ringing would reach a few knot spans inwards).
        let (w, h, r, cz) = (128, 128, 1.0, 1.8);
        let pts = cloud(w, h, |d| {
            let b = d[2] * cz;
            let a = d[0] * d[0] + d[1] * d[1] + 1.0;
            let disc = b * b - a * (cz * cz - r * r);
            (disc > 0.0).then(|| (b - disc.sqrt()) / a)
        });
        let grid = KnotGrid::new(w, h, 8.0, 3).unwrap();
        let s = fit_grid(&pts, w, h, 3, &grid, DEFAULT_LAMBDA, false).unwrap();
        let mut checked = 0;
        for v in (16..112).step_by(4) {
            for u in (16..112).step_by(4) {
                let c = curvature(&s.surface.jet(u as f64, v as f64).unwrap()).unwrap();
                assert!(
                    (c.k1 - 1.0).abs() < 0.01 && (c.k2 - 1.0).abs() < 0.01,
                    "{u} {v} {c:?}"
                );
                checked += 1;
            }
        }
        assert!(checked > 100);
    }

    #[test]
    fn cylinder_has_one_zero_curvature() {
        // Vertical cylinder of radius 0.5 (axis along y) at z = 1, filling the view.
        let (w, h, r, cz) = (128, 96, 0.5, 1.0);
        let pts = cloud(w, h, |d| {
            let a = d[0] * d[0] + 1.0;
            let b = cz;
            let disc = b * b - a * (cz * cz - r * r);
            (disc > 0.0).then(|| (b - disc.sqrt()) / a)
        });
        let grid = KnotGrid::new(w, h, 8.0, 3).unwrap();
        let s = fit_grid(&pts, w, h, 3, &grid, DEFAULT_LAMBDA, false).unwrap();
        for v in (16..80).step_by(8) {
            for u in (16..112).step_by(8) {
                let c = curvature(&s.surface.jet(u as f64, v as f64).unwrap()).unwrap();
                assert!(
                    (c.k1 - 2.0).abs() < 0.02 && c.k2.abs() < 0.02,
                    "{u} {v} {c:?}"
                );
            }
        }
    }
}
