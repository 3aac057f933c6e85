//! First-hit rendering: depth, normals, triangle / object ids and barycentric coordinates of the
//! surface seen through each pixel centre. Rows are rendered in parallel (rayon).

use rayon::prelude::*;
use rgbd_error::{check_interrupt, Result};

use crate::bvh::Hit;
use crate::scene::{Scene, Surface};
use crate::view::View;

/// Per-pixel first-hit attributes, row-major `height x width` (x channels).
#[derive(Debug, Clone, PartialEq)]
pub struct GBuffer {
    /// Depth z along the camera's optical axis (metres), NaN where the ray hits nothing.
    pub depth: Vec<f32>,
    /// Unit normal in the camera frame, facing the camera (3 per pixel, NaN on misses).
    pub normal: Vec<f32>,
    /// Index of the hit triangle in the scene's input order, -1 on misses.
    pub prim: Vec<i32>,
    /// Object index of the hit triangle, -1 on misses.
    pub object: Vec<i32>,
    /// Barycentric coordinates (u, v) of vertices 1 and 2 of the hit triangle (NaN on misses).
    pub bary: Vec<f32>,
}

/// Depth only (z in the camera frame; NaN for misses): the fast path for depth views.
/// Every rendering loop checks for an interrupt once per row.
pub fn render_depth(scene: &Scene, view: &View) -> Result<Vec<f32>> {
    let w = view.width;
    let xs: Vec<f32> = (0..w).map(|u| view.plane_x(u as f64)).collect();
    let mut out = vec![f32::NAN; view.len()];
    out.par_chunks_mut(w)
        .enumerate()
        .try_for_each(|(row, line)| {
            check_interrupt()?;
            let y = view.plane_y(row as f64);
            // Eight neighbouring pixels at a time walk the BVH as one packet.
            let mut px = line.chunks_exact_mut(8);
            let mut x8 = xs.chunks_exact(8);
            for (out, x) in (&mut px).zip(&mut x8) {
                let rays = std::array::from_fn(|i| view.ray_at(x[i], y));
                for (o, h) in out.iter_mut().zip(scene.cast8(&rays, 0.0)) {
                    if let Some(h) = h {
                        *o = h.t;
                    }
                }
            }
            for (o, &x) in px.into_remainder().iter_mut().zip(x8.remainder()) {
                if let Some(h) = scene.cast(&view.ray_at(x, y), 0.0) {
                    *o = h.t;
                }
            }
            Ok(())
        })?;
    Ok(out)
}

/// All first-hit attributes.
pub fn render_gbuffer(scene: &Scene, view: &View) -> Result<GBuffer> {
    let w = view.width;
    // Resolve each hit where its ray is at hand (one ray per pixel, cast and shaded in parallel).
    let hits: Vec<Option<(Hit, Surface)>> = (0..view.len())
        .into_par_iter()
        .with_min_len(w)
        .map(|i| {
            if i % w == 0 {
                check_interrupt()?;
            }
            let ray = view.ray((i % w) as f64, (i / w) as f64);
            Ok(scene.cast(&ray, 0.0).map(|h| (h, scene.surface(&ray, &h))))
        })
        .collect::<Result<_>>()?;
    let n = view.len();
    let mut g = GBuffer {
        depth: vec![f32::NAN; n],
        normal: vec![f32::NAN; 3 * n],
        prim: vec![-1; n],
        object: vec![-1; n],
        bary: vec![f32::NAN; 2 * n],
    };
    for (i, hit) in hits.iter().enumerate() {
        let Some((h, s)) = hit else { continue };
        g.depth[i] = h.t;
        g.normal[3 * i..3 * i + 3].copy_from_slice(&view.to_camera(s.n));
        g.prim[i] = h.prim as i32;
        g.object[i] = s.object as i32;
        g.bary[2 * i] = h.u;
        g.bary[2 * i + 1] = h.v;
    }
    Ok(g)
}
