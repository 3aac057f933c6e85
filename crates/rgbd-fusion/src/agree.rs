//! How far two disparity maps on the same camera agree: the pixels both measure (finite in
//! both) and how many of those lie within a tolerance of each other (`|a - b| <= tol` in f32,
//! as numpy compares an f32 map with a Python float). The fusion's input checks read this.

use rayon::prelude::*;
use rgbd_geom::error::{invalid, Result};

/// Values per parallel task.
const CHUNK: usize = 16384;

/// `(both, within)`: how many pixels are finite in both maps, and how many of those agree
/// within `tol`.
pub fn agreement(a: &[f32], b: &[f32], tol: f32) -> Result<(u64, u64)> {
    if a.len() != b.len() {
        return Err(invalid(
            "stereo_disparity",
            format!("{} values", b.len()),
            format!("{} (the ToF map's size)", a.len()),
        ));
    }
    Ok(a.par_chunks(CHUNK)
        .zip(b.par_chunks(CHUNK))
        .map(|(a, b)| {
            let (mut both, mut within) = (0u64, 0u64);
            for (&x, &y) in a.iter().zip(b) {
                let measured = x.is_finite() && y.is_finite();
                both += u64::from(measured);
                within += u64::from(measured && (x - y).abs() <= tol);
            }
            (both, within)
        })
        .reduce(|| (0, 0), |p, q| (p.0 + q.0, p.1 + q.1)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_the_pixels_both_measure() {
        let n = f32::NAN;
        let a = [1.0, 2.0, n, 4.0, 5.0, f32::INFINITY];
        let b = [1.5, 9.0, 3.0, n, 3.0, 1.0];
        assert_eq!(agreement(&a, &b, 2.0).unwrap(), (3, 2));
        assert!(agreement(&a, &b[1..], 2.0).is_err());
    }
}
