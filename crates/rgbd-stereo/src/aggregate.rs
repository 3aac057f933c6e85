//! SGM path aggregation, streamed: the only volume is the sum `S` (u16, each pixel's searchable
//! disparities: [`Layout`]); every path keeps just its previous row (`W x D` u16), so memory is
//! under `2 W H D` bytes plus `O(W D)`.
//!
//! The reference pixel `x` matches the target pixel `x - d` (a left reference; the right one is
//! matched on mirrored images, see [`crate::sgm`]). Three passes, each computing the census
//! costs it needs (they are never stored):
//!
//! 1. the horizontal paths, every row on its own (rows in parallel);
//! 2. the paths from above, rows top-down, the pixels of a row in parallel chunks that read the
//!    previous row;
//! 3. the paths from below, likewise bottom-up.
//!
//! Each pass adds its paths into `S`; a cell's sum does not depend on how the chunks are
//! scheduled, so the result is the same for any thread count.

use rayon::prelude::*;
use rgbd_error::{check_interrupt, Result};

use crate::kernel::{costs, costs_min, multiversion, start, step, Kernel, EDGE};
use crate::layout::Layout;
use crate::params::{SgmParams, DIRECTIONS};

/// Pixels per parallel task of a row.
const CHUNK: usize = 32;

/// One matching problem: census strings of both views, the reference's grey image (for the
/// adaptive P2) and the constants.
pub(crate) struct Problem<'a> {
    pub census: Strings<'a>,
    pub grey: &'a [u8],
    pub w: usize,
    pub h: usize,
    pub dmin: usize,
    pub nd: usize,
    pub cmax: u8,
    pub p1: u16,
    pub p2: [u16; 256],
    /// Target rows searched above and below (see `SgmParams::vertical_tolerance`).
    pub vertical: usize,
    pub layout: Layout,
}

impl Problem<'_> {
    /// Costs of pixel `(x, y)` at every disparity into `out` (`nd` long).
    #[inline(always)]
    fn pixel_costs(&self, x: usize, y: usize, out: &mut [u8]) {
        let (w, nd, dmin) = (self.w, self.nd, self.dmin);
        if x < dmin {
            out.fill(self.cmax);
            return;
        }
        let valid = (x - dmin + 1).min(nd);
        let (at, from) = (y * w + x, y * w + w - 1 - x + dmin);
        match self.census {
            Strings::Narrow(r, t) => costs(r[at], &t[from..], valid, self.cmax, out),
            Strings::Wide(r, t) => costs(r[at], &t[from..], valid, self.cmax, out),
        }
        // Other target rows (clamped at the border; a clamped row repeats one already taken).
        let (lo, hi) = (
            y.saturating_sub(self.vertical),
            (y + self.vertical).min(self.h - 1),
        );
        for ty in (lo..=hi).filter(|&ty| ty != y) {
            let from = ty * w + w - 1 - x + dmin;
            match self.census {
                Strings::Narrow(r, t) => costs_min(r[at], &t[from..], valid, out),
                Strings::Wide(r, t) => costs_min(r[at], &t[from..], valid, out),
            }
        }
    }

    /// P2 for the step from `(px, py)` to `(x, y)`.
    #[inline(always)]
    fn p2_at(&self, x: usize, y: usize, px: usize, py: usize) -> u16 {
        let a = self.grey[y * self.w + x];
        let b = self.grey[py * self.w + px];
        self.p2[a.abs_diff(b) as usize]
    }
}

/// The census strings of the reference view and of the target (every target row reversed).
#[derive(Clone, Copy)]
pub(crate) enum Strings<'a> {
    /// Windows of up to 32 bits.
    Narrow(&'a [u32], &'a [u32]),
    /// Wider windows.
    Wide(&'a [u64], &'a [u64]),
}

/// One sweep's previous and current rows of path costs: a slot (`D + 2`, see [`EDGE`]) per
/// pixel and path, and each slot's minimum.
struct Rows {
    prev: Vec<u16>,
    prev_min: Vec<u16>,
    cur: Vec<u16>,
    cur_min: Vec<u16>,
}

impl Rows {
    /// `slots` = pixels x paths.
    fn new(slots: usize, nd: usize) -> Self {
        Rows {
            prev: vec![EDGE; slots * (nd + 2)],
            prev_min: vec![0; slots],
            cur: vec![EDGE; slots * (nd + 2)],
            cur_min: vec![0; slots],
        }
    }
}

#[inline(always)]
fn costs_chunk_body(p: &Problem<'_>, y: usize, x0: usize, out: &mut [u8]) {
    for (i, o) in out.chunks_exact_mut(p.nd).enumerate() {
        p.pixel_costs(x0 + i, y, o);
    }
}
multiversion!(costs_chunk => costs_chunk_body(p: &Problem<'_>, y: usize, x0: usize, out: &mut [u8]) -> ());

/// The horizontal paths of row `y` (costs computed into `cost`, `W x D`) added into `acc`.
#[inline(always)]
fn horizontal_body(
    p: &Problem<'_>,
    y: usize,
    from_left: bool,
    from_right: bool,
    cost: &mut [u8],
    acc: &mut [u16],
) {
    let (w, nd) = (p.w, p.nd);
    costs_chunk_body(p, y, 0, cost);
    let mut prev = vec![EDGE; nd + 2];
    let mut cur = vec![EDGE; nd + 2];
    for (on, dx) in [(from_left, 1isize), (from_right, -1)] {
        if !on {
            continue;
        }
        let mut pmin = 0u16;
        for i in 0..w {
            let x = if dx > 0 { i } else { w - 1 - i };
            let c = &cost[x * nd..(x + 1) * nd];
            let a = &mut acc[p.layout.run(x)];
            pmin = if i == 0 {
                start(c, &mut cur, a)
            } else {
                let px = (x as isize - dx) as usize;
                step(c, &prev, pmin, p.p1, p.p2_at(x, y, px, y), &mut cur, a)
            };
            std::mem::swap(&mut prev, &mut cur);
        }
    }
}
multiversion!(horizontal => horizontal_body(p: &Problem<'_>, y: usize, from_left: bool, from_right: bool, cost: &mut [u8], acc: &mut [u16]) -> ());

/// The vertical / diagonal paths of pixels `x0..x0 + len` of row `y`: `cur` and `cur_min` hold
/// the chunk's slots of every path (`[pixel][path][d]`, `[pixel][path]`), `prev` the whole
/// previous row of every path. `cost` is the chunk's costs, `acc` its pixels' runs of `S`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn vertical_body(
    p: &Problem<'_>,
    y: usize,
    dy: isize,
    x0: usize,
    dirs: &[(isize, isize)],
    prev: &[u16],
    prev_min: &[u16],
    cost: &[u8],
    cur: &mut [u16],
    cur_min: &mut [u16],
    acc: &mut [u16],
) {
    let (w, nd, np) = (p.w, p.nd, dirs.len());
    let len = cur_min.len() / np;
    let base = p.layout.run(x0).start;
    let first_row = (dy > 0 && y == 0) || (dy < 0 && y + 1 == p.h);
    let py = (y as isize - dy) as usize;
    for i in 0..len {
        let x = x0 + i;
        let c = &cost[i * nd..(i + 1) * nd];
        let run = p.layout.run(x);
        let a = &mut acc[run.start - base..run.end - base];
        for (j, &(dx, _)) in dirs.iter().enumerate() {
            let o = &mut cur[(i * np + j) * (nd + 2)..(i * np + j + 1) * (nd + 2)];
            let px = x as isize - dx;
            cur_min[i * np + j] = if first_row || px < 0 || px >= w as isize {
                start(c, o, a)
            } else {
                let px = px as usize;
                let slot = px * np + j;
                step(
                    c,
                    &prev[slot * (nd + 2)..(slot + 1) * (nd + 2)],
                    prev_min[slot],
                    p.p1,
                    p.p2_at(x, y, px, py),
                    o,
                    a,
                )
            };
        }
    }
}
multiversion!(vertical => vertical_body(
    p: &Problem<'_>, y: usize, dy: isize, x0: usize, dirs: &[(isize, isize)], prev: &[u16],
    prev_min: &[u16], cost: &[u8], cur: &mut [u16], cur_min: &mut [u16],
    acc: &mut [u16]) -> ());

/// One sweep's state: the vertical paths' rows, interleaved per pixel.
struct Sweep {
    dirs: Vec<(isize, isize)>,
    rows: Rows,
}

/// Aggregates every path the parameters ask for; returns `S` (rows of [`Layout::row_len`]).
pub(crate) fn aggregate(p: &Problem<'_>, params: &SgmParams, kernel: Kernel) -> Result<Vec<u16>> {
    let (w, h, nd) = (p.w, p.h, p.nd);
    let row_len = p.layout.row_len();
    let mut raw = crate::volume::untouched(h * row_len)?;
    let uses = |i: usize| params.paths.uses(i);
    let (from_left, from_right) = (uses(0), uses(1));
    // The horizontal paths: every row on its own, in parallel, each row zeroed first (this
    // also spreads the volume's first touch over the workers).
    raw.par_chunks_mut(row_len).enumerate().try_for_each_init(
        || vec![0u8; w * nd],
        |cost, (y, row)| {
            check_interrupt()?;
            let row = crate::volume::zero_row(row);
            if from_left || from_right {
                horizontal(kernel, p, y, from_left, from_right, cost, row);
            }
            Ok(())
        },
    )?;
    // SAFETY: the pass above wrote every row (it returns Ok only once every row ran).
    let mut sum = unsafe { crate::volume::assume_init(raw) };
    // The paths from above, then from below: rows in order, pixels of a row in parallel.
    for (dy, dirs) in [(1isize, 2..5), (-1, 5..8)] {
        let dirs: Vec<_> = dirs.filter(|&i| uses(i)).map(|i| DIRECTIONS[i]).collect();
        if dirs.is_empty() {
            continue;
        }
        let mut sweep = Sweep {
            rows: Rows::new(w * dirs.len(), nd),
            dirs,
        };
        for i in 0..h {
            let y = if dy > 0 { i } else { h - 1 - i };
            check_interrupt()?;
            let row = &mut sum[y * row_len..(y + 1) * row_len];
            vertical_rows(kernel, p, y, dy, &mut sweep, row);
            std::mem::swap(&mut sweep.rows.prev, &mut sweep.rows.cur);
            std::mem::swap(&mut sweep.rows.prev_min, &mut sweep.rows.cur_min);
        }
    }
    Ok(sum)
}

/// The sweep's vertical paths for row `y` in parallel chunks (each computes its costs).
fn vertical_rows(
    kernel: Kernel,
    p: &Problem<'_>,
    y: usize,
    dy: isize,
    sweep: &mut Sweep,
    row: &mut [u16],
) {
    let (nd, np) = (p.nd, sweep.dirs.len());
    let dirs = &sweep.dirs;
    let r = &mut sweep.rows;
    let (prev, prev_min) = (&r.prev, &r.prev_min);
    p.layout
        .blocks(row, CHUNK)
        .into_par_iter()
        .zip(r.cur.par_chunks_mut(CHUNK * np * (nd + 2)))
        .zip(r.cur_min.par_chunks_mut(CHUNK * np))
        .enumerate()
        .for_each_init(
            || vec![0u8; CHUNK * nd],
            |scratch, (c, ((acc, cur), cur_min))| {
                let x0 = c * CHUNK;
                let len = cur_min.len() / np;
                let c = &mut scratch[..len * nd];
                costs_chunk(kernel, p, y, x0, c);
                vertical(
                    kernel, p, y, dy, x0, dirs, prev, prev_min, c, cur, cur_min, acc,
                )
            },
        );
}
