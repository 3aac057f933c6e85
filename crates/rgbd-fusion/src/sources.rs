//! Where each fused pixel comes from, and the pixels LC cannot decide (the steps after LC in
//! `rgbd_rs.fusion.fuse`; their reasons and measurements are documented in
//! `python/rgbd_rs/fusion/sources.py`). Rows are independent and run in parallel; every
//! comparison is the f32 one numpy makes on the same maps, so the results are numpy's bits.

use rayon::prelude::*;
use rgbd_error::image_len;
use rgbd_geom::error::{check_len, Result};

/// `source` codes (as `rgbd_rs.fusion.sources.SOURCE_*`).
pub const SOURCE_NONE: u8 = 0;
pub const SOURCE_LC: u8 = 1;
pub const SOURCE_TOF: u8 = 2;
pub const SOURCE_STEREO: u8 = 3;
pub const SOURCE_TOF_CARRIED: u8 = 4;
pub const SOURCE_LC_UNMEASURED: u8 = 5;

/// The fused maps the steps edit in place, `H x W` each.
pub struct Fused<'a> {
    pub disparity: &'a mut [f32],
    pub plausibility: &'a mut [f32],
    pub source: &'a mut [u8],
    pub width: usize,
    pub height: usize,
}

impl Fused<'_> {
    fn check(&self, maps: &[(&'static str, Option<&[f32]>)]) -> Result<()> {
        let n = image_len("disparity", self.width, self.height)?;
        check_len("plausibility", self.plausibility, n, "H x W")?;
        check_len("source", self.source, n, "H x W")?;
        check_len("disparity", self.disparity, n, "H x W")?;
        for (name, m) in maps {
            if let Some(m) = m {
                check_len(name, m, n, "H x W of the fused map's size")?;
            }
        }
        Ok(())
    }

    /// The rows of the three maps, in parallel.
    fn rows(&mut self) -> impl IndexedParallelIterator<Item = (usize, Row<'_>)> {
        let w = self.width;
        self.disparity
            .par_chunks_mut(w)
            .zip(self.plausibility.par_chunks_mut(w))
            .zip(self.source.par_chunks_mut(w))
            .enumerate()
    }
}

/// One row of the fused maps: `((disparity, plausibility), source)`.
type Row<'r> = ((&'r mut [f32], &'r mut [f32]), &'r mut [u8]);

/// The confidence of pixel `i` (1 without a confidence map).
#[inline]
fn conf_at(c: Option<&[f32]>, i: usize) -> f32 {
    c.map_or(1.0, |c| c[i])
}

/// `_fill_single_source`: `fused` holds LC's maps on entry (its `source` is written whole).
pub fn fill_single_source(
    fused: &mut Fused<'_>,
    tof: &[f32],
    stereo: &[f32],
    tof_confidence: Option<&[f32]>,
    stereo_confidence: Option<&[f32]>,
    keep_out_zero: bool,
    cross_check: bool,
) -> Result<()> {
    fused.check(&[
        ("tof", Some(tof)),
        ("stereo", Some(stereo)),
        ("tof_confidence", tof_confidence),
        ("stereo_confidence", stereo_confidence),
    ])?;
    let w = fused.width;
    fused.rows().for_each(|(y, ((d, p), s))| {
        for x in 0..w {
            let i = y * w + x;
            let measured = d[x].is_finite();
            s[x] = if !measured {
                SOURCE_NONE
            } else if !tof[i].is_finite() && !stereo[i].is_finite() {
                SOURCE_LC_UNMEASURED
            } else {
                SOURCE_LC
            };
            if cross_check || measured {
                continue;
            }
            for (value, conf, code) in [
                (tof, tof_confidence, SOURCE_TOF),
                (stereo, stereo_confidence, SOURCE_STEREO),
            ] {
                let ruled_out = keep_out_zero && conf.is_some_and(|c| !(c[i] > 0.0));
                if value[i].is_finite() && !ruled_out {
                    (d[x], p[x], s[x]) = (value[i], conf_at(conf, i), code);
                    break;
                }
            }
        }
    });
    Ok(())
}

/// `_unseen_from_tof`: pixels whose ToF target lies outside the other image and that the
/// stereo map has no value for take the ToF's value (`sign`: +1 right reference, -1 left).
pub fn unseen_from_tof(
    fused: &mut Fused<'_>,
    tof: &[f32],
    stereo: &[f32],
    tof_confidence: Option<&[f32]>,
    sign: f32,
) -> Result<()> {
    fused.check(&[
        ("tof", Some(tof)),
        ("stereo", Some(stereo)),
        ("tof_confidence", tof_confidence),
    ])?;
    let w = fused.width;
    let last = (w - 1) as f32;
    fused.rows().for_each(|(y, ((d, p), s))| {
        for x in 0..w {
            let i = y * w + x;
            let target = x as f32 + sign * tof[i];
            let unseen = tof[i].is_finite()
                && (target < 0.0 || target > last)
                && !stereo[i].is_finite()
                && tof_confidence.is_none_or(|c| c[i] > 0.0);
            if unseen {
                (d[x], p[x], s[x]) = (tof[i], conf_at(tof_confidence, i), SOURCE_TOF);
            }
        }
    });
    Ok(())
}

/// Column `x` of the frame where the border the other camera cannot see is column 0.
#[inline]
fn col(flip: bool, w: usize, x: usize) -> usize {
    if flip {
        w - 1 - x
    } else {
        x
    }
}

/// `_extend_tof_into_band`: the band's pixels continuing a surface the fusion confirmed take
/// the ToF's value (see the Python docstring). `chain_step`: the largest step between
/// neighbouring ToF disparities of the chain; `confirm_gap`: the largest gap between the ToF
/// and the fused map that confirms its start (px).
pub fn extend_tof_into_band(
    fused: &mut Fused<'_>,
    tof: &[f32],
    tof_confidence: Option<&[f32]>,
    sign: f32,
    (chain_step, confirm_gap): (f32, f32),
) -> Result<()> {
    fused.check(&[("tof", Some(tof)), ("tof_confidence", tof_confidence)])?;
    let (w, flip) = (fused.width, sign > 0.0);
    fused.rows().for_each(|(y, ((d, p), s))| {
        let row = y * w;
        // In the flipped frame: t(x), the fused map f(x), the confidence c(x).
        let t = |x: usize| tof[row + col(flip, w, x)];
        let c = |x: usize| tof_confidence.map(|c| c[row + col(flip, w, x)]);
        let Some(x_e) = (0..w).find(|&x| t(x).is_finite() && t(x) <= x as f32) else {
            return;
        };
        // The fused map's first value within the edge pixel's disparity of it.
        let reach = t(x_e).ceil() as i64 + 1;
        let end = (x_e as i64).saturating_add(reach).clamp(0, w as i64) as usize;
        let Some(first) = (x_e..end).find(|&x| d[col(flip, w, x)].is_finite()) else {
            return;
        };
        if !((t(first) - d[col(flip, w, first)]).abs() <= confirm_gap) {
            return;
        }
        // The chain runs from after the last break below the edge up to it.
        let continues =
            |x: usize| (t(x) - t(x + 1)).abs() <= chain_step && c(x).is_none_or(|c| c > 0.0);
        let start = (0..x_e.min(w - 1))
            .rev()
            .find(|&x| !continues(x))
            .map_or(0, |b| b + 1);
        for x in start..x_e {
            let xo = col(flip, w, x);
            let i = row + xo;
            (d[xo], p[xo], s[xo]) = (tof[i], conf_at(tof_confidence, i), SOURCE_TOF);
        }
    });
    Ok(())
}

/// `_carry_tof_to_border`: the strip before each row's first ToF pixel, where that pixel's
/// disparity puts the target outside the other image, takes the first trusted ToF value.
pub fn carry_tof_to_border(
    fused: &mut Fused<'_>,
    tof: &[f32],
    tof_confidence: Option<&[f32]>,
    sign: f32,
) -> Result<()> {
    fused.check(&[("tof", Some(tof)), ("tof_confidence", tof_confidence)])?;
    let (w, flip) = (fused.width, sign > 0.0);
    fused.rows().for_each(|(y, ((d, p), s))| {
        let row = y * w;
        let t = |x: usize| tof[row + col(flip, w, x)];
        let Some(first) = (0..w).find(|&x| t(x).is_finite()) else {
            return;
        };
        let trusted = |x: usize| {
            t(x).is_finite() && tof_confidence.is_none_or(|c| c[row + col(flip, w, x)] > 0.0)
        };
        let Some(x0) = (first..w).find(|&x| trusted(x)) else {
            return;
        };
        let (d0, c0) = (t(x0), conf_at(tof_confidence, row + col(flip, w, x0)));
        if !(c0 > 0.0) {
            return;
        }
        for x in (0..first).take_while(|&x| f64::from(x as u32) < f64::from(d0)) {
            let xo = col(flip, w, x);
            (d[xo], p[xo], s[xo]) = (d0, c0, SOURCE_TOF_CARRIED);
        }
    });
    Ok(())
}

/// `_bridge_band_across_dropouts`: in each column, between two consecutive pixels that took
/// the ToF (`SOURCE_TOF`), both unseen by the other camera and stepping by at most
/// `chain_step` a row, the pixels where the ToF has no value and LC's answer (or nothing)
/// stands take the value interpolated between the two, where it keeps their target outside the
/// other image, with the smaller of the two plausibilities (`SOURCE_TOF_CARRIED`). Columns are
/// independent; the few that hold such pairs are read serially (the band is narrow).
pub fn bridge_band_across_dropouts(
    fused: &mut Fused<'_>,
    tof: &[f32],
    sign: f32,
    chain_step: f64,
) -> Result<()> {
    fused.check(&[("tof", Some(tof))])?;
    let (w, h) = (fused.width, fused.height);
    if w == 0 {
        return Ok(());
    }
    let last = (w - 1) as f32;
    // numpy's f32 target x + sign * d: NaN compares false, so a NaN value is never unseen
    let unseen = |x: usize, d: f32| {
        let t = x as f32 + sign * d;
        t < 0.0 || t > last
    };
    let open = |s: u8| matches!(s, SOURCE_LC | SOURCE_LC_UNMEASURED | SOURCE_NONE);
    for x in 0..w {
        let mut prev: Option<usize> = None;
        for y in 0..h {
            if fused.source[y * w + x] != SOURCE_TOF {
                continue;
            }
            if let Some(a) = prev.replace(y) {
                let (ia, ib) = (a * w + x, y * w + x);
                let (da, db) = (fused.disparity[ia], fused.disparity[ib]);
                let span = y - a;
                let limit = (chain_step * span as f64) as f32;
                if span < 2 || !(unseen(x, da) && unseen(x, db)) || !((db - da).abs() <= limit) {
                    continue;
                }
                let (pa, pb) = (fused.plausibility[ia], fused.plausibility[ib]);
                let p = if pb < pa { pb } else { pa }; // Python's min(pa, pb)
                let step = f64::from(db - da);
                for yy in a + 1..y {
                    let i = yy * w + x;
                    let frac = (yy - a) as f64 / span as f64;
                    let v = (f64::from(da) + step * frac) as f32;
                    if tof[i].is_finite() || !open(fused.source[i]) || !unseen(x, v) {
                        continue;
                    }
                    fused.disparity[i] = v;
                    fused.plausibility[i] = p;
                    fused.source[i] = SOURCE_TOF_CARRIED;
                }
            }
        }
    }
    Ok(())
}
