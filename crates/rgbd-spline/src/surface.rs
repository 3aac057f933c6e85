//! A fitted surface: control points on a rectangle of an image-anchored [`KnotGrid`], evaluated
//! with its first and second derivatives (per pixel).

use crate::grid::KnotGrid;
use crate::normal::Region;

/// `channels` control-point grids covering control points `origin .. origin + shape` of `grid`.
#[derive(Debug, Clone, PartialEq)]
pub struct GridSurface {
    pub grid: KnotGrid,
    pub channels: usize,
    /// First control point `(u, v)` of the rectangle.
    pub origin: (usize, usize),
    /// Control points `(along u, along v)` of the rectangle.
    pub shape: (usize, usize),
    /// Row-major `(shape.1, shape.0, channels)`.
    pub ctrl: Vec<f64>,
}

/// Most channels a surface may have (3-D points: 3).
pub const MAX_CHANNELS: usize = 4;

/// Value and derivatives (per pixel) of a surface at one point; entries past `channels` are 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Jet {
    pub channels: usize,
    pub value: [f64; MAX_CHANNELS],
    pub du: [f64; MAX_CHANNELS],
    pub dv: [f64; MAX_CHANNELS],
    pub duu: [f64; MAX_CHANNELS],
    pub duv: [f64; MAX_CHANNELS],
    pub dvv: [f64; MAX_CHANNELS],
}

impl Jet {
    /// All values and derivatives zero.
    pub fn zero(channels: usize) -> Self {
        let z = [0.0; MAX_CHANNELS];
        Self {
            channels,
            value: z,
            du: z,
            dv: z,
            duu: z,
            duv: z,
            dvv: z,
        }
    }
}

impl GridSurface {
    /// The surface `a + b·u + c·v` (per channel, `coef = [a, b, c]` per channel, `u, v` in
    /// pixels) over the control rectangle of cells `cell_min ..= cell_max`. Uniform B-splines
    /// reproduce linear functions exactly when each control point sits at its Greville abscissa
    /// `(i - (p - 1) / 2) · s`.
    pub fn linear(
        grid: &KnotGrid,
        cell_min: (usize, usize),
        cell_max: (usize, usize),
        coef: &[f64],
    ) -> Self {
        let p = grid.degree;
        let channels = coef.len() / 3;
        let shape = (
            cell_max.0 - cell_min.0 + 1 + p,
            cell_max.1 - cell_min.1 + 1 + p,
        );
        let greville = |i: usize| (i as f64 - (p as f64 - 1.0) / 2.0) * grid.spacing;
        let mut ctrl = Vec::with_capacity(shape.0 * shape.1 * channels);
        for j in 0..shape.1 {
            for i in 0..shape.0 {
                let (u, v) = (greville(cell_min.0 + i), greville(cell_min.1 + j));
                for c in coef.chunks(3) {
                    ctrl.push(c[0] + c[1] * u + c[2] * v);
                }
            }
        }
        Self {
            grid: *grid,
            channels,
            origin: cell_min,
            shape,
            ctrl,
        }
    }

    /// Local control column of cell column `cu`, if all its `p + 1` control columns are held.
    pub fn local_u(&self, cu: usize) -> Option<usize> {
        (cu >= self.origin.0 && cu + self.grid.degree < self.origin.0 + self.shape.0)
            .then(|| cu - self.origin.0)
    }

    /// Local control row of cell row `cv`, if all its `p + 1` control rows are held.
    pub fn local_v(&self, cv: usize) -> Option<usize> {
        (cv >= self.origin.1 && cv + self.grid.degree < self.origin.1 + self.shape.1)
            .then(|| cv - self.origin.1)
    }

    /// Whether pixel `(u, v)` lies in a cell whose control points this surface holds.
    pub fn covers(&self, u: f64, v: f64) -> bool {
        let (cu, cv, _, _) = self.grid.support(u, v);
        self.local_u(cu).is_some() && self.local_v(cv).is_some()
    }

    /// The pixels of an image of `width x height` whose cells this surface holds (its cell box).
    pub fn pixel_region(&self, width: usize, height: usize) -> Region {
        let p = self.grid.degree;
        let s = self.grid.spacing;
        // Cells clamp at the image edge: the last cell runs to the last pixel.
        let span = |first: usize, cells: usize, total: usize, len: usize| {
            let last = first + cells - p - 1;
            let start = ((first as f64 * s).ceil() as usize).min(len);
            let end = if last + 1 >= total {
                len
            } else {
                (((last + 1) as f64 * s).ceil() as usize).min(len)
            };
            (start, end)
        };
        let (u0, u1) = span(self.origin.0, self.shape.0, self.grid.cells_u, width);
        let (v0, v1) = span(self.origin.1, self.shape.1, self.grid.cells_v, height);
        Region { u0, u1, v0, v1 }
    }

    /// Value and first/second derivatives (per pixel) at `(u, v)`; `None` outside the
    /// surface's control rectangle.
    pub fn jet(&self, u: f64, v: f64) -> Option<Jet> {
        let (cu, cv, bu, bv) = self.grid.support(u, v);
        let (cu, cv) = (self.local_u(cu)?, self.local_v(cv)?);
        let nu = self.shape.0;
        let c = self.channels;
        let s = self.grid.spacing;
        let mut jet = Jet::zero(c);
        let p = self.grid.degree;
        for j in 0..=p {
            for i in 0..=p {
                let base = ((cv + j) * nu + cu + i) * c;
                let w = [
                    bu.value[i] * bv.value[j],
                    bu.d1[i] * bv.value[j] / s,
                    bu.value[i] * bv.d1[j] / s,
                    bu.d2[i] * bv.value[j] / (s * s),
                    bu.d1[i] * bv.d1[j] / (s * s),
                    bu.value[i] * bv.d2[j] / (s * s),
                ];
                for ch in 0..c {
                    let q = self.ctrl[base + ch];
                    jet.value[ch] += w[0] * q;
                    jet.du[ch] += w[1] * q;
                    jet.dv[ch] += w[2] * q;
                    jet.duu[ch] += w[3] * q;
                    jet.duv[ch] += w[4] * q;
                    jet.dvv[ch] += w[5] * q;
                }
            }
        }
        Some(jet)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_surface_is_exact_for_every_degree() {
        for p in 1..=5 {
            let grid = KnotGrid::new(50, 40, 7.0, p).unwrap();
            let s = GridSurface::linear(&grid, (1, 1), (5, 4), &[2.0, 0.1, -0.3]);
            for (u, v) in [(7.0, 7.0), (20.5, 13.25), (41.9, 34.9)] {
                let j = s.jet(u, v).unwrap();
                assert!(
                    (j.value[0] - (2.0 + 0.1 * u - 0.3 * v)).abs() < 1e-12,
                    "p={p}"
                );
                assert!((j.du[0] - 0.1).abs() < 1e-12 && (j.dv[0] + 0.3).abs() < 1e-12);
            }
            assert!(s.jet(3.0, 20.0).is_none());
        }
    }

    #[test]
    fn pixel_region_is_exactly_the_covered_pixels() {
        let (w, h) = (50, 40);
        for spacing in [1.0, 3.0, 7.0, 7.5, 16.0] {
            let grid = KnotGrid::new(w, h, spacing, 3).unwrap();
            let last = (grid.cells_u - 1, grid.cells_v - 1);
            for (lo, hi) in [((0, 0), last), ((1, 1), (2, 2)), ((0, 1), (last.0, 1))] {
                let hi = (hi.0.min(last.0), hi.1.min(last.1));
                let lo = (lo.0.min(hi.0), lo.1.min(hi.1));
                let s = GridSurface::linear(&grid, lo, hi, &[1.0, 0.0, 0.0]);
                let r = s.pixel_region(w, h);
                for v in 0..h {
                    for u in 0..w {
                        let inside = (r.u0..r.u1).contains(&u) && (r.v0..r.v1).contains(&v);
                        assert_eq!(inside, s.covers(u as f64, v as f64), "s={spacing} {u},{v}");
                    }
                }
            }
        }
    }
}
