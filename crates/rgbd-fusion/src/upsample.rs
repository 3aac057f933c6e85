//! Extended cross bilateral upsampling of sparse ToF depth onto the colour lattice (thesis §3.3
//! step 1, after Dal Mutto et al. [15]).
//!
//! For an output pixel p and the ToF samples q within `radius` (already reprojected onto the
//! colour lattice, NaN elsewhere):
//!
//! `w(p,q) = Gs(|p-q|) * ( Gc(ΔI(p,q))         if seg(p) == seg(q)`
//! `                     ( Gr(z(q) - z0(p))    otherwise )`
//!
//! Samples inside p's mean-shift segment are weighted by colour similarity; samples of other
//! segments only by depth agreement with a first estimate `z0(p)` (the same-segment colour-weighted
//! mean, or the all-sample one where p's segment holds no sample), so over-segmented surfaces
//! still share samples while real depth edges do not bleed. The paper's exact combination and
//! σ values were not available (METHOD_NOTES §4); this form and the defaults are our choice.

use rayon::prelude::*;
use rgbd_error::{check_interrupt, image_len};
use rgbd_geom::error::{check_len, Result};

mod lanes;

use crate::check::window_and_positive;
use crate::color::{gauss_table, sum_abs};

/// Parameters of [`upsample_depth`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UpsampleParams {
    /// Window half-size in output pixels.
    pub radius: usize,
    /// Spatial Gaussian σ in output pixels.
    pub sigma_s: f32,
    /// Colour Gaussian σ in mean-absolute 8-bit levels.
    pub sigma_c: f32,
    /// Depth-range Gaussian σ as a fraction of the first estimate's depth.
    pub sigma_r: f32,
}

impl Default for UpsampleParams {
    fn default() -> Self {
        Self {
            radius: 5,
            sigma_s: 3.0,
            sigma_c: 10.0,
            sigma_r: 0.02,
        }
    }
}

impl UpsampleParams {
    /// Checks every field (the binding calls this when a parameter object is built).
    pub fn validate(&self) -> Result<()> {
        window_and_positive(
            self.radius,
            &[
                ("sigma_s", self.sigma_s),
                ("sigma_c", self.sigma_c),
                ("sigma_r", self.sigma_r),
            ],
        )
    }
}

/// A ToF sample with what the filter reads of its pixel, stored contiguously per row, sorted by
/// x (16 bytes; the carried channel lives in a parallel array so the plain filter stays lean).
#[derive(Clone, Copy)]
struct Tap {
    x: u32,
    z: f32,
    color: [u8; 3],
    label: i32,
}

/// The first sample of `row` at `x >= lo`, searched from `*cursor` on (the window moves right
/// along the output row, so each row's cursor only advances); stored back in `cursor`.
#[inline(always)]
fn first_from(row: &[Tap], cursor: &mut usize, lo: u32) -> usize {
    while *cursor < row.len() && row[*cursor].x < lo {
        *cursor += 1;
    }
    *cursor
}

/// Per row: the samples, and the channel value each carries (empty rows without a channel).
type Rows = (Vec<Vec<Tap>>, Vec<Vec<f32>>);

fn sample_rows(
    sparse: &[f32],
    channel: Option<&[f32]>,
    image: &[u8],
    labels: Option<&[i32]>,
    width: usize,
) -> Rows {
    sparse
        .chunks(width)
        .enumerate()
        .map(|(y, row)| {
            let xs = row
                .iter()
                .enumerate()
                .filter(|(_, z)| z.is_finite() && **z > 0.0)
                .map(|(x, _)| y * width + x);
            let taps = xs
                .clone()
                .map(|q| Tap {
                    x: (q - y * width) as u32,
                    z: sparse[q],
                    color: [image[3 * q], image[3 * q + 1], image[3 * q + 2]],
                    label: labels.map_or(0, |l| l[q]),
                })
                .collect();
            let carried = channel.map_or_else(Vec::new, |c| xs.map(|q| c[q]).collect());
            (taps, carried)
        })
        .unzip()
}

/// Result of [`upsample_depth`].
#[derive(Debug, Clone, PartialEq)]
pub struct Upsampled {
    /// Dense depth, NaN where no sample lies within the radius.
    pub depth: Vec<f32>,
    /// The carried channel interpolated with the very weights the depth got (NaN where the
    /// depth is NaN or no weighted sample carried a value); empty when no channel was given.
    pub channel: Vec<f32>,
    /// The smallest mean absolute colour difference (0-255 levels) between each pixel and a
    /// sample within the radius, NaN where there is none: a large gap means the depth came from
    /// samples of other surfaces only (across an edge), which the image cannot confirm.
    pub color_gap: Vec<f32>,
}

/// Upsamples `sparse` (H x W depth, NaN/<=0 = no sample) guided by `image` (H x W x 3) and, when
/// given, `labels` (H x W segment ids). Pixels with no sample within `radius` stay NaN.
///
/// `channel` (H x W, e.g. the ToF amplitude on the same samples) is carried along: its output is
/// the same weighted mean as the depth's, so its unit and offset never enter the weights (the
/// range term compares depths only).
pub fn upsample_depth(
    sparse: &[f32],
    channel: Option<&[f32]>,
    image: &[u8],
    labels: Option<&[i32]>,
    width: usize,
    height: usize,
    params: &UpsampleParams,
) -> Result<Upsampled> {
    params.validate()?;
    let n = image_len("sparse", width, height)?;
    check_len("sparse", sparse, n, "H x W")?;
    check_len("image", image, n * 3, "H x W x 3 of the depth map's size")?;
    if let Some(l) = labels {
        check_len("labels", l, n, "H x W of the depth map's size")?;
    }
    if let Some(c) = channel {
        check_len("channel", c, n, "H x W of the depth map's size")?;
    }
    let (rows, rows_a) = sample_rows(sparse, channel, image, labels, width);
    let r = params.radius as i64;
    let side = 2 * params.radius + 1;
    let spatial: Vec<f32> = (0..side * side)
        .map(|i| {
            let (dy, dx) = ((i / side) as f32 - r as f32, (i % side) as f32 - r as f32);
            (-(dx * dx + dy * dy) / (2.0 * params.sigma_s * params.sigma_s)).exp()
        })
        .collect();
    let spatial_lanes = lanes::padded_spatial(&spatial, side);
    let gc = gauss_table(params.sigma_c);
    let inv_2r2 = 1.0 / (2.0 * params.sigma_r * params.sigma_r);
    let mut out = vec![f32::NAN; n];
    let mut gap = vec![f32::NAN; n];
    let mut carried = vec![f32::NAN; if channel.is_some() { n } else { 0 }];
    // Without a channel the carried rows are empty and zip stops nothing: chunk them by width
    // only when present.
    let mut carried_rows: Vec<&mut [f32]> = if channel.is_some() {
        carried.chunks_mut(width).collect()
    } else {
        (0..height).map(|_| &mut [][..]).collect()
    };
    let ctx = Ctx {
        rows: &rows,
        rows_a: &rows_a,
        image,
        labels,
        width,
        height,
        r,
        side,
        spatial: &spatial,
        spatial_lanes: &spatial_lanes,
        gc: &gc,
        inv_2r2,
    };
    out.par_chunks_mut(width)
        .zip(gap.par_chunks_mut(width))
        .zip(carried_rows.par_iter_mut())
        .enumerate()
        .try_for_each(|(y, ((out_row, gap_row), a_row))| {
            check_interrupt()?;
            // Monomorphised: without a channel the inner loop does no channel work at all.
            match (channel.is_some(), labels.is_some()) {
                (true, true) => ctx.row::<true>(y, out_row, gap_row, a_row),
                (false, true) => ctx.row::<false>(y, out_row, gap_row, a_row),
                (true, false) => ctx.row_lanes::<true>(y, out_row, gap_row, a_row),
                (false, false) => ctx.row_lanes::<false>(y, out_row, gap_row, a_row),
            }
            Ok(())
        })?;
    drop(carried_rows);
    Ok(Upsampled {
        depth: out,
        channel: carried,
        color_gap: gap,
    })
}

/// What every row of the filter reads.
struct Ctx<'a> {
    rows: &'a [Vec<Tap>],
    rows_a: &'a [Vec<f32>],
    image: &'a [u8],
    labels: Option<&'a [i32]>,
    width: usize,
    height: usize,
    r: i64,
    side: usize,
    spatial: &'a [f32],
    /// `spatial` padded for [`lanes`].
    spatial_lanes: &'a [f32],
    gc: &'a [f32],
    inv_2r2: f32,
}

impl Ctx<'_> {
    /// Filters output row `y` (and its carried channel when `CARRY`); `gap_row` gets each
    /// pixel's smallest colour difference to a sample ([`Upsampled::color_gap`]).
    fn row<const CARRY: bool>(
        &self,
        y: usize,
        out_row: &mut [f32],
        gap_row: &mut [f32],
        a_row: &mut [f32],
    ) {
        let (r, side, width) = (self.r, self.side, self.width);
        let y0 = (y as i64 - r).max(0) as usize;
        let y1 = (y as i64 + r).min(self.height as i64 - 1) as usize;
        let mut cursor = vec![0usize; y1 - y0 + 1];
        // Samples of other segments as (Gs, z, a): only they need a second look.
        let mut others: Vec<(f32, f32, f32)> = Vec::with_capacity(side * side);
        for (x, o) in out_row.iter_mut().enumerate() {
            let p = y * width + x;
            let cp = &self.image[3 * p..3 * p + 3];
            let lp = self.labels.map_or(0, |l| l[p]);
            others.clear();
            let mut same = Sums::<CARRY>::default();
            let mut all = Sums::<CARRY>::default();
            let mut closest = usize::MAX;
            let lo = (x as i64 - r).max(0) as u32;
            let hi = (x as i64 + r) as u32;
            for (k, yq) in (y0..=y1).enumerate() {
                let row = &self.rows[yq];
                let row_a = &self.rows_a[yq];
                let c = first_from(row, &mut cursor[k], lo);
                let srow = (yq as i64 - y as i64 + r) as usize * side;
                for (i, t) in row[c..].iter().enumerate().take_while(|(_, t)| t.x <= hi) {
                    let ws = self.spatial[srow + (t.x as i64 - x as i64 + r) as usize];
                    let a = if CARRY { row_a[c + i] } else { f32::NAN };
                    all.add(ws, t.z, a);
                    let dc = sum_abs(cp, &t.color);
                    closest = closest.min(dc);
                    // Without labels every tap carries label 0 like p: one segment.
                    if t.label == lp {
                        same.add(ws * self.gc[dc], t.z, a);
                    } else {
                        others.push((ws, t.z, a));
                    }
                }
            }
            let (z, a) = estimate(&same, &all, &others, self.inv_2r2);
            *o = z;
            if closest != usize::MAX {
                gap_row[x] = closest as f32 / 3.0;
            }
            if CARRY {
                a_row[x] = a;
            }
        }
    }
}

/// Total weight below which a sum counts as empty: products of weights this small are subnormal
/// in f32 and their ratio is noise (a lone sample at 0.3 m read as 0.4 m, found by the proptest
/// against the f64 reference).
const MIN_WEIGHT: f32 = 1e-30;

/// Running weighted sums of the depth and, when `CARRY`, of the carried channel (whose weight
/// sum counts only the samples that carry a value).
#[derive(Default, Clone, Copy)]
struct Sums<const CARRY: bool> {
    w: f32,
    wz: f32,
    wa_w: f32,
    wa: f32,
}

impl<const CARRY: bool> Sums<CARRY> {
    #[inline]
    fn add(&mut self, w: f32, z: f32, a: f32) {
        self.w += w;
        self.wz += w * z;
        if CARRY && a.is_finite() {
            self.wa_w += w;
            self.wa += w * a;
        }
    }

    fn mean(&self) -> Option<(f32, f32)> {
        let a = if self.wa_w > MIN_WEIGHT {
            self.wa / self.wa_w
        } else {
            f32::NAN
        };
        (self.w > MIN_WEIGHT).then(|| (self.wz / self.w, a))
    }
}

/// The two-pass estimate: `z0` from the same-segment samples (Gs Gc), or from all samples (Gs)
/// where p's segment holds none — colour across segments means little; then the same-segment
/// sums plus the other segments' samples weighted by depth agreement with `z0` (Gs Gr).
fn estimate<const CARRY: bool>(
    same: &Sums<CARRY>,
    all: &Sums<CARRY>,
    others: &[(f32, f32, f32)],
    inv_2r2: f32,
) -> (f32, f32) {
    let Some(first) = same.mean().or_else(|| all.mean()) else {
        return (f32::NAN, f32::NAN);
    };
    let z0 = first.0;
    let mut sums = *same;
    for &(ws, z, a) in others {
        let dz = (z - z0) / z0;
        sums.add(ws * (-dz * dz * inv_2r2).exp(), z, a);
    }
    sums.mean().unwrap_or(first)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2-level step: left half at 1 m (dark), right half at 2 m (bright), samples every 2 px.
    fn step(w: usize, h: usize) -> (Vec<f32>, Vec<u8>, Vec<i32>) {
        let mut sparse = vec![f32::NAN; w * h];
        let mut img = vec![0u8; w * h * 3];
        let mut lab = vec![0i32; w * h];
        for y in 0..h {
            for x in 0..w {
                let right = x >= w / 2;
                if x % 2 == 0 && y % 2 == 0 {
                    sparse[y * w + x] = if right { 2.0 } else { 1.0 };
                }
                img[3 * (y * w + x)..3 * (y * w + x) + 3].fill(if right { 220 } else { 30 });
                lab[y * w + x] = i32::from(right);
            }
        }
        (sparse, img, lab)
    }

    #[test]
    fn edges_stay_sharp_and_holes_fill() {
        let (w, h) = (20, 10);
        let (sparse, img, lab) = step(w, h);
        let p = UpsampleParams::default();
        for labels in [None, Some(&lab[..])] {
            let out = upsample_depth(&sparse, None, &img, labels, w, h, &p)
                .unwrap()
                .depth;
            for y in 0..h {
                for x in 0..w {
                    let want = if x >= w / 2 { 2.0 } else { 1.0 };
                    assert!(
                        (out[y * w + x] - want).abs() < 1e-3,
                        "{x},{y}: {}",
                        out[y * w + x]
                    );
                }
            }
        }
    }

    #[test]
    fn over_segmented_surface_shares_samples_by_depth() {
        // One flat surface at 1.5 m, painted in two colours and split into two segments; the only
        // samples lie in the left segment. The right half must still be filled at 1.5 m.
        let (w, h) = (12, 4);
        let (mut sparse, img, lab) = step(w, h);
        for (i, z) in sparse.iter_mut().enumerate() {
            *z = if i % w < w / 2 && z.is_finite() {
                1.5
            } else {
                f32::NAN
            };
        }
        let p = UpsampleParams::default();
        let out = upsample_depth(&sparse, None, &img, Some(&lab), w, h, &p)
            .unwrap()
            .depth;
        assert!((out[w - 1 - 4] - 1.5).abs() < 1e-4);
        assert!(out[w - 1].is_nan(), "more than radius from every sample");
    }

    #[test]
    fn color_gap_is_the_distance_to_the_closest_coloured_sample() {
        // Samples on the dark left half only: bright pixels within the radius of them got their
        // depth from another colour (gap 190 = 220 - 30), dark ones from their own (gap 0),
        // and pixels beyond the radius of every sample have none (NaN).
        let (w, h) = (20, 4);
        let (mut sparse, img, lab) = step(w, h);
        for (i, z) in sparse.iter_mut().enumerate() {
            if i % w >= w / 2 {
                *z = f32::NAN;
            }
        }
        let p = UpsampleParams::default();
        let out = upsample_depth(&sparse, None, &img, Some(&lab), w, h, &p).unwrap();
        let gap = |x: usize| out.color_gap[w + x];
        assert_eq!(gap(0), 0.0);
        assert_eq!(gap(w / 2 - 1), 0.0);
        assert_eq!(gap(w / 2), 190.0);
        assert_eq!(gap(w / 2 + 3), 190.0, "last sample at x = 8, radius 5");
        assert!(gap(w / 2 + 4).is_nan() && out.depth[w + w / 2 + 4].is_nan());
        assert!(
            (out.depth[w + w / 2] - 1.0).abs() < 1e-6,
            "the bled depth itself stays"
        );
    }

    #[test]
    fn carried_channel_gets_the_depth_weights() {
        // The channel is the depth plus an offset: a weighted mean with the depth's weights keeps
        // the offset exactly, whatever the range term did (a filter run on the channel itself
        // would weight by the channel's own relative differences instead).
        let (w, h) = (20, 10);
        let (sparse, img, lab) = step(w, h);
        let chan: Vec<f32> = sparse.iter().map(|z| z + 10.0).collect();
        let p = UpsampleParams::default();
        for labels in [None, Some(&lab[..])] {
            let out = upsample_depth(&sparse, Some(&chan), &img, labels, w, h, &p).unwrap();
            for (z, a) in out.depth.iter().zip(&out.channel) {
                assert!((a - z - 10.0).abs() < 1e-4, "{z} {a}");
            }
        }
        let none = upsample_depth(&sparse, None, &img, None, w, h, &p).unwrap();
        assert!(none.channel.is_empty());
    }

    #[test]
    fn rejects_bad_arguments() {
        let (sparse, img, _) = step(8, 4);
        let p = UpsampleParams::default();
        assert!(upsample_depth(&sparse, None, &img[3..], None, 8, 4, &p).is_err());
        assert!(upsample_depth(&sparse, None, &img, Some(&[0; 3]), 8, 4, &p).is_err());
        let bad = UpsampleParams { sigma_r: 0.0, ..p };
        assert!(upsample_depth(&sparse, None, &img, None, 8, 4, &bad).is_err());
        let bad = UpsampleParams { radius: 0, ..p };
        assert!(upsample_depth(&sparse, None, &img, None, 8, 4, &bad).is_err());
    }
}
