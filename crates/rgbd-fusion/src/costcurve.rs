//! Statistics of the pointwise stereo matching-cost curve, the input of the heuristic stereo
//! confidence (`rgbd_rs.fusion.confidence.stereo_confidence`).
//!
//! The cost of reference pixel p at integer disparity d is the mean absolute grey difference
//! between the reference and the target shifted by `sign * d`, over a `block x block` box
//! (replicated image border; a target pixel off the image counts 255 and a centre whose target
//! is off the image costs +inf). For every pixel the kernel returns the curve's minimum `c1`,
//! its minimum `c2` over the disparities more than 1 away from the first minimum's, and its
//! value at a given disparity (rounded half to even). The values equal the numpy/OpenCV
//! reference bit for bit: the box sums are integers, scaled by `1 / block²` in f64 and rounded
//! to f32 as `cv2.blur` does.
//!
//! Cost: `(max_disparity + 1) x H x W x (block + 4)` integer additions, in rows of 8 lanes,
//! parallel over bands of rows; the band's whole curve (`(D + 1) x BAND x W` u32) stays in cache.

use rayon::prelude::*;
use rgbd_error::{check_interrupt, image_len};
use rgbd_geom::error::{check_len, invalid, Result};

/// Output rows per parallel task.
const BAND: usize = 16;
/// Largest box side accepted.
pub const MAX_BLOCK: usize = 31;

/// `c1`, `c2` and the cost at the given disparity, each `H x W` (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct CostCurveStats {
    /// The curve's minimum.
    pub best: Vec<f32>,
    /// The minimum more than one disparity away from the first minimum's (+inf if none).
    pub second: Vec<f32>,
    /// The cost at the rounded given disparity (NaN where that is NaN or outside the search).
    pub at: Vec<f32>,
}

/// The statistics of the cost curve of grey `reference` against grey `target` (`H x W` u8) at
/// disparities `0..=max_disparity`, the target pixel of x lying at `x + target_sign * d`.
#[allow(clippy::too_many_arguments)]
pub fn cost_curve_stats(
    reference: &[u8],
    target: &[u8],
    disparity: &[f32],
    width: usize,
    height: usize,
    target_sign: i8,
    max_disparity: usize,
    block: usize,
) -> Result<CostCurveStats> {
    let n = image_len("reference", width, height)?;
    check_len("reference", reference, n, "H x W")?;
    check_len("target", target, n, "H x W of the reference's size")?;
    check_len("disparity", disparity, n, "H x W of the reference's size")?;
    if target_sign != 1 && target_sign != -1 {
        return Err(invalid("target_sign", target_sign, "+1 or -1"));
    }
    if max_disparity == 0 || max_disparity >= width {
        return Err(invalid(
            "max_disparity",
            max_disparity,
            format!("1..{width} (below the image width)"),
        ));
    }
    if block == 0 || block > MAX_BLOCK {
        return Err(invalid("block", block, format!("1..={MAX_BLOCK}")));
    }
    let mut best = vec![0f32; n];
    let mut second = vec![0f32; n];
    let mut at = vec![0f32; n];
    let ctx = Ctx {
        r: reference,
        t: target,
        disp: disparity,
        w: width,
        h: height,
        sign: target_sign,
        dmax: max_disparity,
        k: block,
        scale: 1.0 / (block * block) as f64,
    };
    best.par_chunks_mut(BAND * width)
        .zip(second.par_chunks_mut(BAND * width))
        .zip(at.par_chunks_mut(BAND * width))
        .enumerate()
        .try_for_each(|(band, ((b, s), a))| {
            check_interrupt()?;
            ctx.band(band * BAND, b, s, a);
            Ok(())
        })?;
    Ok(CostCurveStats { best, second, at })
}

struct Ctx<'a> {
    r: &'a [u8],
    t: &'a [u8],
    disp: &'a [f32],
    w: usize,
    h: usize,
    sign: i8,
    dmax: usize,
    k: usize,
    scale: f64,
}

impl Ctx<'_> {
    /// The box rows of output row y: `y - k/2 ..= y - k/2 + k - 1`, clamped (replicate).
    fn src_row(&self, y: isize) -> usize {
        y.clamp(0, self.h as isize - 1) as usize
    }

    /// Fills `row` with the horizontal box sums of the absolute differences of source row y at
    /// disparity d (255 where the target is off the image; replicated border). `ext` holds the
    /// differences with the border replicated, `k - 1` entries longer than the row.
    fn hsum(&self, y: usize, d: usize, ext: &mut [u32], row: &mut [u32]) {
        let w = self.w;
        let lo = self.k / 2;
        let (rr, tt) = (&self.r[y * w..(y + 1) * w], &self.t[y * w..(y + 1) * w]);
        let diff = &mut ext[lo..lo + w];
        diff.fill(255);
        if self.sign > 0 {
            for ((o, &a), &b) in diff[..w - d].iter_mut().zip(&rr[..w - d]).zip(&tt[d..]) {
                *o = u32::from(a.abs_diff(b));
            }
        } else {
            for ((o, &a), &b) in diff[d..].iter_mut().zip(&rr[d..]).zip(&tt[..w - d]) {
                *o = u32::from(a.abs_diff(b));
            }
        }
        let (first, last) = (ext[lo], ext[lo + w - 1]);
        ext[..lo].fill(first);
        ext[lo + w..].fill(last);
        row.copy_from_slice(&ext[..w]);
        for i in 1..self.k {
            for (o, &v) in row.iter_mut().zip(&ext[i..i + w]) {
                *o += v;
            }
        }
    }

    /// The statistics of output rows `y0..y0 + rows` (the chunk lengths give the row count).
    fn band(&self, y0: usize, best: &mut [f32], second: &mut [f32], at: &mut [f32]) {
        let w = self.w;
        let rows = best.len() / w;
        let nd = self.dmax + 1;
        let lo = (self.k / 2) as isize;
        // Source rows the band's boxes read, clamped; horizontal sums per disparity.
        let first = y0 as isize - lo;
        let last = (y0 + rows - 1) as isize - lo + self.k as isize - 1;
        let nsrc = (last - first + 1) as usize;
        let mut hs = vec![0u32; nsrc * w];
        let mut ext = vec![0u32; w + self.k - 1];
        // curve[(d * rows + r) * w + x]: the box sum of output row r at disparity d.
        let mut curve = vec![0u32; nd * rows * w];
        for d in 0..nd {
            for (i, row) in hs.chunks_exact_mut(w).enumerate() {
                let y = self.src_row(first + i as isize);
                self.hsum(y, d, &mut ext, row);
            }
            for r in 0..rows {
                let out = &mut curve[(d * rows + r) * w..(d * rows + r + 1) * w];
                out.copy_from_slice(&hs[r * w..(r + 1) * w]);
                for i in 1..self.k {
                    let src = &hs[(r + i) * w..(r + i + 1) * w];
                    for (o, &v) in out.iter_mut().zip(src) {
                        *o += v;
                    }
                }
            }
        }
        let cost = |sum: u32| (f64::from(sum) * self.scale) as f32;
        // The in-image columns at disparity d: x + sign d within the image.
        let cols = |d: usize| if self.sign > 0 { 0..w - d } else { d..w };
        let mut c1 = vec![u32::MAX; w];
        let mut arg = vec![0u32; w];
        let mut c2 = vec![u32::MAX; w];
        for r in 0..rows {
            let y = y0 + r;
            let curve_at = |d: usize| &curve[(d * rows + r) * w..(d * rows + r + 1) * w];
            c1.fill(u32::MAX);
            c2.fill(u32::MAX);
            // Vectorised over x: the first minimum (strictly smaller wins, as the reference).
            for d in 0..nd {
                let xs = cols(d);
                let v = &curve_at(d)[xs.clone()];
                for ((m, a), &c) in c1[xs.clone()].iter_mut().zip(&mut arg[xs]).zip(v) {
                    let better = c < *m;
                    *m = if better { c } else { *m };
                    *a = if better { d as u32 } else { *a };
                }
            }
            for d in 0..nd {
                let xs = cols(d);
                let v = &curve_at(d)[xs.clone()];
                for ((m, &a), &c) in c2[xs.clone()].iter_mut().zip(&arg[xs]).zip(v) {
                    let far = (d as u32).abs_diff(a) > 1;
                    *m = if far { (*m).min(c) } else { *m };
                }
            }
            let row = r * w..(r + 1) * w;
            for (x, ((b, s), a)) in best[row.clone()]
                .iter_mut()
                .zip(&mut second[row.clone()])
                .zip(&mut at[row])
                .enumerate()
            {
                *b = cost(c1[x]);
                *s = if c2[x] == u32::MAX {
                    f32::INFINITY
                } else {
                    cost(c2[x])
                };
                let want = self.disp[y * w + x].round_ties_even();
                *a = if want >= 0.0 && want <= self.dmax as f32 {
                    let d = want as usize;
                    if cols(d).contains(&x) {
                        cost(curve_at(d)[x])
                    } else {
                        f32::INFINITY
                    }
                } else {
                    f32::NAN
                };
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definition, written plainly: the whole cost volume in f64.
    #[allow(clippy::too_many_arguments)]
    fn reference(
        r: &[u8],
        t: &[u8],
        disp: &[f32],
        w: usize,
        h: usize,
        sign: i8,
        dmax: usize,
        k: usize,
    ) -> CostCurveStats {
        let lo = (k / 2) as isize;
        let clamp = |v: isize, n: usize| v.clamp(0, n as isize - 1) as usize;
        let vol: Vec<Vec<f32>> = (0..=dmax)
            .map(|d| {
                let diff = |y: usize, x: usize| -> f64 {
                    let tx = x as isize + sign as isize * d as isize;
                    if tx < 0 || tx >= w as isize {
                        255.0
                    } else {
                        f64::from(r[y * w + x].abs_diff(t[y * w + tx as usize]))
                    }
                };
                (0..w * h)
                    .map(|i| {
                        let (y, x) = (i / w, i % w);
                        let tx = x as isize + sign as isize * d as isize;
                        if tx < 0 || tx >= w as isize {
                            return f32::INFINITY;
                        }
                        let mut s = 0.0;
                        for dy in 0..k as isize {
                            for dx in 0..k as isize {
                                s += diff(
                                    clamp(y as isize - lo + dy, h),
                                    clamp(x as isize - lo + dx, w),
                                );
                            }
                        }
                        (s / (k * k) as f64) as f32
                    })
                    .collect()
            })
            .collect();
        let n = w * h;
        let (mut best, mut second, mut at) = (vec![0f32; n], vec![0f32; n], vec![f32::NAN; n]);
        for i in 0..n {
            let (mut c1, mut arg) = (f32::INFINITY, 0);
            for (d, v) in vol.iter().enumerate() {
                if v[i] < c1 {
                    c1 = v[i];
                    arg = d;
                }
            }
            best[i] = c1;
            second[i] = (0..=dmax)
                .filter(|&d| d.abs_diff(arg) > 1)
                .map(|d| vol[d][i])
                .fold(f32::INFINITY, f32::min);
            let want = disp[i].round_ties_even();
            if want >= 0.0 && want <= dmax as f32 {
                at[i] = vol[want as usize][i];
            }
        }
        CostCurveStats { best, second, at }
    }

    #[test]
    fn equals_the_plain_definition() {
        let (w, h) = (37, 21);
        let r: Vec<u8> = (0..w * h)
            .map(|i| ((i * 7919 + i / w * 13) % 251) as u8)
            .collect();
        let t: Vec<u8> = (0..w * h)
            .map(|i| r[(i / w) * w + (i % w + 3).min(w - 1)].wrapping_add((i % 5) as u8))
            .collect();
        let disp: Vec<f32> = (0..w * h)
            .map(|i| {
                if i % 11 == 0 {
                    f32::NAN
                } else {
                    (i % 13) as f32 * 0.5 - 1.0
                }
            })
            .collect();
        for sign in [1i8, -1] {
            for (dmax, k) in [(8, 7), (5, 1), (12, 4), (36, 3)] {
                let got = cost_curve_stats(&r, &t, &disp, w, h, sign, dmax, k).unwrap();
                let want = reference(&r, &t, &disp, w, h, sign, dmax, k);
                let same = |a: &[f32], b: &[f32]| {
                    a.iter()
                        .zip(b)
                        .all(|(x, y)| x == y || (x.is_nan() && y.is_nan()))
                };
                assert!(
                    same(&got.best, &want.best),
                    "best sign {sign} dmax {dmax} k {k}"
                );
                assert!(
                    same(&got.second, &want.second),
                    "second sign {sign} dmax {dmax} k {k}"
                );
                assert!(same(&got.at, &want.at), "at sign {sign} dmax {dmax} k {k}");
            }
        }
    }

    #[test]
    fn bad_arguments_are_refused() {
        let img = vec![0u8; 40];
        let d = vec![0f32; 40];
        assert!(cost_curve_stats(&img, &img, &d, 8, 5, 0, 3, 3).is_err());
        assert!(cost_curve_stats(&img, &img, &d, 8, 5, 1, 8, 3).is_err());
        assert!(cost_curve_stats(&img, &img, &d, 8, 5, 1, 3, 0).is_err());
        assert!(cost_curve_stats(&img, &img[..39], &d, 8, 5, 1, 3, 3).is_err());
    }
}
