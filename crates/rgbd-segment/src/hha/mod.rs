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
        // Indoor scenes lie 0.5-10 m away: up to 1000 the map may be centimetres as well.
        let unit = if *median > 1000.0 {
            "depth looks like millimetres; divide by 1000"
        } else {
            "depth looks like centimetres (divide by 100) or millimetres (divide by 1000)"
        };
        return Err(invalid(
            arg,
            format!("a median valid depth of {median}: {unit}"),
            format!("metres (median valid depth <= {MAX_MEDIAN_DEPTH_M})"),
        ));
    }
    Ok(())
}

/// The checks [`hha`] and [`normals`] share: the camera, the depth map ([`check_depth`]) and,
/// if given, the raw depth's size.
fn check_inputs(
    depth: &[f32],
    raw: Option<&[f32]>,
    width: usize,
    height: usize,
    cam: &Pinhole,
) -> Result<()> {
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
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $(-> $ret:ty)? $body:block) => {
        $(#[$meta])*
        #[allow(clippy::too_many_arguments)]
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
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

mod encode;
mod features;
mod gravity;
mod normals;
#[cfg(test)]
mod tests;

use encode::*;
pub use features::{features, Features, FEATURE_DIM};
use gravity::*;
pub use normals::normals;
use normals::*;

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
    check_inputs(depth, raw, width, height, cam)?;
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
