//! From the aggregated costs to a disparity map: winner-take-all, uniqueness, sub-pixel
//! refinement, the left-right check against the other view's winners read from the same sums
//! (Hirschmüller's `D_m` from `S` along the diagonal), and the cost-curve statistics.

use rayon::prelude::*;

use crate::kernel::{multiversion, Kernel};
use crate::layout::Layout;
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

/// Selects every row of `sum` (rows `W` wide laid out by `layout`, disparities `dmin + k`).
pub(crate) fn select(
    sum: &[u16],
    w: usize,
    layout: &Layout,
    params: &SgmParams,
    kernel: Kernel,
) -> Selected {
    let n = sum.len() / layout.row_len().max(1) * w;
    let mut out = Selected {
        disparity: vec![f32::NAN; n],
        best: vec![f32::NAN; n],
        second: vec![f32::NAN; n],
    };
    out.disparity
        .par_chunks_mut(w)
        .zip(out.best.par_chunks_mut(w))
        .zip(out.second.par_chunks_mut(w))
        .zip(sum.par_chunks(layout.row_len().max(1)))
        .for_each(|(((d, b), s2), srow)| select_row(kernel, srow, layout, params, d, b, s2));
    out
}

#[inline(always)]
fn select_row_body(
    srow: &[u16],
    layout: &Layout,
    params: &SgmParams,
    disp: &mut [f32],
    best: &mut [f32],
    second: &mut [f32],
) {
    let (w, dmin) = (disp.len(), params.min_disparity);
    // The other view's winners at its pixel xr = x - dmin - k (smallest k on ties), kept
    // mirrored (index w - 1 - xr) so that the run of pixel x updates consecutive entries:
    // one vectorisable element-wise minimum per pixel.
    let check = params.lr_tolerance;
    let slots = if check.is_some() { w } else { 0 };
    let mut r_cost = vec![u16::MAX; slots];
    let mut r_k = vec![0u32; slots];
    if check.is_some() {
        for x in dmin..w {
            let s = &srow[layout.run(x)];
            let j0 = w - 1 - x + dmin;
            let cost = &mut r_cost[j0..j0 + s.len()];
            let at = &mut r_k[j0..j0 + s.len()];
            for (k, ((&v, c), a)) in s.iter().zip(cost.iter_mut()).zip(at.iter_mut()).enumerate() {
                let less = v < *c;
                *c = if less { v } else { *c };
                *a = if less { k as u32 } else { *a };
            }
        }
    }
    for x in dmin..w {
        let s = &srow[layout.run(x)];
        let kv = s.len();
        #[allow(clippy::reversed_empty_ranges)]
        let s1 = min_of(s, usize::MAX..=0);
        let k = first_of(s, s1);
        // The second best lies outside k - 1 ..= k + 1 (none if that is empty).
        let s2 = (k >= 2 || k + 2 < kv).then(|| min_of(s, k.saturating_sub(1)..=k + 1));
        best[x] = f32::from(s1);
        second[x] = s2.map_or(f32::INFINITY, f32::from);
        if let Some(s2) = s2 {
            if u32::from(s2) * (100 - u32::from(params.uniqueness)) < u32::from(s1) * 100 {
                continue;
            }
        }
        if let Some(tol) = check {
            // The other view's pixel x - dmin - k, mirrored.
            let other = r_k[w - 1 - (x - dmin - k)] as usize;
            if other.abs_diff(k) > usize::from(tol) {
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

/// Values reduced together (one AVX-512 register of u16).
const LANES: usize = 32;

/// The smallest value of `s` outside the indices `skip` (`u16::MAX` for none), a vector-wide
/// block at a time.
#[inline(always)]
fn min_of(s: &[u16], skip: std::ops::RangeInclusive<usize>) -> u16 {
    let (lo, hi) = (*skip.start(), *skip.end());
    let mut mv = [u16::MAX; LANES];
    let mut blocks = s.chunks_exact(LANES);
    for (b, chunk) in blocks.by_ref().enumerate() {
        for i in 0..LANES {
            let at = b * LANES + i;
            let v = if at >= lo && at <= hi {
                u16::MAX
            } else {
                chunk[i]
            };
            mv[i] = mv[i].min(v);
        }
    }
    let tail_at = s.len() - blocks.remainder().len();
    let mut m = mv.iter().fold(u16::MAX, |m, &v| m.min(v));
    for (i, &v) in blocks.remainder().iter().enumerate() {
        if !(lo..=hi).contains(&(tail_at + i)) {
            m = m.min(v);
        }
    }
    m
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

multiversion!(select_row => select_row_body(srow: &[u16], layout: &Layout, params: &SgmParams,
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
