//! Gravity estimation from the normals (the reference's iterative refinement) and the rotation
//! that takes the camera's y axis to it.

use super::*;

/// Eigenvalues and eigenvectors (columns of the second matrix) of a symmetric 3x3 matrix, by
/// cyclic Jacobi rotations.
pub(super) fn eigen_symmetric(mut a: [[f64; 3]; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for _ in 0..64 {
        let off = a[0][1].abs() + a[0][2].abs() + a[1][2].abs();
        let diag = a[0][0].abs() + a[1][1].abs() + a[2][2].abs();
        if off <= 1e-15 * diag || off == 0.0 {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = if theta == 0.0 {
                1.0
            } else {
                theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt())
            };
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            // A <- J^T A J with the rotation J in the (p, q) plane; V <- V J.
            for row in a.iter_mut() {
                let (akp, akq) = (row[p], row[q]);
                row[p] = c * akp - s * akq;
                row[q] = s * akp + c * akq;
            }
            let (rp, rq) = (a[p], a[q]);
            for k in 0..3 {
                a[p][k] = c * rp[k] - s * rq[k];
                a[q][k] = s * rp[k] + c * rq[k];
            }
            for row in v.iter_mut() {
                let (vkp, vkq) = (row[p], row[q]);
                row[p] = c * vkp - s * vkq;
                row[q] = s * vkp + c * vkq;
            }
        }
    }
    ([a[0][0], a[1][1], a[2][2]], v)
}

/// Eigenvalues within this fraction of the spectrum's size of the smallest count as tied.
pub(super) const EIGEN_TIE: f64 = 1e-3;

/// The reference's "eigenvector of the smallest eigenvalue" of `a`, signed toward `prev`. When
/// the smallest eigenvalue is (nearly) repeated, e.g. a single wall and no floor, the reference's
/// pick is arbitrary; this takes the direction of that eigenspace closest to `prev` instead.
pub(super) fn smallest_direction(a: [[f64; 3]; 3], prev: [f64; 3]) -> [f64; 3] {
    let (vals, vecs) = eigen_symmetric(a);
    let col = |k: usize| [vecs[0][k], vecs[1][k], vecs[2][k]];
    let dot = |u: [f64; 3], w: [f64; 3]| u[0] * w[0] + u[1] * w[1] + u[2] * w[2];
    let kmin = (0..3)
        .min_by(|&i, &j| vals[i].total_cmp(&vals[j]))
        .unwrap_or(0);
    let scale: f64 = vals.iter().map(|v| v.abs()).sum();
    let mut e = col(kmin);
    let tied: Vec<usize> = (0..3)
        .filter(|&k| vals[k] - vals[kmin] <= EIGEN_TIE * scale)
        .collect();
    if tied.len() > 1 {
        let mut p = [0.0f64; 3];
        for &k in &tied {
            let c = col(k);
            let d = dot(c, prev);
            for i in 0..3 {
                p[i] += d * c[i];
            }
        }
        let n = dot(p, p).sqrt();
        if n > 1e-6 {
            e = [p[0] / n, p[1] / n, p[2] / n];
        }
    }
    let sign = if dot(e, prev) < 0.0 { -1.0 } else { 1.0 };
    [sign * e[0], sign * e[1], sign * e[2]]
}

/// Normals summed side by side in f32 lanes before each f64 accumulation of the gravity sums.
pub(super) const LANES: usize = 8;
/// Normals per f32 partial sum (then added to the f64 totals).
pub(super) const BLOCK: usize = 64 * LANES;

simd_dispatch! {
    /// `Σ w n nᵀ` (upper triangle: xx, xy, xz, yy, yz, zz) over the normals `(xs, ys, zs)` (a
    /// multiple of [`LANES`] long), with `w = +1` for wall-like (`|n.y| < sin θ`), `-1` for
    /// floor-like (`|n.y| > cos θ`) normals and 0 otherwise. Partial sums of [`BLOCK`] normals
    /// are f32, [`LANES`] wide; their totals f64.
    pub(super) fn gravity_sums(
        xs: &[f32],
        ys: &[f32],
        zs: &[f32],
        y: [f32; 3],
        cos_t: f32,
        sin_t: f32,
    ) -> [f64; 6] {
        let mut total = [0.0f64; 6];
        for ((bx, by), bz) in xs.chunks(BLOCK).zip(ys.chunks(BLOCK)).zip(zs.chunks(BLOCK)) {
            let mut acc = [[0.0f32; LANES]; 6];
            let lanes = bx
                .chunks_exact(LANES)
                .zip(by.chunks_exact(LANES))
                .zip(bz.chunks_exact(LANES));
            for ((lx, ly), lz) in lanes {
                for l in 0..LANES {
                    let (x, yy, z) = (lx[l], ly[l], lz[l]);
                    let c = (x * y[0] + yy * y[1] + z * y[2]).abs();
                    let w = if c < sin_t { 1.0 } else { 0.0 } - if c > cos_t { 1.0 } else { 0.0 };
                    let (wx, wy, wz) = (w * x, w * yy, w * z);
                    acc[0][l] += wx * x;
                    acc[1][l] += wx * yy;
                    acc[2][l] += wx * z;
                    acc[3][l] += wy * yy;
                    acc[4][l] += wy * z;
                    acc[5][l] += wz * z;
                }
            }
            for (t, a) in total.iter_mut().zip(acc) {
                *t += a.iter().map(|&v| f64::from(v)).sum::<f64>();
            }
        }
        total
    }
}

/// Gravity from normal fields (the reference's `getYDir`): starting from `(0, 1, 0)`, for each
/// (threshold, iterations) of [`GRAVITY_SCHEDULE`] take the smallest eigenvector of
/// `Σ_wall n nᵀ − Σ_floor n nᵀ`, where floor normals have `|n.y| > cos θ` and wall normals
/// `|n.y| < sin θ`. `parts` are the normals of each band as structure of arrays, a multiple of
/// [`LANES`] long, zero where undefined (a zero normal adds nothing); their sums are added in
/// band order, so the estimate does not depend on the thread count.
pub(super) fn gravity(parts: &[[Vec<f32>; 3]]) -> Result<[f64; 3]> {
    let mut y = [0.0, 1.0, 0.0];
    for (deg, iters) in GRAVITY_SCHEDULE {
        let (cos_t, sin_t) = (deg.to_radians().cos() as f32, deg.to_radians().sin() as f32);
        for _ in 0..iters {
            check_interrupt()?;
            let yf = y.map(|v| v as f32);
            let sums: Vec<[f64; 6]> = parts
                .par_iter()
                .map(|[xs, ys, zs]| gravity_sums(xs, ys, zs, yf, cos_t, sin_t))
                .collect();
            let mut s = [0.0f64; 6];
            for part in &sums {
                for k in 0..6 {
                    s[k] += part[k];
                }
            }
            if s.iter().all(|&v| v == 0.0) {
                continue; // nothing selected: keep the current estimate
            }
            let a = [[s[0], s[1], s[2]], [s[1], s[3], s[4]], [s[2], s[4], s[5]]];
            y = smallest_direction(a, y);
        }
    }
    let n = (y[0] * y[0] + y[1] * y[1] + y[2] * y[2]).sqrt();
    Ok([y[0] / n, y[1] / n, y[2] / n])
}

/// The rotation taking `(0, 1, 0)` onto `yf` (the reference's `getRMatrix`: Rodrigues about
/// `y0 x yf`, identity below [`MIN_ROTATION_DEG`]).
pub(super) fn rotation_to(yf: [f64; 3]) -> [[f64; 3]; 3] {
    let id = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let phi = yf[1].clamp(-1.0, 1.0).acos();
    if phi.to_degrees().abs() <= MIN_ROTATION_DEG {
        return id;
    }
    // y0 x yf = (yf_z, 0, -yf_x).
    let (ax, az) = (yf[2], -yf[0]);
    let len = (ax * ax + az * az).sqrt();
    let (ax, az) = if len > 1e-12 {
        (ax / len, az / len)
    } else {
        (1.0, 0.0) // yf = -y0: any axis perpendicular to y0
    };
    let axis = [ax, 0.0, az];
    let k = [
        [0.0, -axis[2], axis[1]],
        [axis[2], 0.0, -axis[0]],
        [-axis[1], axis[0], 0.0],
    ];
    let (s, c) = phi.sin_cos();
    let mut r = id;
    for i in 0..3 {
        for j in 0..3 {
            let kk: f64 = (0..3).map(|m| k[i][m] * k[m][j]).sum();
            r[i][j] += s * k[i][j] + (1.0 - c) * kk;
        }
    }
    r
}
