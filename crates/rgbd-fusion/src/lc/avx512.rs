//! The AVX-512 block kernel of [`lc_fuse`](super::lc_fuse): sixteen receiving pixels per step,
//! a 4 x 4 block `(y + s r, x + s c)` of the window step `s`.
//!
//! As in the AVX2 kernel ([`avx2`](super::avx2)) the lanes' windows are walked as one union
//! (row-major, so each lane meets its lenders in the portable kernel's order) and each lender's
//! hypothesis is weighed for all lanes in one vector; a square block wastes fewer lanes on the
//! union's edges than a row of receivers. Every lane keeps the portable kernel's running bin
//! sum, flushes it exactly when that kernel would, and owns its bins: the outputs are
//! bit-identical (tested in `avx2`'s tests).

use std::arch::x86_64::*;

use super::avx2::{pack, Lend};
use super::{lane_winner_and_clear, Plan, LUT_MASK, PHASES};

/// Receiver rows and columns of a block.
const R: usize = 4;
const C: usize = 4;
/// Lanes: lane `C r + c` is receiver `(r, c)`.
const LANES: usize = R * C;

/// Largest bin count: sixteen interleaved bin arrays per worker.
pub(super) const MAX_BINS: usize = 1 << 17;

pub(super) fn available() -> bool {
    std::arch::is_x86_feature_detected!("avx512f")
        && std::arch::is_x86_feature_detected!("avx512bw")
}

/// Image rows one call of [`block`] fuses: `R` rows for each of the `s` row phases.
pub(super) fn rows_per_block(st: usize) -> usize {
    R * st
}

/// Per-call tables of the block kernel.
pub(super) struct Tables {
    lend: Vec<Vec<Lend>>,
    smin: i32,
    /// Window rows / columns either side of the centre (`radius / s`).
    kk: usize,
    /// Union rows `2 kk + R` and columns `2 kk + C` of a block's windows.
    urows: usize,
    ucols: usize,
    /// Spatial weight of union cell `(jj, u)` for each lane, 0 outside the lane's window.
    sp: Vec<f32>,
    /// Lanes whose window holds union row `jj` / union column `u`.
    rowbits: Vec<u16>,
    colbits: Vec<u16>,
}

impl Tables {
    pub(super) fn new(plan: &Plan, (lend, smin): (Vec<Vec<Lend>>, i32)) -> Self {
        let st = plan.st;
        let kk = plan.radius / st;
        let (urows, ucols) = (2 * kk + R, 2 * kk + C);
        let (rad, side) = (plan.radius as isize, plan.side);
        let within = |d: isize| d.unsigned_abs() <= kk;
        let mut sp = vec![0.0f32; urows * ucols * LANES];
        let mut rowbits = vec![0u16; urows];
        let mut colbits = vec![0u16; ucols];
        for jj in 0..urows {
            for u in 0..ucols {
                for r in 0..R {
                    for c in 0..C {
                        let dr = jj as isize - kk as isize - r as isize;
                        let dc = u as isize - kk as isize - c as isize;
                        let lane = C * r + c;
                        if within(dr) {
                            rowbits[jj] |= 1 << lane;
                        }
                        if within(dc) {
                            colbits[u] |= 1 << lane;
                        }
                        if within(dr) && within(dc) {
                            let dy = (st as isize * dr + rad) as usize;
                            let dx = (st as isize * dc + rad) as usize;
                            sp[(jj * ucols + u) * LANES + lane] = plan.spatial[dy * side + dx];
                        }
                    }
                }
            }
        }
        Self {
            lend,
            smin,
            kk,
            urows,
            ucols,
            sp,
            rowbits,
            colbits,
        }
    }
}

/// Sums of absolute byte differences of the RGB pixels in each 32-bit lane (`sum_abs`).
#[target_feature(enable = "avx512f,avx512bw")]
#[inline]
fn sad(a: __m512i, b: __m512i) -> __m512i {
    let diff = _mm512_or_si512(_mm512_subs_epu8(a, b), _mm512_subs_epu8(b, a));
    let pairs = _mm512_maddubs_epi16(diff, _mm512_set1_epi8(1));
    _mm512_madd_epi16(pairs, _mm512_set1_epi16(1))
}

/// `table[idx]` per lane; every index is a channel sum `<= 765` and the tables hold 1024.
#[target_feature(enable = "avx512f,avx512bw")]
#[inline]
fn lookup(table: &[f32; LUT_MASK + 1], idx: __m512i) -> __m512 {
    // SAFETY: each lane's index is a sum of three byte differences, at most 765 < 1024.
    unsafe { _mm512_i32gather_ps::<4>(idx, table.as_ptr()) }
}

/// The lanes' bin arrays, interleaved (`acc[16 b + lane]`), with each lane's touched bins.
struct LaneBins {
    acc: Vec<f32>,
    accd: Vec<f32>,
    touched: [Vec<u32>; LANES],
}

impl LaneBins {
    /// Adds the running sums of the lanes in `bits` to their bins, as `Bins::add` does for each
    /// (a lane with both sums zero is skipped: its add would change nothing).
    #[target_feature(enable = "avx512f,avx512bw")]
    #[inline]
    fn flush(&mut self, bits: u16, rb: __m512i, rw: __m512, rwd: __m512) {
        let zero = _mm512_setzero_ps();
        let nonempty = _mm512_cmp_ps_mask::<_CMP_NEQ_UQ>(rw, zero)
            | _mm512_cmp_ps_mask::<_CMP_NEQ_UQ>(rwd, zero);
        let mut bits = bits & nonempty;
        if bits == 0 {
            return;
        }
        let mut rbs = [0i32; LANES];
        // SAFETY: `rbs` holds sixteen i32.
        unsafe { _mm512_storeu_si512(rbs.as_mut_ptr().cast(), rb) };
        while bits != 0 {
            let b = rbs[bits.trailing_zeros() as usize];
            let same = _mm512_mask_cmpeq_epi32_mask(bits, rb, _mm512_set1_epi32(b));
            let b = b as usize;
            let acc = &mut self.acc[LANES * b..LANES * (b + 1)];
            let accd = &mut self.accd[LANES * b..LANES * (b + 1)];
            // SAFETY: both slices hold sixteen f32.
            let (a, ad) = unsafe {
                (
                    _mm512_loadu_ps(acc.as_ptr()),
                    _mm512_loadu_ps(accd.as_ptr()),
                )
            };
            let fresh = _mm512_mask_cmp_ps_mask::<_CMP_EQ_OQ>(same, a, zero)
                & _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(ad, zero);
            let mut f = fresh;
            while f != 0 {
                self.touched[f.trailing_zeros() as usize].push(b as u32);
                f &= f - 1;
            }
            // SAFETY: both slices hold sixteen f32.
            unsafe {
                _mm512_storeu_ps(acc.as_mut_ptr(), _mm512_mask_add_ps(a, same, a, rw));
                _mm512_storeu_ps(accd.as_mut_ptr(), _mm512_mask_add_ps(ad, same, ad, rwd));
            }
            bits &= !same;
        }
    }

    /// Winner of lane `i` (as `Bins::winner_and_clear`), then its bins cleared.
    fn winner_and_clear(&mut self, i: usize) -> (f32, f32) {
        let touched = &mut self.touched[i];
        lane_winner_and_clear(&mut self.acc, &mut self.accd, touched, LANES, i)
    }
}

/// Slots of the per-block cache of target-side lane values, keyed by shift (direct-mapped).
const SLOTS: usize = 256;

/// What the lanes read at one shift: the target colours at `4 x_c + shift` in row `y_r` and
/// the cross-view term, 0 in lanes whose target position is outside the row or that have no
/// receiver.
#[derive(Clone, Copy, Default)]
#[repr(C, align(64))]
struct AtShift {
    t: [u32; LANES],
    lt: [f32; LANES],
}

/// A flush of the lanes in `bits`, recorded in the lender walk and replayed after it.
#[derive(Clone, Copy)]
#[repr(C, align(64))]
struct Flush {
    rb: [i32; LANES],
    rw: [f32; LANES],
    rwd: [f32; LANES],
    bits: u16,
}

impl Default for Flush {
    fn default() -> Self {
        Self {
            rb: [0; LANES],
            rw: [0.0; LANES],
            rwd: [0.0; LANES],
            bits: 0,
        }
    }
}

impl Flush {
    #[target_feature(enable = "avx512f,avx512bw")]
    #[inline]
    fn record(&mut self, bits: u16, rb: __m512i, rw: __m512, rwd: __m512) {
        // SAFETY: each array holds sixteen lanes, 64-byte aligned by the struct's layout.
        unsafe {
            _mm512_store_si512(self.rb.as_mut_ptr().cast(), rb);
            _mm512_store_ps(self.rw.as_mut_ptr(), rw);
            _mm512_store_ps(self.rwd.as_mut_ptr(), rwd);
        }
        self.bits = bits;
    }

    #[target_feature(enable = "avx512f,avx512bw")]
    #[inline]
    fn replay(&self, bins: &mut LaneBins) {
        // SAFETY: as in `record`.
        let (rb, rw, rwd) = unsafe {
            (
                _mm512_load_si512(self.rb.as_ptr().cast()),
                _mm512_load_ps(self.rw.as_ptr()),
                _mm512_load_ps(self.rwd.as_ptr()),
            )
        };
        bins.flush(self.bits, rb, rw, rwd);
    }
}

/// One worker's buffers, reused across its blocks.
pub(super) struct Scratch {
    /// The block's R target rows, each split by position modulo `p = 4 s` with C zeros either
    /// side of each part: `split[r][q * rs + C + m] = t4[y_r][q + p m]`.
    split: [Vec<u32>; R],
    /// Spatial x reference-colour weights of the block's (union cell, lane).
    base: Vec<f32>,
    bins: LaneBins,
    cache: Box<[AtShift; SLOTS]>,
    keys: Box<[(u64, u16); SLOTS]>,
    group: u64,
    events: Vec<Flush>,
}

impl Scratch {
    pub(super) fn new(plan: &Plan, tabs: &Tables) -> Self {
        let p = PHASES as usize * plan.st;
        let cells = tabs.urows * tabs.ucols;
        Self {
            split: std::array::from_fn(|_| vec![0; p * (plan.len.div_ceil(p) + 2 * C)]),
            base: vec![0.0; cells * LANES],
            bins: LaneBins {
                acc: vec![0.0; (plan.nbins + 2) * LANES],
                accd: vec![0.0; (plan.nbins + 2) * LANES],
                touched: Default::default(),
            },
            cache: Box::new([AtShift::default(); SLOTS]),
            keys: Box::new([(0, 0); SLOTS]),
            group: 0,
            events: vec![Flush::default(); cells + 1],
        }
    }
}

/// Fuses the rows `y_start..` of `d_rows` / `p_rows` (at most [`rows_per_block`] rows).
#[target_feature(enable = "avx512f,avx512bw")]
pub(super) fn block(
    plan: &Plan,
    tabs: &Tables,
    scratch: &mut Scratch,
    y_start: usize,
    d_rows: &mut [f32],
    p_rows: &mut [f32],
) {
    let (width, st) = (plan.width, plan.st);
    let n_rows = d_rows.len() / width;
    for rho in 0..st.min(n_rows) {
        // Rows rho, rho + st, ... of the chunk.
        let nr = ((n_rows - 1 - rho) / st + 1).min(R);
        rows(plan, tabs, scratch, y_start + rho, nr, |r, x, dp| {
            let i = (rho + st * r) * width + x;
            (d_rows[i], p_rows[i]) = dp;
        });
    }
}

/// Fuses the `nr` receiver rows `yb + s r` through `out(r, x, (d, p))`.
#[target_feature(enable = "avx512f,avx512bw")]
#[inline]
fn rows(
    plan: &Plan,
    tabs: &Tables,
    scratch: &mut Scratch,
    yb: usize,
    nr: usize,
    mut out: impl FnMut(usize, usize, (f32, f32)),
) {
    let (width, height, st, len) = (plan.width, plan.height, plan.st, plan.len);
    let (kk, ucols) = (tabs.kk, tabs.ucols);
    let p = PHASES as usize * st;
    let Scratch {
        split,
        base,
        bins,
        cache,
        keys,
        group,
        events,
    } = scratch;
    let rs = len.div_ceil(p) + 2 * C;
    for (r, part) in split.iter_mut().enumerate().take(nr) {
        let y = yb + st * r;
        for (k, &t) in plan.t4[y * len..(y + 1) * len].iter().enumerate() {
            part[(k % p) * rs + C + k / p] = pack(t);
        }
    }
    // Union rows jj (lender row yb + st (jj - kk)), clipped to the image.
    let jj_lo = kk - kk.min(yb / st);
    let jj_hi = (kk + (height - 1 - yb) / st).min(tabs.urows - 1);
    let yq_of = |jj: usize| yb + st * jj - st * kk;
    let row_exists: u16 = (0..nr).fold(0, |m, r| m | (0xf << (C * r)));
    let pi = p as i32;
    // Lane C r + c sits p c quarter pixels right of lane C r.
    let lanes_p = _mm512_mullo_epi32(
        _mm512_setr_epi32(0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3, 0, 1, 2, 3),
        _mm512_set1_epi32(pi),
    );
    let len_v = _mm512_set1_epi32(len as i32);
    let zero_i = _mm512_setzero_si512();
    let refc = &plan.refc;
    for rho in 0..st.min(width) {
        // Receiver columns rho, rho + st, ...: groups of C.
        let count = (width - 1 - rho) / st + 1;
        for g in 0..count.div_ceil(C) {
            *group += 1;
            let x0 = rho + st * C * g;
            let nc = (count - C * g).min(C);
            let col_exists: u16 = 0x1111 * ((1u16 << nc) - 1);
            let exists = row_exists & col_exists;
            let mut cpa = [0u32; LANES];
            for r in 0..nr {
                for c in 0..nc {
                    cpa[C * r + c] = pack(refc[(yb + st * r) * width + x0 + st * c]);
                }
            }
            // SAFETY: `cpa` holds sixteen u32.
            let cp = unsafe { _mm512_loadu_si512(cpa.as_ptr().cast()) };
            let u_lo = kk - kk.min(x0 / st);
            let u_hi = (kk + (width - 1 - x0) / st).min(ucols - 1);
            let xq_of = |u: usize| x0 + st * u - st * kk;
            for jj in jj_lo..=jj_hi {
                let yq = yq_of(jj);
                let cells = (jj * ucols) * LANES..(jj * ucols + ucols) * LANES;
                let (sp, brow) = (&tabs.sp[cells.clone()], &mut base[cells]);
                for u in u_lo..=u_hi {
                    let cq = _mm512_set1_epi32(pack(refc[yq * width + xq_of(u)]) as i32);
                    let col = lookup(&plan.lut_c, sad(cp, cq));
                    let s16 = &sp[u * LANES..(u + 1) * LANES];
                    let b16 = &mut brow[u * LANES..(u + 1) * LANES];
                    // SAFETY: both slices hold sixteen f32.
                    unsafe {
                        _mm512_storeu_ps(
                            b16.as_mut_ptr(),
                            _mm512_mul_ps(_mm512_loadu_ps(s16.as_ptr()), col),
                        )
                    };
                }
            }
            // Fills the cache slot of shift index `sidx` for this block; returns the lanes'
            // validity bits.
            let fill = |sidx: u32, slot: &mut AtShift| -> u16 {
                // Column 0's target position; column c's is p c further.
                let k0 = 4 * x0 as i32 + tabs.smin + sidx as i32;
                let kv = _mm512_add_epi32(_mm512_set1_epi32(k0), lanes_p);
                let bits = _mm512_mask_cmpge_epi32_mask(exists, kv, zero_i)
                    & _mm512_cmplt_epi32_mask(kv, len_v);
                let mut t = _mm512_setzero_si512();
                if bits != 0 {
                    // A valid lane has 0 <= m0 + c < mcount: the loads stay inside the
                    // parts' C-wide margins.
                    let (m0, q) = (k0.div_euclid(pi), k0.rem_euclid(pi));
                    let at = q as usize * rs + (C as i32 + m0) as usize;
                    let four = |r: usize| {
                        let s = &split[r][at..at + C];
                        // SAFETY: `s` holds four u32.
                        unsafe { _mm_loadu_si128(s.as_ptr().cast()) }
                    };
                    t = _mm512_inserti32x4::<1>(t, four(1));
                    t = _mm512_inserti32x4::<2>(t, four(2));
                    t = _mm512_inserti32x4::<3>(t, four(3));
                    t = _mm512_inserti32x4::<0>(t, four(0));
                }
                let lt = _mm512_maskz_mov_ps(bits, lookup(&plan.lut_t, sad(cp, t)));
                // SAFETY: the slot holds sixteen u32 and sixteen f32.
                unsafe {
                    _mm512_storeu_si512(slot.t.as_mut_ptr().cast(), t);
                    _mm512_storeu_ps(slot.lt.as_mut_ptr(), lt);
                }
                bits
            };
            for lend in &tabs.lend {
                let mut rb = _mm512_setzero_si512();
                let (mut rw, mut rwd) = (_mm512_setzero_ps(), _mm512_setzero_ps());
                let mut n_events = 0;
                for jj in jj_lo..=jj_hi {
                    let yq = yq_of(jj);
                    let lenders = lend[yq * width + xq_of(u_lo)..=yq * width + xq_of(u_hi)]
                        .iter()
                        .step_by(st);
                    let brow = &base[(jj * ucols + u_lo) * LANES..(jj * ucols + u_hi + 1) * LANES];
                    let rbits = tabs.rowbits[jj];
                    for ((h, bw), &cols) in lenders
                        .zip(brow.chunks_exact(LANES))
                        .zip(&tabs.colbits[u_lo..=u_hi])
                    {
                        if !(h.w > 0.0) {
                            continue;
                        }
                        let slot = h.sidx as usize % SLOTS;
                        let key = *group << 32 | u64::from(h.sidx);
                        if keys[slot].0 != key {
                            keys[slot] = (key, fill(h.sidx, &mut cache[slot]));
                        }
                        let bits = keys[slot].1 & cols & rbits;
                        if bits == 0 {
                            continue;
                        }
                        let at = &cache[slot];
                        // SAFETY: the slot holds sixteen u32 and sixteen f32 (64-byte
                        // aligned), `bw` sixteen f32.
                        let (t16, lt, bw) = unsafe {
                            (
                                _mm512_load_si512(at.t.as_ptr().cast()),
                                _mm512_load_ps(at.lt.as_ptr()),
                                _mm512_loadu_ps(bw.as_ptr()),
                            )
                        };
                        let lc = lookup(&plan.lut_c, sad(t16, _mm512_set1_epi32(h.col as i32)));
                        let v = _mm512_mul_ps(
                            _mm512_mul_ps(_mm512_mul_ps(bw, _mm512_set1_ps(h.w)), lc),
                            lt,
                        );
                        let bin = _mm512_set1_epi32(h.bin);
                        let change = _mm512_mask_cmpneq_epi32_mask(bits, rb, bin);
                        if change != 0 {
                            events[n_events].record(change, rb, rw, rwd);
                            n_events += 1;
                            rb = _mm512_mask_mov_epi32(rb, change, bin);
                            rw = _mm512_maskz_mov_ps(!change, rw);
                            rwd = _mm512_maskz_mov_ps(!change, rwd);
                        }
                        rw = _mm512_mask_add_ps(rw, bits, rw, v);
                        rwd = _mm512_mask_add_ps(
                            rwd,
                            bits,
                            rwd,
                            _mm512_mul_ps(v, _mm512_set1_ps(h.d)),
                        );
                    }
                }
                events[n_events].record(0xffff, rb, rw, rwd);
                for e in &events[..=n_events] {
                    e.replay(bins);
                }
            }
            for r in 0..nr {
                for c in 0..nc {
                    out(r, x0 + st * c, bins.winner_and_clear(C * r + c));
                }
            }
        }
    }
}
