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
//! Window sums: per column, five f64 sums slide down the rows of a band; along a row, the nine
//! moments of every window are sums of power-of-two runs, in absolute pixel coordinates (the
//! point counts and coordinate moments are integers, exact). Each pixel's 3x3 system is set up
//! about the pixel itself and solved by its adjugate, as the reference. The loops run over
//! whole rows (structure of arrays) and are compiled for AVX2 when the CPU has it.

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
            .with_min_len(4096)
            .map(|(&z, &q)| if is_valid(q) { inv(z) } else { 0.0 })
            .collect(),
        None => depth
            .par_iter()
            .with_min_len(4096)
            .map(|&z| inv(z))
            .collect(),
    }
}

/// Tests cap the SIMD level [`simd_dispatch!`] may pick (2 = AVX-512F, 1 = AVX2, 0 = baseline),
/// to check that every path gives the same bits.
#[cfg(test)]
static SIMD_CAP: std::sync::atomic::AtomicU8 = std::sync::atomic::AtomicU8::new(2);

#[cfg(test)]
#[inline]
fn simd_allowed(level: u8) -> bool {
    SIMD_CAP.load(std::sync::atomic::Ordering::Relaxed) >= level
}

#[cfg(not(test))]
#[inline(always)]
fn simd_allowed(_: u8) -> bool {
    true
}

/// Runs `body` compiled for AVX-512F or AVX2 when the CPU has it (the loops are written to
/// vectorise), else for the baseline. Only elementwise IEEE operations run in these loops (no
/// fused multiply-add, no reassociation), so every version gives the same bits.
macro_rules! simd_dispatch {
    ($(#[$meta:meta])* fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? $body:block) => {
        $(#[$meta])*
        #[allow(clippy::too_many_arguments)]
        fn $name($($arg: $ty),*) $(-> $ret)? {
            #[allow(clippy::too_many_arguments)]
            #[inline(always)]
            fn generic($($arg: $ty),*) $(-> $ret)? $body
            #[cfg(target_arch = "x86_64")]
            {
                #[allow(clippy::too_many_arguments)]
                #[target_feature(enable = "avx2")]
                fn avx2($($arg: $ty),*) $(-> $ret)? {
                    generic($($arg),*)
                }
                #[allow(clippy::too_many_arguments)]
                #[target_feature(enable = "avx512f")]
                fn avx512($($arg: $ty),*) $(-> $ret)? {
                    generic($($arg),*)
                }
                if simd_allowed(2) && std::is_x86_feature_detected!("avx512f") {
                    // SAFETY: the CPU has AVX-512F (checked just above).
                    return unsafe { avx512($($arg),*) };
                }
                if simd_allowed(1) && std::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU has AVX2 (checked just above).
                    return unsafe { avx2($($arg),*) };
                }
            }
            generic($($arg),*)
        }
    };
}

simd_dispatch! {
    fn slide_columns(
        cols: &mut [Vec<f64>; 5],
        r: usize,
        enter: (&[f64], f64),
        leave: (&[f64], f64),
    ) {
        let [cw, cwy, cwyy, cq, cqy] = cols;
        let n = enter.0.len();
        let (cw, cwy, cwyy) = (&mut cw[r..r + n], &mut cwy[r..r + n], &mut cwyy[r..r + n]);
        let (cq, cqy) = (&mut cq[r..r + n], &mut cqy[r..r + n]);
        let ((q_in, y_in), (q_out, y_out)) = (enter, leave);
        let (q_out, yy_in, yy_out) = (&q_out[..n], y_in * y_in, y_out * y_out);
        for i in 0..n {
            let (qi, qo) = (q_in[i], q_out[i]);
            // Branch-free: a pixel that does not take part has q = 0 and adds nothing.
            let wi = if qi > 0.0 { 1.0 } else { 0.0 };
            let wo = if qo > 0.0 { 1.0 } else { 0.0 };
            cw[i] += wi - wo;
            cwy[i] += wi * y_in - wo * y_out;
            cwyy[i] += wi * yy_in - wo * yy_out;
            cq[i] += qi - qo;
            cqy[i] += qi * y_in - qo * y_out;
        }
    }
}

/// The nine window sums of a row, from absolute pixel coordinates `(x, y)` of the points:
/// `Σw, Σwx, Σwx², Σwy, Σwxy, Σwy², Σq, Σqx, Σqy` (`w` = 1 where the pixel takes part, `q` =
/// `1/z` or 0). The `w` sums are integers, exact in f64.
const SUMS: usize = 9;

/// The window sums of the `q` moments (`Σq, Σqx, Σqy`, sums 6 to 8) of a row from the column
/// sums `cq, cqy`: prefix sums along the row, two columns per step (the dependency chain is half
/// as long), then differences `n` apart.
#[inline(always)]
fn q_window_sums(
    cq: &[f64],
    cqy: &[f64],
    xs_pad: &[f64],
    n: usize,
    prefix: &mut [Vec<f64>; SUMS],
    sums: &mut [Vec<f64>; SUMS],
) {
    let len = cq.len();
    let (cqy, xs_pad) = (&cqy[..len], &xs_pad[..len]);
    let [.., p6, p7, p8] = prefix.each_mut().map(|p| {
        p.resize(len + 1, 0.0);
        &mut p[..len + 1]
    });
    let value = |j: usize| [cq[j], cq[j] * xs_pad[j], cqy[j]];
    let mut acc = [0.0f64; 3];
    let mut j = 0;
    while j + 2 <= len {
        let (v0, v1) = (value(j), value(j + 1));
        p6[j + 1] = acc[0] + v0[0];
        p7[j + 1] = acc[1] + v0[1];
        p8[j + 1] = acc[2] + v0[2];
        for k in 0..3 {
            acc[k] += v0[k] + v1[k];
        }
        p6[j + 2] = acc[0];
        p7[j + 2] = acc[1];
        p8[j + 2] = acc[2];
        j += 2;
    }
    if j < len {
        let v0 = value(j);
        p6[j + 1] = acc[0] + v0[0];
        p7[j + 1] = acc[1] + v0[1];
        p8[j + 1] = acc[2] + v0[2];
    }
    let w = len + 1 - n;
    for (p, out) in prefix[6..].iter().zip(sums[6..].iter_mut()) {
        let (lo, hi, out) = (&p[..w], &p[n..n + w], &mut out[..w]);
        for i in 0..w {
            out[i] = hi[i] - lo[i];
        }
    }
}

simd_dispatch! {
    /// The nine window sums ([`SUMS`]) of a row of windows `n` wide from the column sums
    /// `cols`: prefix sums along the row, then differences `n` apart (the `w` sums are
    /// integers, exact in any order).
    fn window_row(
        cols: &[Vec<f64>; 5],
        xs_pad: &[f64],
        n: usize,
        prefix: &mut [Vec<f64>; SUMS],
        sums: &mut [Vec<f64>; SUMS],
    ) {
        let [cw, cwy, cwyy, cq, cqy] = cols.each_ref().map(|c| c.as_slice());
        let len = cw.len();
        let (cwy, cwyy, xs_pad) = (&cwy[..len], &cwyy[..len], &xs_pad[..len]);
        {
            let [p0, p1, p2, p3, p4, p5, ..] = prefix.each_mut().map(|p| {
                p.resize(len + 1, 0.0);
                &mut p[..len + 1]
            });
            let mut acc = [0.0f64; 6];
            for j in 0..len {
                let x = xs_pad[j];
                let v = [cw[j], cw[j] * x, cw[j] * x * x, cwy[j], cwy[j] * x, cwyy[j]];
                for k in 0..6 {
                    acc[k] += v[k];
                }
                p0[j + 1] = acc[0];
                p1[j + 1] = acc[1];
                p2[j + 1] = acc[2];
                p3[j + 1] = acc[3];
                p4[j + 1] = acc[4];
                p5[j + 1] = acc[5];
            }
        }
        let w = len + 1 - n;
        for (p, out) in prefix[..6].iter().zip(sums[..6].iter_mut()) {
            let (lo, hi, out) = (&p[..w], &p[n..n + w], &mut out[..w]);
            for i in 0..w {
                out[i] = hi[i] - lo[i];
            }
        }
        q_window_sums(cq, cqy, xs_pad, n, prefix, sums);
    }
}

/// `(count, Σ i, Σ i²)` over the integers `lo..=hi` (as f64: exact for the image sizes here).
fn run_moments(lo: usize, hi: usize) -> [f64; 3] {
    // Σ_{i <= m} i² = m (m + 1) (2m + 1) / 6.
    let squares = |m: u128| m * (m + 1) * (2 * m + 1) / 6;
    let (l, h) = (lo as u128, hi as u128);
    let below = if lo == 0 { 0 } else { squares(l - 1) };
    [
        (h + 1 - l) as f64,
        ((l + h) * (h + 1 - l) / 2) as f64,
        (squares(h) - below) as f64,
    ]
}

simd_dispatch! {
    /// [`window_row`] for a row whose window rows are all taking part: the point counts and
    /// coordinate moments are products of the row moments `rows` (of the window's rows, see
    /// [`run_moments`]) and the column moments `columns` (per pixel, of its clipped columns),
    /// the same integers as [`window_row`] sums; only the `q` sums are summed along the row.
    fn window_row_full(
        cols: &[Vec<f64>; 5],
        xs_pad: &[f64],
        n: usize,
        rows: [f64; 3],
        columns: &[Vec<f64>; 3],
        prefix: &mut [Vec<f64>; SUMS],
        sums: &mut [Vec<f64>; SUMS],
    ) {
        q_window_sums(&cols[3], &cols[4], xs_pad, n, prefix, sums);
        let w = cols[3].len() + 1 - n;
        let [nc, sx1, sx2] = columns.each_ref().map(|c| &c[..w]);
        let [nr, sy1, sy2] = rows;
        let [s0, s1, s2, s3, s4, s5, ..] = sums.each_mut().map(|s| &mut s[..w]);
        for i in 0..w {
            s0[i] = nr * nc[i];
            s1[i] = nr * sx1[i];
            s2[i] = nr * sx2[i];
            s3[i] = nc[i] * sy1;
            s4[i] = sx1[i] * sy1;
            s5[i] = nc[i] * sy2;
        }
    }
}

simd_dispatch! {
    fn solve_row(
        sums: &[Vec<f64>; SUMS],
        xs: &[f64],
        y: f64,
        depth: &[f32],
        cam: &Pinhole,
        normals: &mut [Vec<f64>; 3],
    ) {
        let n = xs.len();
        let [b0, b1, b2, b3, b4, b5, b6, b7, b8] = sums;
        let (b0, b1, b2, b3, b4) = (&b0[..n], &b1[..n], &b2[..n], &b3[..n], &b4[..n]);
        let (b5, b6, b7, b8, depth) = (&b5[..n], &b6[..n], &b7[..n], &b8[..n], &depth[..n]);
        let [nx, ny, nz] = normals;
        let (nx, ny, nz) = (&mut nx[..n], &mut ny[..n], &mut nz[..n]);
        let (fx, fy, dy) = (cam.fx, cam.fy, cam.cy - y);
        for i in 0..n {
            let x = xs[i];
            // Moments about the window's own pixel (u = x' - x, v = y' - y): exact integers.
            let s1 = b0[i];
            let su = b1[i] - x * s1;
            let sv = b3[i] - y * s1;
            let suu = b2[i] - 2.0 * x * b1[i] + x * x * s1;
            let suv = b4[i] - x * b3[i] - y * b1[i] + x * y * s1;
            let svv = b5[i] - 2.0 * y * b3[i] + y * y * s1;
            let t1 = b6[i];
            let tu = b7[i] - x * t1;
            let tv = b8[i] - y * t1;
            // Adjugate of the normal matrix of q = α u + β v + γ (as the reference's
            // `invertIt`/`mutiplyIt`, in pixel units about the pixel).
            let c0 = svv * s1 - sv * sv;
            let c1 = -suv * s1 + su * sv;
            let c2 = suv * sv - su * svv;
            let c3 = suu * s1 - su * su;
            let c4 = -suu * sv + suv * su;
            let c5 = suu * svv - suv * suv;
            // det = s1³ x det(covariance of (u, v)): the spread of the points in the image.
            let det = suu * c0 + suv * c1 + su * c2;
            let alpha = c0 * tu + c1 * tv + c2 * t1;
            let beta = c1 * tu + c3 * tv + c4 * t1;
            let gamma = c2 * tu + c4 * tv + c5 * t1;
            // With a = (x - cx) / fx: q = n . (a, b, 1), n = (α fx, β fy, γ + α (cx - x) +
            // β (cy - y)), and n . (a, b, 1) at the pixel itself is γ.
            let (n0, n1) = (alpha * fx, beta * fy);
            let n2 = gamma + alpha * (cam.cx - x) + beta * dy;
            let norm2 = n0 * n0 + n1 * n1 + n2 * n2;
            let defined = s1 >= 2.5
                && det >= MIN_SPREAD_PX4 * s1 * s1 * s1
                && norm2 > 0.0
                && norm2 < f64::INFINITY;
            // Oriented as the reference: n_z >= 0, then n . p >= 0 where the depth is valid.
            let up = if n2 < 0.0 { -1.0 } else { 1.0 };
            let z = depth[i];
            let flip = z > 0.0 && z < f32::INFINITY && up * gamma < 0.0;
            let s = if flip { -up } else { up } / norm2.sqrt();
            let nan = f64::NAN;
            nx[i] = if defined { s * n0 } else { nan };
            ny[i] = if defined { s * n1 } else { nan };
            nz[i] = if defined { s * n2 } else { nan };
        }
    }
}

/// Rows per block of the sliding-window sums (fixed, so results do not depend on threads).
const BAND: usize = 48;

/// The window sums of one band for half-size `r`, and the normals of its current row.
struct Window {
    /// Per column, sums over the rows of the window, padded with `r` zeros on both sides:
    /// `Σw, Σwy, Σwy², Σq, Σqy`.
    cols: [Vec<f64>; 5],
    /// `x` of every padded column (`-r` first).
    xs_pad: Vec<f64>,
    sums: [Vec<f64>; SUMS],
    prefix: [Vec<f64>; SUMS],
    /// [`run_moments`] of every pixel's clipped window columns (count, Σx, Σx²).
    columns: [Vec<f64>; 3],
    /// The current row's unit normals (x, y, z components), NaN where undefined, oriented as
    /// the reference (`n . p >= 0`).
    n: [Vec<f64>; 3],
}

impl Window {
    fn new(r: usize, width: usize) -> Self {
        let padded = width + 2 * r;
        Self {
            cols: std::array::from_fn(|_| vec![0.0; padded]),
            xs_pad: (0..padded).map(|j| j as f64 - r as f64).collect(),
            sums: std::array::from_fn(|_| vec![0.0; width]),
            prefix: std::array::from_fn(|_| vec![0.0; padded + 1]),
            columns: {
                let m: Vec<[f64; 3]> = (0..width)
                    .map(|x| run_moments(x.saturating_sub(r), (x + r).min(width - 1)))
                    .collect();
                std::array::from_fn(|k| m.iter().map(|v| v[k]).collect())
            },
            n: std::array::from_fn(|_| vec![0.0; width]),
        }
    }
}

/// What the normals are computed from.
struct Support<'a> {
    depth: &'a [f32],
    iz: Vec<f64>,
    /// `partial_rows[y]`: how many of the rows above `y` have a pixel that takes no part.
    partial_rows: Vec<usize>,
    zeros: Vec<f64>,
    width: usize,
    height: usize,
    cam: Pinhole,
}

impl<'a> Support<'a> {
    fn new(
        depth: &'a [f32],
        raw: Option<&[f32]>,
        width: usize,
        height: usize,
        cam: &Pinhole,
    ) -> Self {
        let iz = inverse_depth(depth, raw);
        let partial: Vec<bool> = iz
            .par_chunks(width.max(1))
            .map(|row| row.iter().any(|&q| q <= 0.0))
            .collect();
        let mut partial_rows = vec![0; height + 1];
        for (y, &p) in partial.iter().enumerate() {
            partial_rows[y + 1] = partial_rows[y] + usize::from(p);
        }
        Self {
            depth,
            iz,
            partial_rows,
            zeros: vec![0.0; width],
            width,
            height,
            cam: *cam,
        }
    }

    fn bands(&self) -> usize {
        self.height.div_ceil(BAND)
    }

    /// The `1/z` row `y` with its `y`, or zeros when there is no such row.
    fn row(&self, y: Option<usize>) -> (&[f64], f64) {
        match y {
            Some(y) => (&self.iz[y * self.width..][..self.width], y as f64),
            None => (&self.zeros, 0.0),
        }
    }

    /// Normals of the rows of band `band` for windows of half-size `r`: `emit(row in band,
    /// window)` with the row's normals in `window.n`. Per column, `cols` slides down the
    /// rows; along the row, window sums come from runs of power-of-two length. Each normal is
    /// solved from the moments about its own pixel, oriented as the reference: first
    /// `n_z >= 0`, then `n . p >= 0` where the pixel's depth is valid.
    fn band(
        &self,
        band: usize,
        r: usize,
        mut emit: impl FnMut(usize, &Window) -> Result<()>,
    ) -> Result<()> {
        let (width, height) = (self.width, self.height);
        let mut win = Window::new(r, width);
        let y_start = band * BAND;
        let xs = &win.xs_pad[r..r + width].to_vec();
        for yy in y_start.saturating_sub(r)..(y_start + r).min(height) {
            slide_columns(&mut win.cols, r, self.row(Some(yy)), self.row(None));
        }
        for y in y_start..(y_start + BAND).min(height) {
            check_interrupt()?;
            // Enter row y + r, leave row y - r - 1.
            let enter = (y + r < height).then_some(y + r);
            let leave = (y > y_start && y > r).then(|| y - r - 1);
            slide_columns(&mut win.cols, r, self.row(enter), self.row(leave));
            let Window {
                cols,
                xs_pad,
                sums,
                n,
                prefix,
                columns,
            } = &mut win;
            let (lo, hi) = (y.saturating_sub(r), (y + r).min(height - 1));
            if self.partial_rows[hi + 1] == self.partial_rows[lo] {
                let rows = run_moments(lo, hi);
                window_row_full(cols, xs_pad, 2 * r + 1, rows, columns, prefix, sums);
            } else {
                window_row(cols, xs_pad, 2 * r + 1, prefix, sums);
            }
            let depth = &self.depth[y * width..][..width];
            solve_row(sums, xs, y as f64, depth, &self.cam, n);
            emit(y - y_start, &win)?;
        }
        Ok(())
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
    let mut out = vec![0.0f32; 3 * width * height];
    out.par_chunks_mut(3 * BAND * width)
        .enumerate()
        .try_for_each(|(band, out)| {
            support.band(band, radius, |dy, win| {
                let row = &mut out[3 * dy * width..][..3 * width];
                let [nx, ny, nz] = &win.n;
                for (((o, &x), &y), &z) in row.chunks_exact_mut(3).zip(nx).zip(ny).zip(nz) {
                    o.copy_from_slice(&[(flip * x) as f32, (flip * y) as f32, (flip * z) as f32]);
                }
                Ok(())
            })
        })?;
    Ok(out)
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
const LANES: usize = 8;
/// Normals per f32 partial sum (then added to the f64 totals).
const BLOCK: usize = 64 * LANES;

simd_dispatch! {
    /// `Σ w n nᵀ` (upper triangle: xx, xy, xz, yy, yz, zz) over the normals `(xs, ys, zs)` (a
    /// multiple of [`LANES`] long), with `w = +1` for wall-like (`|n.y| < sin θ`), `-1` for
    /// floor-like (`|n.y| > cos θ`) normals and 0 otherwise. Partial sums of [`BLOCK`] normals
    /// are f32, [`LANES`] wide; their totals f64.
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
fn gravity(parts: &[[Vec<f32>; 3]]) -> Result<[f64; 3]> {
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
#[inline(always)]
fn to_u8(v: f64) -> u8 {
    // `as` saturates and maps NaN to 0; adding 0.5 then truncating rounds half up for v >= 0
    // (below 0.5 everything gives 0).
    if v >= 0.5 {
        (v + 0.5).min(255.0) as u8
    } else {
        0
    }
}

/// The angle channel's value, `uint8(acos(d) in degrees + ANGLE_OFFSET)`, of a clamped cosine.
fn angle_u8(d: f64) -> u8 {
    to_u8(d.acos().to_degrees() + ANGLE_OFFSET)
}

/// Coefficients of `acos(x) ≈ sqrt(1 - x) Σ c_k x^k` on `[0, 1]`, absolute error <= 2e-8 rad
/// (Abramowitz & Stegun 4.4.46).
const ACOS_POLY: [f64; 8] = [
    1.570_796_305_0,
    -0.214_598_801_6,
    0.088_978_987_4,
    -0.050_174_304_6,
    0.030_891_881_0,
    -0.017_088_125_6,
    0.006_670_090_1,
    -0.001_262_491_1,
];

/// Rounded angles whose polynomial value lies closer than this (degrees) to a rounding boundary
/// are recomputed with `acos` (the polynomial is within 1.2e-6 degrees).
const ANGLE_MARGIN_DEG: f64 = 1e-4;

/// Height channel: `z (k_a a + k_b)` cm is a pixel's height (see [`hha`]).
struct RowGeometry<'a> {
    /// `a` of every column.
    a: &'a [f64],
    /// `(up_x, up_y b + ..., up_z)`: the height of `p = z (a, b, 1)` is `z (up_x a + up_y b + up_z)`.
    up: [f64; 3],
    b: f64,
    floor_cm: f64,
    gravity: [f64; 3],
}

simd_dispatch! {
    /// One row of the HHA image (`3 W` u8) and of the normals handed back (`3 W` f32, toward
    /// the camera) from the row's depth and its [`ANGLE_RADIUS`] normals (reference
    /// orientation, NaN where undefined). The angle's `acos` is a polynomial, recomputed with
    /// `acos` where the rounding is within [`ANGLE_MARGIN_DEG`] of a boundary: the values are
    /// those of `to_u8(acos(d).to_degrees() + ANGLE_OFFSET)`.
    fn encode_row(
        depth: &[f32],
        normals: &[Vec<f64>; 3],
        geo: &RowGeometry<'_>,
        image: &mut [u8],
        out: &mut [f32],
        near: &mut [bool],
    ) {
        let w = depth.len();
        let [nx, ny, nz] = normals;
        let (nx, ny, nz, a) = (&nx[..w], &ny[..w], &nz[..w], &geo.a[..w]);
        let (image, out, near) = (&mut image[..3 * w], &mut out[..3 * w], &mut near[..w]);
        let (up, b, floor_cm, g) = (geo.up, geo.b, geo.floor_cm, geo.gravity);
        let to_deg = 180.0 / std::f64::consts::PI;
        for x in 0..w {
            let z = depth[x];
            let valid = z > 0.0 && z < f32::INFINITY;
            let zf = z as f64;
            let z_cm = (zf * 100.0).max(MIN_DEPTH_CM);
            let disparity = to_u8(DISPARITY_SCALE / z_cm);
            let height = to_u8(zf * (up[0] * a[x] + up[1] * b + up[2]) - floor_cm);
            image[3 * x] = if valid { disparity } else { 0 };
            image[3 * x + 1] = if valid { height } else { 0 };
            let n = [nx[x], ny[x], nz[x]];
            out[3 * x] = -n[0] as f32;
            out[3 * x + 1] = -n[1] as f32;
            out[3 * x + 2] = -n[2] as f32;
            let d = n[0] * g[0] + n[1] * g[1] + n[2] * g[2];
            let d = d.clamp(-1.0, 1.0);
            let t = d.abs();
            let mut poly = ACOS_POLY[7];
            for &c in ACOS_POLY[..7].iter().rev() {
                poly = poly * t + c;
            }
            let rad = poly * (1.0 - t).sqrt();
            let rad = if d < 0.0 { std::f64::consts::PI - rad } else { rad };
            // uint8(v) = floor(v + 0.5) for v = degrees + offset >= 0.5.
            let v = rad * to_deg + (ANGLE_OFFSET + 0.5);
            let frac = v - v.floor();
            let undefined = n[0].is_nan();
            image[3 * x + 2] = if undefined {
                to_u8(NO_NORMAL_ANGLE + ANGLE_OFFSET)
            } else {
                v as u8
            };
            let clear = frac > ANGLE_MARGIN_DEG && frac < 1.0 - ANGLE_MARGIN_DEG;
            near[x] = !(undefined || clear);
        }
        for x in 0..w {
            if near[x] {
                let d = nx[x] * g[0] + ny[x] * g[1] + nz[x] * g[2];
                image[3 * x + 2] = angle_u8(d.clamp(-1.0, 1.0));
            }
        }
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
    // The GRAVITY_RADIUS normals of each band, as f32 structure of arrays.
    let parts: Vec<[Vec<f32>; 3]> = (0..support.bands())
        .into_par_iter()
        .map(|band| {
            let rows = BAND.min(height - band * BAND);
            let len = (rows * width).div_ceil(LANES) * LANES;
            let mut soa: [Vec<f32>; 3] = std::array::from_fn(|_| Vec::with_capacity(len));
            support.band(band, GRAVITY_RADIUS, |_, win| {
                for (out, n) in soa.iter_mut().zip(&win.n) {
                    out.extend(n.iter().map(|&v| if v.is_nan() { 0.0 } else { v as f32 }));
                }
                Ok(())
            })?;
            for out in &mut soa {
                out.resize(len, 0.0);
            }
            Ok(soa)
        })
        .collect::<Result<_>>()?;
    let g = gravity(&parts)?;
    drop(parts);
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
    // The ANGLE_RADIUS normals, band by band, straight into the image and the normals handed
    // back (toward the camera, f32).
    let mut image = vec![0u8; width * height * 3];
    let mut normals = vec![0.0f32; width * height * 3];
    image
        .par_chunks_mut(3 * BAND * width)
        .zip(normals.par_chunks_mut(3 * BAND * width))
        .enumerate()
        .try_for_each(|(band, (img, nrm))| {
            let mut near = vec![false; width];
            support.band(band, ANGLE_RADIUS, |dy, win| {
                let y = band * BAND + dy;
                let geo = RowGeometry {
                    a: &rays.a,
                    up,
                    b: rays.b[y],
                    floor_cm,
                    gravity: g,
                };
                encode_row(
                    &depth[y * width..][..width],
                    &win.n,
                    &geo,
                    &mut img[3 * dy * width..][..3 * width],
                    &mut nrm[3 * dy * width..][..3 * width],
                    &mut near,
                );
                Ok(())
            })
        })?;
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

    /// The reference's normal by brute force: moments `[a², ab, a, b², b, 1, a/z, b/z, 1/z]` of
    /// the window's valid points in normalised coordinates, the adjugate solve, then the
    /// orientation (`n_z >= 0`, then `n . p >= 0` where the depth is valid).
    fn naive_normal(depth: &[f32], w: usize, h: usize, x: usize, y: usize, r: usize) -> [f64; 3] {
        let rays = Rays::new(w, h, &CAM);
        let mut s = [0.0f64; 9];
        for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
            for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                let z = depth[yy * w + xx];
                if !is_valid(z) {
                    continue;
                }
                let (a, b, q) = (rays.a[xx], rays.b[yy], 1.0 / z as f64);
                let m = [a * a, a * b, a, b * b, b, 1.0, q * a, q * b, q];
                for k in 0..9 {
                    s[k] += m[k];
                }
            }
        }
        let [saa, sab, sa, sbb, sb, s1, ta, tb, t1] = s;
        let c0 = sbb * s1 - sb * sb;
        let c1 = -sab * s1 + sa * sb;
        let c2 = sab * sb - sa * sbb;
        let c3 = saa * s1 - sa * sa;
        let c4 = -saa * sb + sab * sa;
        let c5 = saa * sbb - sab * sab;
        let det = saa * c0 + sab * c1 + sa * c2;
        let f2 = CAM.fx * CAM.fy;
        if s1 < 2.5 || det < MIN_SPREAD_PX4 / (f2 * f2) * s1 * s1 * s1 {
            return [f64::NAN; 3];
        }
        let n = [
            c0 * ta + c1 * tb + c2 * t1,
            c1 * ta + c3 * tb + c4 * t1,
            c2 * ta + c4 * tb + c5 * t1,
        ];
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        let mut sign = if n[2] < 0.0 { -1.0 } else { 1.0 };
        let at_pixel = n[0] * rays.a[x] + n[1] * rays.b[y] + n[2];
        if is_valid(depth[y * w + x]) && sign * at_pixel < 0.0 {
            sign = -sign;
        }
        n.map(|v| sign * v / len)
    }

    /// A wavy surface (`w x h`), with holes where `hole(x, y)`.
    fn wavy(w: usize, h: usize, hole: impl Fn(usize, usize) -> bool) -> Vec<f32> {
        (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                if hole(x, y) {
                    f32::NAN
                } else {
                    2.0 + 0.3 * (x as f32 * 0.2).sin() + 0.01 * y as f32 + 0.1 * (y as f32).cos()
                }
            })
            .collect()
    }

    #[test]
    fn sliding_sums_match_brute_force_with_holes() {
        let (w, h) = (37, 101); // more than two bands, odd sizes
                                // Holes everywhere; in a few rows only (rows whose windows are whole take the
                                // closed-form path); none.
        let scattered = wavy(w, h, |x, y| {
            (y * w + x) * 7919 % 13 < 4 || (y > 60 && y < 75 && x < 20)
        });
        let few_rows = wavy(w, h, |x, y| (y == 30 || y == 77) && x % 3 == 0);
        let none = wavy(w, h, |_, _| false);
        for (depth, r) in [1, 3, 10, 40]
            .into_iter()
            .flat_map(|r| [(&scattered, r), (&few_rows, r), (&none, r)])
        {
            let out = normals(depth, None, w, h, &CAM, r, false).unwrap();
            for y in 0..h {
                for x in 0..w {
                    let n = naive_normal(depth, w, h, x, y, r);
                    let got = &out[(y * w + x) * 3..][..3];
                    if n[0].is_nan() {
                        assert!(got[0].is_nan(), "({x}, {y}) r {r}");
                        continue;
                    }
                    for k in 0..3 {
                        assert!(
                            (got[k] as f64 - n[k]).abs() < 1e-5,
                            "({x}, {y}) r {r}: {got:?} {n:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn whole_windows_give_the_same_sums_both_ways() {
        let (w, h, r) = (53, 40, 4);
        let depth = wavy(w, h, |_, _| false);
        let support = Support::new(&depth, None, w, h, &CAM);
        let mut win = Window::new(r, w);
        for yy in 0..=2 * r {
            slide_columns(&mut win.cols, r, support.row(Some(yy)), support.row(None));
        }
        let y = r; // the window covers rows 0..=2r, all whole
        let mut general = win.sums.clone();
        window_row(
            &win.cols,
            &win.xs_pad,
            2 * r + 1,
            &mut win.prefix,
            &mut general,
        );
        let rows = run_moments(0, 2 * r);
        let mut full = win.sums.clone();
        let n = 2 * r + 1;
        window_row_full(
            &win.cols,
            &win.xs_pad,
            n,
            rows,
            &win.columns,
            &mut win.prefix,
            &mut full,
        );
        assert_eq!(general, full, "row {y}");
        assert_eq!(full[0][0], ((r + 1) * n) as f64); // clipped at the left border
        assert_eq!(full[0][w / 2], (n * n) as f64);
    }

    #[test]
    fn every_simd_path_gives_the_same_bits() {
        use std::sync::atomic::Ordering;
        // Floor, wall and holes (both window paths), some pixels near angle rounding bounds.
        let (w, h) = (64, 48);
        let floor = plane([0.0, 1.0, 0.0], 1.2, w, h);
        let wall = plane([0.05, 0.02, 1.0], 5.0, w, h);
        let depth: Vec<f32> = (0..w * h)
            .map(|i| {
                let (f, wl) = (floor[i], wall[i]);
                let z = if f > 0.0 && f < wl { f } else { wl };
                if (i * 7919) % 97 < 3 && i / w > 30 {
                    f32::NAN
                } else {
                    z * (1.0 + 0.002 * ((i % 7) as f32))
                }
            })
            .collect();
        let run = |cap: u8| {
            SIMD_CAP.store(cap, Ordering::Relaxed);
            let out = hha(&depth, None, w, h, &CAM).unwrap();
            let n = normals(&depth, None, w, h, &CAM, 10, true).unwrap();
            SIMD_CAP.store(2, Ordering::Relaxed);
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            (
                out.image,
                out.gravity,
                out.floor_cm,
                bits(&out.normals),
                bits(&n),
            )
        };
        let reference = run(0);
        assert_eq!(run(1), reference);
        assert_eq!(run(2), reference);
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
