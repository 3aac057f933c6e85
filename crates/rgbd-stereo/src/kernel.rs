//! The inner loops of the matcher, written once as plain integer code over slices and compiled
//! three times: for the portable x86-64 / other baseline, for AVX2 and for AVX-512 (BW +
//! VPOPCNTDQ), chosen at run time ([`Kernel::best`]). The arithmetic is integer only (u8 costs,
//! u16 path costs and sums, no saturation reached: see [`crate::params::MAX_P2`]), so the three
//! builds give the same bits; `tests/sgm.rs` checks them against each other and against a
//! naive full-volume reference.

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

/// The first pixel of a path: `L = C`. Adds `L` to `acc` and returns `min L`.
#[inline(always)]
pub(crate) fn start(c: &[u8], out: &mut [u16], acc: &mut [u16]) -> u16 {
    let mut m = u16::MAX;
    for ((o, a), &cv) in out.iter_mut().zip(acc.iter_mut()).zip(c) {
        let v = u16::from(cv);
        *o = v;
        *a += v;
        m = m.min(v);
    }
    m
}

/// One SGM step (Hirschmüller eq. 13): `L(p, d) = C(p, d) + min(L(p-r, d), L(p-r, d±1) + P1,
/// min L(p-r) + P2) - min L(p-r)`, for every disparity (at least two). Adds `L` to `acc` and
/// returns `min L`.
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
    let first = u16::from(c[0]) + prev[0].min(prev[1] + p1).min(base) - prev_min;
    out[0] = first;
    acc[0] += first;
    let last = u16::from(c[n - 1]) + prev[n - 1].min(prev[n - 2] + p1).min(base) - prev_min;
    let mut m = first.min(last);
    let inner = out[1..n - 1]
        .iter_mut()
        .zip(acc[1..n - 1].iter_mut())
        .zip(&c[1..n - 1])
        .zip(prev[..n - 2].iter().zip(&prev[1..n - 1]).zip(&prev[2..]));
    for (((o, a), &cv), ((&lo, &mid), &hi)) in inner {
        let v = u16::from(cv) + mid.min(lo.min(hi) + p1).min(base) - prev_min;
        *o = v;
        *a += v;
        m = m.min(v);
    }
    out[n - 1] = last;
    acc[n - 1] += last;
    m
}

/// The census Hamming costs of one reference pixel at disparities `dmin + k`: `rev` is the
/// target's census row reversed starting at the pixel `x - dmin` (so `rev[k]` is the target
/// pixel `x - dmin - k`), `valid` how many of those lie in the image; the rest cost `cmax`.
#[inline(always)]
pub(crate) fn costs(cref: u64, rev: &[u64], valid: usize, cmax: u8, out: &mut [u8]) {
    let (inside, outside) = out.split_at_mut(valid);
    for (o, &t) in inside.iter_mut().zip(rev) {
        *o = (cref ^ t).count_ones() as u8;
    }
    outside.fill(cmax);
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_step_by_hand() {
        let c = [3u8, 0, 5, 1];
        let prev = [10u16, 2, 7, 30];
        let (mut out, mut acc) = ([0u16; 4], [1u16; 4]);
        let m = step(&c, &prev, 2, 1, 6, &mut out, &mut acc);
        // d0: 3 + min(10, 2+1, 8) - 2 = 4; d1: 0 + min(2, 7+1, 8) - 2 = 0;
        // d2: 5 + min(7, 2+1, 8) - 2 = 6; d3: 1 + min(30, 7+1, 8) - 2 = 7.
        assert_eq!(out, [4, 0, 6, 7]);
        assert_eq!(acc, [5, 1, 7, 8]);
        assert_eq!(m, 0);
        let mut cst = [0u8; 5];
        costs(0b1011, &[0b0011, 0b1011, 0], 2, 9, &mut cst);
        assert_eq!(cst, [1, 0, 9, 9, 9]);
        assert!(Kernel::available().contains(&Kernel::best()));
    }
}
