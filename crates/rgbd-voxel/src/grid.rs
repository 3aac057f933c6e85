//! The cubic voxel grid of a shape and the occupancy it holds.

use rgbd_error::{invalid, Result};
use rgbd_geom::shape::Cube;

/// Largest grid side (voxels); 1024³ bytes is a gigabyte.
pub const MAX_RESOLUTION: usize = 1024;

/// A cubic `res³` grid: voxel `(i, j, k)` covers `min + [i, j, k] * size .. + size`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    pub res: usize,
    pub min: [f64; 3],
    pub size: f64,
}

impl Grid {
    /// The grid over the [`Cube`] of `points` (`n x 3`; rgbd-geom's shape frame, shared with
    /// the depth views): the largest extent spans all `res` voxels, the other axes centred; a
    /// single point lands in the centre voxel (never a division by 0).
    pub fn fit(points: &[f32], res: usize) -> Result<Self> {
        if !(1..=MAX_RESOLUTION).contains(&res) {
            return Err(invalid(
                "resolution",
                res,
                format!("1..={MAX_RESOLUTION} voxels per side"),
            ));
        }
        let cube = Cube::fit(points)?;
        // A hair of margin so the maximum lands inside the last voxel.
        let size = cube.side * (1.0 + 1e-9) / res as f64;
        let min = cube.centre.map(|c| c - 0.5 * size * res as f64);
        Ok(Self { res, min, size })
    }

    /// The voxel index along axis `a` of coordinate `v`, clamped into the grid.
    pub fn cell(&self, a: usize, v: f64) -> usize {
        let c = ((v - self.min[a]) / self.size).floor();
        c.clamp(0.0, (self.res - 1) as f64) as usize
    }

    /// Flat index of voxel `(i, j, k)` (x fastest).
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        (k * self.res + j) * self.res + i
    }
}

/// Occupancy of a [`Grid`], one byte per voxel (0 empty, 1 filled), x fastest.
#[derive(Debug, Clone, PartialEq)]
pub struct Voxels {
    pub grid: Grid,
    pub filled: Vec<u8>,
}

impl Voxels {
    /// An empty grid.
    pub fn empty(grid: Grid) -> Self {
        Self {
            filled: vec![0; grid.res * grid.res * grid.res],
            grid,
        }
    }

    /// Number of filled voxels.
    pub fn count(&self) -> usize {
        self.filled.iter().map(|&v| usize::from(v)).sum()
    }

    /// Whether voxel `(i, j, k)` is filled.
    pub fn get(&self, i: usize, j: usize, k: usize) -> bool {
        self.filled[self.grid.index(i, j, k)] != 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn largest_extent_spans_the_grid_and_others_are_centred() {
        let g = Grid::fit(&[0.0, 0.0, 0.0, 2.0, 1.0, 0.0], 4).unwrap();
        assert!((g.size - 0.5).abs() < 1e-6);
        assert_eq!(g.cell(0, 0.0), 0);
        assert_eq!(g.cell(0, 2.0), 3);
        // y spans 0..1 centred in a 2-wide cube: -0.5..1.5.
        assert!((g.min[1] + 0.5).abs() < 1e-6);
        assert_eq!(g.cell(2, 0.0), 2, "a flat axis sits in the middle");
    }

    #[test]
    fn a_single_point_lands_in_the_centre() {
        let g = Grid::fit(&[5.0, 5.0, 5.0], 3).unwrap();
        assert_eq!((g.cell(0, 5.0), g.cell(1, 5.0), g.cell(2, 5.0)), (1, 1, 1));
    }

    #[test]
    fn bad_input_is_named() {
        assert!(Grid::fit(&[], 8)
            .unwrap_err()
            .to_string()
            .starts_with("points"));
        assert!(Grid::fit(&[0.0, f32::NAN, 0.0], 8).is_err());
        assert!(Grid::fit(&[0.0, 0.0, 0.0, 3e38, 0.0, -3e38], 8).is_err());
        let e = Grid::fit(&[0.0; 3], 0).unwrap_err();
        assert!(e.to_string().starts_with("resolution"), "{e}");
    }
}
