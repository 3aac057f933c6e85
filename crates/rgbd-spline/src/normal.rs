//! Normal equations of a pixel set, stored per knot cell so that the system of a union of
//! disjoint pixel sets is the sum of its parts (region merging, thesis §4.7 eq. 4.8).
//!
//! For every cell a pixel set touches we keep the `k x k` Gram block (`k = (p+1)²` active control
//! points), the right-hand sides, and `Aᵀ1` (to re-centre the data of any union exactly), plus a
//! few scalar moments for the linear (plane-like) fallback and the residual. Accumulation groups
//! pixels into runs (same row, cell and label) so the `k x k` outer products are formed once per
//! run as `M_u ⊗ b_v b_vᵀ` instead of once per pixel.

// Index loops over several fixed-size arrays at once read clearer than zipped iterators here.
#![allow(clippy::needless_range_loop)]

use rayon::prelude::*;

use crate::basis::Basis;
use crate::basis::MAX_DEGREE;
use crate::grid::KnotGrid;
use crate::surface::MAX_CHANNELS;

/// Scalar moments of a pixel set (offset-subtracted values `x`, grid coordinates `g = u / s`).
#[derive(Debug, Clone, PartialEq)]
pub struct Moments {
    /// Valid pixels.
    pub n: usize,
    /// `Σ 1, Σ gu, Σ gv, Σ gu², Σ gu gv, Σ gv²`.
    pub geo: [f64; 6],
    /// Per channel `Σ x, Σ gu x, Σ gv x`.
    pub lin: Vec<f64>,
    /// Per channel `Σ x²`.
    pub sq: Vec<f64>,
}

impl Moments {
    fn zeros(channels: usize) -> Self {
        Self {
            n: 0,
            geo: [0.0; 6],
            lin: vec![0.0; 3 * channels],
            sq: vec![0.0; channels],
        }
    }

    pub(crate) fn add(&mut self, o: &Moments) {
        self.n += o.n;
        for (a, b) in self.geo.iter_mut().zip(&o.geo) {
            *a += b;
        }
        for (a, b) in self.lin.iter_mut().zip(&o.lin) {
            *a += b;
        }
        for (a, b) in self.sq.iter_mut().zip(&o.sq) {
            *a += b;
        }
    }

    /// Mean of each channel (offset-subtracted).
    pub fn mean(&self) -> Vec<f64> {
        let n = self.n.max(1) as f64;
        self.lin.chunks(3).map(|l| l[0] / n).collect()
    }
}

/// Normal equations of one pixel set.
#[derive(Debug, Clone, PartialEq)]
pub struct Normal {
    /// Row-major cell ids `cv * cells_u + cu`, sorted.
    pub cells: Vec<u32>,
    /// Per cell: Gram `k x k`, rhs `k x channels`, `Aᵀ1` (`k`), flattened.
    pub blocks: Vec<f64>,
    pub moments: Moments,
    pub k: usize,
    pub channels: usize,
}

impl Normal {
    /// Floats per cell block.
    pub fn block_len(&self) -> usize {
        self.k * self.k + self.k * self.channels + self.k
    }

    /// The system of no pixel.
    pub(crate) fn empty(k: usize, channels: usize) -> Self {
        Self {
            cells: Vec::new(),
            blocks: Vec::new(),
            moments: Moments::zeros(channels),
            k,
            channels,
        }
    }

    /// The system of the union of two disjoint pixel sets.
    pub fn union(&self, other: &Normal) -> Normal {
        let bl = self.block_len();
        let mut out = Normal::empty(self.k, self.channels);
        out.cells.reserve(self.cells.len() + other.cells.len());
        out.blocks.reserve(self.blocks.len() + other.blocks.len());
        let (mut i, mut j) = (0, 0);
        while i < self.cells.len() || j < other.cells.len() {
            let a = self.cells.get(i).copied().unwrap_or(u32::MAX);
            let b = other.cells.get(j).copied().unwrap_or(u32::MAX);
            if a < b {
                out.cells.push(a);
                out.blocks
                    .extend_from_slice(&self.blocks[i * bl..(i + 1) * bl]);
                i += 1;
            } else if b < a {
                out.cells.push(b);
                out.blocks
                    .extend_from_slice(&other.blocks[j * bl..(j + 1) * bl]);
                j += 1;
            } else {
                out.cells.push(a);
                let (x, y) = (
                    &self.blocks[i * bl..(i + 1) * bl],
                    &other.blocks[j * bl..(j + 1) * bl],
                );
                out.blocks.extend(x.iter().zip(y).map(|(p, q)| p + q));
                i += 1;
                j += 1;
            }
        }
        out.moments = self.moments.clone();
        out.moments.add(&other.moments);
        out
    }
}

impl Normal {
    /// Joins the disjoint pixel set `other` into this one in place: afterwards `self` equals
    /// `self.union(other)` (same cells, same sums), without building a new system. The blocks
    /// after the first cell `other` adds move back once (a merge from the end), and the storage
    /// grows geometrically, so a segment that keeps absorbing neighbours reallocates rarely.
    pub fn absorb(&mut self, other: &Normal) {
        let bl = self.block_len();
        let (na, nb) = (self.cells.len(), other.cells.len());
        let shared = {
            let (mut i, mut j, mut s) = (0, 0, 0);
            while i < na && j < nb {
                match self.cells[i].cmp(&other.cells[j]) {
                    std::cmp::Ordering::Less => i += 1,
                    std::cmp::Ordering::Greater => j += 1,
                    std::cmp::Ordering::Equal => {
                        s += 1;
                        i += 1;
                        j += 1;
                    }
                }
            }
            s
        };
        let total = na + nb - shared;
        self.cells.resize(total, 0);
        self.blocks.resize(total * bl, 0.0);
        let (mut i, mut j, mut out) = (na, nb, total);
        while j > 0 {
            let b = other.cells[j - 1];
            out -= 1;
            if i > 0 && self.cells[i - 1] >= b {
                let a = self.cells[i - 1];
                if out != i - 1 {
                    self.cells[out] = a;
                    self.blocks.copy_within((i - 1) * bl..i * bl, out * bl);
                }
                if a == b {
                    let src = &other.blocks[(j - 1) * bl..j * bl];
                    for (x, y) in self.blocks[out * bl..(out + 1) * bl].iter_mut().zip(src) {
                        *x += y;
                    }
                    j -= 1;
                }
                i -= 1;
            } else {
                self.cells[out] = b;
                self.blocks[out * bl..(out + 1) * bl]
                    .copy_from_slice(&other.blocks[(j - 1) * bl..j * bl]);
                j -= 1;
            }
        }
        debug_assert_eq!(out, i);
        self.moments.add(&other.moments);
    }
}

/// The cells of the union of two systems, ascending, each once (a merge of the sorted lists).
#[derive(Clone)]
pub(crate) struct UnionCells<'a> {
    a: &'a [u32],
    b: &'a [u32],
}

impl<'a> UnionCells<'a> {
    pub(crate) fn new(a: &'a Normal, b: &'a Normal) -> Self {
        Self {
            a: &a.cells,
            b: &b.cells,
        }
    }
}

impl Iterator for UnionCells<'_> {
    type Item = u32;

    #[inline]
    fn next(&mut self) -> Option<u32> {
        match (self.a.first(), self.b.first()) {
            (None, None) => None,
            (Some(&x), None) => {
                self.a = &self.a[1..];
                Some(x)
            }
            (None, Some(&y)) => {
                self.b = &self.b[1..];
                Some(y)
            }
            (Some(&x), Some(&y)) => {
                if x <= y {
                    self.a = &self.a[1..];
                }
                if y <= x {
                    self.b = &self.b[1..];
                }
                Some(x.min(y))
            }
        }
    }
}

const RUN_K: usize = MAX_DEGREE + 1;

/// Sums over one run of pixels (one row, one cell, one label).
struct RunSums {
    n: usize,
    /// Lower triangle of `Σ b_u b_uᵀ` (row stride `RUN_K`).
    mu: [f64; RUN_K * RUN_K],
    ou: [f64; RUN_K],
    /// `Σ b_u x` per channel (channel-major: the basis functions of one channel are contiguous).
    ru: [[f64; RUN_K]; MAX_CHANNELS],
    su: f64,
    suu: f64,
    sx: [f64; MAX_CHANNELS],
    sux: [f64; MAX_CHANNELS],
    sxx: [f64; MAX_CHANNELS],
}

impl RunSums {
    /// Adds this run's scalar moments (the run lies in row `gv`, grid units) to `m`.
    fn add_moments(&self, m: &mut Moments, gv: f64) {
        let n = self.n as f64;
        m.n += self.n;
        let g = [n, self.su, n * gv, self.suu, gv * self.su, n * gv * gv];
        for (acc, x) in m.geo.iter_mut().zip(g) {
            *acc += x;
        }
        for (ch, sq) in m.sq.iter_mut().enumerate() {
            m.lin[3 * ch] += self.sx[ch];
            m.lin[3 * ch + 1] += self.sux[ch];
            m.lin[3 * ch + 2] += gv * self.sx[ch];
            *sq += self.sxx[ch];
        }
    }
}

impl RunSums {
    fn zero() -> Self {
        Self {
            n: 0,
            mu: [0.0; RUN_K * RUN_K],
            ou: [0.0; RUN_K],
            ru: [[0.0; RUN_K]; MAX_CHANNELS],
            su: 0.0,
            suu: 0.0,
            sx: [0.0; MAX_CHANNELS],
            sux: [0.0; MAX_CHANNELS],
            sxx: [0.0; MAX_CHANNELS],
        }
    }

    /// Adds the geometric sums (basis products, column moments) of column `u`.
    #[inline(always)]
    fn add_geometry(&mut self, u: usize, basis: &Basis, k1: usize, inv_s: f64) {
        let bu = &basis.value;
        let gu = u as f64 * inv_s;
        self.su += gu;
        self.suu += gu * gu;
        for a in 0..k1 {
            for b in 0..=a {
                self.mu[a * RUN_K + b] += bu[a] * bu[b];
            }
            self.ou[a] += bu[a];
        }
    }
}

/// Per cell column (from the first of `cols`, which start at column `u0`): its pixel columns
/// `[start, end)` and the geometric sums of a run covering all of them. Most runs are such full runs without holes, and then only the data sums (`Aᵀx`, a
/// few moments) are left to accumulate per pixel.
fn full_runs(
    cols: &[(usize, Basis)],
    u0: usize,
    k1: usize,
    inv_s: f64,
) -> Vec<(usize, usize, RunSums)> {
    let mut out: Vec<(usize, usize, RunSums)> = Vec::new();
    let c0 = cols.first().map_or(0, |c| c.0);
    for (u, (cu, basis)) in (u0..).zip(cols) {
        if out.len() <= cu - c0 {
            out.push((u, u, RunSums::zero()));
        }
        let last = &mut out[cu - c0];
        last.1 = u + 1;
        last.2.n += 1;
        last.2.add_geometry(u, basis, k1, inv_s);
    }
    out
}

/// The sums of one run of `C`-channel pixels `px` (columns `u0..`, bases `cols`); `full` holds
/// the geometric sums to use when every pixel of the run is valid.
#[inline(always)]
fn run_sums<T: Copy + Into<f64>, const C: usize>(
    px: &[T],
    cols: &[(usize, Basis)],
    u0: usize,
    k1: usize,
    inv_s: f64,
    offset: &[f64],
    full: Option<&RunSums>,
) -> RunSums {
    let mut r = RunSums::zero();
    let off: [f64; C] = std::array::from_fn(|c| offset[c]);
    let finite = |p: &[T]| -> Option<[f64; C]> {
        let x: [f64; C] = std::array::from_fn(|c| p[c].into() - off[c]);
        x.iter().all(|v| v.is_finite()).then_some(x)
    };
    for (i, (p, (_, basis))) in px.chunks_exact(C).zip(cols).enumerate() {
        let Some(x) = finite(p) else { continue };
        let bu = &basis.value;
        let gu = (u0 + i) as f64 * inv_s;
        r.n += 1;
        for c in 0..C {
            for a in 0..k1 {
                r.ru[c][a] += bu[a] * x[c];
            }
        }
        for c in 0..C {
            r.sx[c] += x[c];
            r.sux[c] += gu * x[c];
            r.sxx[c] += x[c] * x[c];
        }
    }
    match full {
        Some(t) if r.n == cols.len() => {
            r.mu = t.mu;
            r.ou = t.ou;
            r.su = t.su;
            r.suu = t.suu;
        }
        _ => {
            for (i, (p, (_, basis))) in px.chunks_exact(C).zip(cols).enumerate() {
                if finite(p).is_some() {
                    r.add_geometry(u0 + i, basis, k1, inv_s);
                }
            }
        }
    }
    r
}

/// One label's block in one cell: (label, cell id, block, moments).
type CellEntry = (i32, u32, Vec<f64>, Moments);

/// Basis of the columns (or rows) `a..b` of the image: the cell and the `p + 1` values.
pub(crate) fn axis_table(
    grid: &KnotGrid,
    a: usize,
    b: usize,
    along_u: bool,
) -> Vec<(usize, Basis)> {
    (a..b).map(|x| grid.axis(x as f64, along_u)).collect()
}

/// Pixel rectangle `[u0, u1) x [v0, v1)` that holds every pixel of interest.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Region {
    pub u0: usize,
    pub u1: usize,
    pub v0: usize,
    pub v1: usize,
}

impl Region {
    pub fn full(width: usize, height: usize) -> Self {
        Self {
            u0: 0,
            u1: width,
            v0: 0,
            v1: height,
        }
    }

    /// Bounding box of the true pixels of a `width`-wide row-major mask (`None` if none is).
    pub fn of_mask(width: usize, mask: &[bool]) -> Option<Self> {
        let mut r = Self {
            u0: width,
            u1: 0,
            v0: usize::MAX,
            v1: 0,
        };
        for (v, row) in mask.chunks_exact(width.max(1)).enumerate() {
            // Most rows hold no true pixel: a branch-free OR over the row vectorises, the
            // early-exit search runs only on rows that have one.
            if !row.iter().fold(false, |a, &b| a | b) {
                continue;
            }
            let Some(first) = row.iter().position(|&b| b) else {
                continue;
            };
            let last = row.iter().rposition(|&b| b).unwrap_or(first);
            r.u0 = r.u0.min(first);
            r.u1 = r.u1.max(last + 1);
            r.v0 = r.v0.min(v);
            r.v1 = v + 1;
        }
        (r.u1 > r.u0).then_some(r)
    }

    /// Bounding box of the pixels where `keep` holds (`None` if there are none).
    pub fn bounding(width: usize, height: usize, keep: impl Fn(usize) -> bool) -> Option<Self> {
        let mut r = Self {
            u0: width,
            u1: 0,
            v0: height,
            v1: 0,
        };
        for v in 0..height {
            for u in 0..width {
                if keep(v * width + u) {
                    r.u0 = r.u0.min(u);
                    r.u1 = r.u1.max(u + 1);
                    r.v0 = r.v0.min(v);
                    r.v1 = r.v1.max(v + 1);
                }
            }
        }
        (r.u1 > r.u0).then_some(r)
    }
}

/// What [`cell_rows`] reads: the image, its labels and the tables shared by all cell rows.
struct Ctx<'c, T, L> {
    values: &'c [T],
    width: usize,
    lab: &'c L,
    n_labels: usize,
    cells_u: usize,
    offset: &'c [f64],
    region: Region,
    /// Bases of the region's columns and rows (from `region.u0`, `region.v0`).
    cols: &'c [(usize, Basis)],
    rows: &'c [(usize, Basis)],
    /// Full runs per cell column from the region's first, `cell0`.
    templates: &'c [(usize, usize, RunSums)],
    cell0: usize,
    inv_s: f64,
    /// (index into the Gram block, index into the `tri x tri` sums) of its lower triangle.
    lower: &'c [(usize, usize)],
    block_len: usize,
}

/// Index of the symmetric pair `(a, b)` among the `k1 (k1 + 1) / 2` distinct ones.
#[inline(always)]
fn pair(a: usize, b: usize) -> usize {
    let (hi, lo) = if a >= b { (a, b) } else { (b, a) };
    hi * (hi + 1) / 2 + lo
}

/// The cell blocks of image rows `v0..v1` (one cell row), `K1 = p + 1` basis functions per axis
/// and `C` channels known at compile time (the loops over them unroll).
#[inline(always)]
fn cell_rows<T: Copy + Into<f64>, L: Fn(usize) -> i32, const K1: usize, const C: usize>(
    ctx: &Ctx<'_, T, L>,
    v0: usize,
    v1: usize,
) -> Vec<CellEntry> {
    let k = K1 * K1;
    let tri = K1 * (K1 + 1) / 2;
    let (region, cols, width) = (ctx.region, ctx.cols, ctx.width);
    // Per cell column of this cell row: the (label, index into `out`) seen there.
    let mut slots: Vec<Vec<(i32, usize)>> = vec![Vec::new(); ctx.cells_u];
    let mut out: Vec<CellEntry> = Vec::new();
    let mut g2s: Vec<Vec<f64>> = Vec::new();
    let mut mt = [0.0; RUN_K * (RUN_K + 1) / 2];
    let mut wt = [0.0; RUN_K * (RUN_K + 1) / 2];
    for v in v0..v1 {
        let (cv, bv) = ctx.rows[v - region.v0];
        let gv = v as f64 * ctx.inv_s;
        for a in 0..K1 {
            for b in 0..=a {
                wt[pair(a, b)] = bv.value[a] * bv.value[b];
            }
        }
        let mut u = region.u0;
        while u < region.u1 {
            let label = (ctx.lab)(v * width + u);
            let col = |x: usize| &cols[x - region.u0];
            let cu = col(u).0;
            // One run: same label, same cell.
            let mut end = u + 1;
            while end < region.u1 && col(end).0 == cu && (ctx.lab)(v * width + end) == label {
                end += 1;
            }
            let (u0, u1) = (u, end);
            u = end;
            if label < 0 || label as usize >= ctx.n_labels.max(1) {
                continue;
            }
            let px = &ctx.values[(v * width + u0) * C..(v * width + u1) * C];
            let full = ctx
                .templates
                .get(cu - ctx.cell0)
                .filter(|t| t.0 == u0 && t.1 == u1)
                .map(|t| &t.2);
            let run_cols = &cols[u0 - region.u0..u1 - region.u0];
            let r = run_sums::<T, C>(px, run_cols, u0, K1, ctx.inv_s, ctx.offset, full);
            if r.n == 0 {
                continue;
            }
            let cell = (cv * ctx.cells_u + cu) as u32;
            let slot = match slots[cu].iter().find(|e| e.0 == label) {
                Some(e) => e.1,
                None => {
                    out.push((label, cell, vec![0.0; ctx.block_len], Moments::zeros(C)));
                    g2s.push(vec![0.0; tri * tri]);
                    slots[cu].push((label, out.len() - 1));
                    out.len() - 1
                }
            };
            let (_, _, block, mom) = &mut out[slot];
            r.add_moments(mom, gv);
            let (mu, ru, ou) = (&r.mu, &r.ru, &r.ou);
            let bvv = &bv.value;
            for a in 0..K1 {
                for b in 0..=a {
                    mt[pair(a, b)] = mu[a * RUN_K + b];
                }
            }
            for (row, &m) in g2s[slot].chunks_exact_mut(tri).zip(&mt[..tri]) {
                for (g, &w) in row.iter_mut().zip(&wt[..tri]) {
                    *g += m * w;
                }
            }
            let (_, rest) = block.split_at_mut(k * k);
            let (rhs, ones) = rest.split_at_mut(k * C);
            for ja in 0..K1 {
                for ia in 0..K1 {
                    let a = ja * K1 + ia;
                    for ch in 0..C {
                        rhs[a * C + ch] += ru[ch][ia] * bvv[ja];
                    }
                    ones[a] += ou[ia] * bvv[ja];
                }
            }
        }
    }
    for ((_, _, block, _), g2) in out.iter_mut().zip(&g2s) {
        for &(g, t) in ctx.lower {
            block[g] = g2[t];
        }
    }
    out
}

/// [`cell_rows`] of cubic splines compiled for AVX2 + FMA (the sums keep their separate
/// roundings: the same results as the portable build).
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn cell_rows_avx2<T: Copy + Into<f64>, L: Fn(usize) -> i32, const C: usize>(
    ctx: &Ctx<'_, T, L>,
    v0: usize,
    v1: usize,
) -> Vec<CellEntry> {
    cell_rows::<T, L, 4, C>(ctx, v0, v1)
}

/// [`cell_rows`] for a run-time degree (1 ..= [`MAX_DEGREE`]) and channel count
/// (1 ..= [`MAX_CHANNELS`]).
fn cell_rows_dyn<T: Copy + Into<f64>, L: Fn(usize) -> i32>(
    ctx: &Ctx<'_, T, L>,
    degree: usize,
    channels: usize,
    v0: usize,
    v1: usize,
) -> Vec<CellEntry> {
    #[cfg(target_arch = "x86_64")]
    if degree == 3 && crate::band::avx2_fma() {
        // SAFETY (all three): the CPU supports AVX2 and FMA (checked just above).
        match channels {
            1 => return unsafe { cell_rows_avx2::<T, L, 1>(ctx, v0, v1) },
            3 => return unsafe { cell_rows_avx2::<T, L, 3>(ctx, v0, v1) },
            _ => {}
        }
    }
    macro_rules! by_channels {
        ($k1:literal) => {
            match channels {
                1 => cell_rows::<T, L, $k1, 1>(ctx, v0, v1),
                2 => cell_rows::<T, L, $k1, 2>(ctx, v0, v1),
                3 => cell_rows::<T, L, $k1, 3>(ctx, v0, v1),
                _ => cell_rows::<T, L, $k1, 4>(ctx, v0, v1),
            }
        };
    }
    match degree {
        1 => by_channels!(2),
        2 => by_channels!(3),
        3 => by_channels!(4),
        4 => by_channels!(5),
        _ => by_channels!(6),
    }
}

/// Accumulates the normal equations of every label in `0..n_labels` (`labels[i] < 0` or any
/// non-finite channel: pixel ignored; `labels = None`: one set of all valid pixels) from
/// `values` (`height x width x channels`, row-major, `f32` or `f64`) minus `offset` (per
/// channel), visiting only the pixels of `region`.
#[allow(clippy::too_many_arguments)]
pub fn accumulate<T: Copy + Into<f64> + Sync>(
    values: &[T],
    width: usize,
    height: usize,
    channels: usize,
    labels: Option<&[i32]>,
    n_labels: usize,
    grid: &KnotGrid,
    offset: &[f64],
    region: Region,
) -> Vec<Normal> {
    let lab = |i: usize| labels.map_or(0, |l| l[i]);
    accumulate_by(
        values, width, height, channels, lab, n_labels, grid, offset, region,
    )
}

/// As [`accumulate`] with the label of pixel `i` given by `lab(i)` (a mask needs no label image).
#[allow(clippy::too_many_arguments)]
pub(crate) fn accumulate_by<T: Copy + Into<f64> + Sync>(
    values: &[T],
    width: usize,
    height: usize,
    channels: usize,
    lab: impl Fn(usize) -> i32 + Sync,
    n_labels: usize,
    grid: &KnotGrid,
    offset: &[f64],
    region: Region,
) -> Vec<Normal> {
    let p = grid.degree;
    let (k1, k) = (p + 1, (p + 1) * (p + 1));
    debug_assert!(region.u1 <= width && region.v1 <= height);
    // Only the region's columns and rows: a small segment of a large image costs its box.
    let cols = axis_table(grid, region.u0, region.u1, true);
    let rows = axis_table(grid, region.v0, region.v1, false);
    let inv_s = 1.0 / grid.spacing;
    let templates = full_runs(&cols, region.u0, k1, inv_s);
    // Rows grouped by their cell row; groups are independent and run in parallel.
    let mut groups: Vec<(usize, usize)> = Vec::new();
    for v in region.v0..region.v1 {
        match groups.last_mut() {
            Some(g) if rows[g.0 - region.v0].0 == rows[v - region.v0].0 => g.1 = v + 1,
            _ => groups.push((v, v + 1)),
        }
    }
    // Σ over runs of M_u ⊗ b_v b_vᵀ: both factors are symmetric with `tri` distinct entries, so
    // each run adds the rank-1 product of the two `tri`-vectors to a `tri x tri` matrix (contiguous,
    // vectorisable); it is expanded into the lower triangle of the Gram block once per cell.
    let tri = k1 * (k1 + 1) / 2;
    let lower: Vec<(usize, usize)> = (0..k)
        .flat_map(|a| (0..=a).map(move |b| (a, b)))
        .map(|(a, b)| {
            let ((ja, ia), (jb, ib)) = ((a / k1, a % k1), (b / k1, b % k1));
            (a * k + b, pair(ia, ib) * tri + pair(ja, jb))
        })
        .collect();
    let template = Normal::empty(k, channels);
    let ctx = Ctx {
        values,
        width,
        lab: &lab,
        n_labels,
        cells_u: grid.cells_u,
        offset,
        region,
        cols: &cols,
        rows: &rows,
        templates: &templates,
        cell0: cols.first().map_or(0, |c| c.0),
        inv_s,
        lower: &lower,
        block_len: template.block_len(),
    };
    let parts: Vec<Vec<CellEntry>> = groups
        .par_iter()
        .map(|&(v0, v1)| cell_rows_dyn(&ctx, p, channels, v0, v1))
        .collect();
    let mut all: Vec<CellEntry> = parts.into_iter().flatten().collect();
    all.sort_unstable_by_key(|e| (e.0, e.1));
    let mut normals: Vec<Normal> = (0..n_labels.max(1)).map(|_| template.clone()).collect();
    for (label, cell, block, mom) in all {
        let nrm = &mut normals[label as usize];
        nrm.cells.push(cell);
        nrm.blocks.extend_from_slice(&block);
        nrm.moments.add(&mom);
    }
    normals
}
