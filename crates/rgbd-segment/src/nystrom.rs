//! Normalized-cuts over-segmentation with the Nyström approximation (thesis §4.4; Fowlkes,
//! Belongie, Chung, Malik, PAMI 2004, the one-shot method of METHOD_NOTES §6).
//!
//! **Kernel.** `W_ij = exp(-‖p_i − p_j‖² / σ²)` on the per-pixel feature vectors (the 9-D vectors
//! of eq. 4.1, each group already divided by its average standard deviation), σ = 3 in the
//! thesis ([`DEFAULT_SIGMA`]). Note σ², not 2σ².
//!
//! **Embedding** ([`nystrom_embedding`]). `m` pixels are sampled (seeded); `A` is the `m x m`
//! sample affinity and `K` the `n x m` affinity of every pixel to the samples (the samples'
//! own rows of `K` are rows of `A`, so `W ≈ K A⁺ Kᵀ` is exact on them). Then, as in the one-shot
//! method:
//! 1. degrees `d = K A⁺ (Kᵀ 1)`;
//! 2. `G = D^{-1/2} K`, `S = A^{-1/2} GᵀG A^{-1/2}` (`m x m`), `S = U Λ Uᵀ`;
//! 3. `V = G A^{-1/2} U Λ^{-1/2}` holds orthonormal approximate eigenvectors of
//!    `D^{-1/2} W D^{-1/2}`; the embedding is `E_ik = V_{i,k+1} / V_{i,1}` for the leading
//!    `k = 1..=n_vectors`, with `V_{i,1}` the exact leading eigenvector `sqrt(d_i / Σd)` of the
//!    approximated `W` (the computed one mixes with the next when the graph is nearly
//!    disconnected, and its ratio then blows up). Each coordinate is weighted by its eigenvalue
//!    (one diffusion-map step), so directions with eigenvalues near zero, whose `Λ^{-1/2}`
//!    amplifies noise, do not dominate the k-means distances.
//!
//! `A` is only positive semi-definite in floating point (close samples make it nearly
//! singular), so `A⁺` and `A^{-1/2}` are taken on its eigenvectors whose eigenvalue exceeds
//! [`EIG_FLOOR`] times the largest (a truncated pseudo-inverse), which keeps the one-shot method
//! stable; degrees are floored at [`DEGREE_FLOOR`] times the mean degree.
//!
//! `K` is never stored: three passes (row sums, degrees + `GᵀG`, embedding) recompute it in
//! `f32` blocks of [`BLOCK_ROWS`] rows with rayon; reductions are summed per fixed block in `f64`
//! and the block sums added in block order, so the result does not depend on the thread count.
//!
//! **Over-segmentation** ([`oversegment`]): k-means (seeded k-means++, [`crate::kmeans`]) on
//! `[embedding, feature_weight · features, spatial_weight · position / grid step]`, then every
//! cluster is split into its 4-connected components and components smaller than `min_size`
//! pixels are absorbed by the neighbour they share the longest boundary with. The embedding
//! alone is too smooth for an over-segmentation (on NYUv2 its k-means boundaries find ~0.5 of
//! the ground-truth boundaries against SLIC's ~0.72 at the same count); the features put the
//! sharp edges back, the embedding adds the grouping normalized cuts sees.

#[path = "fragments.rs"]
mod fragments;

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatMut, MatRef, Par, Side};
use rayon::prelude::*;
use rgbd_error::{check_interrupt, check_len, image_len, invalid, Result};

use crate::kmeans::{kmeans, KMeansParams, SplitMix64};
pub use fragments::split_and_absorb;

/// Affinity width σ of `exp(-‖p_i − p_j‖²/σ²)`: the thesis' normalized-cuts parameter (§4.4).
pub const DEFAULT_SIGMA: f32 = 3.0;
/// Default number of Nyström samples `m` (METHOD_NOTES §6: not given by the thesis).
pub const DEFAULT_SAMPLES: usize = 100;
/// Default number of eigenvectors in the embedding (after the trivial first one).
pub const DEFAULT_VECTORS: usize = 8;
/// Default number of k-means clusters. The issue compares over-segmentations at ~300 segments;
/// splitting disconnected clusters adds about a third on NYUv2 frames (net of the absorbed
/// fragments), so 230 clusters give ~300 segments there.
pub const DEFAULT_SEGMENTS: usize = 230;
/// Default weight of the pixel position against the (unit-variance) embedding in k-means,
/// per grid step `sqrt(n_valid / n_segments)` (SLIC's compactness in these units).
pub const DEFAULT_SPATIAL_WEIGHT: f32 = 1.0;
/// Default weight of the input features themselves in k-means, against the unit-variance
/// embedding (the features of eq. 4.1 have unit average deviation per group).
pub const DEFAULT_FEATURE_WEIGHT: f32 = 3.0;
/// Eigenvalues of `A` below this fraction of the largest are dropped from `A⁺` and `A^{-1/2}`.
pub const EIG_FLOOR: f64 = 1e-6;
/// Degrees below this fraction of the mean degree are raised to it.
pub const DEGREE_FLOOR: f64 = 1e-6;
/// Most Nyström samples `m`: the eigensolver of the `m x m` sample affinity is O(m³), so a
/// larger `m` would run for hours instead of failing.
pub const MAX_SAMPLES: usize = 4096;
/// Rows of `K` computed at once (fixed: the reduction order never depends on the thread count).
pub const BLOCK_ROWS: usize = 2048;

/// Parameters of [`nystrom_embedding`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NystromParams {
    /// Affinity width σ (> 0).
    pub sigma: f32,
    /// Number of sampled pixels `m` (>= 2; capped at the number of rows).
    pub n_samples: usize,
    /// Embedding dimensions (>= 1, < the effective `m`).
    pub n_vectors: usize,
    /// Seed of the sample draw.
    pub seed: u64,
}

impl Default for NystromParams {
    fn default() -> Self {
        Self {
            sigma: DEFAULT_SIGMA,
            n_samples: DEFAULT_SAMPLES,
            n_vectors: DEFAULT_VECTORS,
            seed: 0,
        }
    }
}

impl NystromParams {
    /// Checks every field against `n` rows.
    pub fn validate(&self, n: usize) -> Result<()> {
        if !(self.sigma > 0.0) || !self.sigma.is_finite() {
            return Err(invalid("sigma", self.sigma, "a finite number > 0"));
        }
        if !(2..=MAX_SAMPLES).contains(&self.n_samples) {
            return Err(invalid(
                "n_samples",
                self.n_samples,
                format!("2..={MAX_SAMPLES} (the eigensolver is cubic in the samples)"),
            ));
        }
        if n < 2 {
            return Err(invalid(
                "features",
                format!("{n} valid pixels"),
                "at least 2 valid (all-finite) pixels",
            ));
        }
        let m = self.n_samples.min(n);
        if self.n_vectors == 0 || self.n_vectors >= m {
            return Err(invalid(
                "n_vectors",
                self.n_vectors,
                format!("1..={} (fewer than the {m} samples)", m - 1),
            ));
        }
        Ok(())
    }
}

/// The Nyström embedding of [`nystrom_embedding`].
#[derive(Debug, Clone, PartialEq)]
pub struct Embedding {
    /// `n x n_vectors` row-major: `E_ik = λ_{k+1} V_{i,k+1} / V_{i,1}`.
    pub values: Vec<f32>,
    /// Number of columns.
    pub n_vectors: usize,
    /// The leading `n_vectors + 1` approximate eigenvalues of `D^{-1/2} W D^{-1/2}`, descending
    /// (the first is ≈ 1).
    pub eigenvalues: Vec<f64>,
    /// `n x (n_vectors + 1)` row-major `V` (approximate orthonormal eigenvectors), kept only
    /// when asked for (tests).
    pub vectors: Option<Vec<f32>>,
    /// Indices of the sampled rows.
    pub samples: Vec<usize>,
}

/// `exp(x)` for `x <= 0` (clamped at -87), relative error < 1e-5 (range reduction in f32), written so that loops over it
/// vectorise on baseline x86-64 (no libm call): `2^t = 2^i · 2^f`, `i = trunc(t)`, `f ∈ (-1, 0]`.
#[inline(always)]
fn exp_neg(x: f32) -> f32 {
    let t = x.max(-87.0) * std::f32::consts::LOG2_E;
    let i = t as i32; // toward zero: t <= 0 so f = t - i is in (-1, 0]
    let f = (t - i as f32) * std::f32::consts::LN_2;
    // e^f on (-ln 2, 0], Taylor to degree 7 (error < 1.2e-7 relative there).
    let p = 1.0
        + f * (1.0
            + f * (0.5
                + f * (1.0 / 6.0
                    + f * (1.0 / 24.0
                        + f * (1.0 / 120.0 + f * (1.0 / 720.0 + f * (1.0 / 5040.0)))))));
    p * f32::from_bits(((i + 127) as u32) << 23)
}

crate::kmeans::simd_dispatch! {
    /// `k_rj = exp(-max(xn_r + sn_j - 2 dot_rj, 0) / σ²)` in place over `dots` (`rows x m`).
    fn gaussian(dots: &mut [f32], xn: &[f32], sn: &[f32], neg_inv_s2: f32) {
        let m = sn.len();
        for (row, &x) in dots.chunks_exact_mut(m).zip(xn) {
            for (o, &s) in row.iter_mut().zip(sn) {
                let d2 = (x + s - 2.0 * *o).max(0.0);
                *o = exp_neg(d2 * neg_inv_s2);
            }
        }
    }
}

/// The affinity of rows to the samples.
struct Kernel<'a> {
    x: &'a [f32],
    dim: usize,
    /// `m x dim` sample features, row-major.
    samples: Vec<f32>,
    /// Their squared norms.
    sn: Vec<f32>,
    m: usize,
    neg_inv_s2: f32,
}

impl Kernel<'_> {
    /// Rows `[r0, r0 + out.len() / m)` of `K` into `out`: `‖x‖² + ‖s‖² - 2 x·s` with one faer
    /// product per block, then the Gaussian.
    fn block(&self, rows_of: &[f32], out: &mut [f32]) {
        let (m, dim) = (self.m, self.dim);
        let rows = rows_of.len() / dim;
        let xb = MatRef::from_row_major_slice(rows_of, rows, dim);
        let sm = MatRef::from_row_major_slice(&self.samples, m, dim);
        matmul(
            MatMut::from_row_major_slice_mut(out, rows, m),
            Accum::Replace,
            xb,
            sm.transpose(),
            1.0f32,
            Par::Seq,
        );
        let xn: Vec<f32> = rows_of
            .chunks_exact(dim)
            .map(|r| r.iter().map(|v| v * v).sum())
            .collect();
        gaussian(out, &xn, &self.sn, self.neg_inv_s2);
    }

    /// The sample nearest to row `i` in feature space (the first on ties).
    fn nearest(&self, i: usize) -> usize {
        let p = &self.x[i * self.dim..(i + 1) * self.dim];
        let d2: Vec<f32> = self
            .samples
            .chunks_exact(self.dim)
            .map(|s| s.iter().zip(p).map(|(a, b)| (a - b) * (a - b)).sum())
            .collect();
        crate::kmeans::argmin(&d2)
    }

    /// Runs `f(first row, K block)` over fixed blocks of [`BLOCK_ROWS`] rows in parallel and
    /// returns the results in block order.
    fn map_blocks<T: Send>(
        &self,
        n: usize,
        f: impl Fn(usize, &[f32]) -> T + Sync + Send,
    ) -> Result<Vec<T>> {
        let blocks = n.div_ceil(BLOCK_ROWS);
        (0..blocks)
            .into_par_iter()
            .map(|b| {
                check_interrupt()?;
                let r0 = b * BLOCK_ROWS;
                let rows = BLOCK_ROWS.min(n - r0);
                let mut k = vec![0.0f32; rows * self.m];
                self.block(&self.x[r0 * self.dim..(r0 + rows) * self.dim], &mut k);
                Ok(f(r0, &k))
            })
            .collect()
    }
}

/// `A⁺` and `A^{-1/2}` of a symmetric PSD `A` on the eigenvalues above [`EIG_FLOOR`]·max.
fn pinv_and_inv_sqrt(a: &Mat<f64>) -> Result<(Mat<f64>, Mat<f64>)> {
    let m = a.nrows();
    let evd = a.self_adjoint_eigen(Side::Lower).map_err(|e| {
        invalid(
            "features",
            format!("{e:?}"),
            "an affinity with an eigen-decomposition",
        )
    })?;
    let (u, s) = (evd.U(), evd.S().column_vector());
    let top = (0..m).map(|j| s[j]).fold(0.0f64, f64::max);
    let floor = EIG_FLOOR * top;
    let mut pinv = Mat::<f64>::zeros(m, m);
    let mut isq = Mat::<f64>::zeros(m, m);
    for j in 0..m {
        let l = s[j];
        if l > floor && l > 0.0 {
            for r in 0..m {
                for c in 0..m {
                    let uu = u[(r, j)] * u[(c, j)];
                    pinv[(r, c)] += uu / l;
                    isq[(r, c)] += uu / l.sqrt();
                }
            }
        }
    }
    Ok((pinv, isq))
}

/// The normalized-cuts embedding of the `n` rows of `features` (`n x dim`, all finite) by the
/// one-shot Nyström method (module docs). `keep_vectors` also returns `V` (for tests).
pub fn nystrom_embedding(
    features: &[f32],
    dim: usize,
    params: &NystromParams,
    keep_vectors: bool,
) -> Result<Embedding> {
    if dim == 0 {
        return Err(invalid("features", "0 channels", ">= 1 channel"));
    }
    let n = features.len() / dim;
    check_len("features", features, n * dim, "n x dim")?;
    params.validate(n)?;
    crate::workspace::reserve("oversegment")?;
    let mut rng = SplitMix64::new(params.seed);
    let samples = rng.sample_indices(n, params.n_samples);
    let m = samples.len();
    let nv = params.n_vectors;
    let sample_rows: Vec<f32> = samples
        .iter()
        .flat_map(|&i| features[i * dim..(i + 1) * dim].iter().copied())
        .collect();
    let kernel = Kernel {
        x: features,
        dim,
        sn: sample_rows
            .chunks_exact(dim)
            .map(|r| r.iter().map(|v| v * v).sum())
            .collect(),
        samples: sample_rows,
        m,
        neg_inv_s2: -1.0 / (params.sigma * params.sigma),
    };
    // A: the samples' own rows of K (same arithmetic, so K A⁺ Kᵀ is exact on them up to
    // rounding).
    let mut a = Mat::<f64>::zeros(m, m);
    let mut a_rows = vec![0.0f32; m * m];
    kernel.block(&kernel.samples, &mut a_rows);
    for r in 0..m {
        for c in 0..m {
            // Symmetrise (the f32 distance sums may differ in the last bit).
            a[(r, c)] = 0.5 * (a_rows[r * m + c] as f64 + a_rows[c * m + r] as f64);
        }
    }
    let (a_pinv, a_isq) = pinv_and_inv_sqrt(&a)?;

    // Pass 1: column sums of K.
    let partial = kernel.map_blocks(n, |_, k| {
        let mut s = vec![0.0f64; m];
        for row in k.chunks_exact(m) {
            for (acc, &v) in s.iter_mut().zip(row) {
                *acc += v as f64;
            }
        }
        s
    })?;
    let mut colsum = vec![0.0f64; m];
    for p in &partial {
        for (a, b) in colsum.iter_mut().zip(p) {
            *a += b;
        }
    }
    // q = A⁺ Kᵀ1, so d_i = K_i · q.
    let q: Vec<f64> = (0..m)
        .map(|r| (0..m).map(|c| a_pinv[(r, c)] * colsum[c]).sum())
        .collect();
    let mean_degree = colsum.iter().zip(&q).map(|(a, b)| a * b).sum::<f64>() / n as f64;
    let d_floor = (DEGREE_FLOOR * mean_degree).max(f64::MIN_POSITIVE);
    let qf: Vec<f32> = q.iter().map(|&v| v as f32).collect();

    // Pass 2: GᵀG = Σ K_iᵀ K_i / d_i.
    let grams = kernel.map_blocks(n, |_, k| {
        let rows = k.len() / m;
        let mut g = k.to_vec();
        for row in g.chunks_exact_mut(m) {
            let d: f64 = row
                .iter()
                .zip(&qf)
                .map(|(&a, &b)| a as f64 * b as f64)
                .sum();
            let s = (1.0 / d.max(d_floor).sqrt()) as f32;
            row.iter_mut().for_each(|v| *v *= s);
        }
        let gm = MatRef::from_row_major_slice(&g, rows, m);
        let mut out = Mat::<f32>::zeros(m, m);
        matmul(
            out.as_mut(),
            Accum::Replace,
            gm.transpose(),
            gm,
            1.0f32,
            Par::Seq,
        );
        out
    })?;
    let mut gram = Mat::<f64>::zeros(m, m);
    for g in &grams {
        for c in 0..m {
            for r in 0..m {
                gram[(r, c)] += g[(r, c)] as f64;
            }
        }
    }
    drop(grams);
    // S = A^{-1/2} GᵀG A^{-1/2}; its leading eigenvectors.
    let s = &a_isq * &gram * &a_isq;
    let s = Mat::<f64>::from_fn(m, m, |r, c| 0.5 * (s[(r, c)] + s[(c, r)]));
    let evd = s.self_adjoint_eigen(Side::Lower).map_err(|e| {
        invalid(
            "features",
            format!("{e:?}"),
            "an affinity with an eigen-decomposition",
        )
    })?;
    let (u, lam) = (evd.U(), evd.S().column_vector());
    // Ascending order: the leading nv + 1 are the last columns.
    let cols: Vec<usize> = (0..=nv).map(|t| m - 1 - t).collect();
    let eigenvalues: Vec<f64> = cols.iter().map(|&j| lam[j]).collect();
    let lam_floor = EIG_FLOOR * eigenvalues[0].max(0.0);
    let u_top = Mat::<f64>::from_fn(m, nv + 1, |r, t| {
        let l = lam[cols[t]];
        if l > lam_floor && l > 0.0 {
            u[(r, cols[t])] / l.sqrt()
        } else {
            0.0
        }
    });
    // P = A^{-1/2} U Λ^{-1/2}: V_i = G_i P = K_i P / sqrt(d_i).
    let p64 = &a_isq * &u_top;
    let p = Mat::<f32>::from_fn(m, nv + 1, |r, c| p64[(r, c)] as f32);

    // E_ik = V_{i,k} / V_{i,0} with the exact leading vector V_{i,0} = sqrt(d_i / Σd) of
    // W ≈ K A⁺ Kᵀ: unlike the computed column 0, it never crosses zero, also when the graph is
    // (nearly) disconnected and the eigenvalue 1 is repeated. Rows far from every sample (degree
    // below the floor: all affinities underflow) take the embedding of their nearest sample.
    let total_degree = mean_degree * n as f64;
    let embed_row = |kp: &[f32], krow: &[f32], out: &mut [f32], v: Option<&mut Vec<f32>>| -> bool {
        let d: f64 = krow
            .iter()
            .zip(&qf)
            .map(|(&a, &b)| a as f64 * b as f64)
            .sum();
        let s = 1.0 / d.max(d_floor).sqrt();
        if let Some(v) = v {
            v.extend(kp.iter().map(|&x| (x as f64 * s) as f32));
        }
        if !(d > d_floor) {
            return false;
        }
        let e = s * (total_degree / d).sqrt();
        for ((o, &x), &l) in out.iter_mut().zip(&kp[1..]).zip(&eigenvalues[1..]) {
            *o = (x as f64 * e * l.max(0.0)) as f32;
        }
        true
    };
    let mut sample_embed = vec![0.0f32; m * nv];
    {
        let am = MatRef::from_row_major_slice(&a_rows, m, m);
        let mut kp = Mat::<f32>::zeros(m, nv + 1);
        matmul(
            kp.as_mut(),
            Accum::Replace,
            am,
            p.as_ref(),
            1.0f32,
            Par::Seq,
        );
        for j in 0..m {
            let row: Vec<f32> = (0..=nv).map(|c| kp[(j, c)]).collect();
            let krow = &a_rows[j * m..(j + 1) * m];
            embed_row(&row, krow, &mut sample_embed[j * nv..(j + 1) * nv], None);
        }
    }

    // Pass 3: the embedding (and V when asked).
    let blocks = kernel.map_blocks(n, |r0, k| {
        let rows = k.len() / m;
        let km = MatRef::from_row_major_slice(k, rows, m);
        let mut kp = Mat::<f32>::zeros(rows, nv + 1);
        matmul(
            kp.as_mut(),
            Accum::Replace,
            km,
            p.as_ref(),
            1.0f32,
            Par::Seq,
        );
        let mut e = vec![0.0f32; rows * nv];
        let mut v = Vec::with_capacity(if keep_vectors { rows * (nv + 1) } else { 0 });
        let mut row = vec![0.0f32; nv + 1];
        for r in 0..rows {
            for (c, x) in row.iter_mut().enumerate() {
                *x = kp[(r, c)];
            }
            let out = &mut e[r * nv..(r + 1) * nv];
            let krow = &k[r * m..(r + 1) * m];
            if !embed_row(&row, krow, out, keep_vectors.then_some(&mut v)) {
                let j = kernel.nearest(r0 + r);
                out.copy_from_slice(&sample_embed[j * nv..(j + 1) * nv]);
            }
        }
        (e, v)
    })?;
    let mut values = Vec::with_capacity(n * nv);
    let mut vectors = keep_vectors.then(|| Vec::with_capacity(n * (nv + 1)));
    for (e, v) in blocks {
        values.extend_from_slice(&e);
        if let Some(vs) = vectors.as_mut() {
            vs.extend_from_slice(&v);
        }
    }
    Ok(Embedding {
        values,
        n_vectors: nv,
        eigenvalues,
        vectors,
        samples,
    })
}

/// Parameters of [`oversegment`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OversegParams {
    /// The Nyström embedding's parameters (its seed also seeds k-means).
    pub nystrom: NystromParams,
    /// Number of k-means clusters (the output has about this many segments: splitting adds
    /// some, absorbing removes some).
    pub n_segments: usize,
    /// Components smaller than this many pixels are absorbed by a neighbour (1 = none).
    pub min_size: usize,
    /// Weight of the pixel position in k-means (0 = none).
    pub spatial_weight: f32,
    /// Weight of the input features themselves in k-means (0 = the embedding alone).
    pub feature_weight: f32,
    /// Rows k-means fits its centres on.
    pub fit_points: usize,
}

impl OversegParams {
    /// Defaults for `n_segments` clusters.
    pub fn new(n_segments: usize) -> Self {
        Self {
            nystrom: NystromParams::default(),
            n_segments,
            min_size: 1,
            spatial_weight: DEFAULT_SPATIAL_WEIGHT,
            feature_weight: DEFAULT_FEATURE_WEIGHT,
            fit_points: crate::kmeans::DEFAULT_FIT_POINTS,
        }
    }
}

/// Over-segments an `h x w x dim` feature image (row-major; a pixel with any non-finite channel
/// is excluded and labelled -1): Nyström normalized-cuts embedding, seeded k-means on the
/// embedding (scaled to unit mean variance), the features times `feature_weight` and the pixel
/// position (in grid steps `sqrt(n_valid / n_segments)`, times `spatial_weight`), 4-connected
/// split and absorption of components below `min_size`. Returns the `h x w` labels (`0..count`, contiguous, in raster
/// order of first appearance) and `count`.
pub fn oversegment(
    features: &[f32],
    w: usize,
    h: usize,
    dim: usize,
    params: &OversegParams,
) -> Result<(Vec<i32>, usize)> {
    let npx = image_len("features", w, h)?;
    if dim == 0 {
        return Err(invalid("features", "0 channels", ">= 1 channel"));
    }
    check_len("features", features, npx * dim, "h x w x dim")?;
    if !(params.spatial_weight >= 0.0) || !params.spatial_weight.is_finite() {
        return Err(invalid(
            "spatial_weight",
            params.spatial_weight,
            "a finite number >= 0",
        ));
    }
    if !(params.feature_weight >= 0.0) || !params.feature_weight.is_finite() {
        return Err(invalid(
            "feature_weight",
            params.feature_weight,
            "a finite number >= 0",
        ));
    }
    if params.min_size == 0 {
        return Err(invalid("min_size", 0, ">= 1"));
    }
    let valid: Vec<usize> = (0..npx)
        .filter(|&i| {
            features[i * dim..(i + 1) * dim]
                .iter()
                .all(|v| v.is_finite())
        })
        .collect();
    let n = valid.len();
    if n == 0 {
        return Err(invalid(
            "features",
            "no valid pixel",
            "at least one pixel whose channels are all finite",
        ));
    }
    if params.n_segments == 0 || params.n_segments > n {
        return Err(invalid(
            "n_segments",
            params.n_segments,
            format!("1..={n} (the number of valid pixels)"),
        ));
    }
    params.nystrom.validate(n)?;
    let x: Vec<f32> = valid
        .iter()
        .flat_map(|&i| features[i * dim..(i + 1) * dim].iter().copied())
        .collect();
    let emb = nystrom_embedding(&x, dim, &params.nystrom, false)?;
    let nv = emb.n_vectors;
    // Scale the embedding to unit mean variance (sequential f64 sums: thread-count free).
    let mut mean = vec![0.0f64; nv];
    for row in emb.values.chunks_exact(nv) {
        for (a, &v) in mean.iter_mut().zip(row) {
            *a += v as f64;
        }
    }
    mean.iter_mut().for_each(|a| *a /= n as f64);
    let mut var = 0.0f64;
    for row in emb.values.chunks_exact(nv) {
        for (a, &v) in mean.iter().zip(row) {
            var += (v as f64 - a) * (v as f64 - a);
        }
    }
    let scale = {
        let sd = (var / (n * nv) as f64).sqrt();
        if sd > 0.0 && sd.is_finite() {
            (1.0 / sd) as f32
        } else {
            1.0
        }
    };
    let step = (n as f64 / params.n_segments as f64).sqrt().max(1.0) as f32;
    let sw = params.spatial_weight / step;
    let d = nv + dim + 2;
    let fw = params.feature_weight;
    let mut z = vec![0.0f32; n * d];
    z.par_chunks_mut(d * 1024).enumerate().for_each(|(t, out)| {
        for (r, zr) in out.chunks_exact_mut(d).enumerate() {
            let i = t * 1024 + r;
            for (c, o) in zr[..nv].iter_mut().enumerate() {
                *o = (emb.values[i * nv + c] - mean[c] as f32) * scale;
            }
            for (o, &v) in zr[nv..nv + dim].iter_mut().zip(&x[i * dim..(i + 1) * dim]) {
                *o = v * fw;
            }
            let p = valid[i];
            zr[nv + dim] = (p % w) as f32 * sw;
            zr[nv + dim + 1] = (p / w) as f32 * sw;
        }
    });
    drop(emb);
    drop(x);
    let km_params = KMeansParams {
        fit_points: params.fit_points.max(params.n_segments),
        ..KMeansParams::new(params.n_segments, params.nystrom.seed.wrapping_add(1))
    };
    let km = kmeans(&z, d, &km_params)?;
    let assigned = km.labels;
    drop(z);
    let mut labels = vec![-1i32; npx];
    for (&p, &l) in valid.iter().zip(&assigned) {
        labels[p] = l as i32;
    }
    split_and_absorb(&labels, w, h, params.min_size)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_neg_matches_std() {
        let mut worst = 0.0f32;
        for i in 0..200_000 {
            let x = -(i as f32) * 4.0e-4;
            let rel = ((exp_neg(x) - x.exp()) / x.exp()).abs();
            worst = worst.max(rel);
        }
        assert!(worst < 1e-5, "relative error {worst}");
        assert_eq!(exp_neg(0.0), 1.0);
        assert!(exp_neg(-1e9) > 0.0 && exp_neg(-1e9) < 1e-37);
    }

    fn points(n: usize, dim: usize, seed: u64) -> Vec<f32> {
        let mut rng = SplitMix64::new(seed);
        // Three loose clusters so the spectrum has structure.
        (0..n * dim)
            .map(|i| ((i / dim) % 3) as f32 * 2.0 + rng.next_f64() as f32 * 1.5)
            .collect()
    }

    /// With every row sampled, Nyström is exact: V matches the dense eigenvectors of
    /// D^{-1/2} W D^{-1/2} (up to sign) and the eigenvalues match.
    #[test]
    fn all_samples_match_dense_eigendecomposition() {
        let (n, dim, nv) = (60, 3, 4);
        let x = points(n, dim, 1);
        let params = NystromParams {
            sigma: 1.5,
            n_samples: n,
            n_vectors: nv,
            seed: 0,
        };
        let emb = nystrom_embedding(&x, dim, &params, true).unwrap();
        let w = Mat::<f64>::from_fn(n, n, |i, j| {
            let d2: f64 = (0..dim)
                .map(|c| (x[i * dim + c] as f64 - x[j * dim + c] as f64).powi(2))
                .sum();
            (-d2 / 1.5f64.powi(2)).exp()
        });
        let deg: Vec<f64> = (0..n).map(|i| (0..n).map(|j| w[(i, j)]).sum()).collect();
        let l = Mat::<f64>::from_fn(n, n, |i, j| w[(i, j)] / (deg[i] * deg[j]).sqrt());
        let evd = l.self_adjoint_eigen(Side::Lower).unwrap();
        let (u, s) = (evd.U(), evd.S().column_vector());
        let v = emb.vectors.unwrap();
        for t in 0..=nv {
            let j = n - 1 - t;
            assert!(
                (emb.eigenvalues[t] - s[j]).abs() < 1e-4,
                "eigenvalue {t}: {} vs {}",
                emb.eigenvalues[t],
                s[j]
            );
            let dot: f64 = (0..n).map(|i| v[i * (nv + 1) + t] as f64 * u[(i, j)]).sum();
            assert!(
                (dot.abs() - 1.0).abs() < 1e-3,
                "vector {t}: |<v, u>| = {dot}"
            );
        }
        assert!((emb.eigenvalues[0] - 1.0).abs() < 1e-4);
    }

    /// With a subset of samples the approximate eigenvectors are still near-orthonormal and the
    /// embedding separates well-separated groups.
    #[test]
    fn subsampled_embedding_separates_groups() {
        let (n, dim) = (3000, 2);
        let mut rng = SplitMix64::new(5);
        let x: Vec<f32> = (0..n)
            .flat_map(|i| {
                let g = (i % 2) as f32 * 20.0;
                [g + rng.next_f64() as f32, rng.next_f64() as f32]
            })
            .collect();
        let params = NystromParams {
            sigma: 3.0,
            n_samples: 50,
            n_vectors: 2,
            seed: 3,
        };
        let emb = nystrom_embedding(&x, dim, &params, true).unwrap();
        let e1: Vec<f32> = emb.values.chunks(2).map(|r| r[0]).collect();
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        let (mut lo1, mut hi1) = (f32::INFINITY, f32::NEG_INFINITY);
        for (i, &v) in e1.iter().enumerate() {
            if i % 2 == 0 {
                lo = lo.min(v);
                hi = hi.max(v);
            } else {
                lo1 = lo1.min(v);
                hi1 = hi1.max(v);
            }
        }
        assert!(
            hi < lo1 || hi1 < lo,
            "groups overlap: [{lo}, {hi}] vs [{lo1}, {hi1}]"
        );
        let v = emb.vectors.unwrap();
        let n0: f64 = (0..n).map(|i| (v[i * 3] as f64).powi(2)).sum();
        assert!((n0 - 1.0).abs() < 0.05, "|v0|² = {n0}");
    }

    #[test]
    fn bad_parameters_are_refused() {
        let x = points(10, 2, 0);
        let base = NystromParams {
            n_samples: 5,
            n_vectors: 2,
            ..NystromParams::default()
        };
        for p in [
            NystromParams { sigma: 0.0, ..base },
            NystromParams {
                sigma: f32::NAN,
                ..base
            },
            NystromParams {
                n_samples: 1,
                ..base
            },
            NystromParams {
                n_vectors: 5,
                ..base
            },
            NystromParams {
                n_vectors: 0,
                ..base
            },
        ] {
            assert!(nystrom_embedding(&x, 2, &p, false).is_err(), "{p:?}");
        }
        assert!(nystrom_embedding(&x, 2, &base, false).is_ok());
    }

    /// Two halves of different "colour": the over-segmentation never mixes them, every label is
    /// used, and the excluded pixels are exactly -1.
    #[test]
    fn two_colours_are_separated() {
        let (w, h, dim) = (40, 30, 3);
        let mut f = vec![0.0f32; w * h * dim];
        let mut rng = SplitMix64::new(2);
        for y in 0..h {
            for x in 0..w {
                let v = if x < w / 2 { 0.0 } else { 8.0 };
                for c in 0..dim {
                    f[(y * w + x) * dim + c] = v + 0.1 * rng.next_f64() as f32;
                }
            }
        }
        f[(5 * w + 7) * dim + 1] = f32::NAN;
        let mut p = OversegParams::new(6);
        p.nystrom.n_samples = 40;
        p.nystrom.n_vectors = 4;
        p.min_size = 10;
        let (labels, count) = oversegment(&f, w, h, dim, &p).unwrap();
        assert_eq!(labels[5 * w + 7], -1);
        assert_eq!(labels.iter().filter(|&&l| l < 0).count(), 1);
        let mut used = vec![false; count];
        for y in 0..h {
            for x in 0..w {
                let l = labels[y * w + x];
                if l >= 0 {
                    used[l as usize] = true;
                    if x < w / 2 {
                        // No label crosses the colour edge.
                        for x2 in w / 2..w {
                            assert_ne!(labels[y * w + x2], l);
                        }
                    }
                }
            }
        }
        assert!(used.iter().all(|&u| u));
        let again = oversegment(&f, w, h, dim, &p).unwrap();
        assert_eq!(again.0, labels);
    }
}
