//! Locally consistent (LC) accumulation of disparity hypotheses (thesis eq. 2.16–2.19, 3.1).
//!
//! Every reference pixel q carrying a hypothesis `d` from source k (stereo, ToF, ...) with
//! confidence `c_k(q)` lends `c_k(q) * P(q -> p | d)` to each p of its `(2r+1)^2` support window:
//!
//! `P(q->p|d) = e^{-Δ(p,q)/γs} e^{-Δψ(p,q)/γc} e^{-Δ(p_T,q_T)/γs} e^{-Δω(p_T,q_T)/γc} e^{-Δ(p,p_T)/γt}`
//!
//! with Δ the Euclidean pixel distance (equal in both views, so the two spatial terms are one
//! `e^{-2Δ/γs}`), Δψ/Δω colour distances within the reference/target image, and the last term
//! the photometric match of the receiving pixel p with its target pixel `p_T = p + s*d` at the
//! lent disparity. Colour distances are mean absolute channel differences clipped at
//! `truncation` (see `color`).
//!
//! Sub-pixel hypotheses: the target image is resampled at quarter-pixel phases (linear
//! interpolation rounded to u8) and each hypothesis's target position is rounded to the nearest
//! quarter pixel; the hypothesis itself keeps its full value. `Ω(p, ·)` is accumulated on
//! disparity bins of `bin_width` together with the plausibility-weighted disparity; the winner
//! (WTA) is the bin maximising the sum over itself and its two neighbours, and the output is the
//! weighted mean disparity of those three bins (sub-pixel). `plausibility` is the winner's share
//! of everything p received (the per-pixel normalisation). Memory is O(pixels x sources) plus
//! the bin arrays of each worker; the window is never materialised.
//!
//! Three kernels give the same bits, the fastest the CPU supports chosen at run time: the
//! portable one (`Plan::row_scalar`, one receiving pixel at a time); with AVX2, `lc/avx2.rs`,
//! which weighs each lender's hypothesis for eight receiving pixels of a row at once; with
//! AVX-512 F and BW, `lc/avx512.rs`, which does so for a 4 x 4 block of receiving pixels
//! (sixteen lanes, fewer of them idle on the edges of the block's window union). Both SIMD
//! kernels keep every pixel's sums in the portable kernel's order (one bin array per lane).
//!
//! Not done here: the target-view accumulation `Ω^T` and its cross-check product (eq. 2.18);
//! the target-view colour and matching terms of eq. 2.16 are kept.

use rayon::prelude::*;
use rgbd_error::{check_interrupt, image_len, MAX_SIDE};
use rgbd_geom::error::{check_len, invalid, Result};

use crate::check::window_and_positive;
use crate::color::{exp_table, sum_abs};

#[cfg(target_arch = "x86_64")]
mod avx2;
#[cfg(target_arch = "x86_64")]
mod avx512;

/// Quarter-pixel resampling of the target rows.
pub const PHASES: i64 = 4;

/// Parameters of [`lc_fuse`] (eq. 2.16 constants and the window).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LcParams {
    /// Support window half-size `r` (window `(2r+1)^2`).
    pub radius: usize,
    /// γs: spatial decay (pixels).
    pub gamma_s: f32,
    /// γc: colour decay within one view (8-bit levels).
    pub gamma_c: f32,
    /// γt: decay of the cross-view match (8-bit levels).
    pub gamma_t: f32,
    /// Colour distances are clipped at this value before the exponentials.
    pub truncation: f32,
    /// Width of the disparity bins Ω is accumulated on (pixels).
    pub bin_width: f32,
    /// Window sampling step: 1 uses every pixel of the window, 2 every other row and column
    /// (same extent, a quarter of the work).
    pub stride: usize,
    /// `+1` when the target pixel of reference pixel x is `x + d` (reference = right camera of a
    /// pair with d = u_left - u_right), `-1` when it is `x - d` (reference = left camera).
    pub target_sign: i8,
}

/// Support window at full (1920 px) resolution: 39 x 39 as in the literature; scaled with the
/// image width by [`LcParams::for_width`].
pub const WINDOW_FULL_RES: usize = 39;
/// The width [`WINDOW_FULL_RES`] and [`GAMMA_S_FULL_RES`] refer to.
pub const FULL_RES_WIDTH: usize = 1920;
/// eq. 2.16 γs at the 39 x 39 window, scaled with the radius. Mattoccia's published values were
/// not available (METHOD_NOTES §1); these are the checked reimplementation's (γs = 12 at 39 x 39,
/// γc = 30, γt = 25, clip 69).
pub const GAMMA_S_FULL_RES: f32 = 12.0;
/// Default width of the disparity bins (pixels): see [`LcParams::for_width`].
pub const BIN_WIDTH: f32 = 1.0;
/// Largest disparity range, in bins, one call accumulates over (memory per worker).
pub const MAX_BINS: usize = 1 << 22;

impl Default for LcParams {
    /// The defaults for a 960 px wide image (`for_width(960)`).
    fn default() -> Self {
        Self::for_width(960)
    }
}

impl LcParams {
    /// The defaults for an image `width` pixels wide: the 39 x 39 window at 1920 px scaled to
    /// the width (960 px -> radius 10), γs scaled with the radius, window stride 2 (chosen: ~4 %
    /// change in the fusion figures for 3.4x the speed, README), [`BIN_WIDTH`] bins (one pixel,
    /// chosen on a validation set of fresh rendered scenes, never the test set: with quarter-pixel
    /// bins a tightly clustered wrong stereo hypothesis outvotes a correct ToF whose noise spreads
    /// it over more bins, and the wider 3-bin mean denoises; README "Design choices").
    pub fn for_width(width: usize) -> Self {
        let half = WINDOW_FULL_RES / 2;
        let radius = ((half * width) as f64 / FULL_RES_WIDTH as f64)
            .round()
            .max(1.0) as usize;
        Self {
            radius,
            gamma_s: Self::gamma_s_for_radius(radius),
            gamma_c: 30.0,
            gamma_t: 25.0,
            truncation: 69.0,
            bin_width: BIN_WIDTH,
            stride: 2,
            target_sign: 1,
        }
    }

    /// The literature's γs (12 at the 39 x 39 window) scaled to a window of half-size `radius`.
    pub fn gamma_s_for_radius(radius: usize) -> f32 {
        GAMMA_S_FULL_RES * radius as f32 / (WINDOW_FULL_RES / 2) as f32
    }

    /// The window step actually used: `stride` capped at the radius (the window's extent is
    /// kept; a larger step would sample only its centre).
    pub fn effective_stride(&self) -> usize {
        self.stride.min(self.radius.max(1))
    }

    /// Checks every field (the binding calls this when a parameter object is built).
    pub fn validate(&self) -> Result<()> {
        window_and_positive(
            self.radius,
            &[
                ("gamma_s", self.gamma_s),
                ("gamma_c", self.gamma_c),
                ("gamma_t", self.gamma_t),
                ("truncation", self.truncation),
                ("bin_width", self.bin_width),
            ],
        )?;
        if self.stride == 0 {
            return Err(invalid("stride", self.stride, "an integer >= 1"));
        }
        if self.target_sign != 1 && self.target_sign != -1 {
            return Err(invalid("target_sign", self.target_sign, "+1 or -1"));
        }
        Ok(())
    }
}

/// One disparity source: `H x W` disparities (NaN = none) and optional confidences in [0, 1]
/// (None = 1 everywhere; NaN = 0).
#[derive(Debug, Clone, Copy)]
pub struct Source<'a> {
    pub disparity: &'a [f32],
    pub confidence: Option<&'a [f32]>,
}

/// Result of [`lc_fuse`].
#[derive(Debug, Clone, PartialEq)]
pub struct LcOutput {
    /// Winning sub-pixel disparity, NaN where no hypothesis reached the pixel.
    pub disparity: Vec<f32>,
    /// Winner's share of the plausibility the pixel received, in [0, 1] (NaN where none).
    pub plausibility: Vec<f32>,
}

/// A hypothesis prepared for the gather loop.
#[derive(Debug, Clone, Copy, Default)]
struct Hyp {
    /// Target offset in quarter pixels (`round(4 s d)`); added to `4 x` of the receiving pixel.
    shift: i32,
    bin: u32,
    d: f32,
    /// Confidence; 0 marks "no hypothesis".
    w: f32,
    /// Target colour at the lending pixel's own target position.
    col: [u8; 3],
}

/// Target rows resampled at quarter-pixel positions: `4 (W - 1) + 1` RGB samples per row.
///
/// Sample `4 x + k` is the linear interpolation `((4 - k) a + k b) / 4` of pixels x and x + 1,
/// rounded half up: in integers, the exact value of the f32 expression
/// `((1 - k/4) a + (k/4) b).round()` (tested against it for every a, b and k).
pub fn quarter_rows(target: &[u8], width: usize, height: usize) -> Vec<[u8; 3]> {
    let p = PHASES as usize;
    let len = p * (width - 1) + 1;
    let mut out = vec![[0u8; 3]; height * len];
    out.par_chunks_mut(len).enumerate().for_each(|(y, row)| {
        let src = &target[y * width * 3..(y + 1) * width * 3];
        for (k, px) in row.iter_mut().enumerate() {
            let (x0, f) = (k / p, (k % p) as u16);
            for (c, v) in px.iter_mut().enumerate() {
                let a = u16::from(src[3 * x0 + c]);
                let b = if f > 0 {
                    u16::from(src[3 * x0 + 3 + c])
                } else {
                    a
                };
                *v = quarter_mix(a, b, f);
            }
        }
    });
    out
}

/// `((P - k) a + k b) / P` rounded half up (`P` = [`PHASES`]), for bytes `a`, `b` and a
/// phase `k` in `0..P`.
#[inline]
fn quarter_mix(a: u16, b: u16, k: u16) -> u8 {
    // floor(v / P + 1/2) = (2 v + P) / (2 P) for v = (P - k) a + k b, any P; with P = 4 at most
    // (2 * 1020 + 4) / 8 = 255.
    let p = PHASES as u16;
    ((2 * ((p - k) * a + k * b) + p) / (2 * p)) as u8
}

/// Global disparity range of all valid hypotheses, or None when there is none.
fn disparity_range(sources: &[Source<'_>]) -> Option<(f32, f32)> {
    let mut lo = f32::INFINITY;
    let mut hi = f32::NEG_INFINITY;
    for s in sources {
        for &d in s.disparity.iter().filter(|d| d.is_finite()) {
            lo = lo.min(d);
            hi = hi.max(d);
        }
    }
    (lo <= hi).then_some((lo, hi))
}

fn check_inputs(
    reference: &[u8],
    target: &[u8],
    width: usize,
    height: usize,
    sources: &[Source<'_>],
) -> Result<()> {
    if width < 2 || height == 0 {
        return Err(invalid(
            "reference",
            format!("{height}x{width}"),
            "an image at least 1x2",
        ));
    }
    let n = image_len("reference", width, height)?;
    check_len("reference", reference, 3 * n, "H x W x 3")?;
    check_len("target", target, 3 * n, "H x W x 3 of the reference's size")?;
    if sources.is_empty() || sources.len() > 8 {
        return Err(invalid("sources", sources.len(), "1..=8 disparity sources"));
    }
    // No image is wider than MAX_SIDE, so a larger disparity matches nothing; bounding it keeps
    // the quarter-pixel shifts inside i32 and the bin range finite.
    let limit = MAX_SIDE as f32;
    // Named as the Python wrapper names them (`disparities`, `confidences`, map k).
    for (k, s) in sources.iter().enumerate() {
        check_len("disparities", s.disparity, n, "H x W of the images' size")?;
        let too_far = |d: &&f32| d.abs() > limit && d.is_finite();
        if let Some(bad) = s.disparity.iter().find(too_far) {
            return Err(invalid(
                "disparities",
                format!("{bad} in map {k}"),
                format!("disparities within +-{MAX_SIDE} pixels, or NaN"),
            ));
        }
        if let Some(c) = s.confidence {
            check_len("confidences", c, n, "H x W of the images' size")?;
            if let Some(bad) = c.iter().find(|v| !v.is_nan() && !(0.0..=1.0).contains(*v)) {
                return Err(invalid(
                    "confidences",
                    format!("{bad} in map {k}"),
                    "values in [0, 1] (NaN = 0)",
                ));
            }
        }
    }
    Ok(())
}

/// Fuses `sources` on the reference image with the LC accumulation (module docs). With a single
/// unit-confidence source this is the LC stereo refinement of §2.4.2.
pub fn lc_fuse(
    reference: &[u8],
    target: &[u8],
    width: usize,
    height: usize,
    sources: &[Source<'_>],
    params: &LcParams,
) -> Result<LcOutput> {
    fuse_with(reference, target, width, height, sources, params, None)
}

/// [`lc_fuse`] with the row kernel forced (tests compare the kernels) or chosen (`None`).
fn fuse_with(
    reference: &[u8],
    target: &[u8],
    width: usize,
    height: usize,
    sources: &[Source<'_>],
    params: &LcParams,
    force: Option<Kernel>,
) -> Result<LcOutput> {
    params.validate()?;
    check_inputs(reference, target, width, height, sources)?;
    let n = width * height;
    let Some((dmin, dmax)) = disparity_range(sources) else {
        return Ok(LcOutput {
            disparity: vec![f32::NAN; n],
            plausibility: vec![f32::NAN; n],
        });
    };
    // In f64 and compared before the cast: a tiny bin width must not overflow the count.
    let bins_f = (f64::from(dmax) - f64::from(dmin)) / f64::from(params.bin_width);
    if !(bins_f < MAX_BINS as f64) {
        return Err(invalid(
            "bin_width",
            params.bin_width,
            format!(
                "a bin width giving at most {MAX_BINS} bins over the disparity range [{dmin}, {dmax}]"
            ),
        ));
    }
    // The count from the very f32 arithmetic `prepare` bins each disparity with (monotonic, so
    // dmax's bin is the largest): the f64 quotient can floor one lower than the f32 one, and
    // dmax's bin then indexed past the histogram (found by proptest: w 68, bin width 0.25).
    let nbins = ((dmax - dmin) / params.bin_width) as usize + 1;
    let kernel = force.unwrap_or_else(|| Kernel::select(nbins));
    let plan = Plan::new(
        reference, target, width, height, sources, dmin, nbins, params, kernel,
    );
    let mut disparity = vec![f32::NAN; n];
    let mut plausibility = vec![f32::NAN; n];
    let rows = plan.rows_per_task();
    disparity
        .par_chunks_mut(width * rows)
        .zip(plausibility.par_chunks_mut(width * rows))
        .enumerate()
        .try_for_each_init(
            || plan.scratch(),
            |scratch, (k, (d_rows, p_rows))| {
                check_interrupt()?;
                plan.rows(scratch, k * rows, d_rows, p_rows);
                Ok(())
            },
        )?;
    Ok(LcOutput {
        disparity,
        plausibility,
    })
}

/// Which kernel runs: the portable one, eight receiving pixels of a row per step ([`avx2`]), or
/// a 4 x 4 block of them ([`avx512`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kernel {
    Scalar,
    #[cfg(target_arch = "x86_64")]
    Avx2,
    #[cfg(target_arch = "x86_64")]
    Avx512,
}

impl Kernel {
    /// The fastest kernel the running CPU supports for `nbins` bins (the SIMD ones keep a bin
    /// array per lane and worker, so a huge range falls back to a narrower kernel).
    fn select(nbins: usize) -> Self {
        #[cfg(target_arch = "x86_64")]
        if nbins <= avx512::MAX_BINS && avx512::available() {
            return Self::Avx512;
        }
        #[cfg(target_arch = "x86_64")]
        if nbins <= avx2::MAX_BINS && avx2::available() {
            return Self::Avx2;
        }
        let _ = nbins;
        Self::Scalar
    }
}

/// Per-worker buffers of the row kernels, reused across rows (each pixel's bins are cleared
/// after its winner is read).
enum Scratch {
    Scalar {
        bins: Bins,
        base: Vec<f32>,
    },
    #[cfg(target_arch = "x86_64")]
    Avx2(Box<avx2::Scratch>),
    #[cfg(target_arch = "x86_64")]
    Avx512(Box<avx512::Scratch>),
}

/// Everything the row kernels share, built once per call.
struct Plan {
    width: usize,
    height: usize,
    radius: usize,
    /// Effective window step.
    st: usize,
    /// Window side `2 radius + 1`.
    side: usize,
    nbins: usize,
    /// Quarter-pixel target rows ([`quarter_rows`]), `len` samples each.
    t4: Vec<[u8; 3]>,
    len: usize,
    refc: Vec<[u8; 3]>,
    hyps: Vec<Vec<Hyp>>,
    /// `e^{-2 Δ / γs}` of each window offset, row-major `side x side`.
    spatial: Vec<f32>,
    lut_c: Box<[f32; LUT_MASK + 1]>,
    lut_t: Box<[f32; LUT_MASK + 1]>,
    /// The AVX2 kernel's tables when it runs.
    #[cfg(target_arch = "x86_64")]
    simd: Option<avx2::Tables>,
    /// The AVX-512 kernel's tables when it runs.
    #[cfg(target_arch = "x86_64")]
    simd512: Option<avx512::Tables>,
}

impl Plan {
    #[allow(clippy::too_many_arguments)]
    fn new(
        reference: &[u8],
        target: &[u8],
        width: usize,
        height: usize,
        sources: &[Source<'_>],
        dmin: f32,
        nbins: usize,
        params: &LcParams,
        kernel: Kernel,
    ) -> Self {
        let t4 = quarter_rows(target, width, height);
        let ctx = HypCtx::new(&t4, width, dmin, params);
        // The vector kernels build their lenders straight from the sources (below).
        let hyps = match kernel {
            Kernel::Scalar => sources
                .iter()
                .map(|s| ctx.prepare(s, width * height))
                .collect(),
            #[cfg(target_arch = "x86_64")]
            _ => Vec::new(),
        };
        #[cfg(target_arch = "x86_64")]
        let lend = (kernel != Kernel::Scalar).then(|| avx2::lenders(&ctx, sources, width * height));
        let side = 2 * params.radius + 1;
        let r = params.radius as f32;
        let spatial = (0..side * side)
            .map(|i| {
                let (dy, dx) = ((i / side) as f32 - r, (i % side) as f32 - r);
                (-2.0 * (dx * dx + dy * dy).sqrt() / params.gamma_s).exp()
            })
            .collect();
        let plan = Self {
            width,
            height,
            radius: params.radius,
            st: params.effective_stride(),
            side,
            nbins,
            t4,
            len: PHASES as usize * (width - 1) + 1,
            refc: rgb_pixels(reference),
            hyps,
            spatial,
            lut_c: padded(exp_table(params.gamma_c, params.truncation)),
            lut_t: padded(exp_table(params.gamma_t, params.truncation)),
            #[cfg(target_arch = "x86_64")]
            simd: None,
            #[cfg(target_arch = "x86_64")]
            simd512: None,
        };
        match kernel {
            Kernel::Scalar => plan,
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx2 => Self {
                simd: Some(avx2::Tables::new(
                    &plan,
                    lend.expect("built for this kernel"),
                )),
                ..plan
            },
            #[cfg(target_arch = "x86_64")]
            Kernel::Avx512 => Self {
                simd512: Some(avx512::Tables::new(
                    &plan,
                    lend.expect("built for this kernel"),
                )),
                ..plan
            },
        }
    }

    /// Buffers for one worker of the selected kernel.
    fn scratch(&self) -> Scratch {
        #[cfg(target_arch = "x86_64")]
        if let Some(tabs) = &self.simd {
            return Scratch::Avx2(Box::new(avx2::Scratch::new(self, tabs)));
        }
        #[cfg(target_arch = "x86_64")]
        if let Some(tabs) = &self.simd512 {
            return Scratch::Avx512(Box::new(avx512::Scratch::new(self, tabs)));
        }
        Scratch::Scalar {
            bins: Bins::new(self.nbins),
            base: vec![0.0; self.side * self.side],
        }
    }

    /// Fuses row `y` into `d_row` / `p_row` with the kernel `scratch` was made for (the AVX-512
    /// kernel works on blocks of rows and runs from [`Plan::rows`] only).
    fn row(&self, scratch: &mut Scratch, y: usize, d_row: &mut [f32], p_row: &mut [f32]) {
        match scratch {
            #[cfg(target_arch = "x86_64")]
            Scratch::Avx2(s) => {
                if let Some(tabs) = &self.simd {
                    // SAFETY: the tables exist only when `Kernel::select` detected AVX2 on
                    // this CPU.
                    unsafe { avx2::row(self, tabs, s, y, d_row, p_row) };
                }
            }
            #[cfg(target_arch = "x86_64")]
            Scratch::Avx512(_) => {}
            Scratch::Scalar { bins, base } => self.row_scalar(bins, base, y, d_row, p_row),
        }
    }

    /// Image rows one parallel task fuses: the AVX-512 kernel takes blocks of rows.
    fn rows_per_task(&self) -> usize {
        #[cfg(target_arch = "x86_64")]
        if self.simd512.is_some() {
            return avx512::rows_per_block(self.st);
        }
        1
    }

    /// Fuses the rows from `y` on into `d_rows` / `p_rows` ([`Plan::rows_per_task`] at most).
    fn rows(&self, scratch: &mut Scratch, y: usize, d_rows: &mut [f32], p_rows: &mut [f32]) {
        #[cfg(target_arch = "x86_64")]
        if let (Scratch::Avx512(s), Some(tabs)) = (&mut *scratch, &self.simd512) {
            // SAFETY: the tables exist only when `Kernel::select` detected AVX-512F and BW on
            // this CPU.
            unsafe { avx512::block(self, tabs, s, y, d_rows, p_rows) };
            return;
        }
        for (i, (d_row, p_row)) in d_rows
            .chunks_mut(self.width)
            .zip(p_rows.chunks_mut(self.width))
            .enumerate()
        {
            self.row(scratch, y + i, d_row, p_row);
        }
    }

    /// The portable kernel: one receiving pixel at a time. `base` holds the spatial x
    /// reference-colour weight of each window pixel, computed once per p and shared by all
    /// sources.
    fn row_scalar(
        &self,
        bins: &mut Bins,
        base: &mut [f32],
        y: usize,
        d_row: &mut [f32],
        p_row: &mut [f32],
    ) {
        let (width, side, st) = (self.width, self.side, self.st);
        let (refc, spatial) = (&self.refc, &self.spatial);
        let (lut_c, lut_t) = (&self.lut_c, &self.lut_t);
        let trow = &self.t4[y * self.len..(y + 1) * self.len];
        let (y0, y1) = span(y, self.radius, st, self.height);
        for x in 0..width {
            let cp = refc[y * width + x];
            let (x0, x1) = span(x, self.radius, st, width);
            let cols = (x1 - x0) / st + 1;
            for (j, yq) in (y0..=y1).step_by(st).enumerate() {
                let srow = &spatial[(yq + self.radius - y) * side + x0 + self.radius - x..];
                let crow = &refc[yq * width + x0..=yq * width + x1];
                for ((b, &sp), &cq) in base[j * cols..(j + 1) * cols]
                    .iter_mut()
                    .zip(srow.iter().step_by(st))
                    .zip(crow.iter().step_by(st))
                {
                    *b = sp * lut_c[sum_abs(&cp, &cq) & LUT_MASK];
                }
            }
            let px4 = PHASES as i32 * x as i32;
            for hs in &self.hyps {
                // Consecutive window pixels mostly lend to the same bin: sum in registers and
                // touch memory only when the bin changes (breaks the store-load chain).
                let (mut rb, mut rw, mut rwd) = (0u32, 0.0f32, 0.0f32);
                for (j, yq) in (y0..=y1).step_by(st).enumerate() {
                    let hrow = &hs[yq * width + x0..=yq * width + x1];
                    for (h, &bw) in hrow.iter().step_by(st).zip(&base[j * cols..(j + 1) * cols]) {
                        if h.w <= 0.0 {
                            continue;
                        }
                        // A negative position wraps to a huge index: one check for both ends.
                        let Some(t) = trow.get((px4 + h.shift) as usize) else {
                            continue;
                        };
                        let v = bw
                            * h.w
                            * lut_c[sum_abs(t, &h.col) & LUT_MASK]
                            * lut_t[sum_abs(&cp, t) & LUT_MASK];
                        if h.bin != rb {
                            bins.add(rb, rw, rwd);
                            (rb, rw, rwd) = (h.bin, 0.0, 0.0);
                        }
                        rw += v;
                        rwd += v * h.d;
                    }
                }
                bins.add(rb, rw, rwd);
            }
            (d_row[x], p_row[x]) = bins.winner_and_clear();
        }
    }
}

/// First and last window coordinates around `c` that lie on the stride grid through `c`.
fn span(c: usize, radius: usize, stride: usize, n: usize) -> (usize, usize) {
    let k = radius / stride;
    (
        c - stride * k.min(c / stride),
        c + stride * k.min((n - 1 - c) / stride),
    )
}

/// Colour tables padded to a power of two, so `s & LUT_MASK` indexes them without a bounds check.
const LUT_MASK: usize = 1023;

fn padded(mut t: Vec<f32>) -> Box<[f32; LUT_MASK + 1]> {
    t.resize(LUT_MASK + 1, 0.0);
    t.into_boxed_slice()
        .try_into()
        .expect("padded to LUT_MASK + 1")
}

/// RGB triples of an interleaved image.
fn rgb_pixels(img: &[u8]) -> Vec<[u8; 3]> {
    img.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
}

/// What [`Plan::hyp`] reads besides the source: the quarter-pixel target rows and the
/// constants of the call.
pub(super) struct HypCtx<'a> {
    t4: &'a [[u8; 3]],
    width: usize,
    len: usize,
    dmin: f32,
    sign: f32,
    bin_width: f32,
}

impl<'a> HypCtx<'a> {
    fn new(t4: &'a [[u8; 3]], width: usize, dmin: f32, params: &LcParams) -> Self {
        HypCtx {
            t4,
            width,
            len: PHASES as usize * (width - 1) + 1,
            dmin,
            sign: f32::from(params.target_sign) * PHASES as f32,
            bin_width: params.bin_width,
        }
    }

    /// The hypothesis pixel `i` of source `s` lends, if any (a finite disparity with a
    /// positive confidence whose target position lies in the image).
    #[inline]
    fn hyp(&self, s: &Source<'_>, i: usize) -> Option<Hyp> {
        let d = s.disparity[i];
        let c = s.confidence.map_or(1.0, |c| c[i]);
        if !d.is_finite() || !(c > 0.0) {
            return None;
        }
        let (y, x) = (i / self.width, i % self.width);
        let shift = (self.sign * d).round() as i32;
        let pos = PHASES * x as i64 + i64::from(shift);
        if pos < 0 || pos >= self.len as i64 {
            return None;
        }
        Some(Hyp {
            shift,
            // Bins are offset by one so the WTA can read both neighbours.
            bin: ((d - self.dmin) / self.bin_width) as u32 + 1,
            d,
            w: c,
            col: self.t4[y * self.len + pos as usize],
        })
    }

    /// One source's hypotheses, one per pixel (`w == 0` marks none).
    fn prepare(&self, s: &Source<'_>, n: usize) -> Vec<Hyp> {
        (0..n)
            .into_par_iter()
            .map(|i| self.hyp(s, i).unwrap_or_default())
            .collect()
    }
}

/// Per-worker Ω(p, ·) accumulator over disparity bins, with the list of bins touched.
struct Bins {
    acc: Vec<f32>,
    accd: Vec<f32>,
    touched: Vec<u32>,
}

impl Bins {
    fn new(nbins: usize) -> Self {
        Self {
            acc: vec![0.0; nbins + 2],
            accd: vec![0.0; nbins + 2],
            touched: Vec::new(),
        }
    }

    /// Kept out of line so the hot loop's running sums stay in registers.
    #[inline(never)]
    fn add(&mut self, bin: u32, w: f32, wd: f32) {
        if w == 0.0 && wd == 0.0 {
            return;
        }
        let b = bin as usize;
        if self.acc[b] == 0.0 && self.accd[b] == 0.0 {
            self.touched.push(bin);
        }
        self.acc[b] += w;
        self.accd[b] += wd;
    }

    fn winner_and_clear(&mut self) -> (f32, f32) {
        let out = winner(&self.acc, &self.accd, &self.touched);
        for &b in &self.touched {
            self.acc[b as usize] = 0.0;
            self.accd[b as usize] = 0.0;
        }
        self.touched.clear();
        out
    }
}

/// WTA over the touched bins: the bin maximising its 3-bin sum (ties: lowest bin); returns the
/// weighted mean disparity of those bins and their share of the total.
fn winner(acc: &[f32], accd: &[f32], touched: &[u32]) -> (f32, f32) {
    winner_by(touched, |b| acc[b], |b| accd[b])
}

/// [`winner`] over bins read through `acc` / `accd` (the AVX2 kernel interleaves eight pixels'
/// bins); the same sums in the same order.
#[inline(always)]
fn winner_by(
    touched: &[u32],
    acc: impl Fn(usize) -> f32,
    accd: impl Fn(usize) -> f32,
) -> (f32, f32) {
    let mut total = 0.0f32;
    let mut best = (f32::NEG_INFINITY, usize::MAX);
    for &b in touched {
        let b = b as usize;
        total += acc(b);
        let s = acc(b - 1) + acc(b) + acc(b + 1);
        if s > best.0 || (s == best.0 && b < best.1) {
            best = (s, b);
        }
    }
    if !(total > 0.0) {
        return (f32::NAN, f32::NAN);
    }
    let (s, b) = best;
    let d = (accd(b - 1) + accd(b) + accd(b + 1)) / s;
    (d, (s / total).min(1.0))
}

/// Winner of lane `i` of bins interleaved over `lanes` pixels (`acc[lanes * b + i]`), as
/// `Bins::winner_and_clear`, then that lane's bins cleared (the SIMD kernels' lane bins).
#[inline]
fn lane_winner_and_clear(
    acc: &mut [f32],
    accd: &mut [f32],
    touched: &mut Vec<u32>,
    lanes: usize,
    i: usize,
) -> (f32, f32) {
    let out = winner_by(touched, |b| acc[lanes * b + i], |b| accd[lanes * b + i]);
    for &b in touched.iter() {
        acc[lanes * b as usize + i] = 0.0;
        accd[lanes * b as usize + i] = 0.0;
    }
    touched.clear();
    out
}
