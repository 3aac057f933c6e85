//! Semi-global matching (Hirschmüller 2008, thesis §3.3) with a census matching cost, for
//! rgbd_rs:
//!
//! - [`census`]: census strings of a grey image (window up to 64 bits, centre or mean
//!   reference);
//! - [`sgm`]: pixelwise Hamming costs aggregated along 4, 5 or 8 paths (P1, and P2 adapted to
//!   the intensity step along the path), winner-take-all with parabola or equiangular sub-pixel
//!   refinement, uniqueness, a left-right check against the other view's winners (from the
//!   same sums, no second matching), median and speckle filters, and optionally the aggregated
//!   cost curve's best and second-best costs (the heuristic stereo confidence's input);
//! - both views as reference: the right one is matched on mirrored images.
//!
//! Memory: one u16 volume (the sum over paths, each pixel's searchable disparities only: at
//! most `H x W x D`) plus `O(W D)` per path; costs are recomputed from the census strings in
//! each sweep instead of being stored. Rows are
//! parallel (rayon) where the paths allow; the inner loops are compiled for the portable
//! baseline, AVX2 and AVX-512 and chosen at run time ([`Kernel`]), all with the same bits.
//!
//! Images are `H x W` row-major grey `u8`; disparities `d = x_left - x_right` (pixels) on the
//! reference view, NaN = no disparity.

mod aggregate;
pub mod census;
pub mod filter;
mod kernel;
mod layout;
mod median;
mod params;
mod select;
mod volume;

use std::borrow::Cow;

use rgbd_error::{check_len, checked_len, image_len, Result};

pub use census::CensusReference;
pub use kernel::Kernel;
pub use params::{Paths, SgmParams, Subpixel, DIRECTIONS, MAX_MEDIAN, MAX_P2, MAX_VERTICAL};

/// Which view the disparity map lies on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reference {
    /// The left view: its pixel `x` matches the right view's `x - d`.
    Left,
    /// The right view: its pixel `x` matches the left view's `x + d`.
    Right,
}

/// What [`sgm`] returns, every map `H x W` on the reference view.
#[derive(Debug, Clone, PartialEq)]
pub struct SgmOutput {
    /// Sub-pixel disparity, NaN where rejected (checks, filters) or not searchable.
    pub disparity: Vec<f32>,
    /// The aggregated cost of the winner (with [`SgmParams::stats`]).
    pub best: Option<Vec<f32>>,
    /// The smallest aggregated cost more than one disparity away from the winner (+inf if the
    /// search has none; with [`SgmParams::stats`]).
    pub second: Option<Vec<f32>>,
}

/// The disparity map of a rectified grey pair on `reference` (see the crate docs).
pub fn sgm(
    left: &[u8],
    right: &[u8],
    width: usize,
    height: usize,
    reference: Reference,
    params: &SgmParams,
) -> Result<SgmOutput> {
    sgm_with(
        left,
        right,
        width,
        height,
        reference,
        params,
        Kernel::best(),
    )
}

/// [`sgm`] with a chosen build of the inner loops (one of [`Kernel::available`]; an
/// unavailable one runs the portable build). For tests and benchmarks.
pub fn sgm_with(
    left: &[u8],
    right: &[u8],
    width: usize,
    height: usize,
    reference: Reference,
    params: &SgmParams,
    kernel: Kernel,
) -> Result<SgmOutput> {
    // The whole call runs on one pool worker: the many short parallel steps (one per row and
    // sweep) then hand work to the other workers instead of blocking this thread each time.
    on_pool(|| {
        let (sum, layout) = solve(left, right, width, height, reference, params, kernel)?;
        let (w, h) = (width, height);
        let sel = select::select(&sum, w, &layout, params, kernel);
        drop(sum);
        let mut disp = sel.disparity;
        if params.median > 1 {
            disp = median::median_with(kernel, &disp, w, h, params.median);
        }
        filter::remove_speckles(&mut disp, w, h, params.speckle_size, params.speckle_range);
        let (mut best, mut second) = (sel.best, sel.second);
        if reference == Reference::Right {
            for m in [&mut disp, &mut best, &mut second] {
                mirror(m, w);
            }
        }
        Ok(SgmOutput {
            disparity: disp,
            best: params.stats.then_some(best),
            second: params.stats.then_some(second),
        })
    })
}

/// Runs `f` on a worker of rayon's global pool (where a blocking wait costs no context switch
/// per parallel step).
fn on_pool<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    let mut out = None;
    rayon::scope(|_| out = Some(f()));
    out.expect("the scope ran its body")
}

/// The summed path costs `S` (`H x W x D` u16, disparities `min_disparity + k`) of the problem
/// as solved, 0 where a pixel cannot search a disparity (`x < min_disparity + k`): for a right
/// reference the pair is mirrored, so column `x` of `S` is the right view's column `W - 1 - x`.
/// For tests against a reference implementation.
#[doc(hidden)]
pub fn aggregated_with(
    left: &[u8],
    right: &[u8],
    width: usize,
    height: usize,
    reference: Reference,
    params: &SgmParams,
    kernel: Kernel,
) -> Result<Vec<u16>> {
    let (sum, layout) = solve(left, right, width, height, reference, params, kernel)?;
    let nd = params.disparities();
    let mut full = vec![0u16; width * height * nd];
    for (y, row) in sum.chunks_exact(layout.row_len()).enumerate() {
        for x in 0..width {
            let run = &row[layout.run(x)];
            let at = (y * width + x) * nd;
            full[at..at + run.len()].copy_from_slice(run);
        }
    }
    Ok(full)
}

/// Checks the call and aggregates: `S` in its [`layout::Layout`].
fn solve(
    left: &[u8],
    right: &[u8],
    width: usize,
    height: usize,
    reference: Reference,
    params: &SgmParams,
    kernel: Kernel,
) -> Result<(Vec<u16>, layout::Layout)> {
    let n = image_len("left", width, height)?;
    check_len("left", left, n, "H x W grey")?;
    check_len("right", right, n, "H x W grey, the left image's size")?;
    params.validate(width)?;
    let nd = params.disparities();
    checked_len("max_disparity", &[width, height, nd])?;
    let kernel = if Kernel::available().contains(&kernel) {
        kernel
    } else {
        Kernel::Portable
    };
    let (w, h) = (width, height);
    // The reference image and the target, oriented so the match of x lies at x - d.
    let (r_img, t_img): (Cow<'_, [u8]>, Cow<'_, [u8]>) = if reference == Reference::Right {
        let mut r = right.to_vec();
        let mut t = left.to_vec();
        mirror(&mut r, w);
        mirror(&mut t, w);
        (r.into(), t.into())
    } else {
        (left.into(), right.into())
    };
    let layout = layout::Layout::new(w, params.min_disparity, nd);
    // Strings of up to 32 bits are kept as u32: half the memory beside the volume.
    let run = |strings: aggregate::Strings<'_>| {
        let p = problem(strings, &r_img, w, h, params, layout.clone());
        aggregate::aggregate(&p, params, kernel)
    };
    let sum = if params.max_cost() <= 32 {
        let (cref, trev) = census_pair::<u32>(&r_img, &t_img, w, h, params, kernel);
        run(aggregate::Strings::Narrow(&cref, &trev))?
    } else {
        let (cref, trev) = census_pair::<u64>(&r_img, &t_img, w, h, params, kernel);
        run(aggregate::Strings::Wide(&cref, &trev))?
    };
    Ok((sum, layout))
}

/// The census strings of the reference and of the target, every target row reversed.
fn census_pair<T: census::Word>(
    r_img: &[u8],
    t_img: &[u8],
    w: usize,
    h: usize,
    params: &SgmParams,
    kernel: Kernel,
) -> (Vec<T>, Vec<T>) {
    let (cw, ch, cr) = (
        params.census_width,
        params.census_height,
        params.census_reference,
    );
    let cref = census::census_with::<T>(r_img, w, h, cw, ch, cr, kernel);
    let mut trev = census::census_with::<T>(t_img, w, h, cw, ch, cr, kernel);
    for row in trev.chunks_exact_mut(w) {
        row.reverse();
    }
    (cref, trev)
}

/// The matching problem of the checked call.
fn problem<'a>(
    census: aggregate::Strings<'a>,
    grey: &'a [u8],
    w: usize,
    h: usize,
    params: &SgmParams,
    layout: layout::Layout,
) -> aggregate::Problem<'a> {
    aggregate::Problem {
        census,
        grey,
        w,
        h,
        dmin: params.min_disparity,
        nd: params.disparities(),
        cmax: params.max_cost() as u8,
        p1: params.p1,
        p2: params.p2_table(),
        vertical: params.vertical_tolerance,
        layout,
    }
}

/// Reverses every row of an `H x W` map in place.
fn mirror<T>(m: &mut [T], w: usize) {
    for row in m.chunks_exact_mut(w) {
        row.reverse();
    }
}
