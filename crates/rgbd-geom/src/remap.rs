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
/// `src` that sees the same ray, as `(x, y)` pairs row-major. `rotation` rotates destination rays
/// into the source frame's orientation (`R` of OpenCV's `initUndistortRectifyMap`: source ray =
/// `R^T` · destination ray); `None` means identity.
pub fn undistort_map(
    src: &Camera,
    dst: &Intrinsics,
    rotation: Option<&Matrix3<f64>>,
) -> Vec<[f32; 2]> {
    let mut map = vec![[0.0f32; 2]; dst.len()];
    let rinv = rotation.map(|r| r.transpose());
    map.par_chunks_mut(dst.width)
        .enumerate()
        .for_each(|(v, row)| {
            for (u, m) in row.iter_mut().enumerate() {
                let [mut x, mut y] = dst.to_normalized(u as f64, v as f64);
                if let Some(ri) = &rinv {
                    let q = ri * Vector3::new(x, y, 1.0);
                    x = q.x / q.z;
                    y = q.y / q.z;
                }
                let [xd, yd] = src.distortion.distort(x, y);
                let [su, sv] = src.intrinsics.to_pixel(xd, yd);
                *m = [su as f32, sv as f32];
            }
        });
    map
}

/// Samples `img` (`h x w x channels`, row-major) at `map` positions, producing a
/// `map.len() x channels` image. Samples outside the source give NaN.
pub fn remap(
    img: &[f32],
    width: usize,
    height: usize,
    channels: usize,
    map: &[[f32; 2]],
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
    if out_width == 0 || !map.len().is_multiple_of(out_width) {
        return Err(invalid(
            "map",
            map.len(),
            format!("a multiple of the output width {out_width}"),
        ));
    }
    let mut out = vec![f32::NAN; map.len() * channels];
    let (wf, hf) = (width as f32, height as f32);
    out.par_chunks_mut(out_width * channels)
        .zip(map.par_chunks(out_width))
        .for_each(|(orow, mrow)| {
            for (o, &[x, y]) in orow.chunks_exact_mut(channels).zip(mrow) {
                match interp {
                    Interpolation::Nearest => {
                        let (xr, yr) = (x.round(), y.round());
                        if xr >= 0.0 && yr >= 0.0 && xr < wf && yr < hf {
                            let i = (yr as usize * width + xr as usize) * channels;
                            o.copy_from_slice(&img[i..i + channels]);
                        }
                    }
                    Interpolation::Linear => bilinear(img, width, height, channels, x, y, o),
                }
            }
        });
    Ok(out)
}

#[inline]
fn bilinear(img: &[f32], w: usize, h: usize, c: usize, x: f32, y: f32, o: &mut [f32]) {
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
        let map = vec![[2.25f32, 3.5f32], [7.0, 5.0], [-0.1, 1.0]];
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
            &[[2.0, 3.0], [2.5, 3.0]],
            1,
            Interpolation::Linear,
        )
        .unwrap();
        assert!(out[0].is_finite() && out[1].is_nan());
    }
}
