//! The frame of a 3-D shape (thesis ch. 5): the cube that holds its bounding box. The depth
//! views (rgbd-render) and the voxel grid (rgbd-voxel) both place a shape in it, so a view and
//! a density profile of one shape line up.

use rgbd_error::{invalid, Result};

/// Largest bounding-box extent accepted (coordinates beyond it are a unit mistake).
pub const MAX_EXTENT: f64 = 1e30;

/// The cube of a shape: `centre` and `side` in the input's units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cube {
    pub centre: [f64; 3],
    pub side: f64,
}

impl Cube {
    /// The cube of `points` (`n x 3`, finite): centred on the bounding box, side its largest
    /// extent (the other axes centred), or 1 when every extent is 0 (one point): never a
    /// division by zero.
    pub fn fit(points: &[f32]) -> Result<Self> {
        if points.is_empty() || !points.len().is_multiple_of(3) {
            return Err(invalid(
                "points",
                format!("{} values", points.len()),
                "a non-empty n x 3 array",
            ));
        }
        let mut lo = [f64::INFINITY; 3];
        let mut hi = [f64::NEG_INFINITY; 3];
        for p in points.chunks_exact(3) {
            for (a, &c) in p.iter().enumerate() {
                let v = f64::from(c);
                if !v.is_finite() {
                    return Err(invalid("points", v, "finite coordinates"));
                }
                lo[a] = lo[a].min(v);
                hi[a] = hi[a].max(v);
            }
        }
        let extent = (0..3).map(|a| hi[a] - lo[a]).fold(0.0, f64::max);
        if !(extent <= MAX_EXTENT) {
            return Err(invalid(
                "points",
                format!("a bounding box of extent {extent:e}"),
                format!("an extent <= {MAX_EXTENT:e}"),
            ));
        }
        Ok(Self {
            centre: [0, 1, 2].map(|a| 0.5 * (lo[a] + hi[a])),
            side: if extent > 0.0 { extent } else { 1.0 },
        })
    }

    /// `p` in cube coordinates: centre 0, side 1 (every point of the shape in `[-0.5, 0.5]^3`).
    #[inline]
    pub fn normalize(&self, p: &[f32]) -> [f32; 3] {
        [0, 1, 2].map(|a| ((f64::from(p[a]) - self.centre[a]) / self.side) as f32)
    }
}

/// Checks a triangle mesh (`vertices` `n x 3`, `faces` `m x 3` indices) and returns the
/// vertices its faces use (`k x 3`): stray vertices must not shrink the shape in its cube.
pub fn used_vertices(vertices: &[f32], faces: &[u32]) -> Result<Vec<f32>> {
    if vertices.is_empty() || !vertices.len().is_multiple_of(3) {
        return Err(invalid(
            "vertices",
            format!("{} values", vertices.len()),
            "a non-empty n x 3 array",
        ));
    }
    if faces.is_empty() || !faces.len().is_multiple_of(3) {
        return Err(invalid(
            "faces",
            format!("{} values", faces.len()),
            "a non-empty m x 3 array of vertex indices",
        ));
    }
    let n = vertices.len() / 3;
    let mut used = vec![false; n];
    for &f in faces {
        let f = f as usize;
        if f >= n {
            return Err(invalid("faces", f, format!("vertex indices < {n}")));
        }
        used[f] = true;
    }
    Ok(vertices
        .chunks_exact(3)
        .zip(&used)
        .filter(|(_, &u)| u)
        .flat_map(|(p, _)| p.iter().copied())
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn largest_extent_is_the_side_and_degenerate_shapes_get_one() {
        let c = Cube::fit(&[0.0, 0.0, 0.0, 2.0, 1.0, 0.0]).unwrap();
        assert_eq!((c.centre, c.side), ([1.0, 0.5, 0.0], 2.0));
        assert_eq!(Cube::fit(&[5.0, 5.0, 5.0]).unwrap().side, 1.0);
        assert_eq!(c.normalize(&[2.0, 1.0, 0.0]), [0.5, 0.25, 0.0]);
    }

    #[test]
    fn bad_shapes_are_named() {
        assert!(Cube::fit(&[])
            .unwrap_err()
            .to_string()
            .starts_with("points"));
        assert!(Cube::fit(&[0.0, f32::NAN, 0.0]).is_err());
        assert!(Cube::fit(&[0.0, 0.0, 0.0, 3e38, 0.0, -3e38]).is_err());
        let v = [
            0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 9.0, 9.0, 9.0,
        ];
        assert_eq!(
            used_vertices(&v, &[0, 1, 2]).unwrap().len(),
            9,
            "the stray vertex is left out"
        );
        let e = used_vertices(&v, &[0, 1, 7]).unwrap_err();
        assert!(e.to_string().starts_with("faces"), "{e}");
    }
}
