//! Per-pixel maps of fitted surfaces: the surface point, the fitting error (3-D distance between
//! the measured point and the surface at the same (u, v), thesis §4.5) and the curvatures.
//!
//! Evaluation is separable: for each image row the control grid is first contracted with the
//! row's v-basis (and its derivatives), once per surface met in that row; each pixel then needs
//! only `p + 1` terms per output instead of `(p + 1)²`. The pixels of a row are evaluated as
//! columns (structure of arrays: one array per derivative and channel), so the sums over the
//! basis and the curvature formulas vectorise over consecutive pixels (AVX2 where the CPU has
//! it); the results are the per-pixel [`GridSurface::jet`](crate::GridSurface) contraction
//! followed by [`curvature`](crate::curvature()), to rounding (the AVX2 build fuses the basis
//! sums' multiply-adds; the portable build gives the same bits as the per-pixel path).

use rayon::prelude::*;

use crate::basis::Basis;
use crate::curvature::curvature_columns;
use crate::fit::Fit;
use crate::grid::KnotGrid;
use crate::normal::Region;
use crate::surface::MAX_CHANNELS;
use rgbd_error::{invalid, RgbdError};

/// Per-pixel outputs (float32, as every image the library returns), NaN where a pixel has no
/// surface (or no finite measurement, for `error`).
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceMaps {
    /// `height x width x channels`.
    pub fitted: Vec<f32>,
    /// Distance between the measured and the fitted point.
    pub error: Vec<f32>,
    /// Principal curvatures `k1 >= k2`, mean and Gaussian curvature (3-channel surfaces only).
    pub k1: Vec<f32>,
    pub k2: Vec<f32>,
    pub mean: Vec<f32>,
    pub gaussian: Vec<f32>,
}

impl SurfaceMaps {
    /// Maps of `pixels` pixels, all NaN.
    fn nan(pixels: usize, channels: usize) -> Self {
        let nan = || vec![f32::NAN; pixels];
        Self {
            fitted: vec![f32::NAN; pixels * channels],
            error: nan(),
            k1: nan(),
            k2: nan(),
            mean: nan(),
            gaussian: nan(),
        }
    }
}

/// A surface's control grid contracted with one row's v-basis: per local control column, value,
/// ∂v and ∂²v of each channel.
struct RowContraction<'a> {
    fit: &'a Fit,
    cols: Vec<[[f64; MAX_CHANNELS]; 3]>,
}

impl<'a> RowContraction<'a> {
    /// `None` when row `cv` is outside the surface's control rectangle.
    fn new(fit: &'a Fit, cv: usize, bv: &Basis) -> Option<Self> {
        let s = &fit.surface;
        let p = s.grid.degree;
        let cv = s.local_v(cv)?;
        let c = s.channels;
        let inv = 1.0 / s.grid.spacing;
        let mut cols = vec![[[0.0; MAX_CHANNELS]; 3]; s.shape.0];
        for (i, out) in cols.iter_mut().enumerate() {
            for j in 0..=p {
                let q = &s.ctrl[((cv + j) * s.shape.0 + i) * c..][..c];
                let w = [bv.value[j], bv.d1[j] * inv, bv.d2[j] * inv * inv];
                for (d, o) in out.iter_mut().enumerate() {
                    for ch in 0..c {
                        o[ch] += w[d] * q[ch];
                    }
                }
            }
        }
        Some(Self { fit, cols })
    }
}

/// Pixels evaluated together (one AVX2 vector of f64).
const LANES: usize = 4;

/// The u-basis of the columns `u0..u1` of a region, as columns: the cell of each pixel column and
/// `b[d][k]` (value, ∂u, ∂²u per pixel of basis function `k`) over the columns, zero-padded by
/// [`LANES`] so that a group of four pixels starting at any column can be read.
struct ColumnBasis {
    u0: usize,
    cell: Vec<usize>,
    /// `(3 · (p + 1)) x stride`: row `d · (p + 1) + k`.
    b: Vec<f64>,
    k1: usize,
    /// Columns plus padding.
    stride: usize,
}

impl ColumnBasis {
    fn new(grid: &KnotGrid, u0: usize, u1: usize) -> Self {
        let (k1, stride) = (grid.degree + 1, u1 - u0 + LANES);
        let inv = 1.0 / grid.spacing;
        let mut b = vec![0.0; 3 * k1 * stride];
        let mut cell = Vec::with_capacity(u1 - u0);
        for (i, u) in (u0..u1).enumerate() {
            let (cu, _, bu, _) = grid.support(u as f64, 0.0);
            cell.push(cu);
            for k in 0..k1 {
                b[k * stride + i] = bu.value[k];
                b[(k1 + k) * stride + i] = bu.d1[k] * inv;
                b[(2 * k1 + k) * stride + i] = bu.d2[k] * inv * inv;
            }
        }
        Self {
            u0,
            cell,
            b,
            k1,
            stride,
        }
    }

    /// Basis row `d` (0 value, 1 ∂u, 2 ∂²u) of function `k` at columns `u0 + i ..+ LANES`.
    #[inline(always)]
    fn lanes(&self, d: usize, k: usize, i: usize) -> &[f64; LANES] {
        let at = (d * self.k1 + k) * self.stride + i;
        self.b[at..at + LANES]
            .try_into()
            .unwrap_or_else(|_| unreachable!("LANES long"))
    }
}

/// One output row: fitted (`width x channels`), error, k1, k2, mean, gaussian.
type OutRow<'r> = (
    &'r mut [f32],
    &'r mut [f32],
    &'r mut [f32],
    &'r mut [f32],
    &'r mut [f32],
    &'r mut [f32],
);

/// Where the measured points are: pixel `(u, v)` of the image is value
/// `((v - origin.1) · stride + u - origin.0) · channels`.
#[derive(Clone, Copy)]
struct Source<'v, T> {
    values: &'v [T],
    stride: usize,
    origin: (usize, usize),
}

/// `a · b + c`, fused (one rounding) when `FMA` (the AVX2 + FMA build), else two roundings
/// (the portable build, where a fused multiply-add would be a slow library call).
#[inline(always)]
fn madd<const FMA: bool>(a: f64, b: f64, c: f64) -> f64 {
    if FMA {
        a.mul_add(b, c)
    } else {
        c + a * b
    }
}

/// Evaluates one row `v` of `region` into `out` (whose pixel 0 is column `frame_u0`), `C`
/// channels; `jets` is scratch of at least `6 · C · cols.stride` floats.
#[inline(always)]
#[allow(clippy::too_many_arguments, clippy::needless_range_loop)]
fn eval_row<'a, T: Copy + Into<f64>, const C: usize, const FMA: bool>(
    src: Source<'_, T>,
    v: usize,
    (cv, bv): (usize, &Basis),
    region: Region,
    frame_u0: usize,
    cols: &ColumnBasis,
    fit_of: &(impl Fn(usize, usize) -> Option<&'a Fit> + Sync),
    out: OutRow<'_>,
    jets: &mut [f64],
) {
    let (fitted, error, k1, k2, mean, gauss) = out;
    // The outputs are not pre-filled: every pixel of the row gets a value or NaN here.
    let (ra, rb) = (region.u0 - frame_u0, region.u1 - frame_u0);
    fitted[..ra * C].fill(f32::NAN);
    fitted[rb * C..].fill(f32::NAN);
    for o in [&mut *error, &mut *k1, &mut *k2, &mut *mean, &mut *gauss] {
        o[..ra].fill(f32::NAN);
        o[rb..].fill(f32::NAN);
    }
    macro_rules! skip {
        ($u:expr) => {{
            let o = $u - frame_u0;
            fitted[o * C..(o + 1) * C].fill(f32::NAN);
            for out in [&mut *error, &mut *k1, &mut *k2, &mut *mean, &mut *gauss] {
                out[o] = f32::NAN;
            }
        }};
    }
    let mut cache: Option<RowContraction> = None;
    let mut u = region.u0;
    while u < region.u1 {
        let Some(fit) = fit_of(u, v) else {
            skip!(u);
            u += 1;
            continue;
        };
        if !cache.as_ref().is_some_and(|c| std::ptr::eq(c.fit, fit)) {
            cache = RowContraction::new(fit, cv, bv);
        }
        let Some(rc) = cache.as_ref() else {
            skip!(u);
            u += 1;
            continue;
        };
        let surf = &fit.surface;
        let covered = |x: usize| surf.local_u(cols.cell[x - cols.u0]).is_some();
        let mut end = u;
        while end < region.u1
            && covered(end)
            && (end == u || fit_of(end, v).is_some_and(|f| std::ptr::eq(f, fit)))
        {
            end += 1;
        }
        if end == u {
            skip!(u);
            u += 1;
            continue;
        }
        // Jets of pixels u..end as columns: jets[(d · C + ch) · stride + x - u0].
        let p = surf.grid.degree;
        let k1n = p + 1;
        let stride = cols.stride;
        let col = |d: usize, ch: usize| (d * C + ch) * stride;
        // Cell by cell (the contraction columns are the same for all pixels of a cell), four
        // pixels at a time in registers; the last group of a cell may run past its end into
        // the padding or the next cell, whose own groups then overwrite those pixels.
        let mut a = u;
        while a < end {
            let cu = cols.cell[a - cols.u0];
            let mut b = a + 1;
            while b < end && cols.cell[b - cols.u0] == cu {
                b += 1;
            }
            let lc = surf.local_u(cu).unwrap_or_else(|| unreachable!("covered"));
            let rows = &rc.cols[lc..lc + k1n];
            // All channels of a group of pixels together: the basis lanes are loaded once.
            let mut i = a - cols.u0;
            while i < b - cols.u0 {
                // Derivative order: value, du, dv, duu, duv, dvv.
                let mut acc = [[[0.0f64; LANES]; 6]; C];
                for (k, [r0, r1, r2]) in rows.iter().enumerate() {
                    let (b0, b1, b2) = (
                        cols.lanes(0, k, i),
                        cols.lanes(1, k, i),
                        cols.lanes(2, k, i),
                    );
                    for (ch, acc) in acc.iter_mut().enumerate() {
                        let (x0, x1, x2) = (r0[ch], r1[ch], r2[ch]);
                        for l in 0..LANES {
                            acc[0][l] = madd::<FMA>(b0[l], x0, acc[0][l]);
                            acc[1][l] = madd::<FMA>(b1[l], x0, acc[1][l]);
                            acc[2][l] = madd::<FMA>(b0[l], x1, acc[2][l]);
                            acc[3][l] = madd::<FMA>(b2[l], x0, acc[3][l]);
                            acc[4][l] = madd::<FMA>(b1[l], x1, acc[4][l]);
                            acc[5][l] = madd::<FMA>(b0[l], x2, acc[5][l]);
                        }
                    }
                }
                for (ch, acc) in acc.iter().enumerate() {
                    for (d, x) in acc.iter().enumerate() {
                        jets[col(d, ch) + i..][..LANES].copy_from_slice(x);
                    }
                }
                i += LANES;
            }
            a = b;
        }
        let (ja, jb) = (u - cols.u0, end - cols.u0);
        let (oa, ob) = (u - frame_u0, end - frame_u0);
        let meas_row = (v - src.origin.1) * src.stride;
        for (x, o) in (ja..jb).zip(oa..ob) {
            let px = meas_row + (x + cols.u0) - src.origin.0;
            let meas = &src.values[px * C..][..C];
            let mut d2 = 0.0;
            for ch in 0..C {
                let f = jets[col(0, ch) + x];
                fitted[o * C + ch] = f as f32;
                let m: f64 = meas[ch].into();
                d2 += (m - f) * (m - f);
            }
            error[o] = d2.sqrt() as f32;
        }
        if C == 3 {
            let j = |d: usize, ch: usize| &jets[col(d, ch) + ja..col(d, ch) + jb];
            let jet: [[&[f64]; 3]; 6] = std::array::from_fn(|d| [j(d, 0), j(d, 1), j(d, 2)]);
            curvature_columns(
                jet,
                [
                    &mut k1[oa..ob],
                    &mut k2[oa..ob],
                    &mut mean[oa..ob],
                    &mut gauss[oa..ob],
                ],
            );
        } else {
            for o in [&mut *k1, &mut *k2, &mut *mean, &mut *gauss] {
                o[oa..ob].fill(f32::NAN);
            }
        }
        u = end;
    }
}

/// [`eval_row`] compiled for AVX2 + FMA, the basis sums as fused multiply-adds (the results
/// differ from the portable build's by rounding only).
///
/// # Safety
/// The CPU must support AVX2 and FMA.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[allow(clippy::too_many_arguments)]
unsafe fn eval_row_avx2<'a, T: Copy + Into<f64>, const C: usize>(
    src: Source<'_, T>,
    v: usize,
    row: (usize, &Basis),
    region: Region,
    frame_u0: usize,
    cols: &ColumnBasis,
    fit_of: &(impl Fn(usize, usize) -> Option<&'a Fit> + Sync),
    out: OutRow<'_>,
    jets: &mut [f64],
) {
    eval_row::<T, C, true>(src, v, row, region, frame_u0, cols, fit_of, out, jets)
}

/// Maps over `frame` (output `frame` sized, NaN outside `region`), evaluating `fit_of(u, v)` at
/// every pixel of `region ⊆ frame`. All fits must share one knot grid.
fn maps_in<'a, T: Copy + Into<f64> + Sync, const C: usize>(
    src: Source<'_, T>,
    region: Region,
    frame: Region,
    fit_of: impl Fn(usize, usize) -> Option<&'a Fit> + Sync,
) -> SurfaceMaps {
    let fw = frame.u1 - frame.u0;
    let pixels = fw * (frame.v1 - frame.v0);
    let grid = (region.v0..region.v1)
        .flat_map(|v| (region.u0..region.u1).map(move |u| (u, v)))
        .find_map(|(u, v)| fit_of(u, v))
        .map(|f| f.surface.grid);
    let Some(grid) = grid else {
        return SurfaceMaps::nan(pixels, C);
    };
    // Zeroed (fresh pages from the allocator, no pass over them here): every pixel is written
    // once below, in parallel, with its value or NaN.
    let zeros = |n: usize| vec![0.0f32; n];
    let mut out = SurfaceMaps {
        fitted: zeros(pixels * C),
        error: zeros(pixels),
        k1: zeros(pixels),
        k2: zeros(pixels),
        mean: zeros(pixels),
        gaussian: zeros(pixels),
    };
    let cols = ColumnBasis::new(&grid, region.u0, region.u1);
    let fast = avx2_fma();
    let SurfaceMaps {
        fitted,
        error,
        k1,
        k2,
        mean,
        gaussian,
    } = &mut out;
    fitted
        .par_chunks_mut(fw * C)
        .zip(error.par_chunks_mut(fw))
        .zip(k1.par_chunks_mut(fw))
        .zip(k2.par_chunks_mut(fw))
        .zip(mean.par_chunks_mut(fw))
        .zip(gaussian.par_chunks_mut(fw))
        .enumerate()
        // Each job allocates its own scratch: rows in blocks, not one job per row.
        .with_min_len(8)
        .for_each_init(
            || vec![0.0; 6 * C * cols.stride],
            |jets, (r, (((((f, e), a), b), m), g))| {
                let v = frame.v0 + r;
                if !(region.v0..region.v1).contains(&v) {
                    for o in [f, e, a, b, m, g] {
                        o.fill(f32::NAN);
                    }
                    return;
                }
                let (_, cv, _, bv) = grid.support(0.0, v as f64);
                let row = (cv, &bv);
                let out = (f, e, a, b, m, g);
                #[cfg(target_arch = "x86_64")]
                if fast {
                    // SAFETY: the CPU supports AVX2 and FMA (checked by `avx2_fma`).
                    unsafe {
                        eval_row_avx2::<T, C>(
                            src, v, row, region, frame.u0, &cols, &fit_of, out, jets,
                        )
                    };
                    return;
                }
                let _ = fast;
                eval_row::<T, C, false>(src, v, row, region, frame.u0, &cols, &fit_of, out, jets);
            },
        );
    out
}

/// Whether the AVX2 + FMA build of the row kernel can run here.
#[inline]
fn avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// [`maps_in`] for a run-time channel count (1 ..= [`MAX_CHANNELS`]).
fn maps_dyn<'a, T: Copy + Into<f64> + Sync>(
    src: Source<'_, T>,
    channels: usize,
    region: Region,
    frame: Region,
    fit_of: impl Fn(usize, usize) -> Option<&'a Fit> + Sync,
) -> SurfaceMaps {
    match channels {
        1 => maps_in::<T, 1>(src, region, frame, fit_of),
        2 => maps_in::<T, 2>(src, region, frame, fit_of),
        3 => maps_in::<T, 3>(src, region, frame, fit_of),
        _ => maps_in::<T, 4>(src, region, frame, fit_of),
    }
}

/// Evaluates, for every pixel of `region` (`None`: the whole image), the fit
/// `fit_of(pixel index)` at that pixel; the maps are image-sized (NaN outside `region`). All
/// fits must share one knot grid (they come from one image). `channels` must be in
/// `1..=`[`MAX_CHANNELS`] (as every fit's).
pub fn surface_maps<'a, T: Copy + Into<f64> + Sync>(
    values: &[T],
    width: usize,
    height: usize,
    channels: usize,
    region: Option<Region>,
    fit_of: impl Fn(usize) -> Option<&'a Fit> + Sync,
) -> SurfaceMaps {
    let full = Region::full(width, height);
    let src = Source {
        values,
        stride: width,
        origin: (0, 0),
    };
    let region = region.unwrap_or(full);
    maps_dyn(src, channels, region, full, |u, v| fit_of(v * width + u))
}

/// The maps of one fit over the pixel box `frame` of a `width x height` image, sized to the box
/// (`frame` rows x columns, row-major): `values` are the box's measured points
/// (`rows x columns x channels`) and `mask` (box-sized, `None`: every pixel) the pixels the fit
/// belongs to; the others, and the pixels outside the fit's cells, are NaN. Costs only the box,
/// whatever the image size.
pub fn surface_maps_box<T: Copy + Into<f64> + Sync>(
    values: &[T],
    mask: Option<&[bool]>,
    frame: Region,
    width: usize,
    height: usize,
    fit: &Fit,
) -> Result<SurfaceMaps, RgbdError> {
    let c = fit.surface.channels;
    if frame.u0 >= frame.u1 || frame.v0 >= frame.v1 || frame.u1 > width || frame.v1 > height {
        return Err(invalid(
            "frame",
            format!("{frame:?}"),
            format!("a non-empty pixel box inside the {width}x{height} image"),
        ));
    }
    let (fw, fh) = (frame.u1 - frame.u0, frame.v1 - frame.v0);
    if values.len() != fw * fh * c {
        return Err(invalid(
            "values",
            format!("{} values", values.len()),
            format!("rows * columns * channels = {}", fw * fh * c),
        ));
    }
    if let Some(m) = mask {
        if m.len() != fw * fh {
            return Err(invalid(
                "mask",
                format!("{} values", m.len()),
                format!("rows * columns = {}", fw * fh),
            ));
        }
    }
    crate::grid::check_grid(&fit.surface.grid, width, height)?;
    let cells = fit.surface.pixel_region(width, height);
    let region = Region {
        u0: frame.u0.max(cells.u0),
        u1: frame.u1.min(cells.u1),
        v0: frame.v0.max(cells.v0),
        v1: frame.v1.min(cells.v1),
    };
    if region.u0 >= region.u1 || region.v0 >= region.v1 {
        return Ok(SurfaceMaps::nan(fw * fh, c));
    }
    let src = Source {
        values,
        stride: fw,
        origin: (frame.u0, frame.v0),
    };
    Ok(maps_dyn(src, c, region, frame, |u, v| {
        mask.is_none_or(|m| m[(v - frame.v0) * fw + u - frame.u0])
            .then_some(fit)
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::curvature::curvature;
    use crate::grid::{fit_grid, fit_mask, KnotGrid};

    #[test]
    fn separable_evaluation_equals_the_direct_jet() {
        let (w, h) = (37, 29);
        let vals: Vec<f64> = (0..w * h * 3)
            .map(|i| ((i * 7919) % 101) as f64 / 101.0)
            .collect();
        for p in 1..=5 {
            let grid = KnotGrid::new(w, h, 5.5, p).unwrap();
            let fit = fit_grid(&vals, w, h, 3, &grid, 1e-3, false).unwrap();
            let maps = surface_maps(&vals, w, h, 3, None, |_| Some(&fit));
            for px in 0..w * h {
                let j = fit.surface.jet((px % w) as f64, (px / w) as f64).unwrap();
                for c in 0..3 {
                    let got = maps.fitted[px * 3 + c] as f64;
                    assert!(
                        (got - j.value[c]).abs() <= 1e-6 * (1.0 + j.value[c].abs()),
                        "p={p} px={px} c={c} {got} {}",
                        j.value[c]
                    );
                }
                let k = curvature(&j).unwrap();
                let close = |a: f32, b: f64| (a as f64 - b).abs() <= 1e-6 * (1.0 + b.abs());
                assert!(
                    close(maps.k1[px], k.k1) && close(maps.k2[px], k.k2),
                    "p={p} {px}"
                );
                assert!(close(maps.mean[px], k.mean) && close(maps.gaussian[px], k.gaussian));
                let e: f64 = (0..3)
                    .map(|c| (vals[px * 3 + c] - j.value[c]).powi(2))
                    .sum();
                assert!(close(maps.error[px], e.sqrt()));
            }
        }
    }

    /// The box maps are the image maps cut to the box, bit for bit, and NaN off the mask.
    #[test]
    fn box_maps_equal_the_image_maps_cut_to_the_box() {
        let (w, h) = (53, 41);
        let vals: Vec<f32> = (0..w * h * 3)
            .map(|i| 1.0 + ((i * 7919) % 101) as f32 / 1010.0)
            .collect();
        let mask: Vec<bool> = (0..w * h)
            .map(|i| (i % w) * (i % w) + (i / w) * (i / w) < 900 && (i % w) > 3)
            .collect();
        for (s, p) in [(4.0, 3), (7.5, 2), (16.0, 3), (3.0, 5)] {
            let grid = KnotGrid::new(w, h, s, p).unwrap();
            let fit = fit_mask(&vals, w, h, 3, Some(&mask), &grid, 1e-4, false).unwrap();
            let image = surface_maps(&vals, w, h, 3, None, |i| mask[i].then_some(&fit));
            let frame = Region {
                u0: 2,
                u1: 40,
                v0: 1,
                v1: 33,
            };
            let fw = frame.u1 - frame.u0;
            let crop = |x: &[f32], c: usize| -> Vec<f32> {
                (frame.v0..frame.v1)
                    .flat_map(|v| x[(v * w + frame.u0) * c..(v * w + frame.u1) * c].to_vec())
                    .collect()
            };
            let vb: Vec<f32> = crop(&vals, 3);
            let mb: Vec<bool> = (frame.v0..frame.v1)
                .flat_map(|v| mask[v * w + frame.u0..v * w + frame.u1].to_vec())
                .collect();
            let boxed = surface_maps_box(&vb, Some(&mb), frame, w, h, &fit).unwrap();
            let same = |a: &[f32], b: &[f32]| {
                a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
            };
            assert!(same(&boxed.fitted, &crop(&image.fitted, 3)), "s={s}");
            for (a, b) in [
                (&boxed.error, &image.error),
                (&boxed.k1, &image.k1),
                (&boxed.k2, &image.k2),
                (&boxed.mean, &image.mean),
                (&boxed.gaussian, &image.gaussian),
            ] {
                assert!(same(a, &crop(b, 1)), "s={s} p={p}");
            }
            assert!(boxed.k1.iter().zip(&mb).all(|(k, &m)| m || k.is_nan()));
            assert!(boxed.k1.iter().filter(|k| k.is_finite()).count() > fw);
        }
        let grid = KnotGrid::new(w, h, 8.0, 3).unwrap();
        let fit = fit_grid(&vals, w, h, 3, &grid, 1e-4, false).unwrap();
        let frame = Region {
            u0: 0,
            u1: 10,
            v0: 0,
            v1: 10,
        };
        assert!(surface_maps_box(&vals[..299], None, frame, w, h, &fit).is_err());
        let bad = Region { u1: 60, ..frame };
        assert!(surface_maps_box(&vals[..300], None, bad, w, h, &fit).is_err());
        assert!(surface_maps_box(&vals[..300], None, frame, w + 9, h, &fit).is_err());
    }
}
