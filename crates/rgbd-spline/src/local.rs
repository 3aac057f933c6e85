//! The seam test's union fit solved locally: only the control points near the seam move.
//!
//! On an image-anchored grid the fit of `S_i ∪ S_j` differs from the fits of its parts only near
//! the control points that both parts' supports hold (the *contested* points). The local union
//! fit frees the union's control points within `r` points (Chebyshev) of a contested point, holds
//! every other control point at its part's own optimum, and minimises the union's regularised
//! objective over the freed ones. Only the cells whose basis touches a freed point change their
//! residual, so `χ²(S_i ∪ S_j) - χ²(S_i) - χ²(S_j)` is a sum over those cells of
//! `2 dᵀ(A c_p - b) + dᵀ A d` (`d` the move of the cell's control points from its part's
//! coefficients `c_p`, `A`, `b` the cell's stored normal-equation block). The cost depends on the
//! seam's length and `r`, not on the segments' sizes.
//!
//! The freed points are a subspace of the exact union fit's unknowns, so the local minimum of the
//! objective is never below the exact one (the test is conservative: it merges a little less).
//! When the window covers the whole union it is the exact union fit.

// Index loops over several fixed-size arrays at once read clearer than zipped iterators here.
#![allow(clippy::needless_range_loop)]

use crate::band::BandMatrix;
use crate::basis::MAX_DEGREE;
use crate::fit::{Fit, RIDGE};
use crate::grid::KnotGrid;
use crate::normal::Normal;
use rgbd_error::{invalid, RgbdError};

/// Most control points a cell's basis touches, `(p + 1)²`.
const MAX_K: usize = (MAX_DEGREE + 1) * (MAX_DEGREE + 1);

/// Cell box `((u_lo, v_lo), (u_hi, v_hi))` of a pixel set's cells.
pub type CellBox = ((usize, usize), (usize, usize));

/// The cell box of a non-empty set.
pub fn cell_box(n: &Normal, grid: &KnotGrid) -> CellBox {
    let (mut lo, mut hi) = ((usize::MAX, usize::MAX), (0, 0));
    for &c in &n.cells {
        let (u, v) = (c as usize % grid.cells_u, c as usize / grid.cells_u);
        lo = (lo.0.min(u), lo.1.min(v));
        hi = (hi.0.max(u), hi.1.max(v));
    }
    (lo, hi)
}

/// The box of both boxes.
pub fn box_union(a: CellBox, b: CellBox) -> CellBox {
    (
        (a.0 .0.min(b.0 .0), a.0 .1.min(b.0 .1)),
        (a.1 .0.max(b.1 .0), a.1 .1.max(b.1 .1)),
    )
}

/// One part's cell inside the local region: part (0 or 1), cell `(u, v)` relative to the
/// region, and the index of its block.
struct Entry {
    part: usize,
    u: usize,
    v: usize,
    block: usize,
}

/// `(Δχ², |seam|)` of `a ∪ b`: `Δχ² = χ²(a ∪ b) - χ²(a) - χ²(b)` of the union fit that frees
/// the control points within `r` of the contested ones (`fa`, `fb` the parts' fits, one channel,
/// values accumulated minus `offset`; `boxes` their cell boxes), and the seam pixels of
/// [`crate::seam::seam_pixels`]. `None` when the parts' supports share no control point (then
/// they have no seam either).
pub fn local_union_delta(
    parts: [(&Normal, &Fit); 2],
    boxes: [CellBox; 2],
    grid: &KnotGrid,
    lambda: f64,
    offset: f64,
    r: usize,
) -> Result<Option<(f64, usize)>, RgbdError> {
    let p = grid.degree;
    let k1 = p + 1;
    let [(na, _), (nb, _)] = parts;
    if na.channels != 1 || nb.channels != 1 {
        return Err(invalid("channels", na.channels, "one channel"));
    }
    if na.cells.is_empty() || nb.cells.is_empty() {
        return Ok(None);
    }
    let k = na.k;
    let [(alo, ahi), (blo, bhi)] = boxes;
    // Control points both supports' boxes hold (cell c supports points c ..= c + p).
    let plo = (alo.0.max(blo.0), alo.1.max(blo.1));
    let phi = ((ahi.0.min(bhi.0)) + p, (ahi.1.min(bhi.1)) + p);
    if plo.0 > phi.0 || plo.1 > phi.1 {
        return Ok(None);
    }
    // Cells that can touch a freed point or a penalty stencil through one (`p` for the support,
    // 2 for the stencils), clipped to the grid.
    let reach = r + p + 2;
    let c0 = (plo.0.saturating_sub(reach), plo.1.saturating_sub(reach));
    let c1 = (
        (phi.0 + r + 2).min(grid.cells_u - 1),
        (phi.1 + r + 2).min(grid.cells_v - 1),
    );
    let (cw, ch) = (c1.0 - c0.0 + 1, c1.1 - c0.1 + 1);
    let (pw, ph) = (cw + p, ch + p);
    // The parts' cells in the region (row ranges by binary search: cells are sorted row-major).
    let mut entries: Vec<Entry> = Vec::new();
    for (part, n) in [na, nb].into_iter().enumerate() {
        for v in c0.1..=c1.1 {
            let first = (v * grid.cells_u + c0.0) as u32;
            let last = (v * grid.cells_u + c1.0) as u32;
            let start = n.cells.partition_point(|&c| c < first);
            for (i, &c) in n.cells[start..].iter().enumerate() {
                if c > last {
                    break;
                }
                entries.push(Entry {
                    part,
                    u: c as usize % grid.cells_u - c0.0,
                    v: v - c0.1,
                    block: start + i,
                });
            }
        }
    }
    // Seam pixels: those in a cell of one part that holds or touches a cell of the other (the
    // touching cells are all in the region).
    let mut cell_flags = vec![0u8; cw * ch];
    for e in &entries {
        cell_flags[e.v * cw + e.u] |= 1 << e.part;
    }
    let bl = na.block_len();
    let block = |e: &Entry| {
        let n = if e.part == 0 { na } else { nb };
        &n.blocks[e.block * bl..(e.block + 1) * bl]
    };
    let mut seam = 0.0;
    for e in &entries {
        let other = 2u8 >> e.part;
        let touches = (e.v.saturating_sub(1)..=(e.v + 1).min(ch - 1)).any(|y| {
            (e.u.saturating_sub(1)..=(e.u + 1).min(cw - 1))
                .any(|x| cell_flags[y * cw + x] & other != 0)
        });
        if touches {
            // The basis is a partition of unity: Σ over the cell's pixels of Σ_a B_a = count.
            seam += block(e)[bl - k..].iter().sum::<f64>();
        }
    }
    let seam = seam.round() as usize;
    // Support flags per local control point: bit 0 part a, bit 1 part b.
    let mut flags = vec![0u8; pw * ph];
    for e in &entries {
        for j in 0..k1 {
            for i in 0..k1 {
                flags[(e.v + j) * pw + e.u + i] |= 1 << e.part;
            }
        }
    }
    // Freed points: union support within r (Chebyshev) of a contested point.
    let mut near = vec![false; pw * ph];
    let mut any = false;
    for y in 0..ph {
        for x in 0..pw {
            if flags[y * pw + x] == 3 {
                any = true;
                for yy in y.saturating_sub(r)..=(y + r).min(ph - 1) {
                    for xx in x.saturating_sub(r)..=(x + r).min(pw - 1) {
                        near[yy * pw + xx] = true;
                    }
                }
            }
        }
    }
    if !any {
        return Ok(None);
    }
    // Number the freed points along the shorter side of their box (smaller band).
    let (mut lo, mut hi) = ((usize::MAX, usize::MAX), (0, 0));
    for y in 0..ph {
        for x in 0..pw {
            if near[y * pw + x] && flags[y * pw + x] != 0 {
                lo = (lo.0.min(x), lo.1.min(y));
                hi = (hi.0.max(x), hi.1.max(y));
            }
        }
    }
    let by_rows = hi.0 - lo.0 <= hi.1 - lo.1;
    let mut id = vec![u32::MAX; pw * ph];
    let mut n_free = 0u32;
    let mut number = |q: usize| {
        if near[q] && flags[q] != 0 {
            id[q] = n_free;
            n_free += 1;
        }
    };
    if by_rows {
        for y in lo.1..=hi.1 {
            for x in lo.0..=hi.0 {
                number(y * pw + x);
            }
        }
    } else {
        for x in lo.0..=hi.0 {
            for y in lo.1..=hi.1 {
                number(y * pw + x);
            }
        }
    }
    let n_free = n_free as usize;
    // The parts' coefficients (accumulated units: fitted value minus offset) at local points.
    let coef = |part: usize, x: usize, y: usize| -> f64 {
        let s = &parts[part].1.surface;
        let (gx, gy) = (x + c0.0, y + c0.1);
        match (gx.checked_sub(s.origin.0), gy.checked_sub(s.origin.1)) {
            (Some(i), Some(j)) if i < s.shape.0 && j < s.shape.1 => {
                s.ctrl[j * s.shape.0 + i] - offset
            }
            _ => 0.0,
        }
    };
    // Starting coefficients: the owning part's, the mean of both on contested points.
    let mut c = vec![0.0; pw * ph];
    for y in 0..ph {
        for x in 0..pw {
            let q = y * pw + x;
            c[q] = match flags[q] {
                1 => coef(0, x, y),
                2 => coef(1, x, y),
                3 => 0.5 * (coef(0, x, y) + coef(1, x, y)),
                _ => 0.0,
            };
        }
    }
    // A cell's control points: its corner plus these offsets (no allocation per cell).
    let mut offs = [0usize; MAX_K];
    for (a, o) in offs.iter_mut().enumerate().take(k) {
        *o = (a / k1) * pw + a % k1;
    }
    let offs = &offs[..k];
    let corner = |e: &Entry| e.v * pw + e.u;
    let touches = |e: &Entry| offs.iter().any(|&o| id[corner(e) + o] != u32::MAX);
    // Penalty stencils of the union with a freed point (three points in the union support).
    let mut stencils: Vec<[usize; 3]> = Vec::new();
    for y in 0..ph {
        for x in 0..pw {
            let q = y * pw + x;
            let mut push = |s: [usize; 3]| {
                if s.iter().all(|&t| flags[t] != 0) && s.iter().any(|&t| id[t] != u32::MAX) {
                    stencils.push(s);
                }
            };
            if x + 2 < pw {
                push([q, q + 1, q + 2]);
            }
            if y + 2 < ph {
                push([q, q + pw, q + 2 * pw]);
            }
        }
    }
    // Band width of the freed system.
    let mut bw = 0usize;
    let span = |pts: &mut dyn Iterator<Item = usize>| {
        let (mut a, mut b) = (u32::MAX, 0u32);
        for t in pts {
            if id[t] != u32::MAX {
                a = a.min(id[t]);
                b = b.max(id[t]);
            }
        }
        if a == u32::MAX {
            0
        } else {
            (b - a) as usize
        }
    };
    let active: Vec<(&Entry, usize)> = entries
        .iter()
        .filter(|e| touches(e))
        .map(|e| (e, corner(e)))
        .collect();
    for &(_, q0) in &active {
        bw = bw.max(span(&mut offs.iter().map(|&o| q0 + o)));
    }
    for s in &stencils {
        bw = bw.max(span(&mut s.iter().copied()));
    }
    // Assemble: minimise over the freed points with the others held.
    let mut mat = BandMatrix::zeros(n_free, bw);
    let mut rhs = vec![0.0; n_free];
    let mut pts = [0usize; MAX_K];
    let mut pid = [u32::MAX; MAX_K];
    {
        // Entry (i, j), j <= i, of the band storage at (i + 1)·bw + j (`BandMatrix::add`'s sums in
        // the same order, without its per-entry swap and index arithmetic).
        let mbw = mat.bw;
        let data = mat.lower_mut();
        for &(e, q0) in &active {
            for ((p, i), &o) in pts.iter_mut().zip(pid.iter_mut()).zip(offs) {
                *p = q0 + o;
                *i = id[q0 + o];
            }
            let blk = block(e);
            let (gram, rest) = blk.split_at(k * k);
            for a in 0..k {
                let ia = pid[a];
                let grow = &gram[a * k..=a * k + a];
                if ia == u32::MAX {
                    // A held point: only freed columns move their right-hand sides.
                    let ca = c[pts[a]];
                    for (b, &g) in grow.iter().enumerate() {
                        let ib = pid[b];
                        if ib != u32::MAX {
                            rhs[ib as usize] -= g * ca;
                        }
                    }
                    continue;
                }
                let ia = ia as usize;
                rhs[ia] += rest[a];
                for (b, &g) in grow.iter().enumerate() {
                    let ib = pid[b];
                    if ib != u32::MAX {
                        let ib = ib as usize;
                        let (i, j) = if ia >= ib { (ia, ib) } else { (ib, ia) };
                        data[(i + 1) * mbw + j] += g;
                    } else {
                        rhs[ia] -= g * c[pts[b]];
                    }
                }
            }
        }
    }
    let stencil = [1.0, -2.0, 1.0];
    for s in &stencils {
        for x in 0..3 {
            let ix = id[s[x]];
            if ix == u32::MAX {
                continue;
            }
            for y in 0..3 {
                let iy = id[s[y]];
                let w = lambda * stencil[x] * stencil[y];
                if iy == u32::MAX {
                    rhs[ix as usize] -= w * c[s[y]];
                } else if y <= x {
                    mat.add(ix as usize, iy as usize, w);
                }
            }
        }
    }
    for q in 0..pw * ph {
        if id[q] != u32::MAX {
            let i = id[q] as usize;
            mat.add(i, i, RIDGE);
            rhs[i] += RIDGE * c[q];
        }
    }
    let chol = mat.cholesky().map_err(|i| {
        invalid(
            "segment",
            format!("a non-positive pivot at control point {i} of the seam"),
            "a well-posed fit",
        )
    })?;
    chol.solve(&mut rhs, 1);
    // Δχ² over the cells that hold a freed point: 2 dᵀ(A c_p - b) + dᵀ A d.
    let mut delta = 0.0;
    let mut cp = vec![0.0; k];
    let mut d = vec![0.0; k];
    for &(e, q0) in &active {
        let blk = block(e);
        let (gram, rest) = blk.split_at(k * k);
        let lx = |a: usize| (e.u + a % k1, e.v + a / k1);
        for a in 0..k {
            let (x, y) = lx(a);
            cp[a] = coef(e.part, x, y);
            let i = id[q0 + offs[a]];
            d[a] = if i == u32::MAX {
                // Held at the owning part's value: this part's.
                0.0
            } else {
                rhs[i as usize] - cp[a]
            };
        }
        // A is stored as its lower triangle. A held point's row adds d[a] · (…) = 0.
        for a in 0..k {
            if id[q0 + offs[a]] == u32::MAX {
                continue;
            }
            let mut acp = 0.0;
            let mut ad = 0.0;
            for b in 0..k {
                let g = if b <= a {
                    gram[a * k + b]
                } else {
                    gram[b * k + a]
                };
                acp += g * cp[b];
                ad += g * d[b];
            }
            delta += d[a] * (2.0 * (acp - rest[a]) + ad);
        }
    }
    Ok(Some((delta, seam)))
}
