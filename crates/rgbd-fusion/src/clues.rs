//! The confidence ConvNet's input clues (thesis §3.6, eq. 3.2-3.6), elementwise: the warp
//! columns of the stereo map, the four raw clue maps and their normalisation. The Python side
//! (`rgbd_rs.fusion.clues`) computes the grey images, their means, the amplitude's median and
//! the warp itself (OpenCV's `remap`) and passes them in; every operation here is the f32
//! arithmetic numpy does on those arrays, so the maps are the same bits as numpy's.

use rayon::prelude::*;
use rgbd_error::image_len;
use rgbd_geom::error::{check_len, invalid, Result};

/// Values per parallel task.
const CHUNK: usize = 8192;

/// Where reference pixel `(x, y)` sees the target: column `x + sign d` of the stereo map `d`
/// (`H x W`), and -1 where that is NaN or outside `[0, W - 1]`; then the row index of every
/// pixel (the two maps of a row-preserving `remap`).
pub fn warp_maps(
    d: &[f32],
    width: usize,
    height: usize,
    sign: f32,
) -> Result<(Vec<f32>, Vec<f32>)> {
    let n = image_len("stereo_disparity", width, height)?;
    check_len("stereo_disparity", d, n, "H x W")?;
    let mut xs = vec![0f32; n];
    let mut ys = vec![0f32; n];
    xs.par_chunks_mut(width)
        .zip(ys.par_chunks_mut(width))
        .zip(d.par_chunks(width))
        .enumerate()
        .for_each(|(y, ((xr, yr), dr))| {
            for (x, ((o, r), &v)) in xr.iter_mut().zip(yr.iter_mut()).zip(dr).enumerate() {
                let at = x as f32 + sign * v;
                *o = if at.is_finite() && at >= 0.0 && at <= (width - 1) as f32 {
                    at
                } else {
                    -1.0
                };
                *r = y as f32;
            }
        });
    Ok((xs, ys))
}

/// What [`clue_maps`] reads besides the maps.
#[derive(Debug, Clone, Copy)]
pub struct ClueScales {
    /// Mean grey level of the reference and of the target (never 0).
    pub mu_reference: f32,
    pub mu_target: f32,
    /// The amplitude's per-frame median (1 without a usable amplitude).
    pub amplitude: f32,
}

/// The raw clues `4 x H x W` (delta_lr, ToF disparity, stereo disparity, amplitude; NaN where
/// undefined) from the grey reference `g_r`, the target warped onto it through `columns` (the
/// first map of [`warp_maps`]: -1 where the warp leaves the target), and the maps.
#[allow(clippy::too_many_arguments)]
pub fn clue_maps(
    g_r: &[f32],
    warped: &[f32],
    columns: &[f32],
    tof_disparity: &[f32],
    tof_amplitude: &[f32],
    stereo_disparity: &[f32],
    width: usize,
    height: usize,
    s: ClueScales,
) -> Result<Vec<f32>> {
    let n = image_len("reference_image", width, height)?;
    for (name, m) in [
        ("reference_image", g_r),
        ("warped", warped),
        ("columns", columns),
        ("tof_disparity", tof_disparity),
        ("tof_amplitude", tof_amplitude),
        ("stereo_disparity", stereo_disparity),
    ] {
        check_len(name, m, n, "H x W")?;
    }
    if !(s.mu_reference != 0.0 && s.mu_target != 0.0 && s.amplitude != 0.0) {
        return Err(invalid(
            "scales",
            format!("{s:?}"),
            "non-zero means and amplitude median",
        ));
    }
    let mut out = vec![0f32; 4 * n];
    let (delta, rest) = out.split_at_mut(n);
    let (d_t, rest) = rest.split_at_mut(n);
    let (d_s, amp) = rest.split_at_mut(n);
    d_t.copy_from_slice(tof_disparity);
    d_s.copy_from_slice(stereo_disparity);
    delta
        .par_chunks_mut(CHUNK)
        .zip(amp.par_chunks_mut(CHUNK))
        .enumerate()
        .for_each(|(c, (dl, am))| {
            let at = c * CHUNK;
            for (i, (o, a)) in dl.iter_mut().zip(am.iter_mut()).enumerate() {
                let p = at + i;
                *o = if columns[p] >= 0.0 {
                    (warped[p] / s.mu_target - g_r[p] / s.mu_reference).abs()
                } else {
                    f32::NAN
                };
                let v = tof_amplitude[p];
                *a = if v.is_finite() && v > 0.0 && tof_disparity[p].is_finite() {
                    v / s.amplitude
                } else {
                    f32::NAN
                };
            }
        });
    Ok(out)
}

/// `maps / sigmas` per clue (`K x H x W` maps, `K` sigmas), 0 where that is not finite.
pub fn normalise_clues(maps: &[f32], sigmas: &[f32]) -> Result<Vec<f32>> {
    let k = sigmas.len();
    if k == 0 || !maps.len().is_multiple_of(k) {
        return Err(invalid(
            "maps",
            format!("{} values for {k} sigmas", maps.len()),
            "K x H x W for K sigmas",
        ));
    }
    let n = maps.len() / k;
    let mut out = vec![0f32; maps.len()];
    for (c, &sig) in sigmas.iter().enumerate() {
        out[c * n..(c + 1) * n]
            .par_chunks_mut(CHUNK)
            .zip(maps[c * n..(c + 1) * n].par_chunks(CHUNK))
            .for_each(|(o, m)| {
                for (o, &v) in o.iter_mut().zip(m) {
                    let x = v / sig;
                    *o = if x.is_finite() { x } else { 0.0 };
                }
            });
    }
    Ok(out)
}
