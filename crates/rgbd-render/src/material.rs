//! Materials: a Lambertian albedo in the visible (RGB) and in the ToF camera's near infrared,
//! modulated by a procedural or image texture.
//!
//! Textures are evaluated in world space on the plane the surface normal is closest to
//! ("tri-planar" projection), so meshes need no UV coordinates and a texture's scale is in
//! metres, which is what matters for stereo matching. The IR albedo is *not* textured: printed
//! patterns change visible reflectance far more than near-IR reflectance, and this keeps ToF
//! noise tied to the material, not to the paint.

use rgbd_geom::error::invalid;
use rgbd_geom::Result;

use crate::math::V3;
use crate::rng::mix64;

/// The texture of a material; `value` in `[0, 1]` scales the albedo (see [`Material::contrast`]).
#[derive(Debug, Clone, PartialEq)]
pub enum Pattern {
    /// No texture.
    Uniform,
    /// Squares of side `period` metres.
    Checker { period: f32 },
    /// Sinusoidal stripes of `period` metres at `angle` radians in the texture plane.
    Stripes { period: f32, angle: f32 },
    /// Value noise (4 octaves) with features of about `scale` metres.
    Noise { scale: f32, seed: u64 },
    /// An RGB image (row-major `height x width x 3`, values in `[0, 1]`) tiled every `period` m.
    Image {
        width: usize,
        height: usize,
        rgb: Vec<f32>,
        period: f32,
    },
}

/// A Lambertian material.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    /// Visible albedo, RGB in `[0, 1]`.
    pub albedo: [f32; 3],
    /// Near-infrared albedo in `[0, 1]` (drives the ToF amplitude).
    pub albedo_ir: f32,
    pub pattern: Pattern,
    /// How strongly a scalar pattern modulates the albedo: `albedo * (1 - c + c * value)`.
    pub contrast: f32,
}

impl Material {
    /// Checks ranges; `index` names the material in the error.
    pub fn validate(&self) -> Result<()> {
        let in01 = |x: f32| (0.0..=1.0).contains(&x);
        if !self.albedo.iter().all(|&a| in01(a)) || !in01(self.albedo_ir) {
            return Err(invalid(
                "material albedo",
                format!("{:?} / ir {}", self.albedo, self.albedo_ir),
                "values in [0, 1]",
            ));
        }
        if !in01(self.contrast) {
            return Err(invalid(
                "material contrast",
                self.contrast,
                "a value in [0, 1]",
            ));
        }
        let positive = |p: f32| p > 0.0 && p.is_finite();
        match &self.pattern {
            Pattern::Uniform => Ok(()),
            Pattern::Checker { period } | Pattern::Stripes { period, .. } if !positive(*period) => {
                Err(invalid(
                    "texture period",
                    period,
                    "a finite value > 0 (metres)",
                ))
            }
            Pattern::Noise { scale, .. } if !positive(*scale) => Err(invalid(
                "texture scale",
                scale,
                "a finite value > 0 (metres)",
            )),
            Pattern::Image {
                width,
                height,
                rgb,
                period,
            } => {
                if !positive(*period) {
                    return Err(invalid(
                        "texture period",
                        period,
                        "a finite value > 0 (metres)",
                    ));
                }
                if *width == 0 || *height == 0 || rgb.len() != width * height * 3 {
                    return Err(invalid(
                        "texture image",
                        format!("{} values for {width}x{height}", rgb.len()),
                        "a non-empty height x width x 3 image",
                    ));
                }
                Ok(())
            }
            _ => Ok(()),
        }
    }

    /// Visible albedo at world point `p` with unit normal `n`.
    pub fn albedo_at(&self, p: V3, n: V3) -> [f32; 3] {
        let (a, b) = planar(p, n);
        let value = match &self.pattern {
            Pattern::Uniform => return self.albedo,
            Pattern::Checker { period } => {
                let k = (a / period).floor() as i64 + (b / period).floor() as i64;
                (k & 1) as f32
            }
            Pattern::Stripes { period, angle } => {
                let s = a * angle.cos() + b * angle.sin();
                0.5 + 0.5 * (std::f32::consts::TAU * s / period).sin()
            }
            Pattern::Noise { scale, seed } => fbm(a / scale, b / scale, *seed),
            Pattern::Image {
                width,
                height,
                rgb,
                period,
            } => {
                let c = sample(rgb, *width, *height, a / period, b / period);
                return [
                    self.albedo[0] * c[0],
                    self.albedo[1] * c[1],
                    self.albedo[2] * c[2],
                ];
            }
        };
        let k = 1.0 - self.contrast + self.contrast * value;
        [self.albedo[0] * k, self.albedo[1] * k, self.albedo[2] * k]
    }
}

/// Texture-plane coordinates: the two world axes orthogonal to the normal's dominant axis.
#[inline]
fn planar(p: V3, n: V3) -> (f32, f32) {
    let (x, y, z) = (n[0].abs(), n[1].abs(), n[2].abs());
    if x >= y && x >= z {
        (p[2], p[1])
    } else if y >= z {
        (p[0], p[2])
    } else {
        (p[0], p[1])
    }
}

/// Lattice value in `[0, 1)` of integer point `(i, j)`.
#[inline]
fn lattice(i: i64, j: i64, seed: u64) -> f32 {
    let h = mix64(seed ^ mix64((i as u64).wrapping_mul(0x9E37_79B9) ^ ((j as u64) << 32)));
    (h >> 40) as f32 / (1u64 << 24) as f32
}

fn value_noise(x: f32, y: f32, seed: u64) -> f32 {
    let (fx, fy) = (x.floor(), y.floor());
    let (i, j) = (fx as i64, fy as i64);
    let s = |t: f32| t * t * (3.0 - 2.0 * t);
    let (u, v) = (s(x - fx), s(y - fy));
    let a = lattice(i, j, seed);
    let b = lattice(i + 1, j, seed);
    let c = lattice(i, j + 1, seed);
    let d = lattice(i + 1, j + 1, seed);
    let top = a + (b - a) * u;
    let bottom = c + (d - c) * u;
    top + (bottom - top) * v
}

/// Four octaves of value noise, normalised to `[0, 1]`.
fn fbm(x: f32, y: f32, seed: u64) -> f32 {
    let (mut sum, mut amp, mut f, mut total) = (0.0, 1.0, 1.0, 0.0);
    for o in 0..4u64 {
        sum += amp * value_noise(x * f, y * f, seed.wrapping_add(o));
        total += amp;
        amp *= 0.5;
        f *= 2.0;
    }
    sum / total
}

/// Bilinear, wrapping sample of an RGB image at texture coordinates (tiles of size 1).
fn sample(rgb: &[f32], w: usize, h: usize, a: f32, b: f32) -> [f32; 3] {
    let x = (a - a.floor()) * w as f32 - 0.5;
    let y = (b - b.floor()) * h as f32 - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let wrap = |i: f32, n: usize| (i as i64).rem_euclid(n as i64) as usize;
    let (xa, xb) = (wrap(x0, w), wrap(x0 + 1.0, w));
    let (ya, yb) = (wrap(y0, h), wrap(y0 + 1.0, h));
    let px = |xx: usize, yy: usize, c: usize| rgb[(yy * w + xx) * 3 + c];
    std::array::from_fn(|c| {
        let top = px(xa, ya, c) * (1.0 - fx) + px(xb, ya, c) * fx;
        let bot = px(xa, yb, c) * (1.0 - fx) + px(xb, yb, c) * fx;
        top * (1.0 - fy) + bot * fy
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mat(pattern: Pattern) -> Material {
        Material {
            albedo: [0.8, 0.6, 0.4],
            albedo_ir: 0.5,
            pattern,
            contrast: 1.0,
        }
    }

    #[test]
    fn checker_alternates_and_noise_is_bounded() {
        let m = mat(Pattern::Checker { period: 0.1 });
        let n = [0.0, 0.0, 1.0];
        assert_eq!(m.albedo_at([0.05, 0.05, 0.0], n), [0.0; 3]);
        assert_eq!(m.albedo_at([0.15, 0.05, 0.0], n), [0.8, 0.6, 0.4]);
        let m = mat(Pattern::Noise {
            scale: 0.05,
            seed: 3,
        });
        let vals: Vec<f32> = (0..500)
            .map(|i| m.albedo_at([i as f32 * 0.013, 0.2, 0.0], n)[0])
            .collect();
        assert!(vals.iter().all(|&v| (0.0..=0.8).contains(&v)));
        let spread = vals.iter().cloned().fold(f32::MIN, f32::max)
            - vals.iter().cloned().fold(f32::MAX, f32::min);
        assert!(spread > 0.3, "noise should vary, spread {spread}");
    }

    #[test]
    fn validation_names_the_problem() {
        assert!(mat(Pattern::Checker { period: 0.0 }).validate().is_err());
        let mut m = mat(Pattern::Uniform);
        m.albedo_ir = 1.5;
        assert!(m.validate().unwrap_err().to_string().contains("albedo"));
        let img = Pattern::Image {
            width: 2,
            height: 2,
            rgb: vec![0.5; 11],
            period: 1.0,
        };
        assert!(mat(img).validate().is_err());
    }

    #[test]
    fn image_texture_wraps() {
        let rgb = vec![1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0];
        let m = mat(Pattern::Image {
            width: 2,
            height: 2,
            rgb,
            period: 1.0,
        });
        let n = [0.0, 0.0, 1.0];
        let a = m.albedo_at([0.25, 0.25, 0.0], n);
        let b = m.albedo_at([1.25, -0.75, 0.0], n);
        assert!((a[0] - 0.8).abs() < 1e-5 && a == b);
    }
}
