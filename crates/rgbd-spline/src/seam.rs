//! The merge test of eq. 4.8 on real depth: a seam test in sensor-noise units.
//!
//! Two segments are one surface when one smooth surface fits both of them where they meet to
//! within the sensor noise. The test fits the *variance-stabilised depth* `g(z)`, with
//! `g'(z) = 1 / σ(z)`, so that a residual of 1 is one standard deviation of the sensor's depth
//! noise wherever the pixel is (Kinect-class noise grows as `z²`: a far wall is allowed a larger
//! misfit than a near one). Its fits live on an image-anchored knot grid, so the fit of a union
//! differs from the fits of its parts only near where they meet: the *seam*, the pixels in cells
//! that hold or touch a cell of the other segment. Merging the pair trades the parts' separate surfaces for one along
//! the seam; eq. 4.8 accepts the trade when the union's extra squared misfit is below `tolerance`
//! noise variances per seam pixel:
//!
//! `χ²(S_i ∪ S_j) - χ²(S_i) - χ²(S_j) < tolerance · |seam(S_i, S_j)|`.
//!
//! Two segments whose cells do not touch have an empty seam and never merge (Algorithm 1 only
//! tests adjacent segments).

use crate::grid::KnotGrid;
use crate::normal::Normal;
use rgbd_error::{invalid, RgbdError};

/// Kinect v1 axial noise coefficient `a` in `σ_z = a · z²` (metres; Khoshelham & Elberink 2012,
/// "Accuracy and resolution of Kinect depth data for indoor mapping applications", Sensors 12(2),
/// eq. 9 fitted to their plane measurements: `σ_z ≈ 1.425e-3 · z²`).
pub const KINECT_V1_NOISE: f64 = 1.425e-3;

/// Exponent of the depth noise of a triangulating (structured light, stereo) sensor:
/// `σ_z ∝ z²` because depth is inverse to disparity and the disparity noise is constant.
pub const TRIANGULATION_POWER: f64 = 2.0;

/// Default knot spacing of the test grid (pixels of a 640x480 image): the merge test compares
/// fits within about one 16-pixel cell plus the cubic support of the seam.
pub const DEFAULT_TEST_SPACING: f64 = 16.0;

/// Default tolerance: the union may fit its seam pixels worse than the parts did by one noise
/// variance each on average (the parts agree across the seam to within the sensor noise).
pub const DEFAULT_TOLERANCE: f64 = 1.0;

/// Axial depth noise `σ(z) = scale · z^power` (depth and `scale` in the same length unit).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NoiseModel {
    pub scale: f64,
    pub power: f64,
}

impl NoiseModel {
    /// Kinect v1 / structured light: `σ_z = 1.425e-3 · z²` m (see [`KINECT_V1_NOISE`]).
    pub const KINECT_V1: Self = Self {
        scale: KINECT_V1_NOISE,
        power: TRIANGULATION_POWER,
    };

    /// Rejects a non-positive scale or a non-finite power.
    pub fn validate(&self) -> Result<(), RgbdError> {
        if !(self.scale.is_finite() && self.scale > 0.0) {
            return Err(invalid("noise_scale", self.scale, "a noise scale > 0"));
        }
        if !self.power.is_finite() {
            return Err(invalid("noise_power", self.power, "a finite exponent"));
        }
        Ok(())
    }

    /// `σ(z)`.
    pub fn sigma(&self, z: f64) -> f64 {
        self.scale * z.powf(self.power)
    }

    /// Variance-stabilised depth `g(z) = ∫ dz / σ(z)`: `-1 / (a z)` for `power = 2` (disparity in
    /// noise units), `ln z / a` for `power = 1`, `z / a` for constant noise. NaN when `z` is not
    /// a positive finite depth.
    #[inline]
    pub fn stabilize(&self, z: f64) -> f64 {
        if !(z.is_finite() && z > 0.0) {
            return f64::NAN;
        }
        let (a, p) = (self.scale, self.power);
        if p == 2.0 {
            -1.0 / (a * z)
        } else if p == 0.0 {
            z / a
        } else if (p - 1.0).abs() < 1e-12 {
            z.ln() / a
        } else {
            z.powf(1.0 - p) / (a * (1.0 - p))
        }
    }
}

impl Default for NoiseModel {
    fn default() -> Self {
        Self::KINECT_V1
    }
}

/// Default window of the local union fit ([`SeamTest::window`]): the union's control points
/// within this many points of the contested ones move, the others stay at the parts' fits.
pub const DEFAULT_WINDOW: usize = 2;

/// Parameters of the seam test ([`crate::Criterion::Seam`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SeamTest {
    /// Knot spacing of the test grid, pixels.
    pub spacing: f64,
    /// Depth noise of the sensor.
    pub noise: NoiseModel,
    /// Allowed extra squared misfit per seam pixel, in noise variances.
    pub tolerance: f64,
    /// Union fit of the test: `Some(r)` frees only the control points within `r` (Chebyshev,
    /// in control points) of those both parts' supports hold and keeps the others at the parts'
    /// fits ([`crate::local`]: cost independent of the segments' sizes, `χ²` of the union an
    /// upper bound of the exact one); `None` solves the whole union (exact, cost grows with the
    /// larger segment's cell box).
    pub window: Option<usize>,
}

impl Default for SeamTest {
    fn default() -> Self {
        Self {
            spacing: DEFAULT_TEST_SPACING,
            noise: NoiseModel::KINECT_V1,
            tolerance: DEFAULT_TOLERANCE,
            window: Some(DEFAULT_WINDOW),
        }
    }
}

impl SeamTest {
    /// Rejects a spacing below 1 pixel, a bad noise model or a negative tolerance.
    pub fn validate(&self) -> Result<(), RgbdError> {
        if !(self.spacing.is_finite() && self.spacing >= 1.0) {
            return Err(invalid(
                "test_spacing",
                self.spacing,
                "a knot spacing >= 1 pixel",
            ));
        }
        self.noise.validate()?;
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return Err(invalid("tolerance", self.tolerance, "a tolerance >= 0"));
        }
        Ok(())
    }
}

/// Number of seam pixels of `a ∪ b`: those in a cell that holds or touches (8-neighbourhood) a
/// cell of the other set. The union's fit differs from the parts' mostly there (the cubic
/// support reaches further, but its influence decays). Zero when no cell of one set touches a
/// cell of the other.
pub fn seam_pixels(a: &Normal, b: &Normal, grid: &KnotGrid) -> usize {
    if a.cells.is_empty() || b.cells.is_empty() {
        return 0;
    }
    let (alo, ahi) = cell_box(a, grid);
    let (blo, bhi) = cell_box(b, grid);
    if alo.0 > bhi.0 + 1 || blo.0 > ahi.0 + 1 || alo.1 > bhi.1 + 1 || blo.1 > ahi.1 + 1 {
        return 0;
    }
    // Mark grid over the joint cell box with a one-cell border.
    let lo = (alo.0.min(blo.0), alo.1.min(blo.1));
    let hi = (ahi.0.max(bhi.0), ahi.1.max(bhi.1));
    let w = hi.0 - lo.0 + 3;
    let h = hi.1 - lo.1 + 3;
    let at = |c: u32| {
        let (u, v) = (c as usize % grid.cells_u, c as usize / grid.cells_u);
        (v - lo.1 + 1) * w + u - lo.0 + 1
    };
    let mut mark = vec![0u8; w * h];
    for (set, bit) in [(a, 1u8), (b, 2u8)] {
        for &c in &set.cells {
            mark[at(c)] |= bit;
        }
    }
    let k = a.k;
    let mut n = 0.0;
    for (set, other) in [(a, 2u8), (b, 1u8)] {
        let bl = set.block_len();
        for (&c, block) in set.cells.iter().zip(set.blocks.chunks(bl)) {
            let r = at(c);
            let touches = [
                r - w - 1,
                r - w,
                r - w + 1,
                r - 1,
                r,
                r + 1,
                r + w - 1,
                r + w,
                r + w + 1,
            ]
            .iter()
            .any(|&q| mark[q] & other != 0);
            if touches {
                // The basis is a partition of unity: Σ over the cell's pixels of Σ_a B_a = count.
                n += block[bl - k..].iter().sum::<f64>();
            }
        }
    }
    n.round() as usize
}

fn cell_box(n: &Normal, grid: &KnotGrid) -> ((usize, usize), (usize, usize)) {
    let (mut lo, mut hi) = ((usize::MAX, usize::MAX), (0, 0));
    for &c in &n.cells {
        let (u, v) = (c as usize % grid.cells_u, c as usize / grid.cells_u);
        lo = (lo.0.min(u), lo.1.min(v));
        hi = (hi.0.max(u), hi.1.max(v));
    }
    (lo, hi)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::valid_mean;
    use crate::normal::{accumulate, Region};

    #[test]
    fn stabilised_depth_has_unit_noise() {
        // g'(z) σ(z) = 1 for every exponent.
        for p in [0.0, 1.0, 1.5, 2.0, 3.0] {
            let m = NoiseModel {
                scale: 2e-3,
                power: p,
            };
            for z in [0.5, 1.0, 3.0, 7.0] {
                let h = 1e-6 * z;
                let d = (m.stabilize(z + h) - m.stabilize(z - h)) / (2.0 * h);
                assert!((d * m.sigma(z) - 1.0).abs() < 1e-6, "p={p} z={z}: {d}");
            }
        }
        assert!(NoiseModel::KINECT_V1.stabilize(0.0).is_nan());
        assert!(NoiseModel::KINECT_V1.stabilize(f64::NAN).is_nan());
    }

    #[test]
    fn scaled_scene_with_scaled_noise_is_the_same_test() {
        // Depth ×k with σ ×k (scale a·k^(1-p)) gives the same g up to a constant.
        let k: f64 = 3.7;
        for p in [0.0, 2.0, 1.5] {
            let m = NoiseModel {
                scale: 1.425e-3,
                power: p,
            };
            let mk = NoiseModel {
                scale: m.scale * k.powf(1.0 - p),
                power: p,
            };
            let d = m.stabilize(2.0) - m.stabilize(1.0);
            let dk = mk.stabilize(2.0 * k) - mk.stabilize(k);
            assert!((d - dk).abs() < 1e-9 * d.abs(), "p={p}");
        }
    }

    #[test]
    fn bad_parameters() {
        let ok = SeamTest::default();
        assert!(ok.validate().is_ok());
        for t in [
            SeamTest { spacing: 0.5, ..ok },
            SeamTest {
                tolerance: -1.0,
                ..ok
            },
            SeamTest {
                noise: NoiseModel {
                    scale: 0.0,
                    power: 2.0,
                },
                ..ok
            },
            SeamTest {
                noise: NoiseModel {
                    scale: 1e-3,
                    power: f64::NAN,
                },
                ..ok
            },
        ] {
            assert!(t.validate().is_err());
        }
    }

    fn normals(labels: &[i32], w: usize, h: usize, grid: &KnotGrid) -> Vec<Normal> {
        let vals = vec![1.0f64; w * h];
        let full = Region::full(w, h);
        let off = valid_mean(&vals, w, 1, full, |_| true);
        accumulate(&vals, w, h, 1, Some(labels), 3, grid, &off, full)
    }

    #[test]
    fn seam_is_the_cells_touching_the_other_set() {
        // 64x16 image, spacing 8: label 0 = columns < 24 (cells 0..3), label 1 = columns 24..32
        // (cell 3), label 2 = columns >= 56 (cell 7), plus one pixel of label 2 in cell 5.
        let (w, h) = (64, 16);
        let grid = KnotGrid::new(w, h, 8.0, 3).unwrap();
        let labels: Vec<i32> = (0..w * h)
            .map(|i| match i % w {
                u if u < 24 => 0,
                u if u < 32 => 1,
                u if u >= 56 => 2,
                _ => -1,
            })
            .collect();
        let mut labels = labels;
        labels[3 * w + 44] = 2;
        let n = normals(&labels, w, h, &grid);
        // Cell column 2 (label 0) touches cell column 3 (label 1): 8 + 8 pixels per row.
        assert_eq!(seam_pixels(&n[0], &n[1], &grid), 2 * 8 * 16);
        assert_eq!(seam_pixels(&n[1], &n[0], &grid), 2 * 8 * 16);
        assert_eq!(seam_pixels(&n[0], &n[2], &grid), 0);
        // The stray pixel in cell (5, 0) touches nothing of label 1 (cell column 3).
        assert_eq!(seam_pixels(&n[1], &n[2], &grid), 0);
        labels[3 * w + 36] = 2; // cell (4, 0) touches cell (3, 0) and (3, 1)
        let n = normals(&labels, w, h, &grid);
        assert_eq!(seam_pixels(&n[1], &n[2], &grid), 8 * 16 + 1);
    }
}
