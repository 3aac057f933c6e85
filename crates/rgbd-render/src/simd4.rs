//! Four `f32` lanes for the 4-wide BVH: SSE on x86-64 (part of the baseline, so no runtime
//! check is needed; the AVX2 build of the traversal only changes the encoding), plain arrays
//! elsewhere. Every operation is one IEEE operation per lane, in the order written, so a lane
//! computes exactly what the scalar code would.

#[cfg(target_arch = "x86_64")]
mod imp {
    use std::arch::x86_64::*;

    /// Four `f32` lanes.
    #[derive(Clone, Copy)]
    pub struct F4(__m128);

    /// A per-lane mask (all bits set in true lanes).
    #[derive(Clone, Copy)]
    pub struct M4(__m128);

    impl F4 {
        #[inline(always)]
        pub fn splat(x: f32) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86-64 baseline.
            Self(unsafe { _mm_set1_ps(x) })
        }
        #[inline(always)]
        pub fn load(a: &[f32; 4]) -> Self {
            // SAFETY: reads exactly the 16 bytes of `a`; no alignment is required.
            Self(unsafe { _mm_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        pub fn to_array(self) -> [f32; 4] {
            let mut a = [0.0f32; 4];
            // SAFETY: writes exactly the 16 bytes of `a`; no alignment is required.
            unsafe { _mm_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }
        #[inline(always)]
        pub fn add(self, b: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86-64 baseline.
            Self(unsafe { _mm_add_ps(self.0, b.0) })
        }
        #[inline(always)]
        pub fn sub(self, b: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86-64 baseline.
            Self(unsafe { _mm_sub_ps(self.0, b.0) })
        }
        #[inline(always)]
        pub fn mul(self, b: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86-64 baseline.
            Self(unsafe { _mm_mul_ps(self.0, b.0) })
        }
        #[inline(always)]
        pub fn div(self, b: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86-64 baseline.
            Self(unsafe { _mm_div_ps(self.0, b.0) })
        }
        /// `self < b ? self : b` per lane: a NaN in `self` yields `b`.
        #[inline(always)]
        pub fn min(self, b: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86-64 baseline.
            Self(unsafe { _mm_min_ps(self.0, b.0) })
        }
        /// `self > b ? self : b` per lane: a NaN in `self` yields `b`.
        #[inline(always)]
        pub fn max(self, b: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86-64 baseline.
            Self(unsafe { _mm_max_ps(self.0, b.0) })
        }
        #[inline(always)]
        pub fn abs(self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86-64 baseline.
            Self(unsafe { _mm_andnot_ps(_mm_set1_ps(-0.0), self.0) })
        }
        #[inline(always)]
        pub fn lt(self, b: Self) -> M4 {
            // SAFETY: SSE is part of the x86-64 baseline.
            M4(unsafe { _mm_cmplt_ps(self.0, b.0) })
        }
        #[inline(always)]
        pub fn le(self, b: Self) -> M4 {
            // SAFETY: SSE is part of the x86-64 baseline.
            M4(unsafe { _mm_cmple_ps(self.0, b.0) })
        }
        #[inline(always)]
        pub fn gt(self, b: Self) -> M4 {
            // SAFETY: SSE is part of the x86-64 baseline.
            M4(unsafe { _mm_cmpgt_ps(self.0, b.0) })
        }
        #[inline(always)]
        pub fn ge(self, b: Self) -> M4 {
            // SAFETY: SSE is part of the x86-64 baseline.
            M4(unsafe { _mm_cmpge_ps(self.0, b.0) })
        }
    }

    impl M4 {
        #[inline(always)]
        pub fn and(self, b: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86-64 baseline.
            Self(unsafe { _mm_and_ps(self.0, b.0) })
        }
        /// `self & !b`.
        #[inline(always)]
        pub fn and_not(self, b: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86-64 baseline.
            Self(unsafe { _mm_andnot_ps(b.0, self.0) })
        }
        #[inline(always)]
        pub fn or(self, b: Self) -> Self {
            // SAFETY: SSE and SSE2 are part of the x86-64 baseline.
            Self(unsafe { _mm_or_ps(self.0, b.0) })
        }
        /// Bit `i` set when lane `i` is true.
        #[inline(always)]
        pub fn bits(self) -> u32 {
            // SAFETY: SSE is part of the x86-64 baseline.
            unsafe { _mm_movemask_ps(self.0) as u32 }
        }
    }
}

#[cfg(not(target_arch = "x86_64"))]
mod imp {
    /// Four `f32` lanes.
    #[derive(Clone, Copy)]
    pub struct F4([f32; 4]);

    /// A per-lane mask.
    #[derive(Clone, Copy)]
    pub struct M4([bool; 4]);

    #[inline(always)]
    fn zip<T: Copy, U>(a: [T; 4], b: [T; 4], f: impl Fn(T, T) -> U) -> [U; 4] {
        [f(a[0], b[0]), f(a[1], b[1]), f(a[2], b[2]), f(a[3], b[3])]
    }

    impl F4 {
        #[inline(always)]
        pub fn splat(x: f32) -> Self {
            Self([x; 4])
        }
        #[inline(always)]
        pub fn load(a: &[f32; 4]) -> Self {
            Self(*a)
        }
        #[inline(always)]
        pub fn to_array(self) -> [f32; 4] {
            self.0
        }
        #[inline(always)]
        pub fn add(self, b: Self) -> Self {
            Self(zip(self.0, b.0, |x, y| x + y))
        }
        #[inline(always)]
        pub fn sub(self, b: Self) -> Self {
            Self(zip(self.0, b.0, |x, y| x - y))
        }
        #[inline(always)]
        pub fn mul(self, b: Self) -> Self {
            Self(zip(self.0, b.0, |x, y| x * y))
        }
        #[inline(always)]
        pub fn div(self, b: Self) -> Self {
            Self(zip(self.0, b.0, |x, y| x / y))
        }
        /// `self < b ? self : b` per lane: a NaN in `self` yields `b`.
        #[inline(always)]
        pub fn min(self, b: Self) -> Self {
            Self(zip(self.0, b.0, |x, y| if x < y { x } else { y }))
        }
        /// `self > b ? self : b` per lane: a NaN in `self` yields `b`.
        #[inline(always)]
        pub fn max(self, b: Self) -> Self {
            Self(zip(self.0, b.0, |x, y| if x > y { x } else { y }))
        }
        #[inline(always)]
        pub fn abs(self) -> Self {
            Self(self.0.map(f32::abs))
        }
        #[inline(always)]
        pub fn lt(self, b: Self) -> M4 {
            M4(zip(self.0, b.0, |x, y| x < y))
        }
        #[inline(always)]
        pub fn le(self, b: Self) -> M4 {
            M4(zip(self.0, b.0, |x, y| x <= y))
        }
        #[inline(always)]
        pub fn gt(self, b: Self) -> M4 {
            M4(zip(self.0, b.0, |x, y| x > y))
        }
        #[inline(always)]
        pub fn ge(self, b: Self) -> M4 {
            M4(zip(self.0, b.0, |x, y| x >= y))
        }
    }

    impl M4 {
        #[inline(always)]
        pub fn and(self, b: Self) -> Self {
            Self(zip(self.0, b.0, |x, y| x & y))
        }
        /// `self & !b`.
        #[inline(always)]
        pub fn and_not(self, b: Self) -> Self {
            Self(zip(self.0, b.0, |x, y| x & !y))
        }
        #[inline(always)]
        pub fn or(self, b: Self) -> Self {
            Self(zip(self.0, b.0, |x, y| x | y))
        }
        /// Bit `i` set when lane `i` is true.
        #[inline(always)]
        pub fn bits(self) -> u32 {
            self.0
                .iter()
                .enumerate()
                .fold(0, |m, (i, &b)| m | ((b as u32) << i))
        }
    }
}

pub(crate) use imp::{F4, M4};
