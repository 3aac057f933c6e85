//! The inner loops of the matcher, written once as plain integer code over slices and compiled
//! three times: for the portable x86-64 / other baseline, for AVX2 and for AVX-512 (BW +
//! VPOPCNTDQ), chosen at run time ([`Kernel::best`]). The arithmetic is integer only (u8 costs,
//! u16 path costs and sums, no saturation reached: see [`crate::params::MAX_P2`]), so the three
//! builds give the same bits; `tests/sgm.rs` checks them against each other and against a
//! naive full-volume reference.

use crate::census::Word;

/// Which build of the inner loops runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kernel {
    /// The baseline target (SSE2 on x86-64).
    Portable,
    /// AVX2 (x86-64 only).
    Avx2,
    /// AVX-512 F/BW/VL with VPOPCNTDQ (x86-64 only).
    Avx512,
}

impl Kernel {
    /// The fastest build this processor runs.
    pub fn best() -> Kernel {
        Kernel::available()
            .into_iter()
            .last()
            .unwrap_or(Kernel::Portable)
    }

    /// Every build this processor runs, slowest first.
    pub fn available() -> Vec<Kernel> {
        #[allow(unused_mut)]
        let mut v = vec![Kernel::Portable];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2")
                && std::arch::is_x86_feature_detected!("popcnt")
            {
                v.push(Kernel::Avx2);
            }
            if std::arch::is_x86_feature_detected!("avx512f")
                && std::arch::is_x86_feature_detected!("avx512bw")
                && std::arch::is_x86_feature_detected!("avx512vl")
                && std::arch::is_x86_feature_detected!("avx512vpopcntdq")
            {
                v.push(Kernel::Avx512);
            }
        }
        v
    }
}

/// Defines `$name(kernel, args...)`, which runs `$body(args...)` compiled for `kernel`'s target
/// features. Only [`Kernel::available`] kernels may be passed (checked by the caller).
macro_rules! multiversion {
    ($(#[$m:meta])* $name:ident => $body:ident ( $($arg:ident : $ty:ty),* $(,)? ) -> $ret:ty) => {
        $(#[$m])*
        #[allow(clippy::too_many_arguments)]
        pub(crate) fn $name(kernel: $crate::kernel::Kernel, $($arg: $ty),*) -> $ret {
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2,popcnt")]
                #[allow(clippy::too_many_arguments)]
                unsafe fn avx2($($arg: $ty),*) -> $ret { $body($($arg),*) }
                #[target_feature(enable = "avx512f,avx512bw,avx512vl,avx512vpopcntdq,popcnt")]
                #[allow(clippy::too_many_arguments)]
                unsafe fn avx512($($arg: $ty),*) -> $ret { $body($($arg),*) }
                match kernel {
                    // SAFETY: the caller passes only kernels that `Kernel::available` found
                    // this processor to support.
                    $crate::kernel::Kernel::Avx2 => return unsafe { avx2($($arg),*) },
                    $crate::kernel::Kernel::Avx512 => return unsafe { avx512($($arg),*) },
                    $crate::kernel::Kernel::Portable => {}
                }
            }
            let _ = kernel;
            $body($($arg),*)
        }
    };
}
pub(crate) use multiversion;

/// Path costs of one pixel are kept in a *slot* of `D + 2` u16: `[EDGE, L(0) .. L(D-1), EDGE]`,
/// so the neighbours `L(d - 1)` and `L(d + 1)` of every disparity are plain loads. `EDGE` is
/// larger than any path cost plus P2 and stays below `u16::MAX - P1` (see
/// [`crate::params::MAX_P2`]), so `EDGE + P1` never wins a minimum and never overflows.
pub(crate) const EDGE: u16 = 0x7fff;

/// Disparities computed together (one AVX-512 register of u16).
const LANES: usize = 32;

/// The first pixel of a path: `L = C` into `out` (a slot). Adds `L` to `acc` (the pixel's
/// searchable disparities: a prefix of `L`) and returns `min L`.
#[inline(always)]
pub(crate) fn start(c: &[u8], out: &mut [u16], acc: &mut [u16]) -> u16 {
    let n = c.len();
    out[0] = EDGE;
    out[n + 1] = EDGE;
    let mut m = u16::MAX;
    for (o, &cv) in out[1..=n].iter_mut().zip(c) {
        let v = u16::from(cv);
        *o = v;
        m = m.min(v);
    }
    for (a, &o) in acc.iter_mut().zip(&out[1..]) {
        *a += o;
    }
    m
}

/// One SGM step (Hirschmüller eq. 13): `L(p, d) = C(p, d) + min(L(p-r, d), L(p-r, d±1) + P1,
/// min L(p-r) + P2) - min L(p-r)`, for every disparity, from the slot `prev` into the slot
/// `out`. Adds `L` to `acc` (the pixel's searchable disparities: a prefix of `L`) and returns
/// `min L`.
#[inline(always)]
pub(crate) fn step(
    c: &[u8],
    prev: &[u16],
    prev_min: u16,
    p1: u16,
    p2: u16,
    out: &mut [u16],
    acc: &mut [u16],
) -> u16 {
    let n = c.len();
    let base = prev_min + p2;
    let l = |cv: u8, lo: u16, mid: u16, hi: u16| {
        u16::from(cv) + mid.min(lo.min(hi) + p1).min(base) - prev_min
    };
    out[0] = EDGE;
    out[n + 1] = EDGE;
    let full = acc.len() == n;
    let blocks = n / LANES;
    let mut mv = [u16::MAX; LANES];
    for b in 0..blocks {
        let d0 = b * LANES;
        let cb: &[u8; LANES] = c[d0..d0 + LANES].try_into().expect("a block");
        let pb: &[u16; LANES + 2] = prev[d0..d0 + LANES + 2].try_into().expect("a block");
        let mut v = [0u16; LANES];
        for i in 0..LANES {
            v[i] = l(cb[i], pb[i], pb[i + 1], pb[i + 2]);
            mv[i] = mv[i].min(v[i]);
        }
        out[d0 + 1..d0 + 1 + LANES].copy_from_slice(&v);
        if full {
            let ab: &mut [u16; LANES] = (&mut acc[d0..d0 + LANES]).try_into().expect("a block");
            for i in 0..LANES {
                ab[i] += v[i];
            }
        }
    }
    let mut m = mv.iter().fold(u16::MAX, |m, &v| m.min(v));
    let tail = blocks * LANES;
    for d in tail..n {
        let v = l(c[d], prev[d], prev[d + 1], prev[d + 2]);
        out[d + 1] = v;
        m = m.min(v);
    }
    let from = if full { tail } else { 0 }.min(acc.len());
    for (a, &o) in acc[from..].iter_mut().zip(&out[from + 1..]) {
        *a += o;
    }
    m
}

/// The census Hamming costs of one reference pixel at disparities `dmin + k`: `rev` is the
/// target's census row reversed starting at the pixel `x - dmin` (so `rev[k]` is the target
/// pixel `x - dmin - k`), `valid` how many of those lie in the image; the rest cost `cmax`.
#[inline(always)]
pub(crate) fn costs<T: Word>(cref: T, rev: &[T], valid: usize, cmax: u8, out: &mut [u8]) {
    let (inside, outside) = out.split_at_mut(valid);
    for (o, &t) in inside.iter_mut().zip(rev) {
        *o = cref.distance(t);
    }
    outside.fill(cmax);
}

/// [`costs`] of another target row, folded in: each of the `valid` costs becomes the smaller of
/// itself and this row's (the rest already cost `cmax`).
#[inline(always)]
pub(crate) fn costs_min<T: Word>(cref: T, rev: &[T], valid: usize, out: &mut [u8]) {
    for (o, &t) in out[..valid].iter_mut().zip(rev) {
        *o = (*o).min(cref.distance(t));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_step_by_hand() {
        let c = [3u8, 0, 5, 1];
        let prev = [EDGE, 10u16, 2, 7, 30, EDGE];
        let (mut out, mut acc) = ([0u16; 6], [1u16; 4]);
        let m = step(&c, &prev, 2, 1, 6, &mut out, &mut acc);
        // d0: 3 + min(10, 2+1, 8) - 2 = 4; d1: 0 + min(2, 7+1, 8) - 2 = 0;
        // d2: 5 + min(7, 2+1, 8) - 2 = 6; d3: 1 + min(30, 7+1, 8) - 2 = 7.
        assert_eq!(out, [EDGE, 4, 0, 6, 7, EDGE]);
        assert_eq!(acc, [5, 1, 7, 8]);
        assert_eq!(m, 0);
        // A pixel searching two disparities: the same path costs, only two sums.
        let (mut out2, mut acc2) = ([0u16; 6], [1u16; 2]);
        assert_eq!(step(&c, &prev, 2, 1, 6, &mut out2, &mut acc2), 0);
        assert_eq!((out2, acc2), (out, [5, 1]));
        // Forty disparities: a whole block and a remainder give the scalar formula.
        let c: Vec<u8> = (0..40).map(|d| (d * 7 % 13) as u8).collect();
        let mut prev = vec![EDGE; 42];
        for d in 0..40 {
            prev[d + 1] = (d * 5 % 11) as u16 + 3;
        }
        let pm = *prev.iter().min().unwrap();
        let (mut out, mut acc) = (vec![0u16; 42], vec![0u16; 40]);
        let m = step(&c, &prev, pm, 2, 9, &mut out, &mut acc);
        for d in 0..40 {
            let mut best = prev[d + 1].min(pm + 9);
            if d > 0 {
                best = best.min(prev[d] + 2);
            }
            if d + 1 < 40 {
                best = best.min(prev[d + 2] + 2);
            }
            assert_eq!(out[d + 1], u16::from(c[d]) + best - pm, "d {d}");
        }
        assert_eq!(acc[..], out[1..41]);
        assert_eq!(m, *acc.iter().min().unwrap());
        let mut cst = [0u8; 5];
        costs(0b1011u64, &[0b0011, 0b1011, 0], 2, 9, &mut cst);
        assert_eq!(cst, [1, 0, 9, 9, 9]);
        costs_min(0b1011u64, &[0b1011, 0b0000, 0], 2, &mut cst);
        assert_eq!(cst, [0, 0, 9, 9, 9]);
        assert!(Kernel::available().contains(&Kernel::best()));
    }
}
