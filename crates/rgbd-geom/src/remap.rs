//! Undistortion (and optional rectification) of whole images and depth maps by remapping.

use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use crate::camera::Intrinsics;
use crate::error::{check_len, invalid, Result};
use crate::projection::Camera;

/// How [`remap`] samples the source image.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Interpolation {
    /// Nearest pixel: the right choice for depth maps (no flying pixels across edges).
    Nearest,
    /// Bilinear; a NaN neighbour with non-zero weight makes the output NaN.
    Linear,
}

/// For every pixel of the ideal destination lattice `dst` (no distortion), the source pixel of
/// `src` that sees the same ray, as interleaved `x, y` values row-major (`2 * dst.len()`). `rotation` rotates destination rays
/// into the source frame's orientation (`R` of OpenCV's `initUndistortRectifyMap`: source ray =
/// `R^T` · destination ray); `None` means identity.
pub fn undistort_map(src: &Camera, dst: &Intrinsics, rotation: Option<&Matrix3<f64>>) -> Vec<f32> {
    let mut map = vec![0.0f32; 2 * dst.len()];
    // x depends only on the column and y only on the row: hoist both out of the pixel loop.
    let xs: Vec<f64> = (0..dst.width)
        .map(|u| (u as f64 - dst.cx) / dst.fx)
        .collect();
    let rinv = rotation.map(|r| r.transpose());
    let rational = src.distortion.is_rational();
    map.par_chunks_mut(2 * dst.width)
        .enumerate()
        .for_each(|(v, row)| {
            let y = (v as f64 - dst.cy) / dst.fy;
            match (&rinv, rational) {
                (Some(ri), _) => {
                    for (m, &x) in row.chunks_exact_mut(2).zip(&xs) {
                        let q = ri * Vector3::new(x, y, 1.0);
                        m.copy_from_slice(&source_pixel::<true>(src, q.x / q.z, q.y / q.z));
                    }
                }
                (None, true) => map_row::<true>(src, &xs, y, row),
                (None, false) => map_row::<false>(src, &xs, y, row),
            }
        });
    map
}

/// One row of an undistortion map. On x86-64 CPUs with AVX2 + FMA the same code is compiled a
/// second time for them and chosen at run time (4 f64 lanes instead of SSE2's 2); the wheel
/// itself stays baseline x86-64.
fn map_row<const RATIONAL: bool>(src: &Camera, xs: &[f64], y: f64, row: &mut [f32]) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma") {
        // SAFETY: the running CPU supports AVX2 and FMA, checked just above.
        unsafe { map_row_avx2::<RATIONAL>(src, xs, y, row) };
        return;
    }
    map_row_generic::<RATIONAL>(src, xs, y, row);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn map_row_avx2<const RATIONAL: bool>(src: &Camera, xs: &[f64], y: f64, row: &mut [f32]) {
    map_row_generic::<RATIONAL>(src, xs, y, row);
}

#[inline(always)]
fn map_row_generic<const RATIONAL: bool>(src: &Camera, xs: &[f64], y: f64, row: &mut [f32]) {
    for (m, &x) in row.chunks_exact_mut(2).zip(xs) {
        m.copy_from_slice(&source_pixel::<RATIONAL>(src, x, y));
    }
}

#[inline(always)]
fn source_pixel<const RATIONAL: bool>(src: &Camera, x: f64, y: f64) -> [f32; 2] {
    let [xd, yd] = src.distortion.distort_with::<RATIONAL>(x, y);
    let [su, sv] = src.intrinsics.to_pixel(xd, yd);
    [su as f32, sv as f32]
}

/// Samples `img` (`h x w x channels`, row-major) at the interleaved `x, y` positions of `map`,
/// producing a `map.len() / 2 x channels` image. Samples outside the source give NaN.
pub fn remap(
    img: &[f32],
    width: usize,
    height: usize,
    channels: usize,
    map: &[f32],
    out_width: usize,
    interp: Interpolation,
) -> Result<Vec<f32>> {
    if channels == 0 || width == 0 || height == 0 {
        return Err(invalid(
            "image",
            format!("{height}x{width}x{channels}"),
            "a non-empty image",
        ));
    }
    check_len(
        "image",
        img,
        width * height * channels,
        "height * width * channels",
    )?;
    if out_width == 0 || !map.len().is_multiple_of(2 * out_width) {
        return Err(invalid(
            "map",
            map.len(),
            format!("a multiple of 2 x the output width {out_width}"),
        ));
    }
    let mut out = vec![f32::NAN; map.len() / 2 * channels];
    let src = Source { img, width, height };
    out.par_chunks_mut(out_width * channels)
        .zip(map.par_chunks(2 * out_width))
        .for_each(|(orow, mrow)| match channels {
            // Constant channel counts let the compiler unroll the per-channel loops.
            1 => remap_row(&src, 1, mrow, orow, interp),
            3 => remap_row(&src, 3, mrow, orow, interp),
            4 => remap_row(&src, 4, mrow, orow, interp),
            c => remap_row(&src, c, mrow, orow, interp),
        });
    Ok(out)
}

struct Source<'a> {
    img: &'a [f32],
    width: usize,
    height: usize,
}

#[inline(always)]
fn remap_row(src: &Source<'_>, c: usize, mrow: &[f32], orow: &mut [f32], interp: Interpolation) {
    let (w, h) = (src.width, src.height);
    let (wf, hf) = (w as f32, h as f32);
    for (o, xy) in orow.chunks_exact_mut(c).zip(mrow.chunks_exact(2)) {
        let (x, y) = (xy[0], xy[1]);
        match interp {
            Interpolation::Nearest => {
                let (xr, yr) = (x.round(), y.round());
                if xr >= 0.0 && yr >= 0.0 && xr < wf && yr < hf {
                    let i = (yr as usize * w + xr as usize) * c;
                    o.copy_from_slice(&src.img[i..i + c]);
                }
            }
            Interpolation::Linear => bilinear(src.img, w, h, c, x, y, o),
        }
    }
}

/// Bilinear sample. Interior samples take a branch-free lerp; the rare NaN result and the last
/// row/column go through [`bilinear_careful`], which skips zero-weight taps.
#[inline(always)]
fn bilinear(img: &[f32], w: usize, h: usize, c: usize, x: f32, y: f32, o: &mut [f32]) {
    if x >= 0.0 && y >= 0.0 && x < (w - 1) as f32 && y < (h - 1) as f32 {
        let (x0, y0) = (x as usize, y as usize);
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let i = (y0 * w + x0) * c;
        let j = i + w * c;
        let (top, bot) = (&img[i..i + 2 * c], &img[j..j + 2 * c]);
        let mut finite = true;
        for (ch, oc) in o.iter_mut().enumerate() {
            let t = top[ch] + fx * (top[c + ch] - top[ch]);
            let b = bot[ch] + fx * (bot[c + ch] - bot[ch]);
            *oc = t + fy * (b - t);
            finite &= oc.is_finite();
        }
        if finite {
            return;
        }
    }
    bilinear_careful(img, w, h, c, x, y, o);
}

#[inline(never)]
fn bilinear_careful(img: &[f32], w: usize, h: usize, c: usize, x: f32, y: f32, o: &mut [f32]) {
    // Valid only inside [0, w-1] x [0, h-1]; NaN x/y fail these comparisons too.
    if !(x >= 0.0 && y >= 0.0 && x <= (w - 1) as f32 && y <= (h - 1) as f32) {
        return;
    }
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (fx, fy) = (x - x0 as f32, y - y0 as f32);
    let x1 = (x0 + 1).min(w - 1);
    let y1 = (y0 + 1).min(h - 1);
    let taps = [
        ((1.0 - fx) * (1.0 - fy), y0 * w + x0),
        (fx * (1.0 - fy), y0 * w + x1),
        ((1.0 - fx) * fy, y1 * w + x0),
        (fx * fy, y1 * w + x1),
    ];
    for (ch, oc) in o.iter_mut().enumerate() {
        let mut acc = 0.0f32;
        for &(wt, idx) in &taps {
            // Zero-weight taps are skipped so a NaN next to an exact sample does not leak in.
            if wt > 0.0 {
                acc += wt * img[idx * c + ch];
            }
        }
        *oc = acc;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distortion::Distortion;

    #[test]
    fn identity_map_reproduces_image() {
        let k = Intrinsics::new(100.0, 100.0, 15.5, 9.5, 32, 20).unwrap();
        let cam = Camera::new(k, Distortion::NONE);
        let map = undistort_map(&cam, &k, None);
        let img: Vec<f32> = (0..32 * 20 * 2).map(|i| i as f32).collect();
        for interp in [Interpolation::Nearest, Interpolation::Linear] {
            let out = remap(&img, 32, 20, 2, &map, 32, interp).unwrap();
            assert_eq!(out, img);
        }
    }

    #[test]
    fn bilinear_is_exact_on_linear_ramps_and_skips_zero_weight_nan() {
        let (w, h) = (8, 6);
        let mut img: Vec<f32> = (0..w * h)
            .map(|i| (i % w) as f32 * 2.0 + (i / w) as f32)
            .collect();
        let map = vec![2.25f32, 3.5, 7.0, 5.0, -0.1, 1.0];
        let out = remap(&img, w, h, 1, &map, 1, Interpolation::Linear).unwrap();
        assert!((out[0] - (4.5 + 3.5)).abs() < 1e-5);
        assert!((out[1] - 19.0).abs() < 1e-5);
        assert!(out[2].is_nan());
        img[3 * w + 3] = f32::NAN;
        let out = remap(
            &img,
            w,
            h,
            1,
            &[2.0, 3.0, 2.5, 3.0],
            1,
            Interpolation::Linear,
        )
        .unwrap();
        assert!(out[0].is_finite() && out[1].is_nan());
    }
}
