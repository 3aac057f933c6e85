//! Continuous-wave ToF simulation (thesis §2.3, §3.5; METHOD_NOTES §9).
//!
//! The emitter sits at the camera centre. Every return is a phasor `a * exp(-i 2 pi f L / c)`
//! with `L` the optical path length; the sensor measures the sum of all returns in a pixel:
//! - direct light from `s x s` sub-pixel rays (Lambertian: `a = P * albedo_ir * cos / d^2`),
//!   so a pixel straddling a depth edge mixes foreground and background ("flying pixels");
//! - one-bounce indirect light (multipath): cosine-weighted, stratified secondary rays from the
//!   surface seen at the pixel centre; a secondary hit `q` lit by the emitter returns
//!   `albedo_p * albedo_q * P cos_q / |q - e|^2 / K` along the longer path `|e q| + |q p| + |p c|`,
//!   which biases depth away from the camera in concave corners;
//! - noise on the in-phase / quadrature sums: `sigma^2 = read^2 + shot * (A + ambient)` (shot noise
//!   grows with the collected light, so relative phase noise grows as the amplitude falls, the
//!   `sigma_rho ~ sqrt(B)/A` law);
//! - pixels whose amplitude falls below a threshold are invalid (NaN), as on real sensors;
//! - the phase is wrapped at `c / 2f` or, by default, unwrapped with an oracle (the true range
//!   picks the cycle), standing in for multi-frequency unwrapping ("PU" in SYNTH3's file names).
//!
//! Radiometric constants are shared by direct and indirect terms (both carry `albedo_p / pi`,
//! dropped), so their ratio is physical; the absolute scale is set by `power`.

use rayon::prelude::*;
use rgbd_geom::error::invalid;
use rgbd_geom::Result;

use crate::math::{add, basis, dot, norm, scale, sub};
use crate::rng::Rng;
use crate::scene::Scene;
use crate::shade::SURFACE_EPS;
use crate::view::{Projection, View};

/// Speed of light in vacuum (m/s).
pub const SPEED_OF_LIGHT: f64 = 299_792_458.0;
/// Largest accepted sub-pixel grid per axis.
pub const MAX_SUBSAMPLES: usize = 8;
/// Largest accepted number of multipath rays per pixel.
pub const MAX_MULTIPATH_RAYS: usize = 256;

/// Parameters of [`simulate_tof`]; see the module docs for the model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TofOptions {
    /// Modulation frequency (Hz).
    pub frequency_hz: f64,
    /// Sub-pixel rays per axis for the direct return (1 = no mixed pixels).
    pub subsamples: usize,
    /// Secondary rays per pixel for one-bounce multipath (0 = off).
    pub multipath_rays: usize,
    /// Adds read + shot noise to the I/Q sums.
    pub noise: bool,
    /// Emitter power: the amplitude of an albedo-1 surface facing the camera at 1 m.
    pub power: f32,
    /// Read-noise standard deviation of each of I and Q (amplitude units).
    pub read_noise: f32,
    /// Shot-noise coefficient: variance added per unit of collected amplitude.
    pub shot_noise: f32,
    /// Ambient (background) light in amplitude units; adds shot noise only.
    pub ambient: f32,
    /// Pixels with a lower measured amplitude are invalid (NaN depth).
    pub amplitude_threshold: f32,
    /// Wrap the range at `c / 2f` instead of unwrapping it.
    pub wrap_phase: bool,
    pub seed: u64,
}

/// A simulated ToF frame on the ToF camera's lattice.
#[derive(Debug, Clone, PartialEq)]
pub struct TofFrame {
    /// Measured depth z (metres), NaN where invalid.
    pub depth: Vec<f32>,
    /// Measured amplitude (same units as `power`).
    pub amplitude: Vec<f32>,
    /// Ground-truth depth z through the pixel centre (NaN on misses).
    pub truth: Vec<f32>,
}

impl TofOptions {
    fn validate(&self) -> Result<()> {
        if !(self.frequency_hz > 0.0 && self.frequency_hz.is_finite()) {
            return Err(invalid(
                "frequency_hz",
                self.frequency_hz,
                "a finite value > 0",
            ));
        }
        if self.subsamples == 0 || self.subsamples > MAX_SUBSAMPLES {
            return Err(invalid(
                "subsamples",
                self.subsamples,
                format!("1..={MAX_SUBSAMPLES}"),
            ));
        }
        if self.multipath_rays > MAX_MULTIPATH_RAYS {
            return Err(invalid(
                "multipath_rays",
                self.multipath_rays,
                format!("0..={MAX_MULTIPATH_RAYS}"),
            ));
        }
        let named = [
            ("power", self.power),
            ("read_noise", self.read_noise),
            ("shot_noise", self.shot_noise),
            ("ambient", self.ambient),
            ("amplitude_threshold", self.amplitude_threshold),
        ];
        for (name, v) in named {
            if !(v >= 0.0 && v.is_finite()) {
                return Err(invalid(name, v, "a finite value >= 0"));
            }
        }
        Ok(())
    }
}

/// Simulates one ToF frame of `scene` seen by the perspective `view`.
pub fn simulate_tof(scene: &Scene, view: &View, opts: &TofOptions) -> Result<TofFrame> {
    opts.validate()?;
    if !matches!(view.projection, Projection::Perspective { .. }) {
        return Err(invalid(
            "view",
            "an orthographic camera",
            "a perspective ToF camera",
        ));
    }
    let w = view.width;
    let n = view.len();
    let mut frame = TofFrame {
        depth: vec![f32::NAN; n],
        amplitude: vec![0.0; n],
        truth: vec![f32::NAN; n],
    };
    frame
        .depth
        .par_chunks_mut(w)
        .zip(frame.amplitude.par_chunks_mut(w))
        .zip(frame.truth.par_chunks_mut(w))
        .enumerate()
        .for_each(|(row, ((depth, amp), truth))| {
            for col in 0..w {
                let px = pixel(scene, view, opts, col, row);
                depth[col] = px.0;
                amp[col] = px.1;
                truth[col] = px.2;
            }
        });
    Ok(frame)
}

/// (measured depth, amplitude, true depth) of one pixel.
fn pixel(scene: &Scene, view: &View, o: &TofOptions, col: usize, row: usize) -> (f32, f32, f32) {
    let k = std::f64::consts::TAU * o.frequency_hz / SPEED_OF_LIGHT; // rad per metre of path
    let centre = view.ray(col as f64, row as f64);
    let ray_len = norm(centre.d); // |d| with d_z = 1: radial distance = z * ray_len
    let centre_hit = scene.cast(&centre, 0.0);
    let truth = centre_hit.map_or(f32::NAN, |h| h.t);
    let (mut re, mut im) = (0.0f64, 0.0f64);
    let add_phasor = |re: &mut f64, im: &mut f64, a: f64, path: f64| {
        let (s, c) = (k * path).sin_cos();
        *re += a * c;
        *im -= a * s;
    };
    // Direct returns from an s x s grid of sub-pixel rays.
    let s = o.subsamples;
    let weight = 1.0 / (s * s) as f64;
    let (mut ref_range, mut ref_weight) = (0.0f64, 0.0f64);
    for j in 0..s * s {
        let du = ((j % s) as f64 + 0.5) / s as f64 - 0.5;
        let dv = ((j / s) as f64 + 0.5) / s as f64 - 0.5;
        let ray = if s == 1 {
            centre
        } else {
            view.ray(col as f64 + du, row as f64 + dv)
        };
        let Some(hit) = scene.cast(&ray, 0.0) else {
            continue;
        };
        let surf = scene.surface(&ray, &hit);
        let len = norm(ray.d);
        let d = (hit.t * len) as f64;
        let cos = (-dot(surf.n, ray.d) / len).max(0.0) as f64;
        let a = (o.power * scene.material(&surf).albedo_ir) as f64 * cos / (d * d);
        add_phasor(&mut re, &mut im, a * weight, 2.0 * d);
        ref_range += d * a;
        ref_weight += a;
    }
    // One-bounce indirect light from the surface at the pixel centre.
    if let (Some(hit), true) = (centre_hit, o.multipath_rays > 0) {
        let p = scene.surface(&centre, &hit);
        let albedo_p = scene.material(&p).albedo_ir as f64;
        let d_p = (hit.t * ray_len) as f64;
        let emitter = view.centre();
        let origin = add(p.p, scale(p.n, SURFACE_EPS));
        let (t, b) = basis(p.n);
        let mut rng = Rng::new(o.seed, (row * view.width + col) as u64, 0);
        let kk = o.multipath_rays;
        for j in 0..kk {
            // Stratified in azimuth, cosine-weighted in elevation.
            let phi = std::f32::consts::TAU * (j as f32 + rng.uniform()) / kk as f32;
            let r2 = rng.uniform();
            let r = r2.sqrt();
            let dir = add(
                add(scale(t, r * phi.cos()), scale(b, r * phi.sin())),
                scale(p.n, (1.0 - r2).sqrt()),
            );
            let sec = crate::view::Ray { o: origin, d: dir };
            let Some(h2) = scene.cast(&sec, 0.0) else {
                continue;
            };
            let q = scene.surface(&sec, &h2);
            let to_e = sub(emitter, q.p);
            let dist_e = norm(to_e);
            let cos_q = dot(q.n, to_e) / dist_e;
            if cos_q <= 0.0 {
                continue;
            }
            let q_origin = add(q.p, scale(q.n, SURFACE_EPS));
            if scene
                .bvh()
                .occluded(q_origin, sub(emitter, q_origin), 0.0, 1.0)
            {
                continue;
            }
            let albedo_q = scene.material(&q).albedo_ir as f64;
            let e_q = o.power as f64 * cos_q as f64 / (dist_e as f64 * dist_e as f64);
            let a = albedo_p * albedo_q * e_q / kk as f64;
            let path = dist_e as f64 + h2.t as f64 * norm(dir) as f64 + d_p;
            add_phasor(&mut re, &mut im, a, path);
        }
    }
    if o.noise {
        let mut rng = Rng::new(o.seed, (row * view.width + col) as u64, 1);
        let a_clean = (re * re + im * im).sqrt() as f32;
        let sigma = (o.read_noise * o.read_noise + o.shot_noise * (a_clean + o.ambient)).sqrt();
        re += (sigma * rng.normal()) as f64;
        im += (sigma * rng.normal()) as f64;
    }
    let amplitude = (re * re + im * im).sqrt();
    if ref_weight == 0.0 || amplitude < o.amplitude_threshold as f64 || amplitude == 0.0 {
        return (f32::NAN, amplitude as f32, truth);
    }
    let unambiguous = std::f64::consts::PI / k; // c / 2f, in range units
    let range = (-im).atan2(re).rem_euclid(std::f64::consts::TAU) / (2.0 * k);
    let range = if o.wrap_phase {
        range
    } else {
        // Oracle unwrapping: the cycle that brings the range closest to the true one.
        let reference = centre_hit.map_or(ref_range / ref_weight, |h| (h.t * ray_len) as f64);
        range + ((reference - range) / unambiguous).round() * unambiguous
    };
    ((range / ray_len as f64) as f32, amplitude as f32, truth)
}
