//! Voxelization of triangle meshes: the surface by exact triangle-box overlap, the interior by a
//! scanline vote that tolerates holes.

use rayon::prelude::*;
use rgbd_error::{check_interrupt, Result};
use rgbd_geom::shape::used_vertices;

use crate::grid::{Grid, Voxels};
use crate::tribox::overlaps;

/// What a mesh voxelization fills.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Fill {
    /// The voxels the surface touches.
    Surface,
    /// The surface plus every voxel lying between surface voxels along at least two of the
    /// three axes (first and last surface voxel of each axis-parallel line). A hole in the mesh
    /// opens at most the lines through it, and the vote of the other axes closes it, so
    /// non-watertight meshes (most of ModelNet) come out solid; cavities open along at most one
    /// axis (a cup's inside) are filled too: this is the shape's "filled" volume, not a
    /// watertight inside test.
    Solid,
}

/// Voxelizes the mesh `vertices` (`n x 3`) / `faces` (`m x 3` indices) in a `res³`
/// [`Grid::fit`] grid of its used vertices.
pub fn voxelize_mesh(vertices: &[f32], faces: &[u32], res: usize, fill: Fill) -> Result<Voxels> {
    let used = used_vertices(vertices, faces)?;
    let grid = Grid::fit(&used, res)?;
    let corner = |f: u32| -> [f64; 3] {
        let p = &vertices[3 * f as usize..3 * f as usize + 3];
        [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])]
    };
    let h = 0.5 * grid.size;
    let hits: Vec<Vec<usize>> = faces
        .par_chunks(3 * 1024)
        .map(|chunk| -> Result<Vec<usize>> {
            check_interrupt()?;
            let mut out = Vec::new();
            for f in chunk.chunks_exact(3) {
                let t = [corner(f[0]), corner(f[1]), corner(f[2])];
                let lo: [usize; 3] =
                    std::array::from_fn(|a| grid.cell(a, t[0][a].min(t[1][a]).min(t[2][a])));
                let hi: [usize; 3] =
                    std::array::from_fn(|a| grid.cell(a, t[0][a].max(t[1][a]).max(t[2][a])));
                if lo == hi {
                    // The whole triangle lies in one voxel (most faces of a dense mesh).
                    out.push(grid.index(lo[0], lo[1], lo[2]));
                    continue;
                }
                for k in lo[2]..=hi[2] {
                    for j in lo[1]..=hi[1] {
                        for i in lo[0]..=hi[0] {
                            let c = [
                                grid.min[0] + (i as f64 + 0.5) * grid.size,
                                grid.min[1] + (j as f64 + 0.5) * grid.size,
                                grid.min[2] + (k as f64 + 0.5) * grid.size,
                            ];
                            if overlaps(t, c, h) {
                                out.push(grid.index(i, j, k));
                            }
                        }
                    }
                }
            }
            Ok(out)
        })
        .collect::<Result<_>>()?;
    let mut v = Voxels::empty(grid);
    for i in hits.into_iter().flatten() {
        v.filled[i] = 1;
    }
    if fill == Fill::Solid {
        solidify(&mut v);
    }
    Ok(v)
}

/// Marks the voxels between the first and last surface voxel of each axis-parallel line
/// along at least two axes (see [`Fill::Solid`]).
fn solidify(v: &mut Voxels) {
    let r = v.grid.res;
    let mut votes = vec![0u8; v.filled.len()];
    let g = v.grid;
    for axis in 0..3 {
        for b in 0..r {
            for a in 0..r {
                let at = |t: usize| match axis {
                    0 => g.index(t, a, b),
                    1 => g.index(a, t, b),
                    _ => g.index(a, b, t),
                };
                let first = (0..r).find(|&t| v.filled[at(t)] != 0);
                let last = (0..r).rev().find(|&t| v.filled[at(t)] != 0);
                if let (Some(f), Some(l)) = (first, last) {
                    for t in f + 1..l {
                        votes[at(t)] += 1;
                    }
                }
            }
        }
    }
    for (f, &n) in v.filled.iter_mut().zip(&votes) {
        if n >= 2 {
            *f = 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The unit cube as 12 triangles; `open` drops the two top ones.
    fn cube(open: bool) -> (Vec<f32>, Vec<u32>) {
        let v: Vec<f32> = (0..8)
            .flat_map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32])
            .collect();
        let quads = [
            [0, 1, 3, 2], // bottom z=0
            [4, 5, 7, 6], // top z=1
            [0, 1, 5, 4], // y=0
            [2, 3, 7, 6], // y=1
            [0, 2, 6, 4], // x=0
            [1, 3, 7, 5], // x=1
        ];
        let mut f = Vec::new();
        for (n, q) in quads.iter().enumerate() {
            if open && n == 1 {
                continue;
            }
            f.extend([q[0], q[1], q[2], q[0], q[2], q[3]]);
        }
        (v, f)
    }

    #[test]
    fn cube_surface_is_the_grid_shell() {
        let (v, f) = cube(false);
        let s = voxelize_mesh(&v, &f, 8, Fill::Surface).unwrap();
        // The faces lie on the outer voxel faces: exactly the 8³ - 6³ shell.
        assert_eq!(s.count(), 8 * 8 * 8 - 6 * 6 * 6);
        let solid = voxelize_mesh(&v, &f, 8, Fill::Solid).unwrap();
        assert_eq!(solid.count(), 512);
    }

    #[test]
    fn an_open_cube_still_comes_out_solid() {
        let (v, f) = cube(true);
        let solid = voxelize_mesh(&v, &f, 8, Fill::Solid).unwrap();
        assert_eq!(
            solid.count(),
            512,
            "x and y lines still close the missing lid"
        );
    }

    #[test]
    fn a_tilted_triangle_marks_a_connected_band() {
        let v = [0.0f32, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0, 1.0, 1.0];
        let s = voxelize_mesh(&v, &[0, 1, 2], 16, Fill::Surface).unwrap();
        assert!(
            s.count() > 16 * 4 && s.count() < 16 * 16 * 3,
            "{}",
            s.count()
        );
    }

    #[test]
    fn bad_meshes_are_named() {
        let (v, f) = cube(false);
        let e = voxelize_mesh(&v, &[0, 1, 99], 8, Fill::Surface).unwrap_err();
        assert!(e.to_string().starts_with("faces"), "{e}");
        assert!(voxelize_mesh(&v, &[], 8, Fill::Surface).is_err());
        assert!(voxelize_mesh(&[], &f, 8, Fill::Surface).is_err());
        let mut nan = v.clone();
        nan[4] = f32::NAN;
        assert!(voxelize_mesh(&nan, &f, 8, Fill::Surface).is_err());
    }
}
