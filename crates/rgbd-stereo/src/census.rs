//! The census transform (Zabih & Woodfill): each pixel becomes a bit string saying which pixels
//! of its window are darker than a reference value, so the matching cost (the Hamming distance
//! of two strings) depends only on the local order of intensities: unit-free, robust to gain
//! and bias between the cameras, and pixelwise (no block sum carries a surface over its edge).
//!
//! Window `width x height` (odd sides, at most 64 bits without the centre); pixels beyond the
//! image are the nearest border pixel (replicated). Bit `i` (window pixels in row-major order,
//! the centre skipped) is set where that pixel is *smaller* than the reference: the centre
//! pixel ([`CensusReference::Center`]) or the window's mean ([`CensusReference::Mean`], then
//! the centre pixel is compared too and takes the last bit).

use rayon::prelude::*;

use crate::kernel::{multiversion, Kernel};

/// What the window's pixels are compared with.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CensusReference {
    /// The centre pixel (the classic census).
    Center,
    /// The window's mean intensity (rounded down); less sensitive to noise on the centre.
    Mean,
}

/// The number of bits of one census string.
pub fn bits(width: usize, height: usize, reference: CensusReference) -> usize {
    match reference {
        CensusReference::Center => width * height - 1,
        CensusReference::Mean => width * height,
    }
}

/// The census strings of a grey `H x W` image (row-major), one `u64` a pixel.
pub fn census(
    img: &[u8],
    width: usize,
    height: usize,
    win_w: usize,
    win_h: usize,
    reference: CensusReference,
) -> Vec<u64> {
    census_with::<u64>(img, width, height, win_w, win_h, reference, Kernel::best())
}

/// A census string: `u32` for windows of up to 32 bits (half the memory), else `u64`.
pub(crate) trait Word: Copy + Default + Send + Sync {
    /// The string's low bits.
    fn narrow(v: u64) -> Self;
    /// The Hamming distance of two strings.
    fn distance(self, other: Self) -> u8;
}

impl Word for u32 {
    #[inline(always)]
    fn narrow(v: u64) -> Self {
        v as u32
    }
    #[inline(always)]
    fn distance(self, other: Self) -> u8 {
        (self ^ other).count_ones() as u8
    }
}

impl Word for u64 {
    #[inline(always)]
    fn narrow(v: u64) -> Self {
        v
    }
    #[inline(always)]
    fn distance(self, other: Self) -> u8 {
        (self ^ other).count_ones() as u8
    }
}

/// [`census`] with a chosen build of its loops, as strings of type `T` (which must hold the
/// window's bits).
pub(crate) fn census_with<T: Word>(
    img: &[u8],
    width: usize,
    height: usize,
    win_w: usize,
    win_h: usize,
    reference: CensusReference,
    kernel: Kernel,
) -> Vec<T> {
    let (rx, ry) = (win_w / 2, win_h / 2);
    // The image with its border replicated, so every window is a plain slice.
    let pw = width + 2 * rx;
    let mut pad = vec![0u8; pw * (height + 2 * ry)];
    for (py, prow) in pad.chunks_exact_mut(pw).enumerate() {
        let y = py.saturating_sub(ry).min(height - 1);
        let src = &img[y * width..(y + 1) * width];
        prow[..rx].fill(src[0]);
        prow[rx..rx + width].copy_from_slice(src);
        prow[rx + width..].fill(src[width - 1]);
    }
    let mut out = vec![T::default(); width * height];
    let win = Window {
        pad: &pad,
        pw,
        w: width,
        win_w,
        win_h,
    };
    out.par_chunks_mut(width).enumerate().for_each_init(
        || (vec![0u32; width], vec![0u64; width]),
        |(refv, wide), (y, row)| {
            census_row(kernel, &win, y, reference, refv, wide);
            for (o, &v) in row.iter_mut().zip(wide.iter()) {
                *o = T::narrow(v);
            }
        },
    );
    out
}

pub(crate) struct Window<'a> {
    pad: &'a [u8],
    pw: usize,
    w: usize,
    win_w: usize,
    win_h: usize,
}

impl Window<'_> {
    /// The window pixels at offset `(dx, dy)` (0-based in the window) of output row `y`.
    #[inline(always)]
    fn slice(&self, y: usize, dx: usize, dy: usize) -> &[u8] {
        let s = (y + dy) * self.pw + dx;
        &self.pad[s..s + self.w]
    }

    #[inline(always)]
    fn row(&self, y: usize, reference: CensusReference, refv: &mut [u32], out: &mut [u64]) {
        let (rx, ry) = (self.win_w / 2, self.win_h / 2);
        match reference {
            CensusReference::Center => {
                for (r, &c) in refv.iter_mut().zip(self.slice(y, rx, ry)) {
                    *r = u32::from(c);
                }
            }
            CensusReference::Mean => {
                refv.fill(0);
                for dy in 0..self.win_h {
                    for dx in 0..self.win_w {
                        for (r, &v) in refv.iter_mut().zip(self.slice(y, dx, dy)) {
                            *r += u32::from(v);
                        }
                    }
                }
                let n = (self.win_w * self.win_h) as u32;
                for r in refv.iter_mut() {
                    *r /= n;
                }
            }
        }
        out.fill(0);
        for dy in 0..self.win_h {
            for dx in 0..self.win_w {
                if reference == CensusReference::Center && dx == rx && dy == ry {
                    continue;
                }
                for ((o, &v), &r) in out.iter_mut().zip(self.slice(y, dx, dy)).zip(&*refv) {
                    *o = (*o << 1) | u64::from(u32::from(v) < r);
                }
            }
        }
    }
}

#[inline(always)]
fn census_row_body(
    win: &Window<'_>,
    y: usize,
    reference: CensusReference,
    refv: &mut [u32],
    out: &mut [u64],
) {
    win.row(y, reference, refv, out)
}
multiversion!(census_row => census_row_body(win: &Window<'_>, y: usize, reference: CensusReference,
    refv: &mut [u32], out: &mut [u64]) -> ());

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_census_of_a_ramp() {
        // A horizontal ramp: in a 3x3 window the left column is darker than the centre.
        let img: Vec<u8> = (0..5 * 4).map(|i| (i % 5) as u8 * 10).collect();
        let c = census(&img, 5, 4, 3, 3, CensusReference::Center);
        // Row-major bits without the centre: (L C R) (L R) (L C R) = 100, 10, 100.
        assert_eq!(c[5 + 2], 0b1001_0100);
        // At the left border the replicated column equals the centre: nothing darker.
        assert_eq!(c[5], 0);
    }

    #[test]
    fn gain_and_bias_do_not_change_the_strings() {
        let img: Vec<u8> = (0..64u32).map(|i| ((i * 37) % 101) as u8).collect();
        let brighter: Vec<u8> = img.iter().map(|&v| v * 2 + 20).collect();
        for r in [CensusReference::Center, CensusReference::Mean] {
            let a = census(&img, 8, 8, 5, 3, r);
            let b = census(&brighter, 8, 8, 5, 3, r);
            if r == CensusReference::Center {
                assert_eq!(a, b);
            } else {
                // The mean rounds down: equal up to pixels at the mean itself.
                let differ: u32 = a.iter().zip(&b).map(|(x, y)| (x ^ y).count_ones()).sum();
                assert!(differ < 8, "{differ}");
            }
        }
        assert_eq!(bits(9, 7, CensusReference::Center), 62);
    }
}
