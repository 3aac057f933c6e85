//! The AVX2 row kernel of [`lc_fuse`](super::lc_fuse): eight receiving pixels of one row,
//! `x, x + s, ..., x + 7 s` for the window step `s`, per step.
//!
//! The eight windows overlap, so the kernel walks their union once: each lending pixel's
//! hypothesis is loaded once and weighed for all eight receivers in one vector, and lanes whose
//! window misses the lender are masked. The receivers' target positions `4 x_i + shift` are
//! `4 s` quarter pixels apart, so a per-row copy of the quarter-pixel target row split by
//! position modulo `4 s` makes their eight colours one unaligned load; the two colour terms are
//! table gathers; the spatial x reference-colour weight of each (lender, lane) pair is computed
//! once and shared by the sources.
//!
//! Every lane keeps the portable kernel's own running bin sum and flushes it exactly when that
//! kernel would (a masked lane neither adds nor flushes), and a lane's bins are its own: each
//! pixel sees the same float operations in the same order, so the outputs are bit-identical to
//! the portable kernel's (tested below on random inputs).

use std::arch::x86_64::*;

use rayon::prelude::*;

use super::{lane_winner_and_clear, span, HypCtx, Plan, Source, PHASES};

/// Receiving pixels per step.
const LANES: usize = 8;

/// Largest bin count this kernel takes: it keeps eight interleaved bin arrays per worker
/// (16 MiB for both sums at this size); above it the portable kernel runs.
pub(super) const MAX_BINS: usize = 1 << 18;

pub(super) fn available() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
}

/// A hypothesis in the form the lane loops read (this kernel's and the AVX-512 one's).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct Lend {
    /// Quarter-pixel shift minus the smallest one ([`Tables::smin`]).
    pub(super) sidx: u32,
    pub(super) bin: i32,
    pub(super) d: f32,
    /// Confidence; 0 marks "no hypothesis".
    pub(super) w: f32,
    /// Target colour at the lender's own target position, RGB in the low three bytes.
    pub(super) col: u32,
}

/// Per-call tables of the AVX2 kernel.
pub(super) struct Tables {
    /// Per source, per pixel.
    lend: Vec<Vec<Lend>>,
    /// Smallest quarter-pixel shift of any hypothesis.
    smin: i32,
    /// Window rows / columns either side of the centre (`radius / s`).
    kk: usize,
    /// Union columns of the eight windows: `2 kk + 8`.
    ucols: usize,
    /// Spatial weight of window row `jj` (0..=2kk) and union column `u` (0..ucols, lender at
    /// `x_0 + s (u - kk)`) for each lane, 0 where the lane's window misses the column.
    sp8: Vec<f32>,
    /// Per union column: bit i set when lane i's window holds it.
    colbits: Vec<i32>,
}

pub(super) fn pack(c: [u8; 3]) -> u32 {
    u32::from_le_bytes([c[0], c[1], c[2], 0])
}

/// The sources' hypotheses ([`HypCtx::hyp`] of each of the `n` pixels) as [`Lend`]s, and the
/// smallest quarter-pixel shift they index from.
pub(super) fn lenders(ctx: &HypCtx<'_>, sources: &[Source<'_>], n: usize) -> (Vec<Vec<Lend>>, i32) {
    let smin = sources
        .iter()
        .filter_map(|s| {
            (0..n)
                .into_par_iter()
                .filter_map(|i| ctx.hyp(s, i).map(|h| h.shift))
                .min()
        })
        .min()
        .unwrap_or(0);
    let lend = sources
        .iter()
        .map(|s| {
            (0..n)
                .into_par_iter()
                .map(|i| match ctx.hyp(s, i) {
                    Some(h) => Lend {
                        sidx: h.shift.abs_diff(smin),
                        bin: h.bin as i32,
                        d: h.d,
                        w: h.w,
                        col: pack(h.col),
                    },
                    None => Lend::default(),
                })
                .collect()
        })
        .collect();
    (lend, smin)
}

impl Tables {
    pub(super) fn new(plan: &Plan, (lend, smin): (Vec<Vec<Lend>>, i32)) -> Self {
        let st = plan.st;
        let kk = plan.radius / st;
        let ucols = 2 * kk + LANES;
        let (r, side) = (plan.radius as isize, plan.side);
        let mut sp8 = vec![0.0f32; (2 * kk + 1) * ucols * LANES];
        let mut colbits = vec![0i32; ucols];
        for u in 0..ucols {
            for i in 0..LANES {
                let dm = u as isize - kk as isize - i as isize;
                if dm.unsigned_abs() > kk {
                    continue;
                }
                colbits[u] |= 1 << i;
                let dx = (st as isize * dm + r) as usize;
                for jj in 0..=2 * kk {
                    let dy = (st as isize * (jj as isize - kk as isize) + r) as usize;
                    sp8[(jj * ucols + u) * LANES + i] = plan.spatial[dy * side + dx];
                }
            }
        }
        Self {
            lend,
            smin,
            kk,
            ucols,
            sp8,
            colbits,
        }
    }
}

/// Sums of absolute byte differences of the RGB pixels in each 32-bit lane (`sum_abs`).
#[target_feature(enable = "avx2")]
#[inline]
fn sad(a: __m256i, b: __m256i) -> __m256i {
    let diff = _mm256_or_si256(_mm256_subs_epu8(a, b), _mm256_subs_epu8(b, a));
    let pairs = _mm256_maddubs_epi16(diff, _mm256_set1_epi8(1));
    _mm256_madd_epi16(pairs, _mm256_set1_epi16(1))
}

/// `table[idx]` per lane; every index is a channel sum `<= 765` and the tables hold 1024.
#[target_feature(enable = "avx2")]
#[inline]
fn lookup(table: &[f32; super::LUT_MASK + 1], idx: __m256i) -> __m256 {
    // SAFETY: each lane's index is a sum of three byte differences, at most 765 < 1024.
    unsafe { _mm256_i32gather_ps::<4>(table.as_ptr(), idx) }
}

/// Lane mask (all ones / zero) of the low eight bits of `bits`.
#[target_feature(enable = "avx2")]
#[inline]
fn mask_of(bits: i32) -> __m256 {
    let lane_bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
    let m = _mm256_and_si256(_mm256_set1_epi32(bits), lane_bit);
    _mm256_castsi256_ps(_mm256_cmpeq_epi32(m, lane_bit))
}

/// The eight lanes' bin arrays, interleaved (`acc[8 b + lane]`), with each lane's touched bins.
struct LaneBins {
    acc: Vec<f32>,
    accd: Vec<f32>,
    touched: [Vec<u32>; LANES],
}

impl LaneBins {
    /// Adds the running sums of the lanes in `bits` to their bins, as `Bins::add` does for each
    /// (a lane with both sums zero is skipped: its add would change nothing).
    #[target_feature(enable = "avx2")]
    #[inline]
    fn flush(&mut self, bits: i32, rb: __m256i, rw: __m256, rwd: __m256) {
        let zero = _mm256_setzero_ps();
        let empty = _mm256_and_ps(
            _mm256_cmp_ps::<_CMP_EQ_OQ>(rw, zero),
            _mm256_cmp_ps::<_CMP_EQ_OQ>(rwd, zero),
        );
        let mut bits = bits & !_mm256_movemask_ps(empty);
        if bits == 0 {
            return;
        }
        let mut rbs = [0i32; LANES];
        // SAFETY: `rbs` holds eight i32.
        unsafe { _mm256_storeu_si256(rbs.as_mut_ptr().cast(), rb) };
        while bits != 0 {
            let b = rbs[bits.trailing_zeros() as usize];
            let same = bits
                & _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(
                    rb,
                    _mm256_set1_epi32(b),
                )));
            let sel = mask_of(same);
            let b = b as usize;
            let acc = &mut self.acc[LANES * b..LANES * (b + 1)];
            let accd = &mut self.accd[LANES * b..LANES * (b + 1)];
            // SAFETY: both slices hold eight f32.
            let (a, ad) = unsafe {
                (
                    _mm256_loadu_ps(acc.as_ptr()),
                    _mm256_loadu_ps(accd.as_ptr()),
                )
            };
            let fresh = same
                & _mm256_movemask_ps(_mm256_and_ps(
                    _mm256_cmp_ps::<_CMP_EQ_OQ>(a, zero),
                    _mm256_cmp_ps::<_CMP_EQ_OQ>(ad, zero),
                ));
            let mut f = fresh;
            while f != 0 {
                self.touched[f.trailing_zeros() as usize].push(b as u32);
                f &= f - 1;
            }
            // Lanes outside `sel` add +0: their values are unchanged (no sum here is -0).
            // SAFETY: both slices hold eight f32.
            unsafe {
                _mm256_storeu_ps(acc.as_mut_ptr(), _mm256_add_ps(a, _mm256_and_ps(rw, sel)));
                _mm256_storeu_ps(
                    accd.as_mut_ptr(),
                    _mm256_add_ps(ad, _mm256_and_ps(rwd, sel)),
                );
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

/// Slots of the per-group cache of target-side lane values, keyed by shift (direct-mapped: two
/// shifts of one window 128 pixels of disparity apart share a slot and recompute, nothing
/// worse). 512 x 64 bytes stays in L1.
const SLOTS: usize = 512;

/// What the eight lanes read at one shift: the target colours at `4 x_i + shift` and the
/// cross-view term `e^{-Δ(p_i, p_i T)/γt}`, 0 in lanes whose target position is outside the
/// row or that have no receiver (their weights vanish with it).
#[derive(Clone, Copy, Default)]
#[repr(C, align(64))]
struct AtShift {
    t: [u32; LANES],
    lt: [f32; LANES],
}

/// A flush of the lanes in `bits` (their running sums `rw`, `rwd` into their bins `rb`),
/// recorded in the lender loop and replayed after it.
#[derive(Clone, Copy, Default)]
#[repr(C, align(32))]
struct Flush {
    rb: [i32; LANES],
    rw: [f32; LANES],
    rwd: [f32; LANES],
    bits: i32,
}

impl Flush {
    #[target_feature(enable = "avx2")]
    #[inline]
    fn record(&mut self, bits: i32, rb: __m256i, rw: __m256, rwd: __m256) {
        // SAFETY: each array holds eight lanes, 32-byte aligned by the struct's layout.
        unsafe {
            _mm256_store_si256(self.rb.as_mut_ptr().cast(), rb);
            _mm256_store_ps(self.rw.as_mut_ptr(), rw);
            _mm256_store_ps(self.rwd.as_mut_ptr(), rwd);
        }
        self.bits = bits;
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    fn replay(&self, bins: &mut LaneBins) {
        // SAFETY: as in `record`.
        let (rb, rw, rwd) = unsafe {
            (
                _mm256_load_si256(self.rb.as_ptr().cast()),
                _mm256_load_ps(self.rw.as_ptr()),
                _mm256_load_ps(self.rwd.as_ptr()),
            )
        };
        bins.flush(self.bits, rb, rw, rwd);
    }
}

/// One worker's buffers, reused across its rows.
pub(super) struct Scratch {
    /// The target row split by position modulo `p = 4 s`, LANES zeros either side of each
    /// part: `split[r * rs + LANES + m] = t4[y][r + p m]` (positions past the row stay 0).
    split: Vec<u32>,
    /// Spatial x reference-colour weights of the group's (window row, union column, lane).
    base: Vec<f32>,
    bins: LaneBins,
    /// Cache slots and their keys (group number << 32 | shift index, with the lanes' validity
    /// bits); group numbers start at 1 and never repeat, so no key matches a stale slot.
    cache: Box<[AtShift; SLOTS]>,
    keys: Box<[(u64, i32); SLOTS]>,
    group: u64,
    /// At most one flush per lender of a pass, and the final one.
    events: Vec<Flush>,
}

impl Scratch {
    pub(super) fn new(plan: &Plan, tabs: &Tables) -> Self {
        let p = PHASES as usize * plan.st;
        let rows = 2 * tabs.kk + 1;
        Self {
            split: vec![0; p * (plan.len.div_ceil(p) + 2 * LANES)],
            base: vec![0.0; rows * tabs.ucols * LANES],
            bins: LaneBins {
                acc: vec![0.0; (plan.nbins + 2) * LANES],
                accd: vec![0.0; (plan.nbins + 2) * LANES],
                touched: Default::default(),
            },
            cache: Box::new([AtShift::default(); SLOTS]),
            keys: Box::new([(0, 0); SLOTS]),
            group: 0,
            events: vec![Flush::default(); rows * tabs.ucols + 1],
        }
    }
}

/// Fuses row `y` (the portable kernel's `row_scalar`, eight receivers per step).
#[target_feature(enable = "avx2")]
pub(super) fn row(
    plan: &Plan,
    tabs: &Tables,
    scratch: &mut Scratch,
    y: usize,
    d_row: &mut [f32],
    p_row: &mut [f32],
) {
    let (width, st, len) = (plan.width, plan.st, plan.len);
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
    let rs = len.div_ceil(p) + 2 * LANES;
    for (k, &t) in plan.t4[y * len..(y + 1) * len].iter().enumerate() {
        split[(k % p) * rs + LANES + k / p] = pack(t);
    }
    let (y0, y1) = span(y, plan.radius, st, plan.height);
    let nrows = (y1 - y0) / st + 1;
    // sp8 row of y0.
    let jj0 = kk - (y - y0) / st;
    let pi = p as i32;
    let lanes_p = _mm256_mullo_epi32(
        _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
        _mm256_set1_epi32(pi),
    );
    let len_v = _mm256_set1_epi32(len as i32);
    let minus_one = _mm256_set1_epi32(-1);
    let refc = &plan.refc;
    for rho in 0..st.min(width) {
        // Receivers rho, rho + st, ...: groups of LANES.
        let count = (width - 1 - rho) / st + 1;
        for g in 0..count.div_ceil(LANES) {
            *group += 1;
            let x0 = rho + st * LANES * g;
            let n_lanes = (count - LANES * g).min(LANES);
            let exists = (1i32 << n_lanes) - 1;
            let mut cpa = [0u32; LANES];
            for (i, c) in cpa.iter_mut().enumerate().take(n_lanes) {
                *c = pack(refc[y * width + x0 + st * i]);
            }
            // SAFETY: `cpa` holds eight u32.
            let cp8 = unsafe { _mm256_loadu_si256(cpa.as_ptr().cast()) };
            // Union columns u in u_lo..=u_hi (lender x0 + st (u - kk)), clipped to the image.
            let u_lo = kk - kk.min(x0 / st);
            let u_hi = (kk + (width - 1 - x0) / st).min(ucols - 1);
            let xq_of = |u: usize| x0 + st * u - st * kk;
            for j in 0..nrows {
                let yq = y0 + st * j;
                let sp = &tabs.sp8[(jj0 + j) * ucols * LANES..(jj0 + j + 1) * ucols * LANES];
                let brow = &mut base[j * ucols * LANES..(j + 1) * ucols * LANES];
                for u in u_lo..=u_hi {
                    let cq = _mm256_set1_epi32(pack(refc[yq * width + xq_of(u)]) as i32);
                    let col = lookup(&plan.lut_c, sad(cp8, cq));
                    let s8 = &sp[u * LANES..(u + 1) * LANES];
                    let b8 = &mut brow[u * LANES..(u + 1) * LANES];
                    // SAFETY: both slices hold eight f32.
                    unsafe {
                        _mm256_storeu_ps(
                            b8.as_mut_ptr(),
                            _mm256_mul_ps(_mm256_loadu_ps(s8.as_ptr()), col),
                        )
                    };
                }
            }
            // Fills the cache slot of shift index `sidx` for this group; returns the lanes'
            // validity bits.
            let fill = |sidx: u32, slot: &mut AtShift| -> i32 {
                // Lane 0's target position; lane i's is p i further.
                let k0 = 4 * x0 as i32 + tabs.smin + sidx as i32;
                let kv = _mm256_add_epi32(_mm256_set1_epi32(k0), lanes_p);
                let inside = _mm256_and_si256(
                    _mm256_cmpgt_epi32(kv, minus_one),
                    _mm256_cmpgt_epi32(len_v, kv),
                );
                let bits = exists & _mm256_movemask_ps(_mm256_castsi256_ps(inside));
                if bits == 0 {
                    return 0;
                }
                // A valid lane i has 0 <= m0 + i < mcount, so the load stays inside the
                // part's LANES-wide margins.
                let (m0, r4) = (k0.div_euclid(pi), k0.rem_euclid(pi));
                let at = r4 as usize * rs + (LANES as i32 + m0) as usize;
                let s = &split[at..at + LANES];
                // SAFETY: `s` holds eight u32.
                let t8 = unsafe { _mm256_loadu_si256(s.as_ptr().cast()) };
                let lt = _mm256_and_ps(lookup(&plan.lut_t, sad(cp8, t8)), mask_of(bits));
                // SAFETY: the slot holds eight u32 and eight f32.
                unsafe {
                    _mm256_storeu_si256(slot.t.as_mut_ptr().cast(), t8);
                    _mm256_storeu_ps(slot.lt.as_mut_ptr(), lt);
                }
                bits
            };
            for lend in &tabs.lend {
                let mut rb = _mm256_setzero_si256();
                let (mut rw, mut rwd) = (_mm256_setzero_ps(), _mm256_setzero_ps());
                // Flushes are recorded and replayed after the pass (in order, so each lane's
                // bins see the same adds): no call in the loop keeps the sums in registers.
                let mut n_events = 0;
                for j in 0..nrows {
                    let yq = y0 + st * j;
                    let lenders = lend[yq * width + xq_of(u_lo)..=yq * width + xq_of(u_hi)]
                        .iter()
                        .step_by(st);
                    let brow = &base[(j * ucols + u_lo) * LANES..(j * ucols + u_hi + 1) * LANES];
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
                        // Lanes whose window holds the lender and whose target position is
                        // in the row; the others get v = 0 (their lt or spatial weight is 0).
                        let bits = keys[slot].1 & cols;
                        if bits == 0 {
                            continue;
                        }
                        let at = &cache[slot];
                        // SAFETY: the slot holds eight u32 and eight f32 (64-byte aligned),
                        // `bw` eight f32.
                        let (t8, lt, bw) = unsafe {
                            (
                                _mm256_load_si256(at.t.as_ptr().cast()),
                                _mm256_load_ps(at.lt.as_ptr()),
                                _mm256_loadu_ps(bw.as_ptr()),
                            )
                        };
                        let lc = lookup(&plan.lut_c, sad(t8, _mm256_set1_epi32(h.col as i32)));
                        let v = _mm256_mul_ps(
                            _mm256_mul_ps(_mm256_mul_ps(bw, _mm256_set1_ps(h.w)), lc),
                            lt,
                        );
                        let bin = _mm256_set1_epi32(h.bin);
                        let same = _mm256_castsi256_ps(_mm256_cmpeq_epi32(rb, bin));
                        let change = bits & !_mm256_movemask_ps(same);
                        if change != 0 {
                            events[n_events].record(change, rb, rw, rwd);
                            n_events += 1;
                            let sel = mask_of(change);
                            rb = _mm256_castps_si256(_mm256_blendv_ps(
                                _mm256_castsi256_ps(rb),
                                _mm256_castsi256_ps(bin),
                                sel,
                            ));
                            rw = _mm256_andnot_ps(sel, rw);
                            rwd = _mm256_andnot_ps(sel, rwd);
                        }
                        rw = _mm256_add_ps(rw, v);
                        rwd = _mm256_add_ps(rwd, _mm256_mul_ps(v, _mm256_set1_ps(h.d)));
                    }
                }
                events[n_events].record(0xff, rb, rw, rwd);
                for e in &events[..=n_events] {
                    e.replay(bins);
                }
            }
            for i in 0..n_lanes {
                let x = x0 + st * i;
                (d_row[x], p_row[x]) = bins.winner_and_clear(i);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::{fuse_with, Kernel, LcParams, Source};
    use proptest::prelude::*;

    /// The SIMD kernels this CPU runs.
    pub(super) fn simd_kernels() -> Vec<Kernel> {
        let mut out = vec![];
        if super::available() {
            out.push(Kernel::Avx2);
        }
        if super::super::avx512::available() {
            out.push(Kernel::Avx512);
        }
        out
    }

    /// The portable kernel and each SIMD one on one input: the outputs must be identical bit for
    /// bit. Returns how many pixels received a disparity.
    fn same_bits(w: usize, h: usize, seed: u64, p: &LcParams, two: bool, sparse: u64) -> usize {
        let mut state = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let mut next = move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as u32
        };
        let r: Vec<u8> = (0..w * h * 3).map(|_| (next() % 256) as u8).collect();
        let t: Vec<u8> = (0..w * h * 3).map(|_| (next() % 256) as u8).collect();
        let mut map = |scale: f32| -> (Vec<f32>, Vec<f32>) {
            let d = (0..w * h)
                .map(|i| {
                    if u64::from(next() % 100) < sparse {
                        f32::NAN
                    } else {
                        // A smooth ramp plus noise: runs of equal bins with changes.
                        (i % w) as f32 * 0.05 + scale * (next() % 1000) as f32 / 1000.0 - 1.0
                    }
                })
                .collect();
            let c = (0..w * h)
                .map(|_| match next() % 10 {
                    0 => 0.0,
                    1 => f32::NAN,
                    _ => (next() % 1000) as f32 / 999.0,
                })
                .collect();
            (d, c)
        };
        let (d1, c1) = map(3.0);
        let (d2, c2) = map(12.0);
        let mut sources = vec![Source {
            disparity: &d1,
            confidence: Some(&c1),
        }];
        if two {
            sources.push(Source {
                disparity: &d2,
                confidence: None,
            });
            sources.push(Source {
                disparity: &d2,
                confidence: Some(&c2),
            });
        }
        let a = fuse_with(&r, &t, w, h, &sources, p, Some(Kernel::Scalar)).unwrap();
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for k in simd_kernels() {
            let b = fuse_with(&r, &t, w, h, &sources, p, Some(k)).unwrap();
            assert_eq!(bits(&a.disparity), bits(&b.disparity), "{k:?} disparity");
            assert_eq!(
                bits(&a.plausibility),
                bits(&b.plausibility),
                "{k:?} plausibility"
            );
        }
        a.disparity.iter().filter(|d| d.is_finite()).count()
    }

    #[test]
    fn a_narrow_ramp_with_fine_bins_does_not_index_past_its_histogram() {
        // proptest's minimal failing input (index 26 of a 26-bin histogram, in CI).
        let p = LcParams {
            radius: 1,
            stride: 1,
            bin_width: 0.25,
            target_sign: -1,
            ..LcParams::default()
        };
        same_bits(68, 3, 625, &p, false, 8);
    }

    #[test]
    fn defaults_at_the_fuse_window_are_bit_identical() {
        for stride in [1, 2] {
            let p = LcParams {
                stride,
                ..LcParams::default()
            };
            assert!(same_bits(83, 31, 7, &p, true, 10) > 83 * 31 / 2);
        }
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(48))]
        #[test]
        fn simd_kernels_are_bit_identical_to_the_portable_one(
            w in 2usize..70,
            h in 1usize..12,
            radius in 1usize..7,
            stride in 1usize..5,
            sign in prop::bool::ANY,
            bin_width in prop::sample::select(vec![0.25f32, 1.0, 3.0]),
            two in prop::bool::ANY,
            sparse in 0u64..60,
            seed in 0u64..1000,
        ) {
            let p = LcParams {
                radius,
                stride,
                bin_width,
                target_sign: if sign { 1 } else { -1 },
                ..LcParams::default()
            };
            same_bits(w, h, seed, &p, two, sparse);
        }
    }
}

/// Timing of both kernels on a dumped real `fuse()` input (not a test: run by hand with
/// `LC_INPUT=dir cargo test --release -p rgbd-fusion --lib real_input -- --ignored --nocapture`;
/// `dir` holds `right.raw`, `left.raw` (960x540x3 u8), `d0/d1/ct/cs.raw` (f32 maps) and
/// optionally `orig_s{1,2}_{d,p}.raw`, the outputs of an older kernel to compare with).
#[cfg(test)]
mod timing {
    use super::super::{fuse_with, span, Kernel, LcParams, Source, PHASES};
    use std::time::Instant;

    fn cpu_seconds() -> f64 {
        let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
        let after = stat.rsplit(')').next().unwrap_or("");
        let f: Vec<f64> = after
            .split_whitespace()
            .map(|s| s.parse().unwrap_or(0.0))
            .collect();
        // utime and stime, fields 14 and 15 (clock ticks, 100 per second here).
        (f.get(11).unwrap_or(&0.0) + f.get(12).unwrap_or(&0.0)) / 100.0
    }

    fn read_f32(path: &std::path::Path) -> Option<Vec<f32>> {
        let b = std::fs::read(path).ok()?;
        Some(
            b.chunks_exact(4)
                .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect(),
        )
    }

    #[test]
    #[ignore = "needs LC_INPUT; a measurement, not a test"]
    fn real_input() {
        let Ok(dir) = std::env::var("LC_INPUT") else {
            return;
        };
        let dir = std::path::Path::new(&dir);
        let (w, h) = (960, 540);
        let r = std::fs::read(dir.join("right.raw")).unwrap();
        let t = std::fs::read(dir.join("left.raw")).unwrap();
        let m = |n: &str| read_f32(&dir.join(format!("{n}.raw"))).unwrap();
        let (d0, d1, c0, c1) = (m("d0"), m("d1"), m("ct"), m("cs"));
        let sources = [
            Source {
                disparity: &d0,
                confidence: Some(&c0),
            },
            Source {
                disparity: &d1,
                confidence: Some(&c1),
            },
        ];
        let reps: usize = std::env::var("LC_REPS")
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(3);
        for stride in [2, 1] {
            let p = LcParams {
                stride,
                ..LcParams::default()
            };
            // Hypotheses the kernels weigh (a lender with a hypothesis whose target position
            // at the receiver lies in the row).
            let (st, len) = (p.effective_stride(), PHASES * (w as i64 - 1) + 1);
            let mut pairs = 0u64;
            for s in &sources {
                for y in 0..h {
                    let (y0, y1) = span(y, p.radius, st, h);
                    for x in 0..w {
                        let (x0, x1) = span(x, p.radius, st, w);
                        for yq in (y0..=y1).step_by(st) {
                            for xq in (x0..=x1).step_by(st) {
                                let i = yq * w + xq;
                                let (d, c) = (s.disparity[i], s.confidence.unwrap()[i]);
                                if !d.is_finite() || !(c > 0.0) {
                                    continue;
                                }
                                let shift = (PHASES as f32 * d).round() as i64;
                                let own = PHASES * xq as i64 + shift;
                                let at = PHASES * x as i64 + shift;
                                if (0..len).contains(&own) && (0..len).contains(&at) {
                                    pairs += 1;
                                }
                            }
                        }
                    }
                }
            }
            let mut outs = vec![];
            // LC_SIMD_ONLY=1 skips the portable kernel (A/B runs of the SIMD ones).
            let mut kernels = super::tests::simd_kernels();
            if std::env::var("LC_SIMD_ONLY").is_err() {
                kernels.insert(0, Kernel::Scalar);
            }
            // Rounds interleave the kernels, so a change of load hits them alike.
            let mut best = vec![(f64::INFINITY, 0.0); kernels.len()];
            let mut cpu_sum = vec![0.0; kernels.len()];
            for round in 0..reps {
                for (k, &kernel) in kernels.iter().enumerate() {
                    let (t0, c0) = (Instant::now(), cpu_seconds());
                    let out = fuse_with(&r, &t, w, h, &sources, &p, Some(kernel)).unwrap();
                    let run = (t0.elapsed().as_secs_f64(), cpu_seconds() - c0);
                    cpu_sum[k] += run.1;
                    if run.0 < best[k].0 {
                        best[k] = run;
                    }
                    if round == 0 {
                        outs.push(out);
                    }
                }
            }
            for (k, kernel) in kernels.iter().enumerate() {
                println!(
                    "stride {stride} {kernel:?}: wall {:.0} ms, CPU {:.0} ms (the run of best wall \
                     of {reps}; mean CPU {:.0} ms), {:.1} M pairs, {:.2} ns CPU per pair",
                    best[k].0 * 1e3,
                    best[k].1 * 1e3,
                    cpu_sum[k] / reps as f64 * 1e3,
                    pairs as f64 / 1e6,
                    best[k].1 * 1e9 / pairs as f64
                );
            }
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            let last = outs.len() - 1;
            let same = outs.iter().all(|o| {
                bits(&outs[0].disparity) == bits(&o.disparity)
                    && bits(&outs[0].plausibility) == bits(&o.plausibility)
            });
            println!("stride {stride}: kernels bit-identical: {same}");
            for (name, new) in [
                ("d", &outs[last].disparity),
                ("p", &outs[last].plausibility),
            ] {
                if let Some(old) = read_f32(&dir.join(format!("orig_s{stride}_{name}.raw"))) {
                    let nan_same = old.iter().zip(new).all(|(a, b)| a.is_nan() == b.is_nan());
                    let diff = old
                        .iter()
                        .zip(new)
                        .filter(|(a, b)| a.is_finite() && b.is_finite())
                        .map(|(a, b)| (a - b).abs())
                        .fold(0.0f32, f32::max);
                    println!(
                        "stride {stride} {name}: max |new - original| {diff:e}, NaN pattern same: \
                         {nan_same}"
                    );
                }
            }
        }
    }
}
