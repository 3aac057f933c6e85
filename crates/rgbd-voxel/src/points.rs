//! Occupancy of point clouds.

use rgbd_error::{check_interrupt, invalid, Result};

use crate::grid::{Grid, Voxels};

/// The voxels of a `res³` [`Grid::fit`] grid that hold at least one of `points` (`n x 3`),
/// each then dilated by `dilate` voxels (a cube of side `2 dilate + 1`) so that a sparse cloud
/// (1024 points) closes into a surface.
pub fn voxelize_points(points: &[f32], res: usize, dilate: usize) -> Result<Voxels> {
    let grid = Grid::fit(points, res)?;
    if dilate > res {
        return Err(invalid(
            "dilate",
            dilate,
            format!("at most the resolution {res}"),
        ));
    }
    let mut v = Voxels::empty(grid);
    for (n, p) in points.chunks_exact(3).enumerate() {
        if n % (1 << 16) == 0 {
            check_interrupt()?;
        }
        let c: [usize; 3] = std::array::from_fn(|a| grid.cell(a, f64::from(p[a])));
        let span = |x: usize| x.saturating_sub(dilate)..=(x + dilate).min(res - 1);
        for k in span(c[2]) {
            for j in span(c[1]) {
                for i in span(c[0]) {
                    v.filled[grid.index(i, j, k)] = 1;
                }
            }
        }
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn corners_and_dilation() {
        let pts = [0.0f32, 0.0, 0.0, 1.0, 1.0, 1.0];
        let v = voxelize_points(&pts, 4, 0).unwrap();
        assert_eq!(v.count(), 2);
        assert!(v.get(0, 0, 0) && v.get(3, 3, 3));
        let d = voxelize_points(&pts, 4, 1).unwrap();
        assert_eq!(d.count(), 16, "two 2x2x2 corner blocks");
        assert!(voxelize_points(&pts, 4, 5).is_err());
    }
}
