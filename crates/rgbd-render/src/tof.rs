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

/// Radius (pixels) of the edge-aware filter applied to the indirect (multipath) phasors: indirect
/// light varies slowly over a surface, so pooling the secondary rays of neighbouring pixels on
/// the same surface cuts the Monte-Carlo noise by the window size (7x7 -> ~49x fewer variance)
/// without blurring across depth edges.
pub const MULTIPATH_FILTER_RADIUS: usize = 3;
/// Neighbours pool their indirect light only if their depth differs by less than this fraction
/// and their normals by less than ~25 degrees (cosine 0.9).
const FILTER_DEPTH_TOL: f32 = 0.03;
const FILTER_NORMAL_COS: f32 = 0.9;

/// What the first pass records per pixel.
#[derive(Debug, Clone, Copy, Default)]
struct Sample {
    /// Sum of the direct returns' phasors.
    direct: (f64, f64),
    /// Amplitude-weighted mean range of the direct returns (unwrapping reference on misses).
    ref_range: f64,
    ref_weight: f64,
    /// Depth z and normal of the surface at the pixel centre (NaN depth on a miss).
    z: f32,
    /// Length of the centre ray's direction (its z is 1): radial range = z * ray_len.
    ray_len: f32,
    n: [f32; 3],
    /// Indirect returns as phasors of their detour (path minus the direct round trip).
    indirect: (f64, f64),
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
    let (w, h) = (view.width, view.height);
    let samples: Vec<Sample> = (0..view.len())
        .into_par_iter()
        .with_min_len(w)
        .map(|i| {
            if i % w == 0 {
                rgbd_error::check_interrupt()?;
            }
            Ok(first_pass(scene, view, opts, i % w, i / w))
        })
        .collect::<Result<_>>()?;
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
        .try_for_each(|(row, ((depth, amp), truth))| {
            rgbd_error::check_interrupt()?;
            for col in 0..w {
                let indirect = pooled_indirect(&samples, w, h, col, row);
                let px = finish(view, opts, &samples[row * w + col], indirect, col, row);
                depth[col] = px.0;
                amp[col] = px.1;
                truth[col] = samples[row * w + col].z;
            }
            Ok::<_, rgbd_error::RgbdError>(())
        })?;
    Ok(frame)
}

/// Radians of phase per metre of optical path.
fn wavenumber(o: &TofOptions) -> f64 {
    std::f64::consts::TAU * o.frequency_hz / SPEED_OF_LIGHT
}

fn first_pass(scene: &Scene, view: &View, o: &TofOptions, col: usize, row: usize) -> Sample {
    let k = wavenumber(o);
    let centre = view.ray(col as f64, row as f64);
    let centre_hit = scene.cast(&centre, 0.0);
    let mut out = Sample {
        z: centre_hit.map_or(f32::NAN, |h| h.t),
        ray_len: norm(centre.d),
        ..Sample::default()
    };
    let add_phasor = |acc: &mut (f64, f64), a: f64, path: f64| {
        let (s, c) = (k * path).sin_cos();
        acc.0 += a * c;
        acc.1 -= a * s;
    };
    // Direct returns from an s x s grid of sub-pixel rays.
    let s = o.subsamples;
    let weight = 1.0 / (s * s) as f64;
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
        add_phasor(&mut out.direct, a * weight, 2.0 * d);
        out.ref_range += d * a;
        out.ref_weight += a;
    }
    let Some(hit) = centre_hit else { return out };
    let p = scene.surface(&centre, &hit);
    out.n = p.n;
    if o.multipath_rays == 0 {
        return out;
    }
    // One-bounce indirect light from the surface at the pixel centre.
    let albedo_p = scene.material(&p).albedo_ir as f64;
    let emitter = view.centre();
    let origin = add(p.p, scale(p.n, SURFACE_EPS));
    let (t, b) = basis(p.n);
    let mut rng = Rng::new(o.seed, (row * view.width + col) as u64, 0);
    let kk = o.multipath_rays;
    let d_p = (hit.t * out.ray_len) as f64; // emitter (= camera centre) to p
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
        // Detour: emitter -> q -> p instead of emitter -> p (the last leg p -> camera is shared).
        let detour = dist_e as f64 + h2.t as f64 * norm(dir) as f64 - d_p;
        add_phasor(&mut out.indirect, a, detour);
    }
    out
}

/// Edge-aware mean of the indirect detour phasors around `(col, row)`.
fn pooled_indirect(samples: &[Sample], w: usize, h: usize, col: usize, row: usize) -> (f64, f64) {
    let c = &samples[row * w + col];
    if !c.z.is_finite() {
        return (0.0, 0.0);
    }
    let r = MULTIPATH_FILTER_RADIUS;
    let (mut sum, mut n) = ((0.0, 0.0), 0usize);
    for y in row.saturating_sub(r)..(row + r + 1).min(h) {
        for x in col.saturating_sub(r)..(col + r + 1).min(w) {
            let q = &samples[y * w + x];
            if (q.z - c.z).abs() <= FILTER_DEPTH_TOL * c.z && dot(q.n, c.n) >= FILTER_NORMAL_COS {
                sum.0 += q.indirect.0;
                sum.1 += q.indirect.1;
                n += 1;
            }
        }
    }
    (sum.0 / n as f64, sum.1 / n as f64)
}

/// (measured depth, amplitude) of one pixel from its direct and pooled indirect light.
fn finish(
    view: &View,
    o: &TofOptions,
    s: &Sample,
    indirect: (f64, f64),
    col: usize,
    row: usize,
) -> (f32, f32) {
    let k = wavenumber(o);
    let ray_len = s.ray_len as f64;
    let (mut re, mut im) = s.direct;
    if s.z.is_finite() {
        // Multiply the detour phasors by exp(-i k 2 d_p), the pixel's own direct round trip.
        let (sn, cs) = (k * 2.0 * s.z as f64 * ray_len).sin_cos();
        re += indirect.0 * cs + indirect.1 * sn;
        im += indirect.1 * cs - indirect.0 * sn;
    }
    if o.noise {
        let mut rng = Rng::new(o.seed, (row * view.width + col) as u64, 1);
        let a_clean = (re * re + im * im).sqrt() as f32;
        let sigma = (o.read_noise * o.read_noise + o.shot_noise * (a_clean + o.ambient)).sqrt();
        re += (sigma * rng.normal()) as f64;
        im += (sigma * rng.normal()) as f64;
    }
    let amplitude = (re * re + im * im).sqrt();
    if s.ref_weight == 0.0 || amplitude < o.amplitude_threshold as f64 || amplitude == 0.0 {
        return (f32::NAN, amplitude as f32);
    }
    let unambiguous = std::f64::consts::PI / k; // c / 2f, in range units
    let range = (-im).atan2(re).rem_euclid(std::f64::consts::TAU) / (2.0 * k);
    let range = if o.wrap_phase {
        range
    } else {
        // Oracle unwrapping: the cycle that brings the range closest to the true one.
        let reference = if s.z.is_finite() {
            s.z as f64 * ray_len
        } else {
            s.ref_range / s.ref_weight
        };
        range + ((reference - range) / unambiguous).round() * unambiguous
    };
    ((range / ray_len) as f32, amplitude as f32)
}
