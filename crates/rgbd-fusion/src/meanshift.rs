//! Mean-shift filtering of an RGB image: the result of OpenCV's `pyrMeanShiftFiltering` (default
//! pyramid level 1, 5 iterations, ε = 1), bit for bit, in parallel rows.
//!
//! Per pixel, the joint spatial–colour mean shift (Comaniciu and Meer 2002) repeatedly moves a
//! point `(x, y, colour)` to the mean of the pixels within `spatial_radius` pixels (a square
//! window) whose colour lies within `color_radius` of its colour (a ball in RGB), and writes the
//! converged colour. OpenCV's choices are kept exactly so a segmentation built on the filtered
//! image does not change when the implementation does: integer sums, means rounded half to even,
//! the window rounded from `x - sp` as a float, the stop test `|Δx| + |Δy| + |Δc|² ≤ ε`, and the
//! pyramid: the filter runs first on the 2×-reduced image (Gaussian `pyrDown`, radius halved), the
//! result is expanded (`pyrUp`), and only the fine pixels near a coarse colour edge (a coarse
//! neighbour at least `max(sr², 16)` away in squared colour, the mask dilated by one pixel) are
//! filtered again at full resolution; the rest keep the expanded colour.
//!
//! Cost: the fine pass dominates — (masked pixels) × (iterations) × `(2 sp + 1)²` window taps;
//! the tap loop runs branch-free over planar channel rows (vectorised, AVX2 where available).

use rayon::prelude::*;
use rgbd_error::{check_interrupt, image_len};
use rgbd_geom::error::{check_len, invalid, Result};

use crate::check::MAX_RADIUS;

/// Parameters of [`mean_shift_filter`]; the defaults are OpenCV's besides the two radii.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeanShiftParams {
    /// Spatial window half-size at full resolution (pixels; halved per pyramid level, at least 1).
    pub spatial_radius: f64,
    /// Colour radius (8-bit levels; Euclidean in RGB).
    pub color_radius: f64,
    /// Pyramid levels below full resolution (OpenCV `maxLevel`, default 1, at most 8).
    pub max_level: usize,
    /// Iterations per pixel (OpenCV's term criterion count, 1–100, default 5).
    pub max_iter: usize,
    /// Stop when `|Δx| + |Δy| + |Δcolour|²` falls to this (default 1).
    pub epsilon: f64,
}

impl Default for MeanShiftParams {
    fn default() -> Self {
        Self {
            spatial_radius: 8.0,
            color_radius: 16.0,
            max_level: 1,
            max_iter: 5,
            epsilon: 1.0,
        }
    }
}

/// Most pyramid levels (OpenCV's limit).
pub const MAX_LEVEL: usize = 8;

impl MeanShiftParams {
    /// Checks every field.
    pub fn validate(&self) -> Result<()> {
        let sp = self.spatial_radius;
        if !(sp >= 1.0) || sp > MAX_RADIUS as f64 {
            return Err(invalid(
                "spatial_radius",
                sp,
                format!("1..={MAX_RADIUS} pixels"),
            ));
        }
        if !(self.color_radius > 0.0) || !self.color_radius.is_finite() {
            return Err(invalid(
                "color_radius",
                self.color_radius,
                "a finite value > 0",
            ));
        }
        if self.max_level > MAX_LEVEL {
            return Err(invalid(
                "max_level",
                self.max_level,
                format!("0..={MAX_LEVEL}"),
            ));
        }
        if !(1..=100).contains(&self.max_iter) {
            return Err(invalid("max_iter", self.max_iter, "1..=100"));
        }
        if !(self.epsilon >= 0.0) || !self.epsilon.is_finite() {
            return Err(invalid("epsilon", self.epsilon, "a finite value >= 0"));
        }
        Ok(())
    }
}

/// An RGB u8 image with its size.
struct Img {
    data: Vec<u8>,
    w: usize,
    h: usize,
}

/// OpenCV's `BORDER_REFLECT_101` index (`gfedcb|abcdefgh|gfedcba`).
fn reflect101(p: isize, n: usize) -> usize {
    if n == 1 {
        return 0;
    }
    let n = n as isize;
    let mut p = p;
    while p < 0 || p >= n {
        if p < 0 {
            p = -p;
        }
        if p >= n {
            p = 2 * n - 2 - p;
        }
    }
    p as usize
}

/// OpenCV `pyrDown`: 5×5 binomial blur (`[1 4 6 4 1] / 16` per axis, reflect-101 border) and
/// every second pixel, rounded `(s + 128) >> 8`; size `((w + 1) / 2, (h + 1) / 2)`.
fn pyr_down(src: &Img) -> Img {
    const K: [u32; 5] = [1, 4, 6, 4, 1];
    let (w2, h2) = (src.w.div_ceil(2), src.h.div_ceil(2));
    let xs: Vec<[usize; 5]> = (0..w2)
        .map(|x| std::array::from_fn(|k| reflect101(2 * x as isize + k as isize - 2, src.w)))
        .collect();
    // Horizontal pass on every source row (3 channels interleaved).
    let hrows: Vec<u32> = (0..src.h)
        .flat_map(|y| {
            let row = &src.data[3 * y * src.w..3 * (y + 1) * src.w];
            xs.iter().flat_map(move |ix| {
                (0..3).map(move |c| (0..5).map(|k| K[k] * u32::from(row[3 * ix[k] + c])).sum())
            })
        })
        .collect();
    let mut data = vec![0u8; 3 * w2 * h2];
    for (y, out) in data.chunks_mut(3 * w2).enumerate() {
        let iy: [usize; 5] =
            std::array::from_fn(|k| reflect101(2 * y as isize + k as isize - 2, src.h));
        for (i, o) in out.iter_mut().enumerate() {
            let s: u32 = (0..5).map(|k| K[k] * hrows[iy[k] * 3 * w2 + i]).sum();
            *o = ((s + 128) >> 8) as u8;
        }
    }
    Img { data, w: w2, h: h2 }
}

/// OpenCV `pyrUp` of `src` to `w x h` (`w <= 2 src.w`, `h <= 2 src.h`): `[1 6 1] / 8` at even and
/// `[4 4] / 8` at odd positions per axis, rounded `(s + 32) >> 6`. Borders as OpenCV: reflect-101
/// at the start, the last pixel repeated at the end.
fn pyr_up(src: &Img, w: usize, h: usize) -> Vec<u8> {
    let (sw, sh) = (src.w, src.h);
    // Horizontal pass: 2 sw columns per source row.
    let hrow = |y: usize| -> Vec<u32> {
        let s = |x: usize, c: usize| u32::from(src.data[3 * (y * sw + x) + c]);
        let mut row = vec![0u32; 3 * 2 * sw];
        for c in 0..3 {
            if sw == 1 {
                row[c] = 8 * s(0, c);
                row[3 + c] = 8 * s(0, c);
                continue;
            }
            for x in 0..sw {
                let (even, odd) = if x == 0 {
                    (6 * s(0, c) + 2 * s(1, c), 4 * (s(0, c) + s(1, c)))
                } else if x == sw - 1 {
                    (s(x - 1, c) + 7 * s(x, c), 8 * s(x, c))
                } else {
                    (
                        s(x - 1, c) + 6 * s(x, c) + s(x + 1, c),
                        4 * (s(x, c) + s(x + 1, c)),
                    )
                };
                row[3 * 2 * x + c] = even;
                row[3 * (2 * x + 1) + c] = odd;
            }
        }
        row
    };
    let rows: Vec<Vec<u32>> = (0..sh).map(hrow).collect();
    // Source row of ring position sy (OpenCV: reflect-101 of 2 sy within 2 sh, halved).
    let at = |sy: isize| reflect101(2 * sy, 2 * sh) / 2;
    let mut out = vec![0u8; 3 * w * h];
    for y in 0..h {
        let sy = (y / 2) as isize;
        let (r0, r1, r2) = (&rows[at(sy - 1)], &rows[at(sy)], &rows[at(sy + 1)]);
        let orow = &mut out[3 * y * w..3 * (y + 1) * w];
        for (i, o) in orow.iter_mut().enumerate() {
            let s = if y % 2 == 0 {
                r0[i] + 6 * r1[i] + r2[i]
            } else {
                4 * (r1[i] + r2[i])
            };
            *o = ((s + 32) >> 6) as u8;
        }
    }
    out
}

/// OpenCV's re-filter mask of the finer level: for each interior coarse pixel (i, j) with a
/// neighbour at least `thresh` away in squared colour, fine pixel (2i + 1, 2j − 1) (sic), then a
/// 3×3 dilation.
fn refine_mask(coarse: &Img, w: usize, h: usize, thresh: i32) -> Vec<bool> {
    let (cw, ch) = (coarse.w, coarse.h);
    let px = |y: usize, x: usize| -> [i32; 3] {
        let i = 3 * (y * cw + x);
        [0, 1, 2].map(|c| i32::from(coarse.data[i + c]))
    };
    let mut seed = vec![false; w * h];
    for i in 1..ch.saturating_sub(1) {
        for j in 1..cw.saturating_sub(1) {
            let c = px(i, j);
            let far = [
                (i, j - 1),
                (i, j + 1),
                (i - 1, j - 1),
                (i - 1, j),
                (i - 1, j + 1),
                (i + 1, j - 1),
                (i + 1, j),
                (i + 1, j + 1),
            ]
            .iter()
            .any(|&(y, x)| {
                let n = px(y, x);
                (0..3).map(|k| (c[k] - n[k]).pow(2)).sum::<i32>() >= thresh
            });
            seed[(2 * i + 1) * w + 2 * j - 1] = far;
        }
    }
    let mut mask = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let (y0, y1) = (y.saturating_sub(1), (y + 1).min(h - 1));
            let (x0, x1) = (x.saturating_sub(1), (x + 1).min(w - 1));
            mask[y * w + x] = (y0..=y1).any(|yy| seed[yy * w + x0..=yy * w + x1].contains(&true));
        }
    }
    mask
}

/// The image as three planar `i32` channels (the tap loop's layout).
struct Planes {
    c: [Vec<i32>; 3],
    w: usize,
    h: usize,
    stride: usize,
}

impl Planes {
    fn new(img: &Img) -> Self {
        let stride = img.w;
        let c = [0, 1, 2].map(|k| {
            let mut v = vec![0i32; stride * img.h];
            for (row, src) in v
                .chunks_exact_mut(stride)
                .zip(img.data.chunks_exact(3 * img.w))
            {
                for (o, px) in row.iter_mut().zip(src.chunks_exact(3)) {
                    *o = i32::from(px[k]);
                }
            }
            v
        });
        Self {
            c,
            w: img.w,
            h: img.h,
            stride,
        }
    }

    /// `(count, Σr, Σg, Σb, Σx, Σy)` over the window `[minx, maxx] x [miny, maxy]` of the pixels
    /// within `isr2` (squared colour distance) of `c`. (Lane-wise accumulators over whole
    /// 8-lane groups, reduced once per window, measured 3x slower than these row loops.)
    #[inline(always)]
    fn window_sums(&self, x: (i32, i32), y: (i32, i32), c: [i32; 3], isr2: i32) -> [i32; 6] {
        let mut acc = [0i32; 6];
        let (minx, maxx) = x;
        for yy in y.0..=y.1 {
            let base = yy as usize * self.stride;
            let (a, b) = (base + minx as usize, base + maxx as usize + 1);
            let (r, g, bl) = (&self.c[0][a..b], &self.c[1][a..b], &self.c[2][a..b]);
            let (mut n, mut s0, mut s1, mut s2, mut sx) = (0i32, 0i32, 0i32, 0i32, 0i32);
            for i in 0..r.len().min(g.len()).min(bl.len()) {
                let (t0, t1, t2) = (r[i], g[i], bl[i]);
                let (d0, d1, d2) = (t0 - c[0], t1 - c[1], t2 - c[2]);
                let m = -i32::from(d0 * d0 + d1 * d1 + d2 * d2 <= isr2);
                n -= m;
                s0 += t0 & m;
                s1 += t1 & m;
                s2 += t2 & m;
                sx += (minx + i as i32) & m;
            }
            acc[0] += n;
            acc[1] += s0;
            acc[2] += s1;
            acc[3] += s2;
            acc[4] += sx;
            acc[5] += yy * n;
        }
        acc
    }
}

/// Round half to even, as OpenCV's `cvRound` on x86.
#[inline(always)]
fn round_even(v: f64) -> i32 {
    v.round_ties_even() as i32
}

/// One level's constants.
struct Level<'a> {
    src: &'a Planes,
    sp: f32,
    isr2: i32,
    max_iter: usize,
    epsilon: f64,
}

impl Level<'_> {
    /// The converged colour of pixel (x, y).
    #[inline(always)]
    fn shift(&self, x: usize, y: usize) -> [u8; 3] {
        let p = self.src;
        let (w, h) = (p.w as i32, p.h as i32);
        let (mut x0, mut y0) = (x as i32, y as i32);
        let i = y * p.stride + x;
        let mut c = [p.c[0][i], p.c[1][i], p.c[2][i]];
        for _ in 0..self.max_iter {
            let minx = (f64::from(x0 as f32 - self.sp).round_ties_even() as i32).max(0);
            let miny = (f64::from(y0 as f32 - self.sp).round_ties_even() as i32).max(0);
            let maxx = (f64::from(x0 as f32 + self.sp).round_ties_even() as i32).min(w - 1);
            let maxy = (f64::from(y0 as f32 + self.sp).round_ties_even() as i32).min(h - 1);
            let acc = p.window_sums((minx, maxx), (miny, maxy), c, self.isr2);
            if acc[0] == 0 {
                break;
            }
            let inv = 1.0 / f64::from(acc[0]);
            let x1 = round_even(f64::from(acc[4]) * inv);
            let y1 = round_even(f64::from(acc[5]) * inv);
            let s = [1, 2, 3].map(|k| round_even(f64::from(acc[k]) * inv));
            let moved = (x1 - x0).abs()
                + (y1 - y0).abs()
                + (0..3).map(|k| (s[k] - c[k]).pow(2)).sum::<i32>();
            let stop = (x0 == x1 && y0 == y1) || f64::from(moved) <= self.epsilon;
            (x0, y0, c) = (x1, y1, s);
            if stop {
                break;
            }
        }
        c.map(|v| v as u8)
    }

    /// Filters one output row (only where `mask` is set, when given).
    #[inline(always)]
    fn row(&self, y: usize, out: &mut [u8], mask: Option<&[bool]>) {
        for (x, o) in out.chunks_exact_mut(3).enumerate() {
            if mask.is_none_or(|m| m[x]) {
                o.copy_from_slice(&self.shift(x, y));
            }
        }
    }

    fn run_row(&self, y: usize, out: &mut [u8], mask: Option<&[bool]>) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the running CPU supports AVX2, checked just above.
            unsafe { self.row_avx2(y, out, mask) };
            return;
        }
        self.row(y, out, mask);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn row_avx2(&self, y: usize, out: &mut [u8], mask: Option<&[bool]>) {
        self.row(y, out, mask);
    }
}

/// Mean-shift filtered copy of `image` (`H x W x 3` u8), equal to OpenCV's
/// `pyrMeanShiftFiltering(image, sp, sr, maxLevel, (MAX_ITER + EPS, max_iter, epsilon))`.
pub fn mean_shift_filter(
    image: &[u8],
    width: usize,
    height: usize,
    params: &MeanShiftParams,
) -> Result<Vec<u8>> {
    params.validate()?;
    let n = image_len("image", width, height)?;
    check_len("image", image, 3 * n, "H x W x 3")?;
    let isr2 = (params.color_radius * params.color_radius).round_ties_even() as i32;
    let mut pyramid = vec![Img {
        data: image.to_vec(),
        w: width,
        h: height,
    }];
    for level in 1..=params.max_level {
        let down = pyr_down(&pyramid[level - 1]);
        pyramid.push(down);
    }
    let mut coarse: Option<Img> = None;
    for level in (0..=params.max_level).rev() {
        let src = &pyramid[level];
        let planes = Planes::new(src);
        let sp = ((params.spatial_radius / f64::from(1u32 << level)) as f32).max(1.0);
        let lv = Level {
            src: &planes,
            sp,
            isr2,
            max_iter: params.max_iter,
            epsilon: params.epsilon,
        };
        let (mut dst, mask) = match &coarse {
            Some(c) => (
                pyr_up(c, src.w, src.h),
                Some(refine_mask(c, src.w, src.h, isr2.max(16))),
            ),
            None => (vec![0u8; 3 * src.w * src.h], None),
        };
        let w = src.w;
        dst.par_chunks_mut(3 * w)
            .enumerate()
            .try_for_each(|(y, out)| {
                check_interrupt()?;
                lv.run_row(y, out, mask.as_deref().map(|m| &m[y * w..(y + 1) * w]));
                Ok(())
            })?;
        coarse = Some(Img {
            data: dst,
            w: src.w,
            h: src.h,
        });
    }
    Ok(coarse.map(|c| c.data).unwrap_or_default())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflect101_matches_opencv() {
        let got: Vec<usize> = (-3..8).map(|p| reflect101(p, 5)).collect();
        assert_eq!(got, vec![3, 2, 1, 0, 1, 2, 3, 4, 3, 2, 1]);
        assert_eq!(reflect101(-2, 1), 0);
    }

    #[test]
    fn a_flat_image_stays_flat() {
        // Odd sizes exercise the pyramid's cropped borders.
        for (w, h) in [(40, 30), (17, 9), (1, 1), (2, 5)] {
            let img: Vec<u8> = (0..w * h).flat_map(|_| [10, 20, 30]).collect();
            let out = mean_shift_filter(&img, w, h, &MeanShiftParams::default()).unwrap();
            assert_eq!(out, img, "{w}x{h}");
        }
    }

    #[test]
    fn colours_within_the_radius_merge_to_their_mean() {
        // Two interleaved colours 6 levels apart (within sr = 16) become their mean.
        let (w, h) = (24, 24);
        let img: Vec<u8> = (0..w * h)
            .flat_map(|i| {
                if (i % w + i / w) % 2 == 0 {
                    [100, 100, 100]
                } else {
                    [106, 106, 106]
                }
            })
            .collect();
        let p = MeanShiftParams {
            max_level: 0,
            ..MeanShiftParams::default()
        };
        let out = mean_shift_filter(&img, w, h, &p).unwrap();
        let centre = 3 * (12 * w + 12);
        assert_eq!(&out[centre..centre + 3], &[103, 103, 103]);
    }

    #[test]
    fn bad_parameters_are_refused() {
        let img = vec![0u8; 3 * 16];
        for p in [
            MeanShiftParams {
                spatial_radius: 0.5,
                ..MeanShiftParams::default()
            },
            MeanShiftParams {
                color_radius: f64::NAN,
                ..MeanShiftParams::default()
            },
            MeanShiftParams {
                max_level: 9,
                ..MeanShiftParams::default()
            },
            MeanShiftParams {
                max_iter: 0,
                ..MeanShiftParams::default()
            },
        ] {
            assert!(mean_shift_filter(&img, 4, 4, &p).is_err());
        }
        assert!(mean_shift_filter(&img, 5, 4, &MeanShiftParams::default()).is_err());
    }
}
