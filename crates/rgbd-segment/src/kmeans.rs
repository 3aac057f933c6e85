//! Seeded k-means (k-means++ initialisation, Lloyd iterations) on the rows of an `n x d` `f32`
//! matrix, used by the normalized-cuts over-segmentation of §4.4 on the Nyström embedding.
//!
//! Cost control: with `n` = 307 200 pixels and `k` ≈ 300 clusters a full Lloyd iteration is
//! `n·k·d` multiply-adds; instead the centres are fitted on a seeded subsample of
//! [`KMeansParams::fit_points`] rows and every row is then assigned once to its nearest centre.
//!
//! Determinism: every random choice comes from one [`SplitMix64`] stream seeded by the caller;
//! per-row work (distances, assignments) is independent of the row order, and every reduction
//! (the k-means++ potential, the centre sums) runs sequentially in row order. The result is
//! therefore bit-identical for a given seed whatever the rayon thread count.

use faer::linalg::matmul::matmul;
use faer::{Accum, MatMut, MatRef, Par};
use rayon::prelude::*;
use rgbd_error::{check_interrupt, check_len, invalid, Result};

/// Default number of rows the centres are fitted on (the rest are only assigned).
pub const DEFAULT_FIT_POINTS: usize = 50_000;
/// Default cap on Lloyd iterations over the fitting rows.
pub const DEFAULT_MAX_ITER: usize = 20;

/// Rows per parallel work item: fixed, so the work split never depends on the thread count.
const ROWS_PER_TASK: usize = 1024;

/// A small, fast, well-mixed 64-bit generator (Steele et al. 2014); one stream per seed.
#[derive(Debug, Clone)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A stream for `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed ^ 0x5851_F42D_4C95_7F2D)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `[0, 1)` with 53 random bits.
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `0..n` (`n > 0`; Lemire's multiply-shift, bias below 2^-64 · n).
    pub fn below(&mut self, n: usize) -> usize {
        ((self.next_u64() as u128 * n as u128) >> 64) as usize
    }

    /// `count` distinct indices of `0..n`, uniformly (partial Fisher–Yates), in draw order.
    pub fn sample_indices(&mut self, n: usize, count: usize) -> Vec<usize> {
        let count = count.min(n);
        let mut idx: Vec<usize> = (0..n).collect();
        for i in 0..count {
            let j = i + self.below(n - i);
            idx.swap(i, j);
        }
        idx.truncate(count);
        idx
    }
}

/// Parameters of [`kmeans`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KMeansParams {
    /// Number of clusters.
    pub k: usize,
    /// Seed of the subsample and of the k-means++ draws.
    pub seed: u64,
    /// Lloyd iterations at most (they stop earlier when no fitting row changes cluster).
    pub max_iter: usize,
    /// Rows the centres are fitted on (a seeded subsample when `n` is larger).
    pub fit_points: usize,
}

impl KMeansParams {
    /// `k` clusters with the default iteration cap and subsample size.
    pub fn new(k: usize, seed: u64) -> Self {
        Self {
            k,
            seed,
            max_iter: DEFAULT_MAX_ITER,
            fit_points: DEFAULT_FIT_POINTS,
        }
    }
}

/// Result of [`kmeans`].
#[derive(Debug, Clone, PartialEq)]
pub struct KMeans {
    /// `k x d` centres, row-major.
    pub centers: Vec<f32>,
    /// Cluster of every row, `0..k`.
    pub labels: Vec<u32>,
    /// Lloyd iterations run on the fitting rows.
    pub iterations: usize,
}

/// Defines `$name` twice, once compiled for AVX2 and chosen at run time when the CPU has it: the
/// loops over rows of `f32` then run 8 lanes wide instead of SSE2's 4 (the crate is built for
/// baseline x86-64). No fused multiply-add is enabled, so both versions round identically.
macro_rules! simd_dispatch {
    ($(#[$meta:meta])* $vis:vis fn $name:ident($($arg:ident : $ty:ty),* $(,)?) $body:block) => {
        $(#[$meta])*
        $vis fn $name($($arg: $ty),*) {
            #[inline(always)]
            fn body($($arg: $ty),*) $body
            #[cfg(target_arch = "x86_64")]
            {
                #[target_feature(enable = "avx2")]
                unsafe fn avx2($($arg: $ty),*) {
                    body($($arg),*)
                }
                if std::arch::is_x86_feature_detected!("avx2") {
                    // SAFETY: the CPU supports AVX2, checked just above.
                    return unsafe { avx2($($arg),*) };
                }
            }
            body($($arg),*)
        }
    };
}
pub(crate) use simd_dispatch;

/// Index of the smallest value (the first one on ties; NaN never wins).
pub(crate) fn argmin(v: &[f32]) -> usize {
    let mut best = 0;
    let mut bv = f32::INFINITY;
    for (j, &x) in v.iter().enumerate() {
        if x < bv {
            bv = x;
            best = j;
        }
    }
    best
}

simd_dispatch! {
    /// `out[r]` = the nearest centre of row `r`, given `dots` (`rows x k`, the rows' dot products
    /// with the centres) and `cn` (the centres' squared norms): argmin of `cn_j - 2 dot_rj`
    /// (the row's own norm is common to every centre), the first one on ties.
    fn nearest(dots: &[f32], cn: &[f32], out: &mut [u32]) {
        let k = cn.len();
        for (row, o) in dots.chunks_exact(k).zip(out.iter_mut()) {
            let mut lo = f32::INFINITY;
            for (&dv, &c) in row.iter().zip(cn) {
                lo = lo.min(c - 2.0 * dv);
            }
            let j = row.iter().zip(cn).position(|(&dv, &c)| c - 2.0 * dv == lo);
            *o = j.unwrap_or(0) as u32;
        }
    }
}

/// Nearest centre of every row of `data` (`n x d`), in parallel over fixed blocks of rows (row
/// `i`'s answer depends only on row `i` and its block, never on the thread count): one faer
/// matrix product per block gives the dot products with the centres.
pub fn assign(data: &[f32], d: usize, centers: &[f32]) -> Result<Vec<u32>> {
    if d == 0 || centers.is_empty() || !centers.len().is_multiple_of(d) {
        return Err(invalid(
            "centers",
            format!("{} values for d = {d}", centers.len()),
            "a non-empty k x d matrix",
        ));
    }
    let k = centers.len() / d;
    let n = data.len() / d;
    check_len("data", data, n * d, "n x d")?;
    crate::workspace::reserve("kmeans")?;
    let cm = MatRef::from_row_major_slice(centers, k, d);
    let cn: Vec<f32> = centers
        .chunks_exact(d)
        .map(|c| c.iter().map(|v| v * v).sum())
        .collect();
    let mut labels = vec![0u32; n];
    labels
        .par_chunks_mut(ROWS_PER_TASK)
        .enumerate()
        .try_for_each(|(t, out)| {
            check_interrupt()?;
            let r0 = t * ROWS_PER_TASK;
            let rows = out.len();
            let xb = MatRef::from_row_major_slice(&data[r0 * d..(r0 + rows) * d], rows, d);
            let mut dots = vec![0.0f32; rows * k];
            matmul(
                MatMut::from_row_major_slice_mut(&mut dots, rows, k),
                Accum::Replace,
                xb,
                cm.transpose(),
                1.0f32,
                Par::Seq,
            );
            nearest(&dots, &cn, out);
            Ok(())
        })?;
    Ok(labels)
}

/// k-means++ seeding (Arthur & Vassilvitskii 2007) on the rows of `x` (`n x d`): the first centre
/// uniform, each next one drawn with probability ∝ squared distance to the nearest chosen one.
fn seed_plus_plus(x: &[f32], n: usize, d: usize, k: usize, rng: &mut SplitMix64) -> Vec<f32> {
    let mut centers = Vec::with_capacity(k * d);
    let first = rng.below(n);
    centers.extend_from_slice(&x[first * d..(first + 1) * d]);
    let mut d2 = vec![f32::INFINITY; n];
    let mut last = first;
    for _ in 1..k {
        let c = &x[last * d..(last + 1) * d];
        d2.par_chunks_mut(ROWS_PER_TASK)
            .enumerate()
            .for_each(|(t, out)| {
                for (r, o) in out.iter_mut().enumerate() {
                    let i = t * ROWS_PER_TASK + r;
                    let row = &x[i * d..(i + 1) * d];
                    let s: f32 = row.iter().zip(c).map(|(a, b)| (a - b) * (a - b)).sum();
                    *o = o.min(s);
                }
            });
        // Sequential potential and draw: independent of the thread count.
        let total: f64 = d2.iter().map(|&v| v as f64).sum();
        let next = if total > 0.0 && total.is_finite() {
            let target = rng.next_f64() * total;
            let mut acc = 0.0f64;
            let mut pick = n - 1;
            for (i, &v) in d2.iter().enumerate() {
                acc += v as f64;
                if acc > target && v > 0.0 {
                    pick = i;
                    break;
                }
            }
            pick
        } else {
            // Every row coincides with a centre already: any row (the cluster stays empty).
            rng.below(n)
        };
        centers.extend_from_slice(&x[next * d..(next + 1) * d]);
        last = next;
    }
    centers
}

/// Seeded k-means of the rows of `data` (`n x d`, row-major, finite): k-means++ seeding and
/// Lloyd iterations on a subsample of `params.fit_points` rows, then one assignment of every row.
/// Errors when `k` is 0 or larger than `n`.
pub fn kmeans(data: &[f32], d: usize, params: &KMeansParams) -> Result<KMeans> {
    if d == 0 {
        return Err(invalid("d", 0, ">= 1"));
    }
    let n = data.len() / d;
    check_len("data", data, n * d, "n x d")?;
    let k = params.k;
    if k == 0 || k > n {
        return Err(invalid("k", k, format!("1..={n} (the number of rows)")));
    }
    if params.fit_points < k {
        return Err(invalid(
            "fit_points",
            params.fit_points,
            format!(">= k = {k}"),
        ));
    }
    let mut rng = SplitMix64::new(params.seed);
    // The fitting subsample, sorted so the centre sums run in row order.
    let fit: Vec<f32> = if n > params.fit_points {
        let mut idx = rng.sample_indices(n, params.fit_points);
        idx.sort_unstable();
        idx.iter()
            .flat_map(|&i| data[i * d..(i + 1) * d].iter().copied())
            .collect()
    } else {
        data.to_vec()
    };
    let m = fit.len() / d;
    let mut centers = seed_plus_plus(&fit, m, d, k, &mut rng);
    let mut labels = vec![u32::MAX; m];
    let mut iterations = 0;
    for _ in 0..params.max_iter {
        check_interrupt()?;
        let new = assign(&fit, d, &centers)?;
        iterations += 1;
        let changed = new != labels;
        labels = new;
        if !changed {
            break;
        }
        let mut sums = vec![0.0f64; k * d];
        let mut counts = vec![0usize; k];
        for (i, &l) in labels.iter().enumerate() {
            let l = l as usize;
            counts[l] += 1;
            for (s, &v) in sums[l * d..(l + 1) * d].iter_mut().zip(&fit[i * d..]) {
                *s += v as f64;
            }
        }
        for (j, &c) in counts.iter().enumerate() {
            // An empty cluster keeps its centre.
            if c > 0 {
                for (dst, &s) in centers[j * d..(j + 1) * d]
                    .iter_mut()
                    .zip(&sums[j * d..(j + 1) * d])
                {
                    *dst = (s / c as f64) as f32;
                }
            }
        }
    }
    let labels = assign(data, d, &centers)?;
    Ok(KMeans {
        centers,
        labels,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `per` points around each of `centres` (2-D), spread ±0.5.
    fn blobs(centres: &[[f32; 2]], per: usize, seed: u64) -> Vec<f32> {
        let mut rng = SplitMix64::new(seed);
        let mut out = Vec::new();
        for _ in 0..per {
            for c in centres {
                out.push(c[0] + rng.next_f64() as f32 - 0.5);
                out.push(c[1] + rng.next_f64() as f32 - 0.5);
            }
        }
        out
    }

    #[test]
    fn separated_blobs_are_recovered() {
        let centres = [
            [0.0, 0.0],
            [10.0, 0.0],
            [0.0, 10.0],
            [10.0, 10.0],
            [5.0, 20.0],
        ];
        let data = blobs(&centres, 200, 1);
        let mut p = KMeansParams::new(5, 7);
        p.fit_points = 300; // fit on a subsample, assign all
        let km = kmeans(&data, 2, &p).unwrap();
        // Every blob maps to one cluster, distinct blobs to distinct clusters.
        let mut seen = [u32::MAX; 5];
        for (i, &l) in km.labels.iter().enumerate() {
            let b = i % 5;
            if seen[b] == u32::MAX {
                seen[b] = l;
            }
            assert_eq!(seen[b], l, "blob {b} split");
        }
        let mut s = seen.to_vec();
        s.sort_unstable();
        s.dedup();
        assert_eq!(s.len(), 5, "blobs merged: {seen:?}");
    }

    #[test]
    fn same_seed_same_result() {
        let data = blobs(&[[0.0, 0.0], [3.0, 1.0], [1.0, 4.0]], 500, 2);
        let p = KMeansParams {
            fit_points: 400,
            ..KMeansParams::new(8, 3)
        };
        let a = kmeans(&data, 2, &p).unwrap();
        let b = kmeans(&data, 2, &p).unwrap();
        assert_eq!(a, b);
        let c = kmeans(&data, 2, &KMeansParams { seed: 4, ..p }).unwrap();
        assert_ne!(a.centers, c.centers);
    }

    #[test]
    fn identical_rows_and_bad_k() {
        let data = vec![1.0f32; 20];
        let km = kmeans(&data, 2, &KMeansParams::new(3, 0)).unwrap();
        assert!(km.labels.iter().all(|&l| l < 3));
        assert!(kmeans(&data, 2, &KMeansParams::new(11, 0)).is_err());
        assert!(kmeans(&data, 2, &KMeansParams::new(0, 0)).is_err());
        assert!(kmeans(&data, 0, &KMeansParams::new(1, 0)).is_err());
    }

    #[test]
    fn sample_indices_are_distinct() {
        let mut rng = SplitMix64::new(9);
        let mut s = rng.sample_indices(100, 40);
        assert_eq!(s.len(), 40);
        s.sort_unstable();
        s.dedup();
        assert_eq!(s.len(), 40);
        assert!(s.iter().all(|&i| i < 100));
    }
}
