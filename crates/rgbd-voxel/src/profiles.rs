//! The voxel density profiles of thesis §5.3.2: filled voxels counted along each axis.

use crate::grid::Voxels;

/// Counts of filled voxels along X, Y and Z, each an `res x res` row-major map:
///
/// - X profile (side view along x): rows = z from top (max z) down, columns = y;
/// - Y profile (side view along y): rows = z from top down, columns = x;
/// - Z profile (top view along z): rows = y from max y down, columns = x.
///
/// Counts are raw (0..=res); the network's local contrast normalisation makes them unit-free.
pub fn density_profiles(v: &Voxels) -> [Vec<f32>; 3] {
    let r = v.grid.res;
    let mut px = vec![0.0f32; r * r];
    let mut py = vec![0.0f32; r * r];
    let mut pz = vec![0.0f32; r * r];
    for k in 0..r {
        for j in 0..r {
            for i in 0..r {
                if v.get(i, j, k) {
                    px[(r - 1 - k) * r + j] += 1.0;
                    py[(r - 1 - k) * r + i] += 1.0;
                    pz[(r - 1 - j) * r + i] += 1.0;
                }
            }
        }
    }
    [px, py, pz]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Grid;

    #[test]
    fn a_table_has_dense_legs_from_above() {
        // 4x4x4: a top slab at z = 3 and one leg at (0, 0, 0..3).
        let g = Grid::fit(&[0.0, 0.0, 0.0, 1.0, 1.0, 1.0], 4).unwrap();
        let mut v = Voxels::empty(g);
        for j in 0..4 {
            for i in 0..4 {
                v.filled[g.index(i, j, 3)] = 1;
            }
        }
        for k in 0..3 {
            v.filled[g.index(0, 0, k)] = 1;
        }
        let [x, y, z] = density_profiles(&v);
        // Top view: the leg's column counts 4, the rest of the top 1.
        assert_eq!(z[3 * 4], 4.0);
        assert_eq!(z.iter().sum::<f32>(), 19.0);
        // Side views: the top row is 4 deep everywhere, the leg shows in column 0 below it.
        assert_eq!(&x[0..4], &[4.0; 4]);
        assert_eq!((x[4], x[5]), (1.0, 0.0));
        assert_eq!((y[4], y[5]), (1.0, 0.0));
    }
}
