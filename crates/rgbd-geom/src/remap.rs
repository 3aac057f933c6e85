//! Undistortion (and optional rectification) of whole images and depth maps by remapping.
//!
//! Hot loops are compiled twice on x86-64: for the baseline target and for AVX2 + FMA, chosen at
//! run time per row (the wheel itself stays baseline x86-64).

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

/// A source image borrowed as `height x width x channels`, row-major.
#[derive(Clone, Copy)]
pub struct ImageRef<'a> {
    pub data: &'a [f32],
    pub width: usize,
    pub height: usize,
    pub channels: usize,
}

impl<'a> ImageRef<'a> {
    /// Validated view of `data` as `height x width x channels`.
    pub fn new(data: &'a [f32], width: usize, height: usize, channels: usize) -> Result<Self> {
        if channels == 0 || width == 0 || height == 0 {
            return Err(invalid(
                "image",
                format!("{height}x{width}x{channels}"),
                "a non-empty image",
            ));
        }
        check_len(
            "image",
            data,
            width * height * channels,
            "height * width * channels",
        )?;
        Ok(Self {
            data,
            width,
            height,
            channels,
        })
    }
}

/// The per-row recipe of an undistortion map: source pixel of every destination pixel.
struct MapPlan<'a> {
    src: &'a Camera,
    /// Normalised x of every destination column (x depends only on the column, y on the row).
    xs: Vec<f64>,
    cy: f64,
    fy: f64,
    rinv: Option<Matrix3<f64>>,
}

impl<'a> MapPlan<'a> {
    fn new(src: &'a Camera, dst: &Intrinsics, rotation: Option<&Matrix3<f64>>) -> Self {
        Self {
            src,
            xs: (0..dst.width)
                .map(|u| (u as f64 - dst.cx) / dst.fx)
                .collect(),
            cy: dst.cy,
            fy: dst.fy,
            rinv: rotation.map(|r| r.transpose()),
        }
    }

    /// Writes interleaved source `x, y` of destination row `v` into `row` (`2 * width`).
    fn fill_row(&self, v: usize, row: &mut [f32]) {
        let y = (v as f64 - self.cy) / self.fy;
        if let Some(ri) = &self.rinv {
            for (m, &x) in row.chunks_exact_mut(2).zip(&self.xs) {
                let q = ri * Vector3::new(x, y, 1.0);
                m.copy_from_slice(&source_pixel::<true>(self.src, q.x / q.z, q.y / q.z));
            }
            return;
        }
        let rational = self.src.distortion.is_rational();
        #[cfg(target_arch = "x86_64")]
        if has_avx2_fma() {
            // SAFETY: the running CPU supports AVX2 and FMA, checked just above.
            unsafe { map_row_avx2(self.src, &self.xs, y, row, rational) };
            return;
        }
        map_row(self.src, &self.xs, y, row, rational);
    }
}

#[cfg(target_arch = "x86_64")]
#[inline]
fn has_avx2_fma() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn map_row_avx2(src: &Camera, xs: &[f64], y: f64, row: &mut [f32], rational: bool) {
    map_row(src, xs, y, row, rational);
}

#[inline(always)]
fn map_row(src: &Camera, xs: &[f64], y: f64, row: &mut [f32], rational: bool) {
    // Without k4..k6 the rational division is compiled out of the loop.
    if rational {
        for (m, &x) in row.chunks_exact_mut(2).zip(xs) {
            m.copy_from_slice(&source_pixel::<true>(src, x, y));
        }
    } else {
        for (m, &x) in row.chunks_exact_mut(2).zip(xs) {
            m.copy_from_slice(&source_pixel::<false>(src, x, y));
        }
    }
}

#[inline(always)]
fn source_pixel<const RATIONAL: bool>(src: &Camera, x: f64, y: f64) -> [f32; 2] {
    let [xd, yd] = src.distortion.distort_with::<RATIONAL>(x, y);
    let [su, sv] = src.intrinsics.to_pixel(xd, yd);
    [su as f32, sv as f32]
}

/// For every pixel of the ideal destination lattice `dst` (no distortion), the source pixel of
/// `src` that sees the same ray, as interleaved `x, y` values row-major (`2 * dst.len()`).
/// `rotation` rotates destination rays into the source frame's orientation (`R` of OpenCV's
/// `initUndistortRectifyMap`: source ray = `R^T` · destination ray); `None` means identity.
pub fn undistort_map(src: &Camera, dst: &Intrinsics, rotation: Option<&Matrix3<f64>>) -> Vec<f32> {
    let plan = MapPlan::new(src, dst, rotation);
    let mut map = vec![0.0f32; 2 * dst.len()];
    map.par_chunks_mut(2 * dst.width)
        .enumerate()
        .for_each(|(v, row)| plan.fill_row(v, row));
    map
}

/// Samples `img` at the interleaved `x, y` positions of `map`, producing a
/// `map.len() / 2 x channels` image. Samples outside the source give NaN.
pub fn remap(
    img: ImageRef<'_>,
    map: &[f32],
    out_width: usize,
    interp: Interpolation,
) -> Result<Vec<f32>> {
    if out_width == 0 || !map.len().is_multiple_of(2 * out_width) {
        return Err(invalid(
            "map",
            map.len(),
            format!("a multiple of 2 x the output width {out_width}"),
        ));
    }
    let c = img.channels;
    let mut out = vec![0.0f32; map.len() / 2 * c];
    out.par_chunks_mut(out_width * c)
        .zip(map.par_chunks(2 * out_width))
        .for_each(|(orow, mrow)| remap_row_any(&img, mrow, orow, interp));
    Ok(out)
}

/// Undistorts (and optionally rectifies) `img`, seen by `src`, onto the ideal camera `dst`:
/// [`undistort_map`] and [`remap`] fused row by row, so the map is never materialised.
pub fn undistort_image(
    img: ImageRef<'_>,
    src: &Camera,
    dst: &Intrinsics,
    rotation: Option<&Matrix3<f64>>,
    interp: Interpolation,
) -> Result<Vec<f32>> {
    if (img.width, img.height) != (src.intrinsics.width, src.intrinsics.height) {
        return Err(invalid(
            "image",
            format!("{}x{}", img.width, img.height),
            format!(
                "the source camera's size {}x{}",
                src.intrinsics.width, src.intrinsics.height
            ),
        ));
    }
    let plan = MapPlan::new(src, dst, rotation);
    let mut out = vec![0.0f32; dst.len() * img.channels];
    out.par_chunks_mut(dst.width * img.channels)
        .enumerate()
        .for_each_init(
            || vec![0.0f32; 2 * dst.width],
            |mrow, (v, orow)| {
                plan.fill_row(v, mrow);
                remap_row_any(&img, mrow, orow, interp);
            },
        );
    Ok(out)
}

fn remap_row_any(img: &ImageRef<'_>, mrow: &[f32], orow: &mut [f32], interp: Interpolation) {
    #[cfg(target_arch = "x86_64")]
    if has_avx2_fma() {
        // SAFETY: the running CPU supports AVX2 and FMA, checked just above.
        unsafe { remap_row_avx2(img, mrow, orow, interp) };
        return;
    }
    remap_row_channels(img, mrow, orow, interp);
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn remap_row_avx2(img: &ImageRef<'_>, mrow: &[f32], orow: &mut [f32], interp: Interpolation) {
    remap_row_channels(img, mrow, orow, interp);
}

#[inline(always)]
fn remap_row_channels(img: &ImageRef<'_>, mrow: &[f32], orow: &mut [f32], interp: Interpolation) {
    match img.channels {
        // Constant channel counts let the compiler unroll the per-channel loops.
        1 => remap_row(img, 1, mrow, orow, interp),
        3 => remap_row(img, 3, mrow, orow, interp),
        4 => remap_row(img, 4, mrow, orow, interp),
        c => remap_row(img, c, mrow, orow, interp),
    }
}

#[inline(always)]
fn remap_row(img: &ImageRef<'_>, c: usize, mrow: &[f32], orow: &mut [f32], interp: Interpolation) {
    let (w, h) = (img.width, img.height);
    let (wf, hf) = (w as f32, h as f32);
    for (o, xy) in orow.chunks_exact_mut(c).zip(mrow.chunks_exact(2)) {
        let (x, y) = (xy[0], xy[1]);
        match interp {
            Interpolation::Nearest => {
                let (xr, yr) = (x.round(), y.round());
                if xr >= 0.0 && yr >= 0.0 && xr < wf && yr < hf {
                    let i = (yr as usize * w + xr as usize) * c;
                    o.copy_from_slice(&img.data[i..i + c]);
                } else {
                    o.fill(f32::NAN);
                }
            }
            Interpolation::Linear => bilinear(img.data, w, h, c, x, y, o),
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
        o.fill(f32::NAN);
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
            let out = remap(ImageRef::new(&img, 32, 20, 2).unwrap(), &map, 32, interp).unwrap();
            assert_eq!(out, img);
            let fused = undistort_image(
                ImageRef::new(&img, 32, 20, 2).unwrap(),
                &cam,
                &k,
                None,
                interp,
            );
            assert_eq!(fused.unwrap(), img);
        }
    }

    #[test]
    fn bilinear_is_exact_on_linear_ramps_and_skips_zero_weight_nan() {
        let (w, h) = (8, 6);
        let mut img: Vec<f32> = (0..w * h)
            .map(|i| (i % w) as f32 * 2.0 + (i / w) as f32)
            .collect();
        let map = vec![2.25f32, 3.5, 7.0, 5.0, -0.1, 1.0];
        let view = ImageRef::new(&img, w, h, 1).unwrap();
        let out = remap(view, &map, 1, Interpolation::Linear).unwrap();
        assert!((out[0] - (4.5 + 3.5)).abs() < 1e-5);
        assert!((out[1] - 19.0).abs() < 1e-5);
        assert!(out[2].is_nan());
        img[3 * w + 3] = f32::NAN;
        let view = ImageRef::new(&img, w, h, 1).unwrap();
        let out = remap(view, &[2.0, 3.0, 2.5, 3.0], 1, Interpolation::Linear).unwrap();
        assert!(out[0].is_finite() && out[1].is_nan());
    }
}
