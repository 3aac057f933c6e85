//! From the aggregated costs to a disparity map: winner-take-all, uniqueness, sub-pixel
//! refinement, the left-right check against the other view's winners read from the same sums
//! (Hirschmüller's `D_m` from `S` along the diagonal), and the cost-curve statistics.

use rayon::prelude::*;

use crate::kernel::{multiversion, Kernel};
use crate::params::{SgmParams, Subpixel};

/// The selected map and the cost statistics (`H x W` each; NaN where no disparity could be
/// searched: the first `min_disparity` columns).
pub(crate) struct Selected {
    pub disparity: Vec<f32>,
    pub best: Vec<f32>,
    pub second: Vec<f32>,
}

/// The sub-pixel offset of the minimum `b` between its neighbours `a` (one disparity less) and
/// `c` (one more), in `[-0.5, 0.5]`.
pub(crate) fn offset(mode: Subpixel, a: u16, b: u16, c: u16) -> f32 {
    let (a, b, c) = (f32::from(a), f32::from(b), f32::from(c));
    match mode {
        Subpixel::Off => 0.0,
        Subpixel::Parabola => {
            let den = a + c - 2.0 * b;
            if den > 0.0 {
                (a - c) / (2.0 * den)
            } else {
                0.0
            }
        }
        Subpixel::Equiangular => {
            let den = if c < a { a - b } else { c - b };
            if den > 0.0 {
                (a - c) / (2.0 * den)
            } else {
                0.0
            }
        }
    }
}

/// Selects every row of `sum` (`H x W x nd`, rows `W` wide, disparities `dmin + k`).
pub(crate) fn select(sum: &[u16], w: usize, params: &SgmParams, kernel: Kernel) -> Selected {
    let nd = params.disparities();
    let n = sum.len() / nd;
    let mut out = Selected {
        disparity: vec![f32::NAN; n],
        best: vec![f32::NAN; n],
        second: vec![f32::NAN; n],
    };
    out.disparity
        .par_chunks_mut(w)
        .zip(out.best.par_chunks_mut(w))
        .zip(out.second.par_chunks_mut(w))
        .zip(sum.par_chunks(w * nd))
        .for_each(|(((d, b), s2), srow)| select_row(kernel, srow, w, params, d, b, s2));
    out
}

#[inline(always)]
fn select_row_body(
    srow: &[u16],
    w: usize,
    params: &SgmParams,
    disp: &mut [f32],
    best: &mut [f32],
    second: &mut [f32],
) {
    let (nd, dmin) = (params.disparities(), params.min_disparity);
    // The other view's winners at its pixel xr = x - dmin - k (smallest k on ties).
    let check = params.lr_tolerance;
    let slots = if check.is_some() { w } else { 0 };
    let mut r_cost = vec![u16::MAX; slots];
    let mut r_k = vec![0usize; slots];
    if check.is_some() {
        for x in dmin..w {
            let kv = (x - dmin + 1).min(nd);
            for (k, &s) in srow[x * nd..x * nd + kv].iter().enumerate() {
                let xr = x - dmin - k;
                if s < r_cost[xr] {
                    r_cost[xr] = s;
                    r_k[xr] = k;
                }
            }
        }
    }
    for x in dmin..w {
        let kv = (x - dmin + 1).min(nd);
        let s = &srow[x * nd..x * nd + kv];
        let s1 = min_of(s);
        let k = first_of(s, s1);
        // The second best lies outside k - 1 ..= k + 1 (none if that is empty).
        let s2 = (k >= 2 || k + 2 < kv)
            .then(|| min_of(&s[..k.saturating_sub(1)]).min(min_of(s.get(k + 2..).unwrap_or(&[]))));
        best[x] = f32::from(s1);
        second[x] = s2.map_or(f32::INFINITY, f32::from);
        if let Some(s2) = s2 {
            if u32::from(s2) * (100 - u32::from(params.uniqueness)) < u32::from(s1) * 100 {
                continue;
            }
        }
        if let Some(tol) = check {
            let xr = x - dmin - k;
            if r_k[xr].abs_diff(k) > usize::from(tol) {
                continue;
            }
        }
        let off = if k > 0 && k + 1 < kv {
            offset(params.subpixel, s[k - 1], s1, s[k + 1])
        } else {
            0.0
        };
        disp[x] = (dmin + k) as f32 + off;
    }
}

/// The smallest value (`u16::MAX` for none), written as a fold so that it vectorizes.
#[inline(always)]
fn min_of(s: &[u16]) -> u16 {
    s.iter().fold(u16::MAX, |m, &v| m.min(v))
}

/// The first index of `v` in `s` (which holds it), searched a vector-wide block at a time.
#[inline(always)]
fn first_of(s: &[u16], v: u16) -> usize {
    const BLOCK: usize = 32;
    for (b, chunk) in s.chunks(BLOCK).enumerate() {
        if chunk.iter().fold(false, |f, &c| f | (c == v)) {
            return b * BLOCK + chunk.iter().position(|&c| c == v).unwrap_or(0);
        }
    }
    0
}

multiversion!(select_row => select_row_body(srow: &[u16], w: usize, params: &SgmParams,
    disp: &mut [f32], best: &mut [f32], second: &mut [f32]) -> ());

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sub_pixel_fits() {
        // A symmetric curve has its minimum on the integer.
        assert_eq!(offset(Subpixel::Parabola, 10, 4, 10), 0.0);
        // Costs |x - 0.25| * 8 at -1, 0, 1: the equiangular fit is exact.
        assert!((offset(Subpixel::Equiangular, 10, 2, 6) - 0.25).abs() < 1e-6);
        // (x - 0.25)^2 at -1, 0, 1, scaled by 16: the parabola is exact.
        assert!((offset(Subpixel::Parabola, 25, 1, 9) - 0.25).abs() < 1e-6);
        assert_eq!(offset(Subpixel::Off, 25, 1, 9), 0.0);
        assert_eq!(offset(Subpixel::Parabola, 3, 3, 3), 0.0);
    }
}
