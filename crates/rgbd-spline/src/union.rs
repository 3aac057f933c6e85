//! The seam test's union fit in a merge: the one-channel solve of [`crate::fit::solve`] with a
//! blocked band Cholesky.
//!
//! Merging re-solves the whole union of the two segments (its fit is what later tests read), and
//! a segment that keeps absorbing its neighbours (a wall) grows to ~1000 control points with a
//! band half-width ~80. [`crate::band`]'s left-looking factorisation spends most of such a
//! system on short dot products (one per entry, each with its own reduction); the right-looking
//! blocked form here updates the trailing band `NB` columns at a time with contiguous
//! multiply-adds. Same equations, same assembly order: on bands narrower than `BLOCKED_MIN_BW`
//! the fit is [`crate::fit::solve`]'s bit for bit, on wider ones it differs by rounding only
//! (checked by the tests below); the single-surface fits of `fit::solve` are untouched.

use crate::band::{avx2_fma, BandMatrix};
use crate::fit::{add_penalty, linear_coef, Fit, FitKind, Layout, RIDGE};
use crate::grid::KnotGrid;
use crate::local::{box_union, cell_box, CellBox};
use crate::normal::{Normal, UnionCells};
use crate::surface::GridSurface;
use rgbd_error::{invalid, RgbdError};

/// Columns per block of the factorisation.
const NB: usize = 8;

/// Narrowest band factored in blocks (measured: ~1.5x faster than [`crate::band`] at a half-width
/// of 78, no faster at 25-40, slower at 15).
const BLOCKED_MIN_BW: usize = 48;

/// Lower band of a symmetric positive-definite matrix, row `i` holding columns
/// `i - bw ..= i` (the layout of [`BandMatrix`]), factored in place.
struct Band {
    n: usize,
    bw: usize,
    data: Vec<f64>,
}

impl Band {
    /// A copy of `m`.
    fn from(m: &BandMatrix) -> Self {
        let (n, bw) = (m.n, m.bw);
        let w = bw + 1;
        let mut data = vec![0.0; n * w];
        for i in 0..n {
            let (j0, row) = m.row(i);
            let start = i * w + bw + j0 - i;
            data[start..start + row.len()].copy_from_slice(row);
        }
        Self { n, bw, data }
    }

    /// Index of entry `(i, c)`, `i - bw <= c <= i`.
    #[inline(always)]
    fn at(&self, i: usize, c: usize) -> usize {
        i * (self.bw + 1) + self.bw + c - i
    }

    /// `A = L Lᵀ` in place, or the first non-positive pivot's index.
    fn factor(&mut self) -> Result<(), usize> {
        #[cfg(target_arch = "x86_64")]
        if avx2_fma() {
            // SAFETY: the CPU supports AVX2 and FMA (checked just above).
            return unsafe { factor_avx2(self) };
        }
        factor_blocked::<false>(self)
    }

    /// Solves `L Lᵀ x = b` in place.
    fn solve(&self, b: &mut [f64]) {
        let (n, bw) = (self.n, self.bw);
        let d = &self.data;
        for i in 0..n {
            let k0 = i.saturating_sub(bw);
            let s = dot(&d[self.at(i, k0)..self.at(i, i)], &b[k0..i]);
            b[i] = (b[i] - s) / d[self.at(i, i)];
        }
        for i in (0..n).rev() {
            let k0 = i.saturating_sub(bw);
            b[i] /= d[self.at(i, i)];
            let x = b[i];
            for (bk, &lik) in b[k0..i].iter_mut().zip(&d[self.at(i, k0)..self.at(i, i)]) {
                *bk -= lik * x;
            }
        }
    }
}

/// Dot product with eight independent accumulators.
#[inline]
fn dot(a: &[f64], b: &[f64]) -> f64 {
    let mut acc = [0.0; 8];
    let (ca, cb) = (a.chunks_exact(8), b.chunks_exact(8));
    let tail: f64 = ca
        .remainder()
        .iter()
        .zip(cb.remainder())
        .map(|(x, y)| x * y)
        .sum();
    for (x, y) in ca.zip(cb) {
        for k in 0..8 {
            acc[k] += x[k] * y[k];
        }
    }
    ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7])) + tail
}

/// [`factor_blocked`] compiled for AVX2 + FMA.
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn factor_avx2(m: &mut Band) -> Result<(), usize> {
    factor_blocked::<true>(m)
}

/// `s - x·y`, fused when `FMA`.
#[inline(always)]
fn nmadd<const FMA: bool>(x: f64, y: f64, s: f64) -> f64 {
    if FMA {
        (-x).mul_add(y, s)
    } else {
        s - x * y
    }
}

/// Right-looking band Cholesky, `NB` columns at a time: factor the block's diagonal, solve for
/// the block's columns in the at most `bw` rows below it (in `panel`, column by column: `NB`
/// rows of `bw`, zero outside the band, so every step is a contiguous multiply-add over rows),
/// then subtract the block's outer product from the trailing `bw x bw` triangle, row by row.
#[inline(always)]
fn factor_blocked<const FMA: bool>(m: &mut Band) -> Result<(), usize> {
    let (n, bw) = (m.n, m.bw);
    let w = bw + 1;
    let mut panel = vec![0.0; NB * bw.max(1)];
    let mut j0 = 0;
    while j0 < n {
        let j1 = (j0 + NB).min(n);
        // The diagonal block (entries already hold A minus the earlier blocks).
        for i in j0..j1 {
            let ri = i * w + bw - i;
            let c_lo = j0.max(i.saturating_sub(bw));
            for c in c_lo..=i {
                let rc = c * w + bw - c;
                let mut s = m.data[ri + c];
                for k in c_lo..c {
                    s = nmadd::<FMA>(m.data[ri + k], m.data[rc + k], s);
                }
                if c == i {
                    if !(s > 0.0) {
                        return Err(i);
                    }
                    m.data[ri + i] = s.sqrt();
                } else {
                    m.data[ri + c] = s / m.data[rc + c];
                }
            }
        }
        let rows = bw.min(n - j1);
        if rows == 0 {
            j0 = j1;
            continue;
        }
        // The rows below: L[r][c] = (A[r][c] - Σ_{k<c} L[r][k] L[c][k]) / L[c][c] for the
        // block's columns c in order, all rows at once.
        let inside = |r: usize, c: usize| c < j1 && r - c <= bw;
        for k in 0..NB {
            let c = j0 + k;
            for (t, x) in panel[k * rows..(k + 1) * rows].iter_mut().enumerate() {
                let r = j1 + t;
                *x = if inside(r, c) {
                    m.data[r * w + bw + c - r]
                } else {
                    0.0
                };
            }
        }
        for kc in 0..j1 - j0 {
            let c = j0 + kc;
            let rc = c * w + bw - c;
            let (done, rest) = panel.split_at_mut(kc * rows);
            let col = &mut rest[..rows];
            for kk in 0..kc {
                let l = m.data[rc + j0 + kk];
                for (x, &y) in col.iter_mut().zip(&done[kk * rows..(kk + 1) * rows]) {
                    *x = nmadd::<FMA>(l, y, *x);
                }
            }
            let inv = 1.0 / m.data[rc + c];
            for (t, x) in col.iter_mut().enumerate() {
                // Outside the band the entry stays zero (its A entry and all products are 0).
                *x *= inv;
                if inside(j1 + t, c) {
                    let r = j1 + t;
                    m.data[r * w + bw + c - r] = *x;
                }
            }
        }
        for t in 0..rows {
            let r = j1 + t;
            let coef: [f64; NB] = std::array::from_fn(|k| panel[k * rows + t]);
            let start = r * w + bw + j1 - r;
            update_row::<FMA>(&mut m.data[start..=start + t], &panel, rows, &coef);
        }
        j0 = j1;
    }
    Ok(())
}

/// `row[c] -= Σ_k coef[k] · panel[k·stride + c]`, sixteen entries at a time.
#[inline(always)]
fn update_row<const FMA: bool>(row: &mut [f64], panel: &[f64], stride: usize, coef: &[f64; NB]) {
    const L: usize = 16;
    let len = row.len();
    let mut c = 0;
    while c + L <= len {
        let mut acc: [f64; L] = row[c..c + L].try_into().expect("16 entries");
        for (k, &ck) in coef.iter().enumerate() {
            let p = &panel[k * stride + c..k * stride + c + L];
            for l in 0..L {
                acc[l] = nmadd::<FMA>(ck, p[l], acc[l]);
            }
        }
        row[c..c + L].copy_from_slice(&acc);
        c += L;
    }
    while c + 4 <= len {
        let mut acc: [f64; 4] = row[c..c + 4].try_into().expect("4 entries");
        for (k, &ck) in coef.iter().enumerate() {
            let p = &panel[k * stride + c..k * stride + c + 4];
            for l in 0..4 {
                acc[l] = nmadd::<FMA>(ck, p[l], acc[l]);
            }
        }
        row[c..c + 4].copy_from_slice(&acc);
        c += 4;
    }
    for (c, x) in row.iter_mut().enumerate().skip(c) {
        let mut s = *x;
        for (k, &ck) in coef.iter().enumerate() {
            s = nmadd::<FMA>(ck, panel[k * stride + c], s);
        }
        *x = s;
    }
}

/// The one-channel fit of [`crate::fit::solve`] (no degrees of freedom) with the blocked
/// factorisation: the same control points, numbering, assembly and residual.
pub fn solve_one_channel(
    normal: &Normal,
    grid: &KnotGrid,
    lambda: f64,
    offset: &[f64],
) -> Result<Fit, RgbdError> {
    let m = &normal.moments;
    if normal.channels != 1 || m.n < normal.k {
        // Several channels or the linear fallback: nothing to factor.
        return crate::fit::solve(normal, grid, lambda, offset, false);
    }
    let (lo, hi) = cell_box(normal, grid);
    let layout = Layout::new(normal, grid, lo, hi);
    solve_assembled(normal, grid, lambda, offset, (lo, hi), layout, |f| {
        let bl = normal.block_len();
        for (cell, block) in normal.cells.iter().zip(normal.blocks.chunks(bl)) {
            f(*cell, block);
        }
    })
}

/// [`solve_one_channel`] of `a.union(b)` (`boxes`: their cell boxes), without building the
/// union: the same layout, the shared cells' blocks summed as `Normal::union` sums them, the same
/// assembly order, so the same fit bit for bit.
pub fn solve_union(
    a: &Normal,
    b: &Normal,
    boxes: (Option<CellBox>, Option<CellBox>),
    grid: &KnotGrid,
    lambda: f64,
    offset: &[f64],
) -> Result<Fit, RgbdError> {
    let (Some(ba), Some(bb)) = boxes else {
        return solve_one_channel(&a.union(b), grid, lambda, offset);
    };
    let mut moments = a.moments.clone();
    moments.add(&b.moments);
    if a.channels != 1 || b.channels != 1 || moments.n < a.k || a.k != b.k {
        return solve_one_channel(&a.union(b), grid, lambda, offset);
    }
    // The union's moments on a system without cells: what the linear fit and the residual read.
    let head = Normal {
        cells: Vec::new(),
        blocks: Vec::new(),
        moments,
        k: a.k,
        channels: 1,
    };
    let (lo, hi) = box_union(ba, bb);
    let layout = Layout::of_cells(UnionCells::new(a, b), a.k, grid, lo, hi);
    let bl = a.block_len();
    solve_assembled(&head, grid, lambda, offset, (lo, hi), layout, |f| {
        let mut sum = vec![0.0; bl];
        let (mut i, mut j) = (0, 0);
        while i < a.cells.len() || j < b.cells.len() {
            let x = a.cells.get(i).copied().unwrap_or(u32::MAX);
            let y = b.cells.get(j).copied().unwrap_or(u32::MAX);
            if x < y {
                f(x, &a.blocks[i * bl..(i + 1) * bl]);
                i += 1;
            } else if y < x {
                f(y, &b.blocks[j * bl..(j + 1) * bl]);
                j += 1;
            } else {
                let (p, q) = (
                    &a.blocks[i * bl..(i + 1) * bl],
                    &b.blocks[j * bl..(j + 1) * bl],
                );
                for ((s, p), q) in sum.iter_mut().zip(p).zip(q) {
                    *s = p + q;
                }
                f(x, &sum);
                i += 1;
                j += 1;
            }
        }
    })
}

/// The fit of a one-channel system (`normal`: its moments, channels and `k`; `cells`: its cell
/// box; `blocks` calls its argument on each `(cell, block)` in ascending cell order).
fn solve_assembled(
    normal: &Normal,
    grid: &KnotGrid,
    lambda: f64,
    offset: &[f64],
    cells: CellBox,
    layout: Layout,
    blocks: impl FnOnce(&mut dyn FnMut(u32, &[f64])),
) -> Result<Fit, RgbdError> {
    let m = &normal.moments;
    let k = normal.k;
    let (lo, hi) = cells;
    let (lin, _) = linear_coef(normal, grid, offset);
    let Layout {
        shape,
        ref compact,
        n_ids,
        bw,
        ref stencils,
        ..
    } = layout;
    let mean = m.mean()[0];
    let mut gram = BandMatrix::zeros(n_ids, bw);
    let mut rhs = vec![0.0; n_ids];
    let mut ids = vec![0usize; k];
    // Row starts in the band storage: entry (i, j) at row[i] + j, j <= i (the same sums in the
    // same order as `BandMatrix::add`, without its per-entry swap and index arithmetic).
    let w = gram.bw + 1;
    let row: Vec<usize> = (0..n_ids).map(|i| i * w + gram.bw - i).collect();
    {
        let data = gram.lower_mut();
        blocks(&mut |cell, block| {
            for (slot, r) in ids.iter_mut().zip(layout.block_ids(cell)) {
                *slot = compact[r] as usize;
            }
            let (g, rest) = block.split_at(k * k);
            let (brhs, ones) = rest.split_at(k);
            for ia in 0..k {
                let a = ids[ia];
                for (ib, &x) in g[ia * k..=ia * k + ia].iter().enumerate() {
                    let b = ids[ib];
                    let (i, j) = if a >= b { (a, b) } else { (b, a) };
                    data[row[i] + j] += x;
                }
                rhs[a] += brhs[ia] - mean * ones[ia];
            }
        });
    }
    let mut a = gram.clone();
    add_penalty(&mut a, stencils, lambda);
    let target = GridSurface::linear(grid, lo, hi, &lin);
    let mut sol = rhs.clone();
    for (r, &id) in compact.iter().enumerate() {
        if id != u32::MAX {
            let id = id as usize;
            a.add(id, id, RIDGE);
            sol[id] += RIDGE * (target.ctrl[r] - offset[0] - mean);
        }
    }
    let pivot = |i: usize| {
        invalid(
            "segment",
            format!("a non-positive pivot at control point {i}"),
            "a well-posed fit",
        )
    };
    if a.bw < BLOCKED_MIN_BW {
        // Narrow bands: the blocks would be mostly overhead (and the fit is fit::solve's, bit
        // for bit).
        a.cholesky().map_err(pivot)?.solve(&mut sol, 1);
    } else {
        let mut chol = Band::from(&a);
        chol.factor().map_err(pivot)?;
        chol.solve(&mut sol);
    }
    let n = m.n as f64;
    let xx = m.sq[0] - n * mean * mean;
    let cr: f64 = sol.iter().zip(&rhs).map(|(x, r)| x * r).sum();
    let sse = xx - 2.0 * cr + gram.quadratic_form(&sol);
    let ctrl = compact
        .iter()
        .map(|&id| {
            let centred = if id == u32::MAX {
                0.0
            } else {
                sol[id as usize]
            };
            centred + mean + offset[0]
        })
        .collect();
    Ok(Fit {
        surface: GridSurface {
            grid: *grid,
            channels: 1,
            origin: lo,
            shape,
            ctrl,
        },
        kind: FitKind::Spline,
        n: m.n,
        sse: sse.max(0.0),
        dof: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::valid_mean;
    use crate::normal::{accumulate, Region};

    /// A band matrix of `n` unknowns with half-width `bw`, diagonally dominant.
    fn spd(n: usize, bw: usize, seed: u64) -> BandMatrix {
        let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
        let mut rnd = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let mut m = BandMatrix::zeros(n, bw);
        let bw = m.bw;
        for i in 0..n {
            for j in i.saturating_sub(bw)..=i {
                m.add(i, j, if i == j { 2.0 * bw as f64 + 1.0 } else { rnd() });
            }
        }
        m
    }

    #[test]
    fn blocked_factor_solves_like_the_band_module() {
        for (n, bw) in [
            (1, 0),
            (5, 2),
            (9, 8),
            (17, 3),
            (40, 12),
            (200, 37),
            (301, 80),
        ] {
            let m = spd(n, bw, n as u64);
            let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.37).sin()).collect();
            let mut want = b.clone();
            m.clone().cholesky().unwrap().solve(&mut want, 1);
            for fma in [false, true] {
                let mut f = Band::from(&m);
                if fma {
                    f.factor().unwrap();
                } else {
                    factor_blocked::<false>(&mut f).unwrap();
                }
                let mut got = b.clone();
                f.solve(&mut got);
                for (x, y) in got.iter().zip(&want) {
                    assert!((x - y).abs() < 1e-12 * y.abs().max(1.0), "n={n} bw={bw}");
                }
            }
        }
        let mut bad = BandMatrix::zeros(3, 1);
        bad.add(0, 0, 1.0);
        bad.add(1, 1, -1.0);
        bad.add(2, 2, 1.0);
        assert_eq!(Band::from(&bad).factor(), Err(1));
    }

    #[test]
    fn union_fit_matches_the_general_solve() {
        // A curved depth patch in three segments: the fit of one and of unions with bands
        // narrower and wider than BLOCKED_MIN_BW (one part alone: ~27, the others: ~100).
        let (w, h) = (320usize, 240usize);
        let vals: Vec<f64> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                -1.0 / (1.5 + 0.01 * x + 0.002 * y * y / 10.0) + 1e-3 * ((i * 7919) % 13) as f64
            })
            .collect();
        let labels: Vec<i32> = (0..w * h)
            .map(|i| match (i % w, i / w) {
                (x, _) if x < 40 => 0,
                (_, y) if y < 120 => 1,
                _ => 2,
            })
            .collect();
        let grid = KnotGrid::new(w, h, 8.0, 3).unwrap();
        let full = Region::full(w, h);
        let off = valid_mean(&vals, w, 1, full, |_| true);
        let n = accumulate(&vals, w, h, 1, Some(&labels), 3, &grid, &off, full);
        for set in [n[0].clone(), n[1].union(&n[2]), n[0].union(&n[1])] {
            let want = crate::fit::solve(&set, &grid, 0.1, &off, false).unwrap();
            let got = solve_one_channel(&set, &grid, 0.1, &off).unwrap();
            assert_eq!(got.surface.shape, want.surface.shape);
            assert!((got.sse - want.sse).abs() <= 1e-9 * want.sse.max(1e-12));
            for (x, y) in got.surface.ctrl.iter().zip(&want.surface.ctrl) {
                assert!((x - y).abs() <= 1e-10 * y.abs().max(1.0));
            }
        }
    }

    #[test]
    fn union_from_parts_and_in_place_join_equal_the_built_union() {
        // Segments whose cells interleave, share cells, come before and after each other.
        let (w, h) = (200usize, 150usize);
        let vals: Vec<f64> = (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f64, (i / w) as f64);
                1.0 + 0.003 * x + 1e-5 * y * y + 1e-3 * ((i * 7919) % 13) as f64
            })
            .collect();
        let labels: Vec<i32> = (0..w * h)
            .map(|i| {
                let (x, y) = (i % w, i / w);
                match (x, y) {
                    (x, y) if (x / 9 + y / 11) % 3 == 0 && x < 120 => 0,
                    (x, _) if x < 60 => 1,
                    (_, y) if y < 70 => 2,
                    _ => 3,
                }
            })
            .collect();
        let grid = KnotGrid::new(w, h, 8.0, 3).unwrap();
        let full = Region::full(w, h);
        let off = valid_mean(&vals, w, 1, full, |_| true);
        let n = accumulate(&vals, w, h, 1, Some(&labels), 4, &grid, &off, full);
        for (x, y) in [(0, 1), (1, 0), (0, 2), (2, 3), (3, 2), (1, 3), (0, 3)] {
            let (a, b) = (&n[x], &n[y]);
            let built = a.union(b);
            let boxes = (Some(cell_box(a, &grid)), Some(cell_box(b, &grid)));
            let want = solve_one_channel(&built, &grid, 0.1, &off).unwrap();
            let got = solve_union(a, b, boxes, &grid, 0.1, &off).unwrap();
            assert_eq!(got, want, "{x} + {y}");
            let mut joined = a.clone();
            joined.absorb(b);
            assert_eq!(joined, built, "{x} + {y}");
        }
        // A chain of joins in place equals the chain of built unions.
        let mut joined = n[2].clone();
        let mut built = n[2].clone();
        for y in [0, 3, 1] {
            joined.absorb(&n[y]);
            built = built.union(&n[y]);
            assert_eq!(joined, built);
        }
        let mut empty = Normal::empty(n[0].k, 1);
        empty.absorb(&n[1]);
        assert_eq!(empty, Normal::empty(n[0].k, 1).union(&n[1]));
    }
}
