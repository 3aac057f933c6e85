//! Height-field splines of orthographic depth views (thesis §5.3.3, the curvature maps of a
//! shape): `z(u, v)` fitted by regularised least squares to scattered samples (the pixels of a
//! view, or the points a view sees) on a uniform cubic knot grid over the view, and the principal
//! curvatures of the graph `(u, v, z(u, v))` at every pixel.
//!
//! In an orthographic view the 3-D point of pixel `(u, v)` is `(u, v, z)` up to one scale, so
//! `x` and `y` are linear in the parameters and a cubic spline reproduces them exactly: fitting
//! `z` alone is the thesis' 3-D fit (degree 3, unit weights) at a third of the cost.
//!
//! Coordinates: pixel column `i`, row `j` has its centre at `(i, j)`; samples may lie anywhere in
//! `[-0.5, width - 0.5] x [-0.5, height - 0.5]`; `z` is in the unit of the pixel pitch, so the
//! curvatures come out in 1 / pixel. Sign: positive where the surface bulges towards the viewer
//! (the viewer looks along +z; a ball facing it has `k1 = k2 = +1/r`), as in [`crate::curvature`].
//!
//! Cost: the normal equations are accumulated per knot cell (a dense 16 x 16 block, scattered
//! into the band once per cell) and solved by a band Cholesky of `(n_u n_v) (3 n_u + 3)²`
//! operations; a 320 x 320 view with knots every 13.3 px (27 x 27 control points) takes a few
//! milliseconds.

use rayon::prelude::*;

use crate::band::BandMatrix;
use crate::normal::Region;
use rgbd_error::{check_interrupt, invalid, mismatch, RgbdError};

/// Spline degree (thesis §5.3.3: 3 in u and v).
pub const HEIGHT_DEGREE: usize = 3;
/// Control points active on one cell along one axis, and in one cell.
const K1: usize = HEIGHT_DEGREE + 1;
const K: usize = K1 * K1;
/// Distinct entries of a symmetric `K x K` block.
const TRI: usize = K * (K + 1) / 2;
/// Ridge (relative to one sample's weight) pulling every control point towards the samples'
/// least-squares plane: keeps the system positive definite when the samples do not fix a plane (a one
/// pixel wide strip); far below the data and smoothness terms otherwise.
pub const HEIGHT_RIDGE: f64 = 1e-9;

/// A uniform knot grid with knots every `spacing` pixels over a `width x height` view.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeightGrid {
    pub width: usize,
    pub height: usize,
    pub spacing: f64,
    pub cells_u: usize,
    pub cells_v: usize,
}

/// Cubic uniform B-spline basis at local parameter `t`: values, first and second derivatives
/// (with respect to `t`).
#[inline]
fn cubic(t: f64) -> [[f64; K1]; 3] {
    let s = 1.0 - t;
    let (t2, t3) = (t * t, t * t * t);
    [
        [
            s * s * s / 6.0,
            (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0,
            (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
            t3 / 6.0,
        ],
        [
            -s * s / 2.0,
            (3.0 * t2 - 4.0 * t) / 2.0,
            (-3.0 * t2 + 2.0 * t + 1.0) / 2.0,
            t2 / 2.0,
        ],
        [s, 3.0 * t - 2.0, 1.0 - 3.0 * t, t],
    ]
}

impl HeightGrid {
    /// Grid of a `width x height` view (each at least 1) with knots every `spacing >= 1` pixels.
    pub fn new(width: usize, height: usize, spacing: f64) -> Result<Self, RgbdError> {
        if width == 0 || height == 0 {
            return Err(invalid(
                "size",
                format!("{width}x{height}"),
                "a non-empty view",
            ));
        }
        if !(spacing.is_finite() && spacing >= 1.0) {
            return Err(invalid("spacing", spacing, "a knot spacing >= 1 pixel"));
        }
        let cells = |n: usize| ((n as f64 / spacing).ceil() as usize).max(1);
        Ok(Self {
            width,
            height,
            spacing,
            cells_u: cells(width),
            cells_v: cells(height),
        })
    }

    /// Control points along u and v.
    pub fn ctrl_shape(&self) -> (usize, usize) {
        (self.cells_u + HEIGHT_DEGREE, self.cells_v + HEIGHT_DEGREE)
    }

    /// Cell and local parameter of coordinate `x` (pixel units) along an axis of `cells` cells.
    #[inline]
    fn locate(&self, x: f64, cells: usize) -> (usize, f64) {
        let g = (x + 0.5) / self.spacing;
        let c = (g.floor().max(0.0) as usize).min(cells - 1);
        (c, (g - c as f64).clamp(0.0, 1.0))
    }
}

/// A fitted height field `z(u, v) = offset + Σ ctrl[j][i] N_i(u) N_j(v)`.
#[derive(Debug, Clone, PartialEq)]
pub struct HeightSpline {
    pub grid: HeightGrid,
    /// Row-major `n_v x n_u` control values (relative to `offset`); NaN for control points no
    /// sample's cell touches.
    pub ctrl: Vec<f64>,
    pub offset: f64,
}

/// Fits `z(u, v)` to `samples` (`[u, v, z]`, every value finite) with second-difference
/// smoothness `lambda` (relative to one sample's weight). `None` when there are fewer than 16
/// samples (too few for one cubic patch: the caller reports no curvature).
pub fn fit_height(
    samples: &[[f64; 3]],
    grid: &HeightGrid,
    lambda: f64,
) -> Result<Option<HeightSpline>, RgbdError> {
    if !(lambda.is_finite() && lambda > 0.0) {
        return Err(invalid("lambda", lambda, "a finite smoothness weight > 0"));
    }
    if let Some(bad) = samples
        .iter()
        .position(|s| !s.iter().all(|x| x.is_finite()))
    {
        return Err(invalid(
            "samples",
            format!("a non-finite sample at index {bad}"),
            "finite u, v, z",
        ));
    }
    if samples.len() < K {
        return Ok(None);
    }
    let (nu, nv) = grid.ctrl_shape();
    let n_cells = grid.cells_u * grid.cells_v;
    let offset = samples.iter().map(|s| s[2]).sum::<f64>() / samples.len() as f64;
    // Counting sort of the samples by cell, so each cell's block is accumulated in one place.
    let located: Vec<(usize, f64, f64, f64)> = samples
        .iter()
        .map(|s| {
            let (cu, tu) = grid.locate(s[0], grid.cells_u);
            let (cv, tv) = grid.locate(s[1], grid.cells_v);
            (cv * grid.cells_u + cu, tu, tv, s[2] - offset)
        })
        .collect();
    let mut start = vec![0usize; n_cells + 1];
    for l in &located {
        start[l.0 + 1] += 1;
    }
    for c in 0..n_cells {
        start[c + 1] += start[c];
    }
    let mut next = start.clone();
    let mut order = vec![0usize; located.len()];
    for (i, l) in located.iter().enumerate() {
        order[next[l.0]] = i;
        next[l.0] += 1;
    }
    // The unknowns are the control points of cells holding samples; the others stay NaN, so no
    // curvature is reported where they would matter. They are numbered along the shorter side
    // of their bounding box (the band half-width is about 3 times that side).
    let cell_id = |cell: usize, x: usize| {
        let (cu, cv) = (cell % grid.cells_u, cell / grid.cells_u);
        (cv + x / K1) * nu + cu + x % K1
    };
    let occupied: Vec<usize> = (0..n_cells).filter(|&c| start[c + 1] > start[c]).collect();
    let mut compact = vec![usize::MAX; nu * nv];
    let (mut lo, mut hi) = ((usize::MAX, usize::MAX), (0, 0));
    for &cell in &occupied {
        for x in 0..K {
            let r = cell_id(cell, x);
            compact[r] = 0;
            lo = (lo.0.min(r % nu), lo.1.min(r / nu));
            hi = (hi.0.max(r % nu), hi.1.max(r / nu));
        }
    }
    let mut n = 0;
    let mut number = |r: usize| {
        if compact[r] == 0 {
            compact[r] = n + 1; // 0 marks "touched, not numbered yet"
            n += 1;
        }
    };
    if hi.0 - lo.0 <= hi.1 - lo.1 {
        for j in lo.1..=hi.1 {
            for i in lo.0..=hi.0 {
                number(j * nu + i);
            }
        }
    } else {
        for i in lo.0..=hi.0 {
            for j in lo.1..=hi.1 {
                number(j * nu + i);
            }
        }
    }
    let id = |r: usize| compact[r].wrapping_sub(1); // usize::MAX - 1 + 1 wraps: untouched stays huge
    let stencils: Vec<[usize; 3]> = (0..nv)
        .flat_map(|j| (0..nu).map(move |i| (i, j)))
        .flat_map(|(i, j)| {
            let r = j * nu + i;
            [
                (i + 2 < nu).then(|| [r, r + 1, r + 2]),
                (j + 2 < nv).then(|| [r, r + nu, r + 2 * nu]),
            ]
        })
        .flatten()
        .filter(|s| s.iter().all(|&r| compact[r] != usize::MAX))
        .map(|s| s.map(id))
        .collect();
    let mut bw = 0;
    for &cell in &occupied {
        let ids = (0..K).map(|x| id(cell_id(cell, x)));
        let (min, max) = ids.fold((usize::MAX, 0), |(a, b), x| (a.min(x), b.max(x)));
        bw = bw.max(max - min);
    }
    for s in &stencils {
        bw = bw.max(s.iter().max().unwrap_or(&0) - s.iter().min().unwrap_or(&0));
    }
    let mut a = BandMatrix::zeros(n, bw);
    let mut rhs = vec![0.0; n];
    let mut gram = [0.0; TRI];
    let mut brhs = [0.0; K];
    for cell in 0..n_cells {
        let members = &order[start[cell]..start[cell + 1]];
        if members.is_empty() {
            continue;
        }
        gram.fill(0.0);
        brhs.fill(0.0);
        // The block is Σ (b_v b_vᵀ) ⊗ (b_u b_uᵀ): samples of one pixel row share b_v (the
        // stable sort keeps a view's row-major order), so each run of equal `tv` sums its
        // `b_u b_uᵀ` first and touches the 16 x 16 block once.
        let mut k = 0;
        while k < members.len() {
            let tv = located[members[k]].2;
            let mut tu_sum = [[0.0; K1]; K1];
            let mut ru = [0.0; K1];
            while k < members.len() && located[members[k]].2 == tv {
                let (_, tu, _, z) = located[members[k]];
                let bu = cubic(tu)[0];
                for (x, &bx) in bu.iter().enumerate() {
                    ru[x] += bx * z;
                    for (y, &by) in bu.iter().enumerate() {
                        tu_sum[x][y] += bx * by;
                    }
                }
                k += 1;
            }
            let bv = cubic(tv)[0];
            let mut slot = 0;
            for (x, bx) in brhs.iter_mut().enumerate() {
                let (jx, ix) = (x / K1, x % K1);
                *bx += bv[jx] * ru[ix];
                for y in 0..=x {
                    gram[slot] += bv[jx] * bv[y / K1] * tu_sum[ix][y % K1];
                    slot += 1;
                }
            }
        }
        let ids: [usize; K] = std::array::from_fn(|x| id(cell_id(cell, x)));
        let mut slot = 0;
        for x in 0..K {
            rhs[ids[x]] += brhs[x];
            for y in 0..=x {
                a.add(ids[x], ids[y], gram[slot]);
                slot += 1;
            }
        }
    }
    // Second differences along u and along v (P-spline penalty), and the ridge.
    let stencil = [1.0, -2.0, 1.0];
    let mut penalise = |ids: [usize; 3]| {
        for x in 0..3 {
            for y in 0..=x {
                a.add(ids[x], ids[y], lambda * stencil[x] * stencil[y]);
            }
        }
    };
    for s in &stencils {
        penalise(*s);
    }
    // The ridge pulls towards the samples' least-squares plane, which the spline reproduces
    // (control point `k` of a uniform cubic sits at `(k - 1)·spacing - 0.5`): planes stay exact.
    let plane = least_squares_plane(samples, offset);
    let at = |k: usize| (k as f64 - 1.0) * grid.spacing - 0.5;
    for j in 0..nv {
        for i in 0..nu {
            let r = id(j * nu + i);
            if r < n {
                a.add(r, r, HEIGHT_RIDGE);
                rhs[r] += HEIGHT_RIDGE * (plane[0] + plane[1] * at(i) + plane[2] * at(j));
            }
        }
    }
    let chol = a.cholesky().map_err(|i| {
        invalid(
            "samples",
            format!("a non-positive pivot at control point {i}"),
            "a well-posed fit",
        )
    })?;
    chol.solve(&mut rhs, 1);
    let ctrl = compact
        .iter()
        .map(|&c| {
            if c == usize::MAX {
                f64::NAN
            } else {
                rhs[c - 1]
            }
        })
        .collect();
    Ok(Some(HeightSpline {
        grid: *grid,
        ctrl,
        offset,
    }))
}

/// `[a, b, c]` of the least-squares plane `z - offset = a + b·u + c·v` (a tiny ridge on the
/// slopes keeps collinear samples well-posed).
fn least_squares_plane(samples: &[[f64; 3]], offset: f64) -> [f64; 3] {
    let n = samples.len() as f64;
    let (mu, mv) = samples
        .iter()
        .fold((0.0, 0.0), |(a, b), s| (a + s[0] / n, b + s[1] / n));
    let (mut suu, mut suv, mut svv, mut suz, mut svz) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for s in samples {
        let (du, dv, dz) = (s[0] - mu, s[1] - mv, s[2] - offset);
        suu += du * du;
        suv += du * dv;
        svv += dv * dv;
        suz += du * dz;
        svz += dv * dz;
    }
    let eps = 1e-9 * n;
    let det = (suu + eps) * (svv + eps) - suv * suv;
    let b = ((svv + eps) * suz - suv * svz) / det;
    let c = ((suu + eps) * svz - suv * suz) / det;
    [-b * mu - c * mv, b, c]
}

/// Principal curvatures `(k1, k2)`, `k1 >= k2`, of the graph `(u, v, z)` from the derivatives
/// `p = z_u, q = z_v, r = z_uu, s = z_uv, t = z_vv` (bulges towards the viewer positive).
#[inline]
pub fn graph_curvatures(p: f64, q: f64, r: f64, s: f64, t: f64) -> (f64, f64) {
    let w2 = 1.0 + p * p + q * q;
    let gaussian = (r * t - s * s) / (w2 * w2);
    let mean = ((1.0 + q * q) * r - 2.0 * p * q * s + (1.0 + p * p) * t) / (2.0 * w2 * w2.sqrt());
    let disc = (mean * mean - gaussian).max(0.0).sqrt();
    (mean + disc, mean - disc)
}

impl HeightSpline {
    /// `(k1, k2)` maps (`height x width`, 1 / pixel) at the pixel centres where `eval(pixel
    /// index)` holds and the fitted slope `|∇z|` is at most `max_slope`; NaN elsewhere.
    pub fn curvature_maps(
        &self,
        eval: impl Fn(usize) -> bool,
        max_slope: f64,
    ) -> (Vec<f32>, Vec<f32>) {
        let (w, h) = (self.grid.width, self.grid.height);
        let mut k1 = vec![f32::NAN; w * h];
        let mut k2 = vec![f32::NAN; w * h];
        let all = Region::full(w, h);
        self.curvatures_into(eval, max_slope, all, &mut k1, &mut k2);
        (k1, k2)
    }

    /// [`Self::curvature_maps`] written into `k1`, `k2` (`height x width`) inside `region`
    /// only (other pixels untouched).
    pub fn curvatures_into(
        &self,
        eval: impl Fn(usize) -> bool,
        max_slope: f64,
        region: Region,
        k1: &mut [f32],
        k2: &mut [f32],
    ) {
        let g = &self.grid;
        let w = g.width;
        let (nu, _) = g.ctrl_shape();
        let inv = 1.0 / g.spacing;
        let cols: Vec<(usize, [[f64; K1]; 3])> = (region.u0..region.u1)
            .map(|u| {
                let (c, t) = g.locate(u as f64, g.cells_u);
                (c, cubic(t))
            })
            .collect();
        let max2 = max_slope * max_slope;
        // Per row: the control grid contracted with the row's v-basis (value, ∂v, ∂²v).
        let mut contracted = vec![[0.0f64; 3]; nu];
        for v in region.v0..region.v1 {
            let row = v * w;
            if !(region.u0..region.u1).any(|u| eval(row + u)) {
                continue;
            }
            let (cv, bv) = g.locate(v as f64, g.cells_v);
            let bv = cubic(bv);
            for (i, out) in contracted.iter_mut().enumerate() {
                let mut acc = [0.0; 3];
                for (j, ((b0, b1), b2)) in bv[0].iter().zip(&bv[1]).zip(&bv[2]).enumerate() {
                    let c = self.ctrl[(cv + j) * nu + i];
                    acc[0] += b0 * c;
                    acc[1] += b1 * c;
                    acc[2] += b2 * c;
                }
                *out = [acc[0], acc[1] * inv, acc[2] * inv * inv];
            }
            for (u, (cu, bu)) in (region.u0..region.u1).zip(&cols) {
                if !eval(row + u) {
                    continue;
                }
                let (mut p, mut q, mut r, mut s, mut t) = (0.0, 0.0, 0.0, 0.0, 0.0);
                for i in 0..K1 {
                    let [c0, c1, c2] = contracted[cu + i];
                    p += bu[1][i] * c0;
                    r += bu[2][i] * c0;
                    q += bu[0][i] * c1;
                    s += bu[1][i] * c1;
                    t += bu[0][i] * c2;
                }
                let (p, r, s) = (p * inv, r * inv * inv, s * inv);
                if p * p + q * q > max2 {
                    continue;
                }
                let (a, b) = graph_curvatures(p, q, r, s, t);
                k1[row + u] = a as f32;
                k2[row + u] = b as f32;
            }
        }
    }

    /// The fitted depth at pixel `(u, v)` (for tests and diagnostics).
    pub fn value(&self, u: f64, v: f64) -> f64 {
        let g = &self.grid;
        let (nu, _) = g.ctrl_shape();
        let (cu, tu) = g.locate(u, g.cells_u);
        let (cv, tv) = g.locate(v, g.cells_v);
        let (bu, bv) = (cubic(tu)[0], cubic(tv)[0]);
        let mut z = self.offset;
        for (j, b) in bv.iter().enumerate() {
            for (i, c) in bu.iter().enumerate() {
                z += b * c * self.ctrl[(cv + j) * nu + cu + i];
            }
        }
        z
    }
}

/// Curvature maps of `views` orthographic views of `width x height` pixels at once (parallel
/// over the views). `samples` is `N x 3` row-major `[u, v, z]` (pixels), `view_of[i]` the view
/// sample `i` belongs to, `eval` (`views x height x width`) the pixels to report. Returns
/// `views x 2 x height x width` (k1 then k2 per view, 1 / pixel), NaN where not reported (not in
/// `eval`, fitted slope above `max_slope`, or a view with fewer than 16 samples).
#[allow(clippy::too_many_arguments)]
pub fn view_curvatures(
    views: usize,
    width: usize,
    height: usize,
    samples: &[f64],
    view_of: &[u32],
    eval: &[bool],
    spacing: f64,
    lambda: f64,
    max_slope: f64,
) -> Result<Vec<f32>, RgbdError> {
    let grid = HeightGrid::new(width, height, spacing)?;
    let n = view_of.len();
    if samples.len() != 3 * n {
        return Err(mismatch(
            "samples",
            format!("{} values", samples.len()),
            format!("3 per entry of view_of ({n})"),
        ));
    }
    let px = width * height;
    if eval.len() != views * px {
        return Err(mismatch(
            "eval",
            format!("{} values", eval.len()),
            format!("{views} x {height} x {width}"),
        ));
    }
    if let Some(bad) = view_of.iter().position(|&v| v as usize >= views) {
        return Err(invalid(
            "view_of",
            format!("{} at index {bad}", view_of[bad]),
            format!("view indices below {views}"),
        ));
    }
    if max_slope.is_nan() || max_slope <= 0.0 {
        return Err(invalid("max_slope", max_slope, "a slope > 0 (inf: none)"));
    }
    let mut per_view: Vec<Vec<[f64; 3]>> = vec![Vec::new(); views];
    for (s, &v) in samples.chunks_exact(3).zip(view_of) {
        per_view[v as usize].push([s[0], s[1], s[2]]);
    }
    let mut out = vec![f32::NAN; views * 2 * px];
    out.par_chunks_mut(2 * px)
        .zip(per_view.par_iter())
        .enumerate()
        .try_for_each(|(v, (dst, pts))| {
            check_interrupt()?;
            let Some(fit) = fit_height(pts, &grid, lambda)? else {
                return Ok(());
            };
            let mask = &eval[v * px..(v + 1) * px];
            let (k1, k2) = fit.curvature_maps(|i| mask[i], max_slope);
            dst[..px].copy_from_slice(&k1);
            dst[px..].copy_from_slice(&k2);
            Ok::<(), RgbdError>(())
        })?;
    Ok(out)
}

/// Depth slope (per pixel, in the unit of `z`) of pixel `(u, v)` of a `w x h` image `z` (NaN:
/// empty): central differences, one-sided next to an empty pixel, infinite along an axis whose
/// two neighbours are both empty.
fn slope(z: &[f64], w: usize, h: usize, u: usize, v: usize) -> f64 {
    let at = |x: usize, y: usize| z[y * w + x];
    let c = at(u, v);
    let diff = |lo: Option<f64>, hi: Option<f64>| {
        let (lo, hi) = (lo.filter(|x| !x.is_nan()), hi.filter(|x| !x.is_nan()));
        match (lo, hi) {
            (Some(a), Some(b)) => (b - a) / 2.0,
            (Some(a), None) => c - a,
            (None, Some(b)) => b - c,
            (None, None) => f64::INFINITY,
        }
    };
    let gx = diff(
        (u > 0).then(|| at(u - 1, v)),
        (u + 1 < w).then(|| at(u + 1, v)),
    );
    let gy = diff(
        (v > 0).then(|| at(u, v - 1)),
        (v + 1 < h).then(|| at(u, v + 1)),
    );
    gx.hypot(gy)
}

/// 4-connected components of the `true` pixels of a `w x h` mask: per-pixel label
/// (`u32::MAX` outside the mask) and the number of components.
fn components(mask: &[bool], w: usize, h: usize) -> (Vec<u32>, usize) {
    let mut labels = vec![u32::MAX; mask.len()];
    let mut n = 0u32;
    let mut stack = Vec::new();
    for start in 0..mask.len() {
        if !mask[start] || labels[start] != u32::MAX {
            continue;
        }
        labels[start] = n;
        stack.push(start);
        while let Some(i) = stack.pop() {
            let (u, v) = (i % w, i / w);
            let near = [
                (u > 0).then(|| i - 1),
                (u + 1 < w).then(|| i + 1),
                (v > 0).then(|| i - w),
                (v + 1 < h).then(|| i + w),
            ];
            for j in near.into_iter().flatten() {
                if mask[j] && labels[j] == u32::MAX {
                    labels[j] = n;
                    stack.push(j);
                }
            }
        }
        n += 1;
    }
    (labels, n as usize)
}

/// Curvature maps of `views` orthographic depth images (`views x height x width`, NaN where
/// empty; `scale` converts a depth to pixels), parallel over the views. Each 4-connected piece
/// of a view's pixels whose depth slope ([`slope`], in depth pixels per pixel) is at most
/// `max_slope` is fitted on its own and reported there (pieces of fewer than 16 pixels: NaN); `views x 2 x height x width` k1, k2 in 1 / pixel, NaN elsewhere (and in a
/// view with fewer than 16 such pixels).
#[allow(clippy::too_many_arguments)]
pub fn depth_curvatures(
    depth: &[f32],
    views: usize,
    width: usize,
    height: usize,
    scale: f64,
    spacing: f64,
    lambda: f64,
    max_slope: f64,
) -> Result<Vec<f32>, RgbdError> {
    let grid = HeightGrid::new(width, height, spacing)?;
    let px = width * height;
    if depth.len() != views * px {
        return Err(mismatch(
            "depth",
            format!("{} values", depth.len()),
            format!("{views} x {height} x {width}"),
        ));
    }
    if !(scale.is_finite() && scale > 0.0) {
        return Err(invalid("scale", scale, "a finite factor > 0"));
    }
    if max_slope.is_nan() || max_slope <= 0.0 {
        return Err(invalid("max_slope", max_slope, "a slope > 0 (inf: none)"));
    }
    if let Some(bad) = depth.iter().position(|d| d.is_infinite()) {
        return Err(invalid(
            "depth",
            format!("an infinite depth at index {bad}"),
            "finite depths or NaN for empty pixels",
        ));
    }
    let mut out = vec![f32::NAN; views * 2 * px];
    out.par_chunks_mut(2 * px)
        .zip(depth.par_chunks(px))
        .try_for_each(|(dst, view)| {
            check_interrupt()?;
            let z: Vec<f64> = view.iter().map(|&d| d as f64 * scale).collect();
            let mut keep = vec![false; px];
            for v in 0..height {
                for u in 0..width {
                    let i = v * width + u;
                    keep[i] = !z[i].is_nan() && slope(&z, width, height, u, v) <= max_slope;
                }
            }
            // Each 4-connected piece of kept pixels is fitted on its own: the cut separates
            // surfaces at depth steps, and one spline across a step would ring on both sides.
            let (labels, n) = components(&keep, width, height);
            let mut samples: Vec<Vec<[f64; 3]>> = vec![Vec::new(); n];
            let empty = Region {
                u0: usize::MAX,
                u1: 0,
                v0: usize::MAX,
                v1: 0,
            };
            let mut boxes = vec![empty; n];
            for (i, &l) in labels.iter().enumerate() {
                if l != u32::MAX {
                    let (u, v) = (i % width, i / width);
                    samples[l as usize].push([u as f64, v as f64, z[i]]);
                    let b = &mut boxes[l as usize];
                    (b.u0, b.u1) = (b.u0.min(u), b.u1.max(u + 1));
                    (b.v0, b.v1) = (b.v0.min(v), b.v1.max(v + 1));
                }
            }
            let (k1, k2) = dst.split_at_mut(px);
            for (l, (pts, region)) in samples.iter().zip(boxes).enumerate() {
                if let Some(fit) = fit_height(pts, &grid, lambda)? {
                    let mine = |i: usize| labels[i] == l as u32;
                    fit.curvatures_into(mine, f64::INFINITY, region, k1, k2);
                }
            }
            Ok::<(), RgbdError>(())
        })?;
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Samples of `z` at every pixel of a `w x h` view.
    fn pixels(w: usize, h: usize, z: impl Fn(f64, f64) -> Option<f64>) -> Vec<[f64; 3]> {
        let mut out = Vec::new();
        for v in 0..h {
            for u in 0..w {
                if let Some(d) = z(u as f64, v as f64) {
                    out.push([u as f64, v as f64, d]);
                }
            }
        }
        out
    }

    #[test]
    fn quadratic_height_is_reproduced_with_its_curvatures() {
        // z = 0.01 (u - 20)² + 0.02 (v - 15)²: at (20, 15) k1 = 0.04, k2 = 0.02.
        let (w, h) = (40, 30);
        let z = |u: f64, v: f64| 0.01 * (u - 20.0).powi(2) + 0.02 * (v - 15.0).powi(2);
        let grid = HeightGrid::new(w, h, 5.0).unwrap();
        let fit = fit_height(&pixels(w, h, |u, v| Some(z(u, v))), &grid, 1e-6)
            .unwrap()
            .unwrap();
        for (u, v) in [(3.0, 4.0), (20.0, 15.0), (37.5, 28.0)] {
            assert!((fit.value(u, v) - z(u, v)).abs() < 1e-4, "{u} {v}");
        }
        let (k1, k2) = fit.curvature_maps(|_| true, f64::INFINITY);
        let c = 15 * w + 20;
        assert!((k1[c] - 0.04).abs() < 1e-4 && (k2[c] - 0.02).abs() < 1e-4);
    }

    #[test]
    fn a_sphere_facing_the_viewer_has_k_one_over_r_inside() {
        let (w, r) = (101usize, 40.0);
        let z = |u: f64, v: f64| {
            let d2 = (u - 50.0).powi(2) + (v - 50.0).powi(2);
            let s = (r * r - d2).sqrt();
            // Leave out the grazing rim (slope > 2), as the shape pipeline does.
            (d2 <= 0.8 * r * r).then_some(100.0 - s)
        };
        let grid = HeightGrid::new(w, w, 4.0).unwrap();
        let fit = fit_height(&pixels(w, w, z), &grid, 1e-6).unwrap().unwrap();
        let (k1, k2) = fit.curvature_maps(|_| true, 2.0);
        for v in 0..w {
            for u in 0..w {
                let d = ((u as f64 - 50.0).powi(2) + (v as f64 - 50.0).powi(2)).sqrt();
                if d < 0.7 * r {
                    let i = v * w + u;
                    let e = (k1[i] as f64 * r - 1.0)
                        .abs()
                        .max((k2[i] as f64 * r - 1.0).abs());
                    assert!(e < 0.02, "{u} {v} {} {}", k1[i], k2[i]);
                }
            }
        }
    }

    #[test]
    fn planes_have_zero_curvature_and_steep_pixels_are_not_reported() {
        let w = 32;
        let grid = HeightGrid::new(w, w, 4.0).unwrap();
        let fit = fit_height(&pixels(w, w, |u, v| Some(3.0 * u - 0.5 * v)), &grid, 1e-6)
            .unwrap()
            .unwrap();
        let (k1, k2) = fit.curvature_maps(|_| true, f64::INFINITY);
        let worst = k1.iter().chain(&k2).fold(0.0f32, |m, k| m.max(k.abs()));
        assert!(worst < 1e-6, "{worst}");
        let (k1, _) = fit.curvature_maps(|_| true, 2.0); // slope 3.04 > 2
        assert!(k1.iter().all(|k| k.is_nan()));
    }

    #[test]
    fn views_are_fitted_independently_and_small_ones_are_skipped() {
        let (w, h) = (16, 12);
        let mut samples = Vec::new();
        let mut view_of = Vec::new();
        for v in 0..h {
            for u in 0..w {
                let (x, y) = (u as f64 - 8.0, v as f64 - 6.0);
                samples.extend_from_slice(&[u as f64, v as f64, 0.05 * (x * x + y * y)]);
                view_of.push(1u32);
            }
        }
        samples.extend_from_slice(&[1.0, 1.0, 1.0]);
        view_of.push(0); // one sample: no fit
        let eval = vec![true; 3 * w * h];
        let out = view_curvatures(3, w, h, &samples, &view_of, &eval, 2.0, 1e-6, 10.0).unwrap();
        let px = w * h;
        assert!(out[..2 * px].iter().all(|k| k.is_nan()));
        let centre = 2 * px + 6 * w + 8;
        assert!((out[centre] - 0.1).abs() < 1e-3 && (out[centre + px] - 0.1).abs() < 1e-3);
        assert!(out[4 * px..].iter().all(|k| k.is_nan()));
        let bad = view_curvatures(3, w, h, &samples, &view_of, &eval[1..], 2.0, 1e-6, 1.0);
        assert!(bad.is_err());
        let mut nan = samples.clone();
        nan[0] = f64::NAN;
        assert!(view_curvatures(3, w, h, &nan, &view_of, &eval, 2.0, 1e-6, 1.0).is_err());
    }

    #[test]
    fn depth_images_are_cut_at_steep_pixels_and_fitted_elsewhere() {
        // A ball of radius 20 px seen face-on: pixels steeper than 2 (beyond 0.894 r) and
        // empty ones are not reported; inside 0.7 r, k1 = k2 = 1/r within 2 %.
        let (w, r) = (48usize, 20.0);
        let mut depth = vec![f32::NAN; 2 * w * w];
        for v in 0..w {
            for u in 0..w {
                let d2 = (u as f64 - 24.0).powi(2) + (v as f64 - 24.0).powi(2);
                if d2 < r * r {
                    // view 1, in units of half a pixel (scale 2)
                    depth[w * w + v * w + u] = ((30.0 - (r * r - d2).sqrt()) / 2.0) as f32;
                }
            }
        }
        let out = depth_curvatures(&depth, 2, w, w, 2.0, 2.0, 1e-6, 2.0).unwrap();
        let px = w * w;
        assert!(out[..2 * px].iter().all(|k| k.is_nan())); // the empty view
        let (k1, k2) = (&out[2 * px..3 * px], &out[3 * px..]);
        for v in 0..w {
            for u in 0..w {
                let d = ((u as f64 - 24.0).powi(2) + (v as f64 - 24.0).powi(2)).sqrt();
                let i = v * w + u;
                if d < 0.7 * r {
                    let e = (k1[i] as f64 * r - 1.0)
                        .abs()
                        .max((k2[i] as f64 * r - 1.0).abs());
                    assert!(e < 0.02, "{u} {v} {} {}", k1[i], k2[i]);
                } else if d > 0.95 * r {
                    assert!(k1[i].is_nan(), "{u} {v}");
                }
            }
        }
        let mut inf = depth.clone();
        inf[5] = f32::INFINITY;
        assert!(depth_curvatures(&inf, 2, w, w, 2.0, 2.0, 1e-6, 2.0).is_err());
        assert!(depth_curvatures(&depth[1..], 2, w, w, 2.0, 2.0, 1e-6, 2.0).is_err());
    }

    #[test]
    fn pieces_separated_by_a_depth_step_are_fitted_apart() {
        // Two flat pieces 20 px apart in depth: the step pixels are cut, each piece is a plane
        // (zero curvature up to the step); one spline over both would ring next to the step.
        let (w, h) = (40usize, 24usize);
        let depth: Vec<f32> = (0..w * h)
            .map(|i| {
                if i % w < 20 {
                    5.0
                } else {
                    25.0 + 0.1 * (i / w) as f32
                }
            })
            .collect();
        let out = depth_curvatures(&depth, 1, w, h, 1.0, 4.0, 1e-6, 2.0).unwrap();
        let px = w * h;
        let reported: Vec<f32> = out.iter().copied().filter(|k| !k.is_nan()).collect();
        assert!(reported.len() >= 2 * (px - 2 * h)); // all but the two cut columns
        let worst = reported.iter().fold(0.0f32, |m, k| m.max(k.abs()));
        assert!(worst < 1e-5, "{worst}");
        let (labels, n) = components(&[true, false, false, true], 2, 2); // diagonal: apart
        assert_eq!((n, labels), (2, vec![0, u32::MAX, u32::MAX, 1]));
    }
}
