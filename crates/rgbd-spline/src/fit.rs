//! Solving the normal equations of one pixel set: the regularised spline fit, its residual,
//! effective degrees of freedom, and the linear fallback for tiny sets.

use crate::band::BandMatrix;
use crate::grid::KnotGrid;
use crate::local::cell_box;
use crate::normal::Normal;
use crate::surface::GridSurface;
use rgbd_error::{invalid, RgbdError};

/// Ridge weight pulling every control point towards the set's least-squares linear fit
/// (relative to one data point's weight). It only matters for control points that neither data
/// nor the second-difference penalty pin down (degree 1 on thin sets); a linear surface is
/// reproduced exactly whatever its value, since it has zero penalty and zero ridge.
pub const RIDGE: f64 = 1e-10;

/// How a set was fitted.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FitKind {
    /// Regularised tensor-product B-spline.
    Spline,
    /// `a + b·u + c·v` per channel: fewer than `(p+1)²` valid pixels.
    Linear,
}

/// A fitted pixel set.
#[derive(Debug, Clone, PartialEq)]
pub struct Fit {
    pub surface: GridSurface,
    pub kind: FitKind,
    /// Valid pixels fitted.
    pub n: usize,
    /// Sum over pixels of the squared 3-D (all channels) distance to the surface.
    pub sse: f64,
    /// Effective degrees of freedom `tr(H)` (`H` the hat matrix), `None` unless requested.
    pub dof: Option<f64>,
}

impl Fit {
    /// Mean squared error `sse / n` (thesis §4.5 / eq. 4.8's `e`).
    pub fn mse(&self) -> f64 {
        self.sse / self.n as f64
    }

    /// Generalised cross-validation score `n · sse / (n - dof)²`: the expected squared error on
    /// new points of the same surface, so a set does not score better merely because it is
    /// small. Infinite when the fit interpolates (`dof >= n`).
    pub fn gcv(&self) -> f64 {
        let n = self.n as f64;
        let d = self.dof.unwrap_or(0.0);
        if n - d <= 1e-9 * n {
            f64::INFINITY
        } else {
            n * self.sse / ((n - d) * (n - d))
        }
    }
}

/// Fits the pixel set of `normal` (values were accumulated minus `offset`).
pub fn solve(
    normal: &Normal,
    grid: &KnotGrid,
    lambda: f64,
    offset: &[f64],
    with_dof: bool,
) -> Result<Fit, RgbdError> {
    let m = &normal.moments;
    if m.n == 0 {
        return Err(invalid(
            "segment",
            "no valid pixel",
            "at least one pixel with finite values",
        ));
    }
    let (lo, hi) = cell_box(normal, grid);
    let (lin, lin_sse) = linear_coef(normal, grid, offset);
    if m.n < normal.k {
        return Ok(Fit {
            surface: GridSurface::linear(grid, lo, hi, &lin),
            kind: FitKind::Linear,
            n: m.n,
            sse: lin_sse,
            dof: Some(3.0f64.min(m.n as f64)),
        });
    }
    let c = normal.channels;
    let k = normal.k;
    let layout = Layout::new(normal, grid, lo, hi);
    let Layout {
        shape,
        ref compact,
        n_ids,
        bw,
        ref stencils,
        ..
    } = layout;
    let rect = shape.0 * shape.1;
    // Assemble the centred system: rhs_c = Aᵀ(x - mean) = Aᵀx - mean · Aᵀ1.
    let mean = m.mean();
    let bl = normal.block_len();
    let mut a = BandMatrix::zeros(n_ids, bw);
    let mut rhs = vec![0.0; n_ids * c];
    let mut rhs_ridge = vec![0.0; n_ids * c];
    let mut ids = vec![0usize; k];
    // Entry (i, j), j <= i, of the band storage at (i + 1)·bw + j: `BandMatrix::add`'s sums in
    // the same order, without its per-entry swap and index arithmetic.
    let abw = a.bw;
    for (cell, block) in normal.cells.iter().zip(normal.blocks.chunks(bl)) {
        for (slot, r) in ids.iter_mut().zip(layout.block_ids(*cell)) {
            *slot = compact[r] as usize;
        }
        let (gram, rest) = block.split_at(k * k);
        let (brhs, ones) = rest.split_at(k * c);
        let data = a.lower_mut();
        for ia in 0..k {
            let x = ids[ia];
            for (ib, &g) in gram[ia * k..=ia * k + ia].iter().enumerate() {
                let y = ids[ib];
                let (i, j) = if x >= y { (x, y) } else { (y, x) };
                data[(i + 1) * abw + j] += g;
            }
            for ch in 0..c {
                rhs[ids[ia] * c + ch] += brhs[ia * c + ch] - mean[ch] * ones[ia];
            }
        }
    }
    // The data Gram matrix alone is needed for the residual and the degrees of freedom.
    let gram_band = a.clone();
    add_penalty(&mut a, stencils, lambda);
    let target = GridSurface::linear(grid, lo, hi, &lin);
    for (r, &id) in compact.iter().enumerate() {
        if id != u32::MAX {
            let id = id as usize;
            a.add(id, id, RIDGE);
            for ch in 0..c {
                rhs_ridge[id * c + ch] = RIDGE * (target.ctrl[r * c + ch] - offset[ch] - mean[ch]);
            }
        }
    }
    let chol = a.cholesky().map_err(|i| {
        invalid(
            "segment",
            format!("a non-positive pivot at control point {i}"),
            "a well-posed fit",
        )
    })?;
    let mut sol: Vec<f64> = rhs.iter().zip(&rhs_ridge).map(|(a, b)| a + b).collect();
    chol.solve(&mut sol, c);
    // ||A c - x̃||² = x̃ᵀx̃ - 2 cᵀ Aᵀx̃ + cᵀ G c, with x̃ = x - mean.
    let n = m.n as f64;
    let mut sse = 0.0;
    let mut col = vec![0.0; n_ids];
    for ch in 0..c {
        let xx = m.sq[ch] - n * mean[ch] * mean[ch];
        let mut cr = 0.0;
        for (i, x) in col.iter_mut().enumerate() {
            *x = sol[i * c + ch];
            cr += *x * rhs[i * c + ch];
        }
        sse += xx - 2.0 * cr + gram_band.quadratic_form(&col);
    }
    let dof = with_dof.then(|| {
        let z = chol.inverse_band();
        let mut tr = 0.0;
        for i in 0..n_ids {
            for j in i.saturating_sub(gram_band.bw)..=i {
                let w = if i == j { 1.0 } else { 2.0 };
                tr += w * z.get(i, j) * gram_band.get(i, j);
            }
        }
        tr
    });
    let mut ctrl = Vec::with_capacity(rect * c);
    for &id in compact {
        for ch in 0..c {
            let centred = if id == u32::MAX {
                0.0
            } else {
                sol[id as usize * c + ch]
            };
            ctrl.push(centred + mean[ch] + offset[ch]);
        }
    }
    Ok(Fit {
        surface: GridSurface {
            grid: *grid,
            channels: c,
            origin: lo,
            shape,
            ctrl,
        },
        kind: FitKind::Spline,
        n: m.n,
        sse: sse.max(0.0),
        dof,
    })
}

/// The control points a pixel set touches, in the set's cell box grown by the degree, numbered
/// compactly, and what the band system over them needs (shared by [`solve`] and the merge's
/// one-channel union fit, `crate::union::solve_one_channel`).
pub(crate) struct Layout {
    /// Control points of the box, `(u, v)`.
    pub shape: (usize, usize),
    /// Compact id of each control point of the box (row-major), `u32::MAX` where untouched.
    pub compact: Vec<u32>,
    /// Number of touched control points.
    pub n_ids: usize,
    /// Band half-width of the Gram matrix plus the penalty.
    pub bw: usize,
    /// [`penalty_stencils`] of the compact numbering.
    pub stencils: Vec<[u32; 3]>,
    lo: (usize, usize),
    cells_u: usize,
    k: usize,
    k1: usize,
}

impl Layout {
    pub(crate) fn new(
        normal: &Normal,
        grid: &KnotGrid,
        lo: (usize, usize),
        hi: (usize, usize),
    ) -> Self {
        Self::of_cells(normal.cells.iter().copied(), normal.k, grid, lo, hi)
    }

    /// [`Self::new`] of a system with these cells (ascending, each once) and `k` points per
    /// cell, e.g. the union of two systems that is not built.
    pub(crate) fn of_cells<I: Iterator<Item = u32> + Clone>(
        cells: I,
        k: usize,
        grid: &KnotGrid,
        lo: (usize, usize),
        hi: (usize, usize),
    ) -> Self {
        let p = grid.degree;
        let shape = (hi.0 - lo.0 + 1 + p, hi.1 - lo.1 + 1 + p);
        let mut layout = Self {
            shape,
            compact: vec![u32::MAX; shape.0 * shape.1],
            n_ids: 0,
            bw: 0,
            stencils: Vec::new(),
            lo,
            cells_u: grid.cells_u,
            k,
            k1: p + 1,
        };
        for cell in cells.clone() {
            for r in layout.block_ids(cell) {
                layout.compact[r] = 0;
            }
        }
        // Numbered along the shorter side of the box: the band half-width is about p times that
        // side, and the band Cholesky costs n·bw² (a wide wall segment: several times less).
        let mut n_ids = 0u32;
        if shape.0 <= shape.1 {
            for x in layout.compact.iter_mut().filter(|x| **x == 0) {
                *x = n_ids;
                n_ids += 1;
            }
        } else {
            for i in 0..shape.0 {
                for j in 0..shape.1 {
                    let x = &mut layout.compact[j * shape.0 + i];
                    if *x == 0 {
                        *x = n_ids;
                        n_ids += 1;
                    }
                }
            }
        }
        layout.n_ids = n_ids as usize;
        let mut bw = 0;
        for cell in cells {
            let first = layout.compact[layout.block_ids(cell).next().unwrap_or(0)];
            let last = layout.compact[layout.block_ids(cell).next_back().unwrap_or(0)];
            bw = bw.max((last - first) as usize);
        }
        layout.stencils = penalty_stencils(&layout.compact, shape);
        for s in &layout.stencils {
            bw = bw.max((s[2] - s[0]) as usize);
        }
        layout.bw = bw;
        layout
    }

    /// Box indices of the `k` control points of grid cell `cell`, in the block order.
    pub(crate) fn block_ids(&self, cell: u32) -> impl DoubleEndedIterator<Item = usize> {
        let (cu, cv) = (
            cell as usize % self.cells_u - self.lo.0,
            cell as usize / self.cells_u - self.lo.1,
        );
        let (k1, w) = (self.k1, self.shape.0);
        (0..self.k).map(move |a| (cv + a / k1) * w + cu + a % k1)
    }
}

/// Adds `lambda` times the second-difference penalty of `stencils` to `a`.
pub(crate) fn add_penalty(a: &mut BandMatrix, stencils: &[[u32; 3]], lambda: f64) {
    let stencil = [1.0, -2.0, 1.0];
    for s in stencils {
        for x in 0..3 {
            for y in 0..=x {
                a.add(
                    s[x] as usize,
                    s[y] as usize,
                    lambda * stencil[x] * stencil[y],
                );
            }
        }
    }
}

/// Second-difference stencils (compact ids, ascending) whose three control points all belong to
/// the set, along u and along v.
pub(crate) fn penalty_stencils(compact: &[u32], shape: (usize, usize)) -> Vec<[u32; 3]> {
    let mut out = Vec::new();
    let (w, h) = shape;
    for j in 0..h {
        for i in 0..w {
            let r = j * w + i;
            if i + 2 < w {
                let s = [compact[r], compact[r + 1], compact[r + 2]];
                if s.iter().all(|&x| x != u32::MAX) {
                    out.push(s);
                }
            }
            if j + 2 < h {
                let s = [compact[r], compact[r + w], compact[r + 2 * w]];
                if s.iter().all(|&x| x != u32::MAX) {
                    out.push(s);
                }
            }
        }
    }
    out
}

/// Least-squares `a + b·gu + c·gv` per channel from the moments, in coordinates centred on the
/// set (a tiny ridge on the slopes keeps a one-pixel-wide line well-posed).
pub(crate) fn linear_coef(normal: &Normal, grid: &KnotGrid, offset: &[f64]) -> (Vec<f64>, f64) {
    let m = &normal.moments;
    let g = m.geo;
    let n = m.n as f64;
    let (mu, mv) = (g[1] / n, g[2] / n);
    let suu = g[3] - n * mu * mu;
    let suv = g[4] - n * mu * mv;
    let svv = g[5] - n * mv * mv;
    let eps = 1e-9 * n;
    let det = (suu + eps) * (svv + eps) - suv * suv;
    let mut coef = Vec::with_capacity(3 * normal.channels);
    let mut sse = 0.0;
    for (ch, l) in m.lin.chunks(3).enumerate() {
        let mean = l[0] / n;
        let (tu, tv) = (l[1] - n * mu * mean, l[2] - n * mv * mean);
        let bu = ((svv + eps) * tu - suv * tv) / det;
        let bv = ((suu + eps) * tv - suv * tu) / det;
        let xx = m.sq[ch] - n * mean * mean;
        sse += xx - 2.0 * (bu * tu + bv * tv) + bu * bu * suu + 2.0 * bu * bv * suv + bv * bv * svv;
        // Grid coordinates -> pixels, offset restored.
        let a = mean - bu * mu - bv * mv + offset[ch];
        coef.extend_from_slice(&[a, bu / grid.spacing, bv / grid.spacing]);
    }
    (coef, sse.max(0.0))
}
