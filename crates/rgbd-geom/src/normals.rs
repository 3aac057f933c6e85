//! Surface normals of an organised point cloud (`H x W x 3`), robust to NaN holes.
//!
//! Tangents come from one-sided differences: along each axis the side whose neighbour is valid
//! and closer in depth is used, so a normal next to a depth edge is taken from its own surface
//! and a normal next to a hole still exists. Normals point towards the camera (n · p < 0).

use rayon::prelude::*;

use crate::error::{check_len, invalid, Result};

type P3 = [f32; 3];

#[inline]
fn get(pts: &[f32], i: usize) -> Option<P3> {
    let p = [pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]];
    p.iter().all(|v| v.is_finite()).then_some(p)
}

#[inline]
fn sub(a: P3, b: P3) -> P3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// The tangent along one axis at `c`: prefer the neighbour with the smaller depth jump.
#[inline]
fn tangent(c: P3, prev: Option<P3>, next: Option<P3>, max_jump: f32) -> Option<P3> {
    let fwd = next.map(|n| (sub(n, c), (n[2] - c[2]).abs()));
    let bwd = prev.map(|p| (sub(c, p), (c[2] - p[2]).abs()));
    let best = match (fwd, bwd) {
        (Some(f), Some(b)) => Some(if f.1 <= b.1 { f } else { b }),
        (f, b) => f.or(b),
    }?;
    (best.1 <= max_jump).then_some(best.0)
}

/// Per-point unit normals (NaN where a point or both neighbours on an axis are missing, or
/// where the only neighbour is more than `max_depth_jump` away in depth).
pub fn normals_from_points(
    points: &[f32],
    width: usize,
    height: usize,
    max_depth_jump: f32,
) -> Result<Vec<f32>> {
    if width == 0 || height == 0 {
        return Err(invalid(
            "points",
            format!("{height}x{width} points"),
            "a grid at least 1x1",
        ));
    }
    check_len("points", points, width * height * 3, "height * width * 3")?;
    if !(max_depth_jump > 0.0) {
        return Err(invalid(
            "max_depth_jump",
            max_depth_jump,
            "a depth jump > 0 (metres; inf = no limit)",
        ));
    }
    let mut out = vec![f32::NAN; points.len()];
    out.par_chunks_mut(3 * width)
        .enumerate()
        .for_each(|(v, row)| {
            for (u, o) in row.chunks_exact_mut(3).enumerate() {
                let i = v * width + u;
                let Some(c) = get(points, i) else { continue };
                let left = (u > 0).then(|| get(points, i - 1)).flatten();
                let right = (u + 1 < width).then(|| get(points, i + 1)).flatten();
                let up = (v > 0).then(|| get(points, i - width)).flatten();
                let down = (v + 1 < height).then(|| get(points, i + width)).flatten();
                let (Some(tu), Some(tv)) = (
                    tangent(c, left, right, max_depth_jump),
                    tangent(c, up, down, max_depth_jump),
                ) else {
                    continue;
                };
                let mut n = [
                    tu[1] * tv[2] - tu[2] * tv[1],
                    tu[2] * tv[0] - tu[0] * tv[2],
                    tu[0] * tv[1] - tu[1] * tv[0],
                ];
                let norm = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                if !(norm > 0.0) {
                    continue;
                }
                let sign = if n[0] * c[0] + n[1] * c[1] + n[2] * c[2] > 0.0 {
                    -1.0
                } else {
                    1.0
                };
                for x in &mut n {
                    *x *= sign / norm;
                }
                o.copy_from_slice(&n);
            }
        });
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plane(w: usize, h: usize, hole: Option<usize>) -> Vec<f32> {
        // z = 2 + 0.5 x, seen by a camera at the origin.
        let mut pts = Vec::new();
        for v in 0..h {
            for u in 0..w {
                let (x, y) = (u as f32 * 0.1 - 1.0, v as f32 * 0.1 - 1.0);
                pts.extend_from_slice(&[x, y, 2.0 + 0.5 * x]);
            }
        }
        if let Some(i) = hole {
            pts[3 * i..3 * i + 3].fill(f32::NAN);
        }
        pts
    }

    #[test]
    fn tilted_plane_with_hole() {
        let (w, h) = (12, 9);
        let n = normals_from_points(&plane(w, h, Some(40)), w, h, f32::INFINITY).unwrap();
        let s = 1.0 / (1.25f32).sqrt();
        for i in 0..w * h {
            if i == 40 {
                assert!(n[3 * i].is_nan());
                continue;
            }
            assert!((n[3 * i] - 0.5 * s).abs() < 1e-5, "{i}");
            assert!(n[3 * i + 1].abs() < 1e-5);
            assert!((n[3 * i + 2] + s).abs() < 1e-5);
        }
        assert!(normals_from_points(&[0.0; 6], 2, 1, 0.0).is_err());
        // An empty grid is refused, not a zero-sized chunk (found by a fuzz of the binding).
        for (w, h) in [(0, 5), (5, 0), (0, 0)] {
            assert!(normals_from_points(&[], w, h, 1.0).is_err(), "{w}x{h}");
        }
    }
}
