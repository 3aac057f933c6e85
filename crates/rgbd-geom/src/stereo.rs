//! Rectified stereo: depth <-> disparity, `z = b·f / d` (thesis eq. 2.15).

use rayon::prelude::*;

use crate::error::{invalid, Result};

/// Converts depth to disparity or disparity to depth (the map is its own inverse):
/// `out = baseline * focal / value`. Non-finite or non-positive inputs give NaN.
pub fn depth_disparity(values: &[f32], baseline: f64, focal: f64) -> Result<Vec<f32>> {
    if !(baseline.is_finite() && baseline > 0.0) {
        return Err(invalid(
            "baseline",
            baseline,
            "a finite baseline > 0 (metres)",
        ));
    }
    if !(focal.is_finite() && focal > 0.0) {
        return Err(invalid(
            "focal",
            focal,
            "a finite focal length > 0 (pixels)",
        ));
    }
    let bf = baseline * focal;
    Ok(values
        .par_iter()
        .with_min_len(4096)
        .map(|&v| {
            if v > 0.0 && v.is_finite() {
                (bf / f64::from(v)) as f32
            } else {
                f32::NAN
            }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eq_2_15_and_invalids() {
        let d = depth_disparity(&[2.0, 0.0, -1.0, f32::NAN, f32::INFINITY], 0.12, 1000.0).unwrap();
        assert!((d[0] - 60.0).abs() < 1e-5);
        assert!(d[1..].iter().all(|v| v.is_nan()));
        let z = depth_disparity(&d[..1], 0.12, 1000.0).unwrap();
        assert!((z[0] - 2.0).abs() < 1e-6);
        assert!(depth_disparity(&[1.0], 0.0, 1.0).is_err());
        assert!(depth_disparity(&[1.0], 1.0, -1.0).is_err());
    }
}
