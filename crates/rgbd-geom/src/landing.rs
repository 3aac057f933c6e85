//! Where points land on a map: each point (already in the camera's frame) projected through
//! the camera, rounded to its nearest pixel, and the map's value there beside the point's own
//! disparity `b f / z`. The ToF pose checks compare a ToF's disparities with the stereo map's
//! this way for many candidate poses at once.

use rayon::prelude::*;

use crate::error::{invalid, Result};
use crate::projection::Camera;

/// Points per parallel task.
const CHUNK: usize = 4096;

/// What [`land_points`] gives for each point.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Landed {
    /// `bf / z` (NaN for a point not in front of the camera).
    pub disparity: Vec<f64>,
    /// The map's value at the point's nearest pixel (the map's first value where the point
    /// lands outside it or lies behind the camera: meaningless there).
    pub map: Vec<f64>,
    /// Where both are finite and the point lands inside the map.
    pub both: Vec<bool>,
}

/// Lands `N x 3` points `pts` (row-major, camera frame) on the `width x height` map `map`
/// through `cam` (pixel centres at integers; halves round to even). `bf` is the stereo
/// baseline times the focal length.
pub fn land_points(
    cam: &Camera,
    pts: &[f64],
    map: &[f32],
    width: usize,
    height: usize,
    bf: f64,
) -> Result<Landed> {
    if !pts.len().is_multiple_of(3) {
        return Err(invalid(
            "points",
            format!("{} values", pts.len()),
            "a multiple of 3 (N x 3)",
        ));
    }
    if width == 0 || height == 0 || map.len() != width * height {
        return Err(invalid(
            "map",
            format!("{} values for {width} x {height}", map.len()),
            "a non-empty H x W map",
        ));
    }
    let n = pts.len() / 3;
    let mut out = Landed {
        disparity: vec![0.0; n],
        map: vec![0.0; n],
        both: vec![false; n],
    };
    out.disparity
        .par_chunks_mut(CHUNK)
        .zip(out.map.par_chunks_mut(CHUNK))
        .zip(out.both.par_chunks_mut(CHUNK))
        .zip(pts.par_chunks(3 * CHUNK))
        .for_each(|(((d, m), b), p)| {
            for (((d, m), b), p) in d.iter_mut().zip(m).zip(b).zip(p.chunks_exact(3)) {
                let z = p[2];
                let front = z.is_finite() && z > 0.0;
                // Behind the camera: projected from a harmless point, then dropped.
                let q = if front {
                    [p[0], p[1], p[2]]
                } else {
                    [0.0, 0.0, 1.0]
                };
                let [u, v] = cam.project(q).map(f64::round_ties_even);
                let inside = front && u >= 0.0 && u < width as f64 && v >= 0.0 && v < height as f64;
                let at = if inside {
                    v as usize * width + u as usize
                } else {
                    0
                };
                *m = f64::from(map[at]);
                *d = if front { bf / z } else { f64::NAN };
                *b = inside && m.is_finite() && d.is_finite();
            }
        });
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Distortion, Intrinsics};

    #[test]
    fn lands_on_the_nearest_pixel() {
        let k = Intrinsics::new(100.0, 100.0, 2.0, 1.0, 5, 3).unwrap();
        let cam = Camera::new(k, Distortion::default());
        let map: Vec<f32> = (0..15).map(|i| i as f32).collect();
        // (0, 0, 2) lands on (2, 1); x = 0.025 at z 2 is 1.25 px right: (3, 1);
        // behind the camera; far outside; a NaN coordinate.
        let pts = [
            0.0,
            0.0,
            2.0,
            0.025,
            0.0,
            2.0,
            0.0,
            0.0,
            -1.0,
            1.0,
            0.0,
            1.0,
            f64::NAN,
            0.0,
            1.0,
        ];
        let out = land_points(&cam, &pts, &map, 5, 3, 10.0).unwrap();
        assert_eq!(out.map[..2], [7.0, 8.0]);
        assert_eq!(out.disparity[..2], [5.0, 5.0]);
        assert_eq!(out.both, [true, true, false, false, false]);
        assert!(out.disparity[2].is_nan());
        assert!(land_points(&cam, &pts[..4], &map, 5, 3, 10.0).is_err());
        assert!(land_points(&cam, &pts, &map[..3], 5, 3, 10.0).is_err());
    }
}
