//! Colour images: Lambertian shading of textured materials under point lights with hard
//! shadows plus ambient light, anti-aliased by a regular `s x s` grid of sub-pixel rays.
//! The output is linear radiance; exposure, gamma, sensor noise and quantisation are applied
//! by the caller (python/rgbd_rs/render.py) so they can differ per camera.

use rayon::prelude::*;
use rgbd_geom::error::invalid;
use rgbd_geom::Result;

use crate::math::{add, dot, norm, scale, sub};
use crate::scene::Scene;
use crate::view::{Ray, View};

/// Offset of secondary-ray origins along the normal (metres), against self-intersection.
pub const SURFACE_EPS: f32 = 1e-4;
/// Largest accepted sub-pixel grid (per axis).
pub const MAX_SUPERSAMPLE: usize = 8;

/// Radiance reaching the camera along `ray` (RGB, linear; black background).
pub fn radiance(scene: &Scene, ray: &Ray, shadows: bool) -> [f32; 3] {
    let Some(hit) = scene.cast(ray, 0.0) else {
        return [0.0; 3];
    };
    let s = scene.surface(ray, &hit);
    let albedo = scene.material(&s).albedo_at(s.p, s.n);
    let mut e = scene.ambient;
    let origin = add(s.p, scale(s.n, SURFACE_EPS));
    for light in &scene.lights {
        let to = sub(light.position, s.p);
        let dist = norm(to);
        let cos = dot(s.n, to) / dist;
        if cos <= 0.0 {
            continue;
        }
        if shadows
            && scene
                .bvh()
                .occluded(origin, sub(light.position, origin), 0.0, 1.0)
        {
            continue;
        }
        let k = cos / (dist * dist);
        for (ec, ic) in e.iter_mut().zip(light.intensity) {
            *ec += ic * k;
        }
    }
    [albedo[0] * e[0], albedo[1] * e[1], albedo[2] * e[2]]
}

/// Renders `height x width x 3` linear RGB with `supersample^2` rays per pixel.
pub fn render_color(
    scene: &Scene,
    view: &View,
    supersample: usize,
    shadows: bool,
) -> Result<Vec<f32>> {
    if supersample == 0 || supersample > MAX_SUPERSAMPLE {
        return Err(invalid(
            "supersample",
            supersample,
            format!("1..={MAX_SUPERSAMPLE} rays per axis"),
        ));
    }
    let w = view.width;
    let s = supersample;
    let inv = 1.0 / (s * s) as f32;
    let mut out = vec![0.0f32; 3 * view.len()];
    out.par_chunks_mut(3 * w)
        .enumerate()
        .try_for_each(|(row, line)| {
            rgbd_error::check_interrupt()?;
            for (col, px) in line.chunks_exact_mut(3).enumerate() {
                let mut acc = [0.0f32; 3];
                for k in 0..s * s {
                    let du = ((k % s) as f64 + 0.5) / s as f64 - 0.5;
                    let dv = ((k / s) as f64 + 0.5) / s as f64 - 0.5;
                    let ray = view.ray(col as f64 + du, row as f64 + dv);
                    let r = radiance(scene, &ray, shadows);
                    for c in 0..3 {
                        acc[c] += r[c];
                    }
                }
                for c in 0..3 {
                    px[c] = acc[c] * inv;
                }
            }
            Ok::<_, rgbd_error::RgbdError>(())
        })?;
    Ok(out)
}
