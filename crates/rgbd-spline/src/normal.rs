//! Normal equations of a pixel set, stored per knot cell so that the system of a union of
//! disjoint pixel sets is the sum of its parts (region merging, thesis §4.7 eq. 4.8).
//!
//! For every cell a pixel set touches we keep the `k x k` Gram block (`k = (p+1)²` active control
//! points), the right-hand sides, and `Aᵀ1` (to re-centre the data of any union exactly), plus a
//! few scalar moments for the linear (plane-like) fallback and the residual. Accumulation groups
//! pixels into runs (same row, cell and label) so the `k x k` outer products are formed once per
//! run as `M_u ⊗ b_v b_vᵀ` instead of once per pixel.

use std::collections::HashMap;

use rayon::prelude::*;

use crate::basis::Basis;
use crate::grid::KnotGrid;

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

    fn add(&mut self, o: &Moments) {
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

    fn empty(k: usize, channels: usize) -> Self {
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

/// One label's block in one cell: (label, cell id, block, moments).
type CellEntry = (i32, u32, Vec<f64>, Moments);

/// Basis of every column (or row) of the image: the cell and the `p + 1` values.
fn axis_table(grid: &KnotGrid, len: usize, along_u: bool) -> Vec<(usize, Basis)> {
    (0..len)
        .map(|x| {
            let (c0, _, b0, _) = grid.support(x as f64, 0.0);
            let (_, c1, _, b1) = grid.support(0.0, x as f64);
            if along_u {
                (c0, b0)
            } else {
                (c1, b1)
            }
        })
        .collect()
}

/// Accumulates the normal equations of every label in `0..n_labels` (`labels[i] < 0` or any
/// non-finite channel: pixel ignored; `labels = None`: one set of all valid pixels) from
/// `values` (`height x width x channels`, row-major) minus `offset` (per channel).
#[allow(clippy::too_many_arguments)]
pub fn accumulate(
    values: &[f64],
    width: usize,
    height: usize,
    channels: usize,
    labels: Option<&[i32]>,
    n_labels: usize,
    grid: &KnotGrid,
    offset: &[f64],
) -> Vec<Normal> {
    let p = grid.degree;
    let (k1, k) = (p + 1, (p + 1) * (p + 1));
    let cols = axis_table(grid, width, true);
    let rows = axis_table(grid, height, false);
    let inv_s = 1.0 / grid.spacing;
    // Rows grouped by their cell row; groups are independent and run in parallel.
    let mut groups: Vec<(usize, usize)> = Vec::new();
    for v in 0..height {
        match groups.last_mut() {
            Some(g) if rows[g.0].0 == rows[v].0 => g.1 = v + 1,
            _ => groups.push((v, v + 1)),
        }
    }
    let template = Normal::empty(k, channels);
    let bl = template.block_len();
    let parts: Vec<Vec<CellEntry>> = groups
        .par_iter()
        .map(|&(v0, v1)| {
            let mut slots: HashMap<(i32, u32), usize> = HashMap::new();
            let mut out: Vec<CellEntry> = Vec::new();
            let mut mu = vec![0.0; k1 * k1];
            let mut ru = vec![0.0; k1 * channels];
            let mut ou = vec![0.0; k1];
            for v in v0..v1 {
                let (cv, bv) = rows[v];
                let gv = v as f64 * inv_s;
                let mut u = 0;
                while u < width {
                    let label = labels.map_or(0, |l| l[v * width + u]);
                    let cu = cols[u].0;
                    if label < 0 || label as usize >= n_labels.max(1) {
                        u += 1;
                        continue;
                    }
                    // One run: same label, same cell.
                    mu.iter_mut().for_each(|x| *x = 0.0);
                    ru.iter_mut().for_each(|x| *x = 0.0);
                    ou.iter_mut().for_each(|x| *x = 0.0);
                    let mut m = Moments::zeros(channels);
                    while u < width
                        && cols[u].0 == cu
                        && labels.map_or(0, |l| l[v * width + u]) == label
                    {
                        let px = &values[(v * width + u) * channels..][..channels];
                        if px.iter().all(|x| x.is_finite()) {
                            let bu = &cols[u].1.value;
                            let gu = u as f64 * inv_s;
                            for a in 0..k1 {
                                for b in 0..=a {
                                    mu[a * k1 + b] += bu[a] * bu[b];
                                }
                                ou[a] += bu[a];
                            }
                            m.n += 1;
                            let g = [1.0, gu, gv, gu * gu, gu * gv, gv * gv];
                            for (acc, x) in m.geo.iter_mut().zip(g) {
                                *acc += x;
                            }
                            for (ch, &raw) in px.iter().enumerate() {
                                let x = raw - offset[ch];
                                for a in 0..k1 {
                                    ru[a * channels + ch] += bu[a] * x;
                                }
                                m.lin[3 * ch] += x;
                                m.lin[3 * ch + 1] += gu * x;
                                m.lin[3 * ch + 2] += gv * x;
                                m.sq[ch] += x * x;
                            }
                        }
                        u += 1;
                    }
                    if m.n == 0 {
                        continue;
                    }
                    let cell = (cv * grid.cells_u + cu) as u32;
                    let slot = *slots.entry((label, cell)).or_insert_with(|| {
                        out.push((label, cell, vec![0.0; bl], Moments::zeros(channels)));
                        out.len() - 1
                    });
                    let (_, _, block, mom) = &mut out[slot];
                    mom.add(&m);
                    let bvv = &bv.value;
                    let (gram, rest) = block.split_at_mut(k * k);
                    let (rhs, ones) = rest.split_at_mut(k * channels);
                    for ja in 0..k1 {
                        for ia in 0..k1 {
                            let a = ja * k1 + ia;
                            for jb in 0..k1 {
                                for ib in 0..k1 {
                                    let (hi, lo) = if ia >= ib { (ia, ib) } else { (ib, ia) };
                                    gram[a * k + jb * k1 + ib] +=
                                        mu[hi * k1 + lo] * bvv[ja] * bvv[jb];
                                }
                            }
                            for ch in 0..channels {
                                rhs[a * channels + ch] += ru[ia * channels + ch] * bvv[ja];
                            }
                            ones[a] += ou[ia] * bvv[ja];
                        }
                    }
                }
            }
            out
        })
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
