//! Symmetric positive-definite band matrices: Cholesky factorisation, solves and the band of the
//! inverse (selected inversion), which gives the effective degrees of freedom of a fit.
//!
//! The normal equations of a tensor-product spline on an image-anchored grid couple control
//! point `(i, j)` only with `(i ± p, j ± p)`; numbered row-major over a bounding box of `w`
//! columns they form a band of half-width `p·w + p`. A band Cholesky costs `O(n·b²)` instead of
//! the dense `O(n³)`: a whole 640×480 view at 16-pixel spacing (1419 unknowns, b = 132) factors
//! in a few milliseconds. (faer 0.24 has dense and general sparse Cholesky but no band storage;
//! its sparse path needs a symbolic analysis per system, which costs more than the whole solve
//! for the ~100-unknown systems of segment merging.)

/// Dot product with sixteen independent accumulators (four AVX vectors in flight; the compiler
/// vectorises the fixed-size lanes). `FMA` fuses each multiply-add (only inside a function
/// compiled with the `fma` target feature: elsewhere `mul_add` would be a library call).
#[inline(always)]
fn dot_lanes<const FMA: bool>(a: &[f64], b: &[f64]) -> f64 {
    const L: usize = 16;
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let mut acc = [0.0; L];
    let (ca, cb) = (a.chunks_exact(L), b.chunks_exact(L));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for k in 0..L {
            acc[k] = if FMA {
                x[k].mul_add(y[k], acc[k])
            } else {
                acc[k] + x[k] * y[k]
            };
        }
    }
    // The remainder four lanes at a time into the first vector (band rows are short: a scalar
    // tail of up to 15 dependent multiply-adds would cost as much as the vector part).
    let (qa, qb) = (ra.chunks_exact(4), rb.chunks_exact(4));
    let (ta, tb) = (qa.remainder(), qb.remainder());
    for (x, y) in qa.zip(qb) {
        for k in 0..4 {
            acc[k] = if FMA {
                x[k].mul_add(y[k], acc[k])
            } else {
                acc[k] + x[k] * y[k]
            };
        }
    }
    let mut tail = 0.0;
    for (x, y) in ta.iter().zip(tb) {
        tail = if FMA {
            x.mul_add(*y, tail)
        } else {
            tail + x * y
        };
    }
    let mut s = [0.0; 4];
    for k in 0..4 {
        s[k] = (acc[k] + acc[k + 4]) + (acc[k + 8] + acc[k + 12]);
    }
    (s[0] + s[1]) + (s[2] + s[3]) + tail
}

/// Dot product (the portable build: SSE2 on x86-64).
#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    dot_lanes::<false>(a, b)
}

/// Whether the AVX2 + FMA kernels can run here (checked once; cached by std).
#[inline]
pub(crate) fn avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Lower band of a symmetric `n x n` matrix: row `i` stores columns `i - bw ..= i`.
#[derive(Debug, Clone, PartialEq)]
pub struct BandMatrix {
    pub n: usize,
    pub bw: usize,
    data: Vec<f64>,
}

impl BandMatrix {
    pub fn zeros(n: usize, bw: usize) -> Self {
        let bw = bw.min(n.saturating_sub(1));
        Self {
            n,
            bw,
            data: vec![0.0; n * (bw + 1)],
        }
    }

    #[inline]
    fn slot(&self, i: usize, j: usize) -> usize {
        debug_assert!(j <= i && i - j <= self.bw);
        i * (self.bw + 1) + (self.bw + j - i)
    }

    /// Entry `(i, j)` of the symmetric matrix (zero outside the band).
    #[inline]
    pub fn get(&self, i: usize, j: usize) -> f64 {
        let (i, j) = if i >= j { (i, j) } else { (j, i) };
        if i - j > self.bw {
            0.0
        } else {
            self.data[self.slot(i, j)]
        }
    }

    /// Row `i` of the lower band: `(j0, [A[i][j0], ..., A[i][i]])`.
    #[inline]
    pub fn row(&self, i: usize) -> (usize, &[f64]) {
        let j0 = i.saturating_sub(self.bw);
        let r = i * (self.bw + 1) + self.bw - i;
        (j0, &self.data[r + j0..=r + i])
    }

    /// `xᵀ A x` for one vector `x` of length `n`.
    pub fn quadratic_form(&self, x: &[f64]) -> f64 {
        debug_assert_eq!(x.len(), self.n);
        let mut s = 0.0;
        for i in 0..self.n {
            let (j0, r) = self.row(i);
            let (off, diag) = r.split_at(r.len() - 1);
            s += x[i] * (2.0 * dot(off, &x[j0..i]) + diag[0] * x[i]);
        }
        s
    }

    /// The band's storage: entry `(i, j)`, `i - bw <= j <= i`, at `i·(bw + 1) + bw + j - i`
    /// (for assembly loops that add many entries: no index swap or check per entry).
    #[inline]
    pub(crate) fn lower_mut(&mut self) -> &mut [f64] {
        &mut self.data
    }

    /// Adds `x` to entry `(i, j)` and its mirror; `|i - j|` must be within the band.
    #[inline]
    pub fn add(&mut self, i: usize, j: usize, x: f64) {
        let (i, j) = if i >= j { (i, j) } else { (j, i) };
        let s = self.slot(i, j);
        self.data[s] += x;
    }

    /// Cholesky factor `L` (lower, same band), or the first non-positive pivot's index. Uses
    /// AVX2 + FMA where the CPU has them (results then differ from the portable path by
    /// rounding only).
    pub fn cholesky(mut self) -> Result<BandCholesky, usize> {
        #[cfg(target_arch = "x86_64")]
        if avx2_fma() {
            // SAFETY: the CPU supports AVX2 and FMA (checked just above).
            unsafe { factor_avx2(&mut self) }?;
            return Ok(BandCholesky { l: self });
        }
        factor::<false>(&mut self)?;
        Ok(BandCholesky { l: self })
    }
}

/// [`factor`] compiled for AVX2 + FMA.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn factor_avx2(m: &mut BandMatrix) -> Result<(), usize> {
    factor::<true>(m)
}

/// In-place band Cholesky `A = L Lᵀ`, or the first non-positive pivot's index.
#[inline(always)]
fn factor<const FMA: bool>(m: &mut BandMatrix) -> Result<(), usize> {
    let (n, bw) = (m.n, m.bw);
    let w = bw + 1;
    let data = &mut m.data;
    for i in 0..n {
        let j0 = i.saturating_sub(bw);
        let ri = i * w + bw - i;
        for j in j0..=i {
            // L[i][j] = (A[i][j] - sum_k L[i][k] L[j][k]) / L[j][j], k from max(j0, j-bw).
            let k0 = j0.max(j.saturating_sub(bw));
            let rj = j * w + bw - j;
            let s = data[ri + j] - dot_lanes::<FMA>(&data[ri + k0..ri + j], &data[rj + k0..rj + j]);
            if j == i {
                if !(s > 0.0) {
                    return Err(i);
                }
                data[ri + i] = s.sqrt();
            } else {
                data[ri + j] = s / data[rj + j];
            }
        }
    }
    Ok(())
}

/// [`solve_lanes`] compiled for AVX2 + FMA.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn solve_one_avx2(l: &BandMatrix, b: &mut [f64]) {
    solve_lanes::<true>(l, b)
}

/// Forward and back substitution with the factor `l` for one right-hand side `b`.
#[inline(always)]
fn solve_lanes<const FMA: bool>(l: &BandMatrix, b: &mut [f64]) {
    let (n, bw) = (l.n, l.bw);
    let w = bw + 1;
    let d = &l.data;
    for i in 0..n {
        let (ri, k0) = (i * w + bw - i, i.saturating_sub(bw));
        b[i] = (b[i] - dot_lanes::<FMA>(&d[ri + k0..ri + i], &b[k0..i])) / d[ri + i];
    }
    for i in (0..n).rev() {
        let (ri, k0) = (i * w + bw - i, i.saturating_sub(bw));
        b[i] /= d[ri + i];
        let x = b[i];
        for (bk, &lik) in b[k0..i].iter_mut().zip(&d[ri + k0..ri + i]) {
            *bk -= lik * x;
        }
    }
}

/// `A = L Lᵀ` with `L` in band storage.
#[derive(Debug, Clone, PartialEq)]
pub struct BandCholesky {
    l: BandMatrix,
}

impl BandCholesky {
    /// Solves `A X = B` in place for `B` of shape `n x channels` (row-major): one channel at a
    /// time on contiguous row slices (dot products and axpys, AVX2 + FMA where the CPU has them).
    pub fn solve(&self, b: &mut [f64], channels: usize) {
        let n = self.l.n;
        debug_assert_eq!(b.len(), n * channels);
        if channels == 1 {
            self.solve_one(b);
            return;
        }
        let mut col = vec![0.0; n];
        for c in 0..channels {
            for (x, row) in col.iter_mut().zip(b.chunks_exact(channels)) {
                *x = row[c];
            }
            self.solve_one(&mut col);
            for (x, row) in col.iter().zip(b.chunks_exact_mut(channels)) {
                row[c] = *x;
            }
        }
    }

    /// Solves `A x = b` in place for one right-hand side.
    fn solve_one(&self, b: &mut [f64]) {
        #[cfg(target_arch = "x86_64")]
        if avx2_fma() {
            // SAFETY: the CPU supports AVX2 and FMA (checked just above).
            unsafe { solve_one_avx2(&self.l, b) };
            return;
        }
        solve_lanes::<false>(&self.l, b);
    }

    /// The entries of `A⁻¹` inside the band (Takahashi's selected inversion), `O(n·b²)`.
    pub fn inverse_band(&self) -> BandMatrix {
        let (n, bw) = (self.l.n, self.l.bw);
        let w = bw + 1;
        let ld = &self.l.data;
        // Both halves of the band of Z, row j holding columns j - bw ..= j + bw, so the inner
        // products below run over contiguous memory.
        let fw = 2 * bw + 1;
        let mut zf = vec![0.0; n * fw];
        let mut col = vec![0.0; bw];
        for i in (0..n).rev() {
            let lii = ld[i * w + bw];
            let hi = (i + bw).min(n - 1);
            let m = hi - i;
            for (t, c) in col.iter_mut().enumerate().take(m) {
                let k = i + 1 + t;
                *c = ld[k * w + bw + i - k];
            }
            // Z[j][i] = -(1/L_ii) Σ_k L[k][i] Z[j][k], k in i+1..=hi, for j = hi down to i + 1.
            for j in (i + 1..=hi).rev() {
                let row = &zf[j * fw + bw + (i + 1) - j..][..m];
                let x = -dot(&col[..m], row) / lii;
                zf[j * fw + bw + i - j] = x;
                zf[i * fw + bw + j - i] = x;
            }
            let row = &zf[i * fw + bw + 1..][..m];
            zf[i * fw + bw] = 1.0 / (lii * lii) - dot(&col[..m], row) / lii;
        }
        let mut z = BandMatrix::zeros(n, bw);
        for i in 0..n {
            for j in i.saturating_sub(bw)..=i {
                let slot = z.slot(i, j);
                z.data[slot] = zf[i * fw + bw + j - i];
            }
        }
        z
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use faer::linalg::solvers::{DenseSolveCore, Solve};
    use faer::{Mat, Side};
    use proptest::prelude::*;

    fn random_spd(n: usize, bw: usize, seed: u64) -> (BandMatrix, Mat<f64>) {
        let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
        let mut rnd = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let mut band = BandMatrix::zeros(n, bw);
        let mut dense = Mat::<f64>::zeros(n, n);
        for i in 0..n {
            for j in i.saturating_sub(band.bw)..=i {
                let x = if i == j {
                    2.0 * band.bw as f64 + 1.0 + rnd()
                } else {
                    rnd()
                };
                band.add(i, j, x);
                dense[(i, j)] = x;
                dense[(j, i)] = x;
            }
        }
        (band, dense)
    }

    proptest! {
        #[test]
        fn solve_and_inverse_match_dense(n in 1usize..40, bw in 0usize..12, seed in 0u64..1000) {
            let (band, dense) = random_spd(n, bw, seed);
            let bw = band.bw;
            let chol = band.cholesky().unwrap();
            let mut b: Vec<f64> = (0..2 * n).map(|i| (i as f64 * 0.37).sin()).collect();
            let rhs = Mat::<f64>::from_fn(n, 2, |i, c| b[i * 2 + c]);
            chol.solve(&mut b, 2);
            let llt = dense.llt(Side::Lower).unwrap();
            let x = llt.solve(&rhs);
            let inv = llt.inverse();
            for i in 0..n {
                for c in 0..2 {
                    prop_assert!((b[i * 2 + c] - x[(i, c)]).abs() < 1e-10);
                }
            }
            // One right-hand side takes the row-slice path.
            let mut b1: Vec<f64> = (0..n).map(|i| (2.0 * i as f64 * 0.37).sin()).collect();
            chol.solve(&mut b1, 1);
            for i in 0..n {
                prop_assert!((b1[i] - x[(i, 0)]).abs() < 1e-10);
            }
            let z = chol.inverse_band();
            for i in 0..n {
                for j in i.saturating_sub(bw)..=i {
                    prop_assert!((z.get(i, j) - inv[(i, j)]).abs() < 1e-10);
                }
            }
        }
    }

    #[test]
    fn simd_factor_equals_the_portable_one() {
        for (n, bw) in [(1, 0), (7, 3), (60, 17), (200, 40)] {
            let (band, _) = random_spd(n, bw, n as u64);
            let mut plain = band.clone();
            factor::<false>(&mut plain).unwrap();
            let fast = band.cholesky().unwrap();
            for (a, b) in plain.data.iter().zip(&fast.l.data) {
                assert!(
                    (a - b).abs() <= 1e-12 * a.abs().max(1.0),
                    "n={n} bw={bw}: {a} vs {b}"
                );
            }
        }
        assert_eq!(dot(&[1.0; 37], &[2.0; 37]), 74.0);
    }

    #[test]
    fn indefinite_is_reported() {
        let mut m = BandMatrix::zeros(3, 1);
        m.add(0, 0, 1.0);
        m.add(1, 1, -1.0);
        m.add(2, 2, 1.0);
        assert_eq!(m.cholesky().unwrap_err(), 1);
    }
}
