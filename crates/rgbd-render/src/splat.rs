//! Point clouds rendered as camera-facing disks ("splats") with a z-buffer: the depth views of
//! the shape pipeline (thesis ch. 5) when the input is a point cloud rather than a mesh.

use rgbd_geom::error::invalid;
use rgbd_geom::Result;

use crate::math::{sub, V3};
use crate::view::{Projection, View};

/// Depth (z, NaN where empty) and winning point index (-1 where empty) of `points` (n x 3,
/// world frame) drawn as disks of world radius `radius`.
pub fn render_points(points: &[f32], radius: f32, view: &View) -> Result<(Vec<f32>, Vec<i32>)> {
    if !points.len().is_multiple_of(3) {
        return Err(invalid(
            "points",
            points.len(),
            "a multiple of 3 values (n x 3)",
        ));
    }
    if !(radius > 0.0 && radius.is_finite()) {
        return Err(invalid("radius", radius, "a finite radius > 0 (metres)"));
    }
    let (w, h) = (view.width, view.height);
    let mut depth = vec![f32::INFINITY; w * h];
    let mut index = vec![-1i32; w * h];
    let origin = view.centre();
    for (i, p) in points.chunks_exact(3).enumerate() {
        if i % (1 << 16) == 0 {
            rgbd_error::check_interrupt()?;
        }
        let pc = view.to_camera(sub([p[0], p[1], p[2]] as V3, origin));
        let z = pc[2];
        let (u, v, r) = match view.projection {
            Projection::Perspective { fx, fy, cx, cy } => {
                if !(z > 0.0) {
                    continue;
                }
                let (x, y) = ((pc[0] / z) as f64, (pc[1] / z) as f64);
                (fx * x + cx, fy * y + cy, radius as f64 * fx / z as f64)
            }
            Projection::Orthographic { sx, sy, cx, cy } => (
                sx * pc[0] as f64 + cx,
                sy * pc[1] as f64 + cy,
                radius as f64 * sx,
            ),
        };
        if !(u.is_finite() && v.is_finite()) {
            continue;
        }
        let (c0, c1) = ((u - r).ceil().max(0.0), (u + r).floor().min(w as f64 - 1.0));
        let (r0, r1) = ((v - r).ceil().max(0.0), (v + r).floor().min(h as f64 - 1.0));
        if c0 > c1 || r0 > r1 {
            continue;
        }
        for row in r0 as usize..=r1 as usize {
            for col in c0 as usize..=c1 as usize {
                let (du, dv) = (col as f64 - u, row as f64 - v);
                if du * du + dv * dv > r * r {
                    continue;
                }
                let k = row * w + col;
                if z < depth[k] {
                    depth[k] = z;
                    index[k] = i as i32;
                }
            }
        }
    }
    depth
        .iter_mut()
        .filter(|d| d.is_infinite())
        .for_each(|d| *d = f32::NAN);
    Ok((depth, index))
}
