//! The per-pixel 9-D vectors of eq. 4.1 (Lab colour, 3-D position, normal).

use super::*;

/// Length of a pixel's feature vector (eq. 4.1): Lab colour, 3-D position, normal.
pub const FEATURE_DIM: usize = 9;

/// The eq. 4.1 vectors of an image (see [`features`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Features {
    /// `H x W x 9`: `[L, a, b] / σc`, `[x, y, z] / σg`, `[nx, ny, nz] / σn`; NaN where invalid.
    pub vectors: Vec<f32>,
    /// `H x W x 3` points (camera frame, the depth's units), NaN where the depth is invalid.
    pub points: Vec<f32>,
    /// `H x W`: depth valid and normal defined.
    pub valid: Vec<bool>,
    /// `(σc, σg, σn)`: each group's mean per-channel population standard deviation over the
    /// valid pixels.
    pub sigmas: [f64; 3],
}

/// Per-pixel 9-D vectors of eq. 4.1 from a Lab image (`H x W x 3`), a depth map and unit
/// normals (`H x W x 3`, NaN = undefined): each group of three divided by its average
/// standard deviation over the valid pixels (a group with none is left unscaled). Statistics
/// are accumulated in f64 per row and added in row order (two passes: means, then centred
/// squares), so the result does not depend on the thread count.
pub fn features(
    lab: &[f32],
    depth: &[f32],
    normals: &[f32],
    width: usize,
    height: usize,
    cam: &Pinhole,
) -> Result<Features> {
    cam.validate()?;
    check_depth("depth", depth, width, height)?;
    let n = width * height;
    let what = format!("{height} x {width} x 3");
    check_len("lab", lab, 3 * n, &what)?;
    check_len("normals", normals, 3 * n, &what)?;
    let rays = Rays::new(width, height, cam);
    const D: usize = FEATURE_DIM;
    // Pass 1: unnormalised vectors [lab, point, normal], points, validity.
    let mut vectors = vec![f32::NAN; D * n];
    let mut points = vec![f32::NAN; 3 * n];
    let mut valid = vec![false; n];
    // Pass 1 also sums each row's valid vectors (for the means).
    let row_totals: Vec<[f64; D]> = vectors
        .par_chunks_mut(D * width)
        .zip(points.par_chunks_mut(3 * width))
        .zip(valid.par_chunks_mut(width))
        .enumerate()
        .map(|(y, ((vrow, prow), ok))| {
            let mut s = [0.0f64; D];
            let b = rays.b[y];
            for x in 0..width {
                let i = y * width + x;
                let z = depth[i];
                if !is_valid(z) {
                    continue;
                }
                let zf = z as f64;
                let p = [(rays.a[x] * zf) as f32, (b * zf) as f32, z];
                prow[3 * x..3 * x + 3].copy_from_slice(&p);
                let nrm = &normals[3 * i..3 * i + 3];
                if nrm.iter().all(|v| v.is_finite()) {
                    ok[x] = true;
                    let v = &mut vrow[D * x..D * x + D];
                    v[0..3].copy_from_slice(&lab[3 * i..3 * i + 3]);
                    v[3..6].copy_from_slice(&p);
                    v[6..9].copy_from_slice(nrm);
                    for k in 0..D {
                        s[k] += f64::from(v[k]);
                    }
                }
            }
            s
        })
        .collect();
    let count = valid.iter().filter(|&&v| v).count();
    if count == 0 {
        return Err(invalid(
            "depth",
            "no pixel with both a valid depth and a surface normal",
            "at least one (a normal needs 3 non-collinear valid pixels in its window)",
        ));
    }
    // Per-row sums of f(v) over the valid pixels, added in row order.
    let row_sums = |f: &(dyn Fn(&[f32], &mut [f64; D]) + Sync)| -> [f64; D] {
        let rows: Vec<[f64; D]> = vectors
            .par_chunks(D * width)
            .zip(valid.par_chunks(width))
            .map(|(vrow, ok)| {
                let mut s = [0.0f64; D];
                for (v, _) in vrow.chunks_exact(D).zip(ok).filter(|(_, &ok)| ok) {
                    f(v, &mut s);
                }
                s
            })
            .collect();
        let mut s = [0.0f64; D];
        for r in &rows {
            for k in 0..D {
                s[k] += r[k];
            }
        }
        s
    };
    // Two passes (means, then centred squares) for the population standard deviations.
    let mut sums = [0.0f64; D];
    for r in &row_totals {
        for k in 0..D {
            sums[k] += r[k];
        }
    }
    let mean = sums.map(|s| s / count as f64);
    let sq = row_sums(&|v, s| {
        for k in 0..D {
            let d = f64::from(v[k]) - mean[k];
            s[k] += d * d;
        }
    });
    let std = sq.map(|s| (s / count as f64).sqrt());
    let sigmas = [0, 1, 2].map(|g| (std[3 * g] + std[3 * g + 1] + std[3 * g + 2]) / 3.0);
    let scale = sigmas.map(|s| if s > 0.0 { (1.0 / s) as f32 } else { 1.0 });
    vectors.par_chunks_mut(D * width).for_each(|row| {
        for v in row.chunks_exact_mut(D) {
            for k in 0..D {
                v[k] *= scale[k / 3];
            }
        }
    });
    Ok(Features {
        vectors,
        points,
        valid,
        sigmas,
    })
}
