//! The HHA image rows: uint8 rounding, the angle channel's acos, the per-row geometry.

use super::*;

/// MATLAB's `uint8(v)`: round half away from zero, saturate; NaN gives 0.
#[inline(always)]
pub(super) fn to_u8(v: f64) -> u8 {
    // `as` saturates and maps NaN to 0; adding 0.5 then truncating rounds half up for v >= 0
    // (below 0.5 everything gives 0).
    if v >= 0.5 {
        (v + 0.5).min(255.0) as u8
    } else {
        0
    }
}

/// The angle channel's value, `uint8(acos(d) in degrees + ANGLE_OFFSET)`, of a clamped cosine.
pub(super) fn angle_u8(d: f64) -> u8 {
    to_u8(d.acos().to_degrees() + ANGLE_OFFSET)
}

/// Coefficients of `acos(x) ≈ sqrt(1 - x) Σ c_k x^k` on `[0, 1]`, absolute error <= 2e-8 rad
/// (Abramowitz & Stegun 4.4.46).
pub(super) const ACOS_POLY: [f64; 8] = [
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
pub(super) const ANGLE_MARGIN_DEG: f64 = 1e-4;

/// Height channel: `z (k_a a + k_b)` cm is a pixel's height (see [`hha`]).
pub(super) struct RowGeometry<'a> {
    /// `a` of every column.
    pub(super) a: &'a [f64],
    /// `(up_x, up_y b + ..., up_z)`: the height of `p = z (a, b, 1)` is `z (up_x a + up_y b + up_z)`.
    pub(super) up: [f64; 3],
    pub(super) b: f64,
    pub(super) floor_cm: f64,
    pub(super) gravity: [f64; 3],
}

simd_dispatch! {
    /// One row of the HHA image (`3 W` u8) and of the normals handed back (`3 W` f32, toward
    /// the camera) from the row's depth and its [`ANGLE_RADIUS`] normals (reference
    /// orientation, NaN where undefined). The angle's `acos` is a polynomial, recomputed with
    /// `acos` where the rounding is within [`ANGLE_MARGIN_DEG`] of a boundary: the values are
    /// those of `to_u8(acos(d).to_degrees() + ANGLE_OFFSET)`.
    pub(super) fn encode_row(
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
