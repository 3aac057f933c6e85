//! HHA encoding (Gupta et al. 2014) and the per-pixel geometry it needs: normals by least-squares
//! planes in square windows, gravity estimation, height above the floor, angle with gravity.
//!
//! The steps and constants are those of Gupta's MATLAB code (`processDepthImage`, `saveHHA`), as
//! described in METHOD_NOTES §7. Differences, all confined to inputs the reference cannot take:
//!
//! - depth that is NaN, infinite or `<= 0` is missing (the reference assumes a filled map): such
//!   pixels get 0 disparity and 0 height (MATLAB's `uint8(NaN)`), and are left out of the normals
//!   and of the lowest-point search;
//! - a window whose valid points are fewer than 3 or collinear in the image has no normal (the
//!   reference divides rounding noise by rounding noise there);
//! - gravity pointing exactly away from the initial guess rotates about the x axis (the Rodrigues
//!   axis is undefined there).
//!
//! Window sums come from one `f64` summed-area table of the nine per-pixel moments, shared by
//! both window sizes; every pixel's 3x3 system is solved from four table lookups per moment.

use rayon::prelude::*;
use rgbd_error::{check_interrupt, check_len, image_len, invalid, Result};

/// Window half-size of the normals behind the angle channel (7x7 windows).
pub const ANGLE_RADIUS: usize = 3;
/// Window half-size of the normals used to estimate gravity (21x21 windows).
pub const GRAVITY_RADIUS: usize = 10;
/// Gravity estimation schedule: (threshold in degrees, iterations).
pub const GRAVITY_SCHEDULE: [(f64, usize); 2] = [(45.0, 5), (15.0, 5)];
/// Below this rotation angle (degrees) the reference keeps the identity rotation.
pub const MIN_ROTATION_DEG: f64 = 0.1;
/// If the lowest point is higher than this (cm, relative to the camera) the floor is assumed...
pub const FLOOR_TRIGGER_CM: f64 = -90.0;
/// ...this far below the camera (cm).
pub const ASSUMED_FLOOR_CM: f64 = -130.0;
/// Disparity channel: `DISPARITY_SCALE / max(z_cm, MIN_DEPTH_CM)`.
pub const DISPARITY_SCALE: f64 = 31000.0;
/// Depth clamp of the disparity channel (cm).
pub const MIN_DEPTH_CM: f64 = 100.0;
/// Angle channel: `angle_deg + ANGLE_OFFSET` (the reference's `+ 128 - 90`).
pub const ANGLE_OFFSET: f64 = 38.0;
/// Angle given to pixels without a normal (MATLAB's NaN-ignoring `max`/`min` make it 180).
pub const NO_NORMAL_ANGLE: f64 = 180.0;
/// A median valid depth above this many metres means the map is not in metres.
pub const MAX_MEDIAN_DEPTH_M: f32 = 50.0;
/// Smallest determinant of the window's pixel-coordinate covariance (px^4) for a normal: any
/// three non-collinear integer pixels give at least 1/27; collinear ones give rounding noise.
const MIN_SPREAD_PX4: f64 = 1e-3;

/// Ideal pinhole intrinsics in pixels; pixel centres at integer coordinates from 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pinhole {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

impl Pinhole {
    fn validate(&self) -> Result<()> {
        for (name, v) in [("fx", self.fx), ("fy", self.fy)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(invalid(
                    "camera",
                    format!("{name} = {v}"),
                    "a focal length > 0",
                ));
            }
        }
        for (name, v) in [("cx", self.cx), ("cy", self.cy)] {
            if !v.is_finite() {
                return Err(invalid(
                    "camera",
                    format!("{name} = {v}"),
                    "a finite principal point",
                ));
            }
        }
        Ok(())
    }
}

/// The HHA image and what it was built from.
#[derive(Debug, Clone, PartialEq)]
pub struct Hha {
    /// `H x W x 3` u8: [disparity, height, angle].
    pub image: Vec<u8>,
    /// Unit gravity direction in the camera frame (x right, y down, z forward), pointing down.
    pub gravity: [f64; 3],
    /// Height of the floor below the camera used by the height channel (cm, negative = below):
    /// the lowest valid point, or [`ASSUMED_FLOOR_CM`] when that is above [`FLOOR_TRIGGER_CM`].
    pub floor_cm: f64,
    /// The [`ANGLE_RADIUS`] normals behind the angle channel, `H x W x 3`, oriented toward the
    /// camera (as [`normals`] with `toward_camera`), NaN where undefined.
    pub normals: Vec<f32>,
}

#[inline]
fn is_valid(z: f32) -> bool {
    z.is_finite() && z > 0.0
}

/// Largest number of valid depths the units check takes its median from (an even subsample).
const MEDIAN_SAMPLES: usize = 1 << 15;

/// Checks a depth map: its size, at least one valid pixel, and metres (median of the valid
/// depths, over an even subsample of at most [`MEDIAN_SAMPLES`], at most [`MAX_MEDIAN_DEPTH_M`]).
pub fn check_depth(arg: &'static str, depth: &[f32], width: usize, height: usize) -> Result<()> {
    let n = image_len(arg, width, height)?;
    check_len(arg, depth, n, &format!("{height} x {width}"))?;
    let step = n.div_ceil(MEDIAN_SAMPLES).max(1);
    let mut valid: Vec<f32> = depth
        .iter()
        .step_by(step)
        .copied()
        .filter(|&z| is_valid(z))
        .collect();
    if valid.is_empty() {
        // The subsample may have missed the few valid pixels.
        valid = depth.iter().copied().filter(|&z| is_valid(z)).collect();
    }
    if valid.is_empty() {
        return Err(invalid(
            arg,
            "no valid depth (every pixel NaN, infinite or <= 0)",
            "at least one depth > 0 in metres",
        ));
    }
    let mid = valid.len() / 2;
    let (_, median, _) = valid.select_nth_unstable_by(mid, f32::total_cmp);
    if *median > MAX_MEDIAN_DEPTH_M {
        return Err(invalid(
            arg,
            format!(
                "a median valid depth of {median}: depth looks like millimetres; divide by 1000"
            ),
            format!("metres (median valid depth <= {MAX_MEDIAN_DEPTH_M})"),
        ));
    }
    Ok(())
}

/// Number of per-pixel moments: `[a², ab, a, b², b, 1, a/z, b/z, 1/z]` with `a = x/z, b = y/z`.
const M: usize = 9;

/// The normalised image coordinates `a = (x - cx) / fx` of every column and `b` of every row.
struct Rays {
    a: Vec<f64>,
    b: Vec<f64>,
}

impl Rays {
    fn new(width: usize, height: usize, cam: &Pinhole) -> Self {
        Self {
            a: (0..width).map(|x| (x as f64 - cam.cx) / cam.fx).collect(),
            b: (0..height).map(|y| (y as f64 - cam.cy) / cam.fy).collect(),
        }
    }
}

/// `1 / z` of every pixel that takes part in the normals (valid `depth`, and valid `raw` when
/// given), 0 for the others.
fn inverse_depth(depth: &[f32], raw: Option<&[f32]>) -> Vec<f64> {
    let inv = |z: f32| if is_valid(z) { 1.0 / z as f64 } else { 0.0 };
    match raw {
        Some(r) => depth
            .par_iter()
            .zip(r.par_iter())
            .map(|(&z, &q)| if is_valid(q) { inv(z) } else { 0.0 })
            .collect(),
        None => depth.par_iter().map(|&z| inv(z)).collect(),
    }
}

/// Adds the moments of row `enter` and subtracts those of row `leave` (either may be absent)
/// in one pass over `acc` (`W` entries); `iz` is [`inverse_depth`].
#[inline]
fn slide_row_moments(
    acc: &mut [[f64; M]],
    enter: Option<usize>,
    leave: Option<usize>,
    iz: &[f64],
    rays: &Rays,
    zeros: &[f64],
) {
    let width = acc.len();
    let row = |y: Option<usize>| match y {
        Some(y) => (rays.b[y], &iz[y * width..][..width]),
        None => (0.0, zeros),
    };
    let ((b_in, q_in), (b_out, q_out)) = (row(enter), row(leave));
    for (((v, &qi), &qo), &a) in acc.iter_mut().zip(q_in).zip(q_out).zip(&rays.a) {
        // Branch-free: a pixel that does not take part adds zeros.
        let wi = if qi > 0.0 { 1.0 } else { 0.0 };
        let wo = if qo > 0.0 { 1.0 } else { 0.0 };
        let (dw, wb) = (wi - wo, wi * b_in - wo * b_out);
        let (dq, qb) = (qi - qo, qi * b_in - qo * b_out);
        let m = [
            dw * a * a,
            wb * a,
            dw * a,
            wi * b_in * b_in - wo * b_out * b_out,
            wb,
            dw,
            dq * a,
            qb,
            dq,
        ];
        for k in 0..M {
            v[k] += m[k];
        }
    }
}

/// Rows per block of the sliding-window sums (fixed, so results do not depend on threads).
const BAND: usize = 48;

/// The unit normal of the plane `n . (a, b, 1) = 1/z` fitted to window sums `s`, or NaN when the
/// window's points do not define a plane. `min_det` is the determinant of the normal matrix
/// below which the points count as collinear (for `s1` points: `s1³ MIN_SPREAD_PX4 / (fx fy)²`).
#[inline(always)]
fn solve_plane(s: [f64; M], min_det_per_point3: f64) -> [f64; 3] {
    const NAN: [f64; 3] = [f64::NAN; 3];
    let [saa, sab, sa, sbb, sb, s1, ta, tb, t1] = s;
    if s1 < 2.5 {
        return NAN;
    }
    // Adjugate of the symmetric normal matrix, as the reference (`invertIt`, `mutiplyIt`).
    let c0 = sbb * s1 - sb * sb;
    let c1 = -sab * s1 + sa * sb;
    let c2 = sab * sb - sa * sbb;
    let c3 = saa * s1 - sa * sa;
    let c4 = -saa * sb + sab * sa;
    let c5 = saa * sbb - sab * sab;
    // det = s1³ x det(covariance of (a, b)): the spread of the points in the image.
    let det = saa * c0 + sab * c1 + sa * c2;
    if det < min_det_per_point3 * s1 * s1 * s1 {
        return NAN;
    }
    let n = [
        c0 * ta + c1 * tb + c2 * t1,
        c1 * ta + c3 * tb + c4 * t1,
        c2 * ta + c4 * tb + c5 * t1,
    ];
    let norm2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    if !(norm2.is_finite() && norm2 > 0.0) {
        return NAN;
    }
    let inv = 1.0 / norm2.sqrt();
    [n[0] * inv, n[1] * inv, n[2] * inv]
}

/// What the normals are computed from.
struct Support<'a> {
    depth: &'a [f32],
    iz: Vec<f64>,
    rays: Rays,
    width: usize,
    height: usize,
    /// [`MIN_SPREAD_PX4`] in normalised units (see [`solve_plane`]).
    min_det: f64,
}

impl<'a> Support<'a> {
    fn new(
        depth: &'a [f32],
        raw: Option<&[f32]>,
        width: usize,
        height: usize,
        cam: &Pinhole,
    ) -> Self {
        let f2 = cam.fx * cam.fy;
        Self {
            depth,
            iz: inverse_depth(depth, raw),
            rays: Rays::new(width, height, cam),
            width,
            height,
            min_det: MIN_SPREAD_PX4 / (f2 * f2),
        }
    }

    fn bands(&self) -> usize {
        self.height.div_ceil(BAND)
    }

    /// Normals of the rows of band `band` for windows of half-size `r`, passed to
    /// `emit(x, row in band, n)` where defined. Sliding box sums: `col` holds the vertical window
    /// sums of the current row for every column, `s` slides along the row. Oriented as the
    /// reference: first `n_z >= 0`, then `n . p >= 0` where the pixel's depth is valid (`n . p`
    /// has the sign of `n . (a, b, 1)`); `flip = -1` reverses them all.
    fn band(
        &self,
        band: usize,
        r: usize,
        flip: f64,
        mut emit: impl FnMut(usize, usize, [f64; 3]),
    ) -> Result<()> {
        let (width, height, rays) = (self.width, self.height, &self.rays);
        let y_start = band * BAND;
        let mut col = vec![[0.0f64; M]; width];
        let zeros = vec![0.0f64; width];
        for yy in y_start.saturating_sub(r)..(y_start + r).min(height) {
            slide_row_moments(&mut col, Some(yy), None, &self.iz, rays, &zeros);
        }
        for y in y_start..(y_start + BAND).min(height) {
            check_interrupt()?;
            // Enter row y + r, leave row y - r - 1.
            let enter = (y + r < height).then_some(y + r);
            let leave = (y > y_start && y > r).then(|| y - r - 1);
            slide_row_moments(&mut col, enter, leave, &self.iz, rays, &zeros);
            let mut s = [0.0f64; M];
            for c in &col[..r.min(width)] {
                for k in 0..M {
                    s[k] += c[k];
                }
            }
            let b = rays.b[y];
            let d = &self.depth[y * width..][..width];
            for x in 0..width {
                if x + r < width {
                    for k in 0..M {
                        s[k] += col[x + r][k];
                    }
                }
                if x > r {
                    for k in 0..M {
                        s[k] -= col[x - r - 1][k];
                    }
                }
                let n = solve_plane(s, self.min_det);
                if n[0].is_nan() {
                    continue;
                }
                let mut sign = if n[2] < 0.0 { -1.0 } else { 1.0 };
                if is_valid(d[x]) && sign * (n[0] * rays.a[x] + n[1] * b + n[2]) < 0.0 {
                    sign = -sign;
                }
                sign *= flip;
                emit(x, y - y_start, [sign * n[0], sign * n[1], sign * n[2]]);
            }
        }
        Ok(())
    }

    /// The normal field for half-size `r`, `H x W`, `undefined` where there is no normal.
    fn field<T: Copy + Send>(
        &self,
        r: usize,
        flip: f64,
        undefined: T,
        conv: impl Fn([f64; 3]) -> T + Sync,
    ) -> Result<Vec<T>> {
        let width = self.width;
        let mut field = vec![undefined; width * self.height];
        field
            .par_chunks_mut(BAND * width)
            .enumerate()
            .try_for_each(|(band, out)| {
                self.band(band, r, flip, |x, dy, n| out[dy * width + x] = conv(n))
            })?;
        Ok(field)
    }

    /// The defined normals for half-size `r`, in row-major order (orientation as [`band`]).
    fn defined(&self, r: usize) -> Result<Vec<[f32; 3]>> {
        let parts: Vec<Vec<[f32; 3]>> = (0..self.bands())
            .into_par_iter()
            .map(|band| {
                let mut v = Vec::with_capacity(BAND * self.width);
                self.band(band, r, 1.0, |_, _, n| v.push(n.map(|c| c as f32)))?;
                Ok(v)
            })
            .collect::<Result<_>>()?;
        Ok(parts.concat())
    }
}

/// Unit surface normals (`H x W x 3` f32, NaN where undefined) from least-squares planes in
/// `(2 radius + 1)^2` windows of the back-projected `depth` (metres), as the reference's
/// `computeNormalsSquareSupport`. Pixels missing in `depth`, or in `raw` when given, do not take
/// part. Oriented toward the camera (`n . p <= 0`) if `toward_camera`, else as the reference
/// (`n . p >= 0`).
pub fn normals(
    depth: &[f32],
    raw: Option<&[f32]>,
    width: usize,
    height: usize,
    cam: &Pinhole,
    radius: usize,
    toward_camera: bool,
) -> Result<Vec<f32>> {
    cam.validate()?;
    check_depth("depth", depth, width, height)?;
    if let Some(r) = raw {
        check_len(
            "raw_depth",
            r,
            width * height,
            &format!("{height} x {width}"),
        )?;
    }
    if radius == 0 || radius > width.max(height) {
        return Err(invalid(
            "radius",
            radius,
            format!("1..={} (the image's larger side)", width.max(height)),
        ));
    }
    let flip = if toward_camera { -1.0 } else { 1.0 };
    let support = Support::new(depth, raw, width, height, cam);
    let field = support.field(radius, flip, [f32::NAN; 3], |n| n.map(|v| v as f32))?;
    Ok(field.into_iter().flatten().collect())
}

/// Eigenvalues and eigenvectors (columns of the second matrix) of a symmetric 3x3 matrix, by
/// cyclic Jacobi rotations.
fn eigen_symmetric(mut a: [[f64; 3]; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
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
const EIGEN_TIE: f64 = 1e-3;

/// The reference's "eigenvector of the smallest eigenvalue" of `a`, signed toward `prev`. When
/// the smallest eigenvalue is (nearly) repeated, e.g. a single wall and no floor, the reference's
/// pick is arbitrary; this takes the direction of that eigenspace closest to `prev` instead.
fn smallest_direction(a: [[f64; 3]; 3], prev: [f64; 3]) -> [f64; 3] {
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
const LANES: usize = 4;
/// Normals per f32 partial sum (then added to the f64 totals).
const BLOCK: usize = 64 * LANES;

/// `Σ w n nᵀ` (upper triangle: xx, xy, xz, yy, yz, zz) over the normals `(xs, ys, zs)` (a
/// multiple of [`LANES`] long), with `w = +1` for wall-like (`|n.y| < sin θ`), `-1` for
/// floor-like (`|n.y| > cos θ`) normals and 0 otherwise. Partial sums of [`BLOCK`] normals are
/// f32, 4 lanes wide; their totals f64.
#[cfg(target_arch = "x86_64")]
fn gravity_sums(
    xs: &[f32],
    ys: &[f32],
    zs: &[f32],
    y: [f32; 3],
    cos_t: f32,
    sin_t: f32,
) -> [f64; 6] {
    use std::arch::x86_64::*;
    assert!(xs.len() == ys.len() && xs.len() == zs.len() && xs.len().is_multiple_of(LANES));
    let mut total = [0.0f64; 6];
    // SAFETY: SSE2 is part of the x86_64 baseline; every load reads 4 floats at an index
    // `i < len` with `len` a multiple of 4 (asserted above), so it stays in bounds.
    unsafe {
        let (y0, y1, y2) = (_mm_set1_ps(y[0]), _mm_set1_ps(y[1]), _mm_set1_ps(y[2]));
        let (cos_v, sin_v, one) = (_mm_set1_ps(cos_t), _mm_set1_ps(sin_t), _mm_set1_ps(1.0));
        let abs_mask = _mm_castsi128_ps(_mm_set1_epi32(0x7fff_ffff));
        let mut start = 0;
        while start < xs.len() {
            let end = (start + BLOCK).min(xs.len());
            let mut acc = [_mm_setzero_ps(); 6];
            let mut i = start;
            while i < end {
                let x = _mm_loadu_ps(xs.as_ptr().add(i));
                let yy = _mm_loadu_ps(ys.as_ptr().add(i));
                let z = _mm_loadu_ps(zs.as_ptr().add(i));
                let dot = _mm_add_ps(
                    _mm_add_ps(_mm_mul_ps(x, y0), _mm_mul_ps(yy, y1)),
                    _mm_mul_ps(z, y2),
                );
                let c = _mm_and_ps(dot, abs_mask);
                let wall = _mm_and_ps(_mm_cmplt_ps(c, sin_v), one);
                let floor = _mm_and_ps(_mm_cmpgt_ps(c, cos_v), one);
                let w = _mm_sub_ps(wall, floor);
                let (wx, wy, wz) = (_mm_mul_ps(w, x), _mm_mul_ps(w, yy), _mm_mul_ps(w, z));
                acc[0] = _mm_add_ps(acc[0], _mm_mul_ps(wx, x));
                acc[1] = _mm_add_ps(acc[1], _mm_mul_ps(wx, yy));
                acc[2] = _mm_add_ps(acc[2], _mm_mul_ps(wx, z));
                acc[3] = _mm_add_ps(acc[3], _mm_mul_ps(wy, yy));
                acc[4] = _mm_add_ps(acc[4], _mm_mul_ps(wy, z));
                acc[5] = _mm_add_ps(acc[5], _mm_mul_ps(wz, z));
                i += LANES;
            }
            for (t, a) in total.iter_mut().zip(acc) {
                let mut lanes = [0.0f32; LANES];
                _mm_storeu_ps(lanes.as_mut_ptr(), a);
                *t += lanes.iter().map(|&v| f64::from(v)).sum::<f64>();
            }
            start = end;
        }
    }
    total
}

/// Portable version of the x86_64 [`gravity_sums`] (same lanes and blocks, same result).
#[cfg(not(target_arch = "x86_64"))]
fn gravity_sums(
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
        for i in 0..bx.len() {
            let (x, yy, z, l) = (bx[i], by[i], bz[i], i % LANES);
            let c = (x * y[0] + yy * y[1] + z * y[2]).abs();
            let w = f32::from(u8::from(c < sin_t)) - f32::from(u8::from(c > cos_t));
            let (wx, wy, wz) = (w * x, w * yy, w * z);
            acc[0][l] += wx * x;
            acc[1][l] += wx * yy;
            acc[2][l] += wx * z;
            acc[3][l] += wy * yy;
            acc[4][l] += wy * z;
            acc[5][l] += wz * z;
        }
        for (t, a) in total.iter_mut().zip(acc) {
            *t += a.iter().map(|&v| f64::from(v)).sum::<f64>();
        }
    }
    total
}

/// Gravity from a normal field (the reference's `getYDir`): starting from `(0, 1, 0)`, for each
/// (threshold, iterations) of [`GRAVITY_SCHEDULE`] take the smallest eigenvector of
/// `Σ_wall n nᵀ − Σ_floor n nᵀ`, where floor normals have `|n.y| > cos θ` and wall normals
/// `|n.y| < sin θ`.
fn gravity(normals: &[[f32; 3]]) -> Result<[f64; 3]> {
    /// Normals per partial sum (a multiple of [`BLOCK`]); the partial sums are added in order,
    /// so the estimate does not depend on the thread count.
    const CHUNK: usize = 16 * BLOCK;
    // Structure of arrays, padded with zero normals (weight 0, they add nothing).
    let n = normals.len().div_ceil(LANES) * LANES;
    let (mut xs, mut ys, mut zs) = (vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]);
    for (i, v) in normals.iter().enumerate() {
        (xs[i], ys[i], zs[i]) = (v[0], v[1], v[2]);
    }
    let mut y = [0.0, 1.0, 0.0];
    for (deg, iters) in GRAVITY_SCHEDULE {
        let (cos_t, sin_t) = (deg.to_radians().cos() as f32, deg.to_radians().sin() as f32);
        for _ in 0..iters {
            check_interrupt()?;
            let yf = y.map(|v| v as f32);
            let parts: Vec<[f64; 6]> = xs
                .par_chunks(CHUNK)
                .zip(ys.par_chunks(CHUNK))
                .zip(zs.par_chunks(CHUNK))
                .map(|((cx, cy), cz)| gravity_sums(cx, cy, cz, yf, cos_t, sin_t))
                .collect();
            let mut s = [0.0f64; 6];
            for part in &parts {
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
fn rotation_to(yf: [f64; 3]) -> [[f64; 3]; 3] {
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

/// MATLAB's `uint8(v)`: round half away from zero, saturate; NaN gives 0.
#[inline]
fn to_u8(v: f64) -> u8 {
    // `as` saturates and maps NaN to 0; adding 0.5 then truncating rounds half up for v >= 0
    // (below 0.5 everything gives 0).
    if v >= 0.5 {
        (v + 0.5).min(255.0) as u8
    } else {
        0
    }
}

/// HHA of a depth map in metres (NaN or `<= 0` = missing). `raw`, if given, is the unfilled
/// depth whose holes are left out of the normals (the reference's `missingMask = RD == 0`);
/// disparity and height always come from `depth`.
pub fn hha(
    depth: &[f32],
    raw: Option<&[f32]>,
    width: usize,
    height: usize,
    cam: &Pinhole,
) -> Result<Hha> {
    cam.validate()?;
    check_depth("depth", depth, width, height)?;
    if let Some(r) = raw {
        check_len(
            "raw_depth",
            r,
            width * height,
            &format!("{height} x {width}"),
        )?;
    }
    let support = Support::new(depth, raw, width, height, cam);
    let angle_normals = support.field(ANGLE_RADIUS, 1.0, [f64::NAN; 3], |n| n)?;
    let g = gravity(&support.defined(GRAVITY_RADIUS)?)?;
    let r = rotation_to(g);
    // Height is -(Rᵀ p).y = -(column 1 of R) . p, in cm; p = z (a, b, 1).
    let up = [-r[0][1] * 100.0, -r[1][1] * 100.0, -r[2][1] * 100.0];
    let rays = Rays::new(width, height, cam);
    let height_of =
        |x: usize, y: usize, z: f32| z as f64 * (up[0] * rays.a[x] + up[1] * rays.b[y] + up[2]);
    let lowest = depth
        .par_chunks(width)
        .enumerate()
        .map(|(y, row)| {
            let mut m = f64::INFINITY;
            for (x, &z) in row.iter().enumerate() {
                if is_valid(z) {
                    let h = height_of(x, y, z);
                    if h < m {
                        m = h;
                    }
                }
            }
            m
        })
        .reduce(|| f64::INFINITY, f64::min);
    let floor_cm = if lowest > FLOOR_TRIGGER_CM {
        ASSUMED_FLOOR_CM
    } else {
        lowest
    };
    let mut image = vec![0u8; width * height * 3];
    // The normals handed back (toward the camera, f32) are written in the same pass.
    let mut normals = vec![0.0f32; width * height * 3];
    image
        .par_chunks_mut(width * 3)
        .zip(normals.par_chunks_mut(width * 3))
        .enumerate()
        .for_each(|(y, (row, nrow))| {
            for ((x, px), out) in row
                .chunks_exact_mut(3)
                .enumerate()
                .zip(nrow.chunks_exact_mut(3))
            {
                let i = y * width + x;
                let z = depth[i];
                if is_valid(z) {
                    let z_cm = (z as f64 * 100.0).max(MIN_DEPTH_CM);
                    px[0] = to_u8(DISPARITY_SCALE / z_cm);
                    px[1] = to_u8(height_of(x, y, z) - floor_cm);
                }
                let n = angle_normals[i];
                for (o, v) in out.iter_mut().zip(n) {
                    *o = -v as f32;
                }
                let angle = if n[0].is_nan() {
                    NO_NORMAL_ANGLE
                } else {
                    (n[0] * g[0] + n[1] * g[1] + n[2] * g[2])
                        .clamp(-1.0, 1.0)
                        .acos()
                        .to_degrees()
                };
                px[2] = to_u8(angle + ANGLE_OFFSET);
            }
        });
    Ok(Hha {
        image,
        gravity: g,
        floor_cm,
        normals,
    })
}

/// Length of a pixel's feature vector (eq. 4.1): Lab colour, 3-D position, normal.
pub const FEATURE_DIM: usize = 9;

/// The eq. 4.1 vectors of an image (see [`features`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Features {
    /// `H x W x 9`: `[L, a, b] / σc`, `[x, y, z] / σg`, `[nx, ny, nz] / σn`; NaN where invalid.
    pub vectors: Vec<f32>,
    /// `H x W x 3` points (camera frame, the depth's units), NaN where the depth is invalid.
    pub points: Vec<f32>,
    /// `H x W`: depth valid and normal defined.
    pub valid: Vec<bool>,
    /// `(σc, σg, σn)`: each group's mean per-channel population standard deviation over the
    /// valid pixels.
    pub sigmas: [f64; 3],
}

/// Per-pixel 9-D vectors of eq. 4.1 from a Lab image (`H x W x 3`), a depth map and unit
/// normals (`H x W x 3`, NaN = undefined): each group of three divided by its average
/// standard deviation over the valid pixels (a group with none is left unscaled). Statistics
/// are accumulated in f64 per row and added in row order (two passes: means, then centred
/// squares), so the result does not depend on the thread count.
pub fn features(
    lab: &[f32],
    depth: &[f32],
    normals: &[f32],
    width: usize,
    height: usize,
    cam: &Pinhole,
) -> Result<Features> {
    cam.validate()?;
    check_depth("depth", depth, width, height)?;
    let n = width * height;
    let what = format!("{height} x {width} x 3");
    check_len("lab", lab, 3 * n, &what)?;
    check_len("normals", normals, 3 * n, &what)?;
    let rays = Rays::new(width, height, cam);
    const D: usize = FEATURE_DIM;
    // Pass 1: unnormalised vectors [lab, point, normal], points, validity.
    let mut vectors = vec![f32::NAN; D * n];
    let mut points = vec![f32::NAN; 3 * n];
    let mut valid = vec![false; n];
    // Pass 1 also sums each row's valid vectors (for the means).
    let row_totals: Vec<[f64; D]> = vectors
        .par_chunks_mut(D * width)
        .zip(points.par_chunks_mut(3 * width))
        .zip(valid.par_chunks_mut(width))
        .enumerate()
        .map(|(y, ((vrow, prow), ok))| {
            let mut s = [0.0f64; D];
            let b = rays.b[y];
            for x in 0..width {
                let i = y * width + x;
                let z = depth[i];
                if !is_valid(z) {
                    continue;
                }
                let zf = z as f64;
                let p = [(rays.a[x] * zf) as f32, (b * zf) as f32, z];
                prow[3 * x..3 * x + 3].copy_from_slice(&p);
                let nrm = &normals[3 * i..3 * i + 3];
                if nrm.iter().all(|v| v.is_finite()) {
                    ok[x] = true;
                    let v = &mut vrow[D * x..D * x + D];
                    v[0..3].copy_from_slice(&lab[3 * i..3 * i + 3]);
                    v[3..6].copy_from_slice(&p);
                    v[6..9].copy_from_slice(nrm);
                    for k in 0..D {
                        s[k] += f64::from(v[k]);
                    }
                }
            }
            s
        })
        .collect();
    let count = valid.iter().filter(|&&v| v).count();
    if count == 0 {
        return Err(invalid(
            "depth",
            "no pixel with both a valid depth and a surface normal",
            "at least one (a normal needs 3 non-collinear valid pixels in its window)",
        ));
    }
    // Per-row sums of f(v) over the valid pixels, added in row order.
    let row_sums = |f: &(dyn Fn(&[f32], &mut [f64; D]) + Sync)| -> [f64; D] {
        let rows: Vec<[f64; D]> = vectors
            .par_chunks(D * width)
            .zip(valid.par_chunks(width))
            .map(|(vrow, ok)| {
                let mut s = [0.0f64; D];
                for (v, _) in vrow.chunks_exact(D).zip(ok).filter(|(_, &ok)| ok) {
                    f(v, &mut s);
                }
                s
            })
            .collect();
        let mut s = [0.0f64; D];
        for r in &rows {
            for k in 0..D {
                s[k] += r[k];
            }
        }
        s
    };
    // Two passes (means, then centred squares) for the population standard deviations.
    let mut sums = [0.0f64; D];
    for r in &row_totals {
        for k in 0..D {
            sums[k] += r[k];
        }
    }
    let mean = sums.map(|s| s / count as f64);
    let sq = row_sums(&|v, s| {
        for k in 0..D {
            let d = f64::from(v[k]) - mean[k];
            s[k] += d * d;
        }
    });
    let std = sq.map(|s| (s / count as f64).sqrt());
    let sigmas = [0, 1, 2].map(|g| (std[3 * g] + std[3 * g + 1] + std[3 * g + 2]) / 3.0);
    let scale = sigmas.map(|s| if s > 0.0 { (1.0 / s) as f32 } else { 1.0 });
    vectors.par_chunks_mut(D * width).for_each(|row| {
        for v in row.chunks_exact_mut(D) {
            for k in 0..D {
                v[k] *= scale[k / 3];
            }
        }
    });
    Ok(Features {
        vectors,
        points,
        valid,
        sigmas,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A wide camera (~65° across), so a floor and a wall both show in a 64 x 48 image.
    const CAM: Pinhole = Pinhole {
        fx: 50.0,
        fy: 50.0,
        cx: 31.5,
        cy: 23.5,
    };

    /// Depth of the plane `n . p = d` seen through `CAM` (`w x h`).
    fn plane(n: [f64; 3], d: f64, w: usize, h: usize) -> Vec<f32> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                let ray = [(x - CAM.cx) / CAM.fx, (y - CAM.cy) / CAM.fy, 1.0];
                (d / (n[0] * ray[0] + n[1] * ray[1] + n[2] * ray[2])) as f32
            })
            .collect()
    }

    #[test]
    fn plane_normals_are_exact_and_oriented() {
        let len = (0.2f64 * 0.2 + 0.5 * 0.5 + 1.0).sqrt();
        let n = [0.2 / len, -0.5 / len, -1.0 / len]; // faces the camera
        let depth = plane(n, -2.0, 64, 48);
        for toward in [true, false] {
            let out = normals(&depth, None, 64, 48, &CAM, 3, toward).unwrap();
            let s = if toward { 1.0 } else { -1.0 };
            for px in out.chunks(3) {
                for k in 0..3 {
                    assert!((px[k] as f64 - s * n[k]).abs() < 1e-4, "{px:?} vs {n:?}");
                }
            }
        }
    }

    /// Window sums by brute force, for comparison with the sliding sums.
    fn naive_normal(depth: &[f32], w: usize, h: usize, x: usize, y: usize, r: usize) -> [f64; 3] {
        let rays = Rays::new(w, h, &CAM);
        let iz = inverse_depth(depth, None);
        let mut s = [0.0f64; M];
        for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
            let mut row = vec![[0.0f64; M]; w];
            slide_row_moments(&mut row, Some(yy), None, &iz, &rays, &vec![0.0; w]);
            for c in &row[x.saturating_sub(r)..(x + r + 1).min(w)] {
                for k in 0..M {
                    s[k] += c[k];
                }
            }
        }
        let f2 = CAM.fx * CAM.fy;
        solve_plane(s, MIN_SPREAD_PX4 / (f2 * f2))
    }

    #[test]
    fn sliding_sums_match_brute_force_with_holes() {
        let (w, h) = (37, 101); // more than two bands, odd sizes
        let depth: Vec<f32> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let hole = (i * 7919) % 13 < 4 || (y > 60.0 && y < 75.0 && x < 20.0);
                if hole {
                    f32::NAN
                } else {
                    2.0 + 0.3 * (x * 0.2).sin() + 0.01 * y
                }
            })
            .collect();
        for r in [1, 3, 10, 40] {
            let out = normals(&depth, None, w, h, &CAM, r, false).unwrap();
            for y in 0..h {
                for x in 0..w {
                    let n = naive_normal(&depth, w, h, x, y, r);
                    let got = &out[(y * w + x) * 3..][..3];
                    if n[0].is_nan() {
                        assert!(got[0].is_nan(), "({x}, {y}) r {r}");
                        continue;
                    }
                    let dot: f64 = (0..3).map(|k| got[k] as f64 * n[k]).sum();
                    assert!(
                        (dot.abs() - 1.0).abs() < 1e-5,
                        "({x}, {y}) r {r}: {got:?} {n:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn holes_are_skipped_and_isolated_pixels_have_no_normal() {
        let mut depth = vec![f32::NAN; 64 * 48];
        depth[10 * 64 + 10] = 2.0;
        let out = normals(&depth, None, 64, 48, &CAM, 3, true).unwrap();
        assert!(out.iter().all(|v| v.is_nan()));
        // A single row of points is collinear in the image: no plane.
        let mut depth = vec![f32::NAN; 64 * 48];
        depth[640..704].fill(2.0);
        let out = normals(&depth, None, 64, 48, &CAM, 3, true).unwrap();
        assert!(out.iter().all(|v| v.is_nan()));
    }

    #[test]
    fn jacobi_finds_the_smallest_eigenvector() {
        let y = [0.0, 1.0, 0.0];
        let e = smallest_direction([[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 5.0]], y);
        let s = std::f64::consts::FRAC_1_SQRT_2;
        assert!(
            (e[0] + s).abs() < 1e-12 && (e[1] - s).abs() < 1e-12 && e[2] == 0.0,
            "{e:?}"
        );
        // A single wall (normals along z): the tied x-y eigenspace keeps the previous estimate.
        let e = smallest_direction([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 9.0]], y);
        assert_eq!(e, y);
        let prev = [0.6, 0.8, 0.0];
        let e = smallest_direction([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 9.0]], prev);
        assert!((e[0] - 0.6).abs() < 1e-12 && (e[1] - 0.8).abs() < 1e-12);
    }

    #[test]
    fn rotation_takes_y0_to_gravity() {
        for g in [
            [0.0, 1.0, 0.0],
            [0.3, 0.9, -0.1],
            [0.0, -1.0, 0.0],
            [1.0, 0.0, 0.0],
        ] {
            let n: f64 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
            let g = g.map(|v: f64| v / n.sqrt());
            let r = rotation_to(g);
            for i in 0..3 {
                assert!((r[i][1] - g[i]).abs() < 1e-12, "{r:?} {g:?}");
            }
        }
    }

    #[test]
    fn millimetres_and_empty_depth_are_refused() {
        let mm = vec![2500.0f32; 16];
        let e = hha(&mm, None, 4, 4, &CAM).unwrap_err().to_string();
        assert!(e.contains("millimetres"), "{e}");
        let none = vec![f32::NAN; 16];
        let e = hha(&none, None, 4, 4, &CAM).unwrap_err().to_string();
        assert!(e.starts_with("depth: got no valid depth"), "{e}");
    }

    #[test]
    fn floor_and_wall_give_gravity_down() {
        // Floor 1.2 m below the camera (y = 1.2) and a wall at z = 8 in front.
        let (w, h) = (64, 48);
        let floor = plane([0.0, 1.0, 0.0], 1.2, w, h);
        let wall = plane([0.0, 0.0, 1.0], 8.0, w, h);
        let depth: Vec<f32> = floor
            .iter()
            .zip(&wall)
            .map(|(&f, &wl)| if f > 0.0 && f < wl { f } else { wl })
            .collect();
        let out = hha(&depth, None, w, h, &CAM).unwrap();
        // Windows straddling the crease tilt the estimate a little in so small an image.
        let tilt = out.gravity[1].clamp(-1.0, 1.0).acos().to_degrees();
        assert!(tilt < 2.0, "{:?}", out.gravity);
        assert!((out.floor_cm + 120.0).abs() < 20.0, "{}", out.floor_cm);
        // Floor pixels: angle ~0 (+38); wall: angle ~90 (+38); wall disparity 31000/800.
        let last = (h - 1) * w + w / 2;
        assert!(
            out.image[last * 3 + 2].abs_diff(38) <= 2,
            "{}",
            out.image[last * 3 + 2]
        );
        assert!(out.image[(w / 2) * 3 + 2].abs_diff(128) <= 2);
        assert_eq!(out.image[(w / 2) * 3], 39);
    }
}
