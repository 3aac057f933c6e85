//! The median filter of a disparity map (NaN = none): the median of the valid values in the
//! `side x side` window of every valid pixel (the mean of the two middle values for an even
//! count); invalid pixels stay invalid.
//!
//! Where a window lies inside the image (all but a border `side / 2` wide) the median is the
//! middle output of a selection network: Batcher's odd-even merge sort on the next power of
//! two, padded with -inf / +inf, with the comparators that only move padding removed and
//! those that do not reach the middle output pruned (23, 114 and 320 comparators for sides 3,
//! 5 and 7). It runs on 16 pixels at once, so the min / max compile to vector instructions.
//! A window's holes enter it as -inf and +inf in turn (see `padded_medians`), so holes cost
//! at most a second run. The border takes the exact selection. Both give the same value: a
//! median is a value of the window (or the mean of two, computed alike), and min / max of
//! non-NaN floats are exact.

use std::sync::OnceLock;

use rayon::prelude::*;

use crate::kernel::{multiversion, Kernel};
use crate::params::MAX_MEDIAN;

/// Pixels filtered together by the network.
const LANES: usize = 16;

/// A network of comparators on the `n` value slots after which slot `out` holds the median of
/// the `n` (odd) inputs.
#[derive(Debug)]
pub(crate) struct Network {
    /// `(a, b)`: slot `a` takes the smaller value, slot `b` the larger.
    pub pairs: Vec<(u8, u8)>,
    pub out: usize,
}

/// Batcher's odd-even merge sort of `m` (a power of two) wires, as comparators in order.
fn batcher(m: usize) -> Vec<(usize, usize)> {
    let mut v = Vec::new();
    let mut p = 1;
    while p < m {
        let mut k = p;
        while k >= 1 {
            let mut j = k % p;
            while j + k < m {
                for i in 0..k.min(m - j - k) {
                    if (i + j) / (2 * p) == (i + j + k) / (2 * p) {
                        v.push((i + j, i + j + k));
                    }
                }
                j += 2 * k;
            }
            k /= 2;
        }
        p *= 2;
    }
    v
}

/// What a wire of the padded network carries.
#[derive(Clone, Copy, PartialEq)]
enum Wire {
    NegInf,
    PosInf,
    /// One of the `n` value slots.
    Slot(usize),
}

/// The median network of `n` (odd) values.
pub(crate) fn network(n: usize) -> Network {
    assert!(n % 2 == 1, "median networks take an odd count");
    let m = n.next_power_of_two();
    let neg = (m - n) / 2;
    let mut wire: Vec<Wire> = (0..m)
        .map(|i| {
            if i < neg {
                Wire::NegInf
            } else if i < neg + n {
                Wire::Slot(i - neg)
            } else {
                Wire::PosInf
            }
        })
        .collect();
    // Forward: comparators with a padding input either do nothing or swap what the wires
    // carry; only value-value comparators remain.
    let mut kept: Vec<(usize, usize)> = Vec::new();
    for (i, j) in batcher(m) {
        match (wire[i], wire[j]) {
            (Wire::NegInf, _) | (_, Wire::PosInf) => {}
            (Wire::Slot(a), Wire::Slot(b)) => kept.push((a, b)),
            _ => wire.swap(i, j),
        }
    }
    let Wire::Slot(out) = wire[neg + (n - 1) / 2] else {
        unreachable!("the middle wire of a sorted padded input is a value")
    };
    // Backward: keep what the middle output depends on.
    let mut needed = vec![false; n];
    needed[out] = true;
    let mut pairs = Vec::new();
    for &(a, b) in kept.iter().rev() {
        if needed[a] || needed[b] {
            needed[a] = true;
            needed[b] = true;
            pairs.push((a as u8, b as u8));
        }
    }
    pairs.reverse();
    Network { pairs, out }
}

/// The network of a `side x side` window (built once per side).
fn window_network(side: usize) -> &'static Network {
    static NETS: [OnceLock<Network>; MAX_MEDIAN / 2 + 1] =
        [const { OnceLock::new() }; MAX_MEDIAN / 2 + 1];
    NETS[side / 2].get_or_init(|| network(side * side))
}

/// The median filter (see the module docs). An even `side` takes the window of `side + 1`.
pub fn median(disp: &[f32], w: usize, h: usize, side: usize) -> Vec<f32> {
    median_with(Kernel::best(), disp, w, h, side)
}

/// [`median`] with a chosen build of the network loop.
pub(crate) fn median_with(
    kernel: Kernel,
    disp: &[f32],
    w: usize,
    h: usize,
    side: usize,
) -> Vec<f32> {
    let mut out = vec![f32::NAN; w * h];
    if side <= 1 {
        out.copy_from_slice(disp);
        return out;
    }
    if side.is_multiple_of(2) || side > MAX_MEDIAN {
        // No network for these sides (the matcher never asks for them): the exact selection.
        out.par_chunks_mut(w)
            .enumerate()
            .for_each_init(Vec::new, |win, (y, row)| {
                for (x, o) in row.iter_mut().enumerate() {
                    *o = exact(disp, w, h, side, x, y, win);
                }
            });
        return out;
    }
    let net = window_network(side);
    out.par_chunks_mut(w).enumerate().for_each_init(
        || {
            (
                Vec::with_capacity(side * side),
                vec![[0f32; LANES]; 2 * side * side],
            )
        },
        |(win, lanes), (y, row)| median_row(kernel, disp, w, h, side, y, net, win, lanes, row),
    );
    out
}

#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn median_row_body(
    disp: &[f32],
    w: usize,
    h: usize,
    side: usize,
    y: usize,
    net: &Network,
    win: &mut Vec<f32>,
    lanes: &mut [[f32; LANES]],
    row: &mut [f32],
) {
    let r = side / 2;
    let n = side * side;
    let interior_row = y >= r && y + r < h;
    let (first, second) = lanes.split_at_mut(n);
    let mut x = 0;
    while x < w {
        // A block of LANES whole windows inside the image goes through the network.
        if interior_row && x >= r && x + LANES + r <= w {
            for (k, lane) in first.iter_mut().enumerate() {
                let (dy, dx) = (k / side, k % side);
                let src = (y + dy - r) * w + x + dx - r;
                lane.copy_from_slice(&disp[src..src + LANES]);
            }
            padded_medians(net, first, second, &mut row[x..x + LANES]);
            x += LANES;
        } else {
            row[x] = exact(disp, w, h, side, x, y, win);
            x += 1;
        }
    }
}

/// Runs the comparators of `net` on `lanes` (one window per lane).
#[inline(always)]
fn sort_network(net: &Network, lanes: &mut [[f32; LANES]]) {
    for &(a, b) in &net.pairs {
        let (a, b) = (usize::from(a), usize::from(b));
        let (va, vb) = (lanes[a], lanes[b]);
        let (mut lo, mut hi) = ([0f32; LANES], [0f32; LANES]);
        for l in 0..LANES {
            let less = va[l] < vb[l];
            lo[l] = if less { va[l] } else { vb[l] };
            hi[l] = if less { vb[l] } else { va[l] };
        }
        lanes[a] = lo;
        lanes[b] = hi;
    }
}

/// The medians of windows with holes (`lanes`, NaN = none; `spare` the same size), as
/// [`exact`] gives them: a window's holes become -inf and +inf in turn, so an even number of
/// holes leaves the middle output on the median of the valid values. With an odd number (an
/// even count of values) the first hole taken as -inf puts the lower middle value there and as
/// +inf the upper one; the median is their mean. A lane whose centre is a hole gives NaN.
#[inline(always)]
fn padded_medians(
    net: &Network,
    lanes: &mut [[f32; LANES]],
    spare: &mut [[f32; LANES]],
    out: &mut [f32],
) {
    let centre = lanes.len() / 2;
    let hole = lanes[centre].map(f32::is_nan);
    // Per lane, the parity of the holes seen so far (0 / 1, as u32 lanes so this vectorises).
    let mut odd = [0u32; LANES];
    for (lane, other) in lanes.iter_mut().zip(spare.iter_mut()) {
        for l in 0..LANES {
            let v = lane[l];
            let nan = u32::from(v.is_nan());
            // -inf for an even number of holes before this one, +inf for an odd number.
            let low = f32::from_bits(0x7f80_0000 | ((odd[l] ^ 1) << 31));
            lane[l] = if nan == 1 { low } else { v };
            other[l] = if nan == 1 { -low } else { v };
            odd[l] ^= nan;
        }
    }
    sort_network(net, lanes);
    let any_odd = odd.contains(&1);
    if any_odd {
        sort_network(net, spare);
    }
    for l in 0..LANES {
        let lower = lanes[net.out][l];
        out[l] = if hole[l] {
            f32::NAN
        } else if odd[l] == 1 {
            0.5 * (lower + spare[net.out][l])
        } else {
            lower
        };
    }
}
multiversion!(median_row => median_row_body(disp: &[f32], w: usize, h: usize, side: usize,
    y: usize, net: &Network, win: &mut Vec<f32>, lanes: &mut [[f32; LANES]], row: &mut [f32]) -> ());

/// The exact median of pixel `(x, y)`'s window (NaN for an invalid pixel).
fn exact(
    disp: &[f32],
    w: usize,
    h: usize,
    side: usize,
    x: usize,
    y: usize,
    win: &mut Vec<f32>,
) -> f32 {
    if disp[y * w + x].is_nan() {
        return f32::NAN;
    }
    let r = side / 2;
    win.clear();
    for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
        for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
            let v = disp[yy * w + xx];
            if !v.is_nan() {
                win.push(v);
            }
        }
    }
    let m = win.len();
    // A selection, not a sort: the upper middle, then the largest value below it.
    let (below, &mut mid, _) = win.select_nth_unstable_by(m / 2, f32::total_cmp);
    if m % 2 == 1 {
        mid
    } else {
        let lower = below.iter().copied().fold(f32::NEG_INFINITY, f32::max);
        0.5 * (lower + mid)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The network's middle output is the median, on every 0/1 input of 9 values and on
    /// random permutations of 25 and 49 (the 0/1 principle covers the rest for 9).
    #[test]
    fn networks_select_the_median() {
        let apply = |net: &Network, v: &mut [i32]| {
            for &(a, b) in &net.pairs {
                let (a, b) = (usize::from(a), usize::from(b));
                if v[a] > v[b] {
                    v.swap(a, b);
                }
            }
            v[net.out]
        };
        let n9 = network(9);
        for bits in 0u32..(1 << 9) {
            let mut v: Vec<i32> = (0..9).map(|i| ((bits >> i) & 1) as i32).collect();
            let ones = v.iter().sum::<i32>();
            assert_eq!(apply(&n9, &mut v), i32::from(ones >= 5), "bits {bits:09b}");
        }
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        for n in [25usize, 49] {
            let net = network(n);
            assert!(
                net.pairs.len() < 20 * n,
                "{} comparators for {n}",
                net.pairs.len()
            );
            for _ in 0..2000 {
                let mut v: Vec<i32> = (0..n as i32).collect();
                for i in (1..n).rev() {
                    seed ^= seed << 13;
                    seed ^= seed >> 7;
                    seed ^= seed << 17;
                    v.swap(i, (seed % (i as u64 + 1)) as usize);
                }
                assert_eq!(apply(&net, &mut v), (n / 2) as i32);
            }
        }
    }

    #[test]
    fn median_ignores_holes() {
        let n = f32::NAN;
        let d = [1.0, 2.0, n, 9.0, 3.0, 4.0, 5.0, 6.0, 7.0];
        let m = median(&d, 3, 3, 3);
        assert!(m[2].is_nan());
        // Centre: the 8 valid values 1..7 and 9 -> (4 + 5) / 2.
        assert_eq!(m[4], 4.5);
        // Top left: 1, 2, 9, 3 -> 2.5.
        assert_eq!(m[0], 2.5);
    }

    /// The network path equals the exact selection on maps with few to many holes (odd and
    /// even counts per window), every kernel.
    #[test]
    fn network_equals_exact_selection() {
        let (w, h) = (61, 23);
        for holes_in in [331u64, 7, 3, 2] {
            let mut seed = 12345u64;
            let d: Vec<f32> = (0..w * h)
                .map(|_| {
                    seed = seed
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    let r = (seed >> 33) as u32;
                    if (seed >> 20).is_multiple_of(holes_in) {
                        f32::NAN
                    } else {
                        (r % 4000) as f32 / 16.0
                    }
                })
                .collect();
            for side in [3, 5, 7, 4, 9] {
                let mut win = Vec::new();
                let want: Vec<f32> = (0..w * h)
                    .map(|i| exact(&d, w, h, side, i % w, i / w, &mut win))
                    .collect();
                for k in Kernel::available() {
                    let got = median_with(k, &d, w, h, side);
                    for (i, (g, e)) in got.iter().zip(&want).enumerate() {
                        assert!(
                            g.to_bits() == e.to_bits(),
                            "holes 1/{holes_in} side {side} {k:?} pixel {i}: {g} vs {e}"
                        );
                    }
                }
            }
        }
    }
}
