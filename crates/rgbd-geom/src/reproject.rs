//! Reprojection of a depth map from one camera into another (e.g. ToF -> colour camera) by
//! z-buffered forward splatting.
//!
//! Every valid source pixel is back-projected (through the source lens model), moved by the
//! pose, projected through the target lens model and written to the target pixel(s) it covers
//! if it is the nearest so far. The z-test runs in parallel and deterministically: each target
//! pixel holds an `AtomicU64` key `(depth bits << 32) | source index`, updated with `fetch_min`
//! (positive f32 bit patterns order like the floats), so the winner does not depend on thread
//! timing. Occluded points lose the z-test; target pixels that nothing reaches stay NaN.

use std::sync::atomic::{AtomicU64, Ordering};

use rayon::prelude::*;

use crate::camera::Pose;
use crate::error::{check_len, invalid, Result};
use crate::projection::Camera;

/// Largest accepted splat radius (target pixels); larger footprints blur edges beyond use.
pub const MAX_SPLAT_RADIUS: usize = 8;

/// The reprojected maps on the target lattice.
#[derive(Debug, Clone, PartialEq)]
pub struct Reprojected {
    /// Depth (z in the target frame), `H_t x W_t`, NaN where nothing landed.
    pub depth: Vec<f32>,
    /// Carried channels of the winning source pixel, `H_t x W_t x C` (empty if none given).
    pub channels: Vec<f32>,
    /// Row-major source index of the winning pixel, `-1` where nothing landed.
    pub source_index: Vec<i64>,
}

/// Options of [`reproject_depth`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReprojectOptions {
    /// Each point also fills target pixels within this Chebyshev radius (0 = its own pixel).
    pub splat_radius: usize,
    /// Newton iteration cap / tolerance for the source lens inversion.
    pub max_iter: usize,
    pub tol: f64,
}

/// Reprojects `depth` (`src` lattice, z along the source optical axis) into `dst`.
///
/// `pose` maps source-frame points into the target frame. `channels` is an optional
/// `H_s x W_s x n_channels` buffer carried along with the winning samples.
pub fn reproject_depth(
    depth: &[f32],
    src: &Camera,
    dst: &Camera,
    pose: &Pose,
    channels: Option<(&[f32], usize)>,
    opts: ReprojectOptions,
) -> Result<Reprojected> {
    let (sk, dk) = (src.intrinsics, dst.intrinsics);
    check_len(
        "depth",
        depth,
        sk.len(),
        "height * width of the source camera",
    )?;
    if let Some((c, n)) = channels {
        if n == 0 {
            return Err(invalid("channels", "0 channels", "at least one channel"));
        }
        check_len(
            "channels",
            c,
            sk.len() * n,
            "source height * width * channels",
        )?;
    }
    if opts.splat_radius > MAX_SPLAT_RADIUS {
        return Err(invalid(
            "splat_radius",
            opts.splat_radius,
            format!("0..={MAX_SPLAT_RADIUS} target pixels"),
        ));
    }
    let rays = src.pixel_rays(opts.max_iter, opts.tol);
    let zbuf: Vec<AtomicU64> = (0..dk.len()).map(|_| AtomicU64::new(u64::MAX)).collect();
    let r = opts.splat_radius as i64;
    let (dw, dh) = (dk.width as i64, dk.height as i64);

    depth
        .par_chunks(sk.width)
        .zip(rays.par_chunks(sk.width))
        .enumerate()
        .for_each(|(v, (drow, rrow))| {
            for (u, (&z, ray)) in drow.iter().zip(rrow).enumerate() {
                if !(z > 0.0 && z.is_finite() && ray[0].is_finite()) {
                    continue;
                }
                let z64 = f64::from(z);
                let q = pose.apply([ray[0] * z64, ray[1] * z64, z64]);
                if !(q[2] > 0.0) {
                    continue;
                }
                let (x, y) = (q[0] / q[2], q[1] / q[2]);
                if !dst.distortion.is_monotonic_at(x, y) {
                    continue;
                }
                let [xd, yd] = dst.distortion.distort(x, y);
                let [pu, pv] = dk.to_pixel(xd, yd);
                let (cu, cv) = (pu.round() as i64, pv.round() as i64);
                if cu < -r || cv < -r || cu >= dw + r || cv >= dh + r {
                    continue;
                }
                let key = (u64::from((q[2] as f32).to_bits()) << 32) | (v * sk.width + u) as u64;
                for tv in (cv - r).max(0)..=(cv + r).min(dh - 1) {
                    for tu in (cu - r).max(0)..=(cu + r).min(dw - 1) {
                        zbuf[(tv * dw + tu) as usize].fetch_min(key, Ordering::Relaxed);
                    }
                }
            }
        });

    let n_ch = channels.map_or(0, |(_, n)| n);
    let mut out = Reprojected {
        depth: vec![f32::NAN; dk.len()],
        channels: vec![f32::NAN; dk.len() * n_ch],
        source_index: vec![-1; dk.len()],
    };
    out.depth
        .par_iter_mut()
        .zip(out.source_index.par_iter_mut())
        .zip(zbuf.par_iter())
        .for_each(|((d, s), key)| {
            let key = key.load(Ordering::Relaxed);
            if key != u64::MAX {
                *d = f32::from_bits((key >> 32) as u32);
                *s = (key & 0xFFFF_FFFF) as i64;
            }
        });
    if let Some((c, n)) = channels {
        out.channels
            .par_chunks_mut(n)
            .zip(out.source_index.par_iter())
            .for_each(|(o, &s)| {
                if s >= 0 {
                    let s = s as usize * n;
                    o.copy_from_slice(&c[s..s + n]);
                }
            });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::camera::Intrinsics;
    use crate::distortion::{Distortion, UNDISTORT_MAX_ITER, UNDISTORT_TOL};

    fn opts(r: usize) -> ReprojectOptions {
        ReprojectOptions {
            splat_radius: r,
            max_iter: UNDISTORT_MAX_ITER,
            tol: UNDISTORT_TOL,
        }
    }

    #[test]
    fn identity_reprojection_is_lossless() {
        let k = Intrinsics::new(50.0, 50.0, 15.5, 11.5, 32, 24).unwrap();
        let cam = Camera::new(k, Distortion::from_opencv(&[0.05, 0.0, 0.0, 0.0]).unwrap());
        let depth: Vec<f32> = (0..k.len()).map(|i| 1.0 + (i % 5) as f32).collect();
        let amp: Vec<f32> = (0..k.len()).map(|i| i as f32).collect();
        let out = reproject_depth(
            &depth,
            &cam,
            &cam,
            &Pose::identity(),
            Some((&amp, 1)),
            opts(0),
        )
        .unwrap();
        for i in 0..k.len() {
            assert!((out.depth[i] - depth[i]).abs() < 1e-5);
            assert_eq!(out.channels[i], amp[i]);
            assert_eq!(out.source_index[i], i as i64);
        }
    }

    #[test]
    fn nearer_surface_wins_the_z_test() {
        // A target shifted sideways sees a near square in front of a far wall; where both land on
        // the same target pixel the near one must win.
        let k = Intrinsics::new(40.0, 40.0, 19.5, 19.5, 40, 40).unwrap();
        let cam = Camera::new(k, Distortion::NONE);
        let mut depth = vec![4.0f32; k.len()];
        for v in 15..25 {
            for u in 15..25 {
                depth[v * 40 + u] = 1.0;
            }
        }
        let pose = Pose::new(
            [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            [0.2, 0.0, 0.0],
        )
        .unwrap();
        let out = reproject_depth(&depth, &cam, &cam, &pose, None, opts(1)).unwrap();
        // Near square shifts by f*b/z = 8 px, the wall by 2 px: pixel (20, 27) sees the square.
        assert!((out.depth[20 * 40 + 27] - 1.0).abs() < 1e-6);
        assert!((out.depth[5 * 40 + 5] - 4.0).abs() < 1e-6);
        assert!(reproject_depth(&depth, &cam, &cam, &pose, None, opts(99)).is_err());
    }
}
