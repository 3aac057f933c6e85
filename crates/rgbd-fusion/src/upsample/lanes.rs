//! The upsampling filter without segment labels, [`LANES`] output pixels of a row at a time:
//! every ToF sample within the radius of any of them is visited once and weighted for all of
//! them in vector lanes (a lane outside the sample's window gets weight 0 there, which adds an
//! exact +0 to its sums). Each lane therefore sums its own samples in the order the one-pixel
//! filter does, with the same f32 operations: the same bits, on every instruction set. The
//! loops are compiled for AVX-512, AVX2 and the baseline and chosen at run time.

use super::{estimate, first_from, Ctx, Sums};
use crate::color::MAX_SUM;

/// Output pixels filtered together.
pub(super) const LANES: usize = 16;

/// Per window row `dy`, the spatial weights laid out so that the sample at column offset
/// `t.x - x0` from the block's first pixel reads its weights for lanes `0..LANES` as one
/// reversed run: entry `LANES - 1 + (dx + r)` holds `Gs(dx, dy)` for `|dx| <= r`, 0 elsewhere.
pub(super) fn padded_spatial(spatial: &[f32], side: usize) -> Vec<f32> {
    let len = side + 2 * (LANES - 1);
    let mut out = vec![0f32; side * len];
    for dy in 0..side {
        out[dy * len + LANES - 1..dy * len + LANES - 1 + side]
            .copy_from_slice(&spatial[dy * side..(dy + 1) * side]);
    }
    out
}

impl Ctx<'_> {
    /// Filters output row `y` as `row` does, for a map without labels (every sample in the
    /// pixel's segment).
    pub(super) fn row_lanes<const CARRY: bool>(
        &self,
        y: usize,
        out_row: &mut [f32],
        gap_row: &mut [f32],
        a_row: &mut [f32],
    ) {
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx512f")
                && std::arch::is_x86_feature_detected!("avx512bw")
                && std::arch::is_x86_feature_detected!("avx512vl")
            {
                // SAFETY: the running CPU supports these features, checked just above.
                return unsafe { self.lanes_avx512::<CARRY>(y, out_row, gap_row, a_row) };
            }
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: as above, for AVX2.
                return unsafe { self.lanes_avx2::<CARRY>(y, out_row, gap_row, a_row) };
            }
        }
        self.lanes_body::<CARRY>(y, out_row, gap_row, a_row);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx512bw,avx512vl")]
    fn lanes_avx512<const CARRY: bool>(
        &self,
        y: usize,
        out_row: &mut [f32],
        gap_row: &mut [f32],
        a_row: &mut [f32],
    ) {
        self.lanes_body::<CARRY>(y, out_row, gap_row, a_row);
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn lanes_avx2<const CARRY: bool>(
        &self,
        y: usize,
        out_row: &mut [f32],
        gap_row: &mut [f32],
        a_row: &mut [f32],
    ) {
        self.lanes_body::<CARRY>(y, out_row, gap_row, a_row);
    }

    #[inline(always)]
    // Lane-indexed loops over several arrays are what vectorises here.
    #[allow(clippy::needless_range_loop)]
    pub(super) fn lanes_body<const CARRY: bool>(
        &self,
        y: usize,
        out_row: &mut [f32],
        gap_row: &mut [f32],
        a_row: &mut [f32],
    ) {
        let (r, side, width) = (self.r, self.side, self.width);
        let len = side + 2 * (LANES - 1);
        let y0 = (y as i64 - r).max(0) as usize;
        let y1 = (y as i64 + r).min(self.height as i64 - 1) as usize;
        let mut cursor = vec![0usize; y1 - y0 + 1];
        let gc: &[f32; MAX_SUM + 1] = self.gc.try_into().expect("a colour table per channel sum");
        for x0 in (0..width).step_by(LANES) {
            let n = (width - x0).min(LANES);
            let mut colour = [[0i32; LANES]; 3];
            for l in 0..n {
                let p = 3 * (y * width + x0 + l);
                for (c, ch) in colour.iter_mut().enumerate() {
                    ch[l] = i32::from(self.image[p + c]);
                }
            }
            let mut all = LaneSums::default();
            let mut same = LaneSums::default();
            let mut closest = [i32::MAX; LANES];
            let lo = (x0 as i64 - r).max(0) as u32;
            let hi = (x0 as i64 + n as i64 - 1 + r) as u32;
            for (k, yq) in (y0..=y1).enumerate() {
                let row = &self.rows[yq];
                let row_a = &self.rows_a[yq];
                let c = first_from(row, &mut cursor[k], lo);
                let dy = (yq as i64 - y as i64 + r) as usize;
                let table = &self.spatial_lanes[dy * len..(dy + 1) * len];
                for (i, t) in row[c..].iter().enumerate().take_while(|(_, t)| t.x <= hi) {
                    // Lane l reads entry LANES - 1 + (t.x - x0 - l + r).
                    let end = (t.x as i64 - x0 as i64 + r) as usize + LANES;
                    let run: &[f32; LANES] = table[end - LANES..end]
                        .try_into()
                        .expect("a window's run of the padded table");
                    let a = if CARRY { row_a[c + i] } else { f32::NAN };
                    let carried = CARRY && a.is_finite();
                    let off = t.x as i32 - x0 as i32;
                    let (tr, tg, tb) = (
                        i32::from(t.color[0]),
                        i32::from(t.color[1]),
                        i32::from(t.color[2]),
                    );
                    let mut ws = [0f32; LANES];
                    let mut wc = [0f32; LANES];
                    for l in 0..LANES {
                        ws[l] = run[LANES - 1 - l];
                        let dc = (colour[0][l] - tr).abs()
                            + (colour[1][l] - tg).abs()
                            + (colour[2][l] - tb).abs();
                        let inside = (off - l as i32).abs() as i64 <= r;
                        closest[l] = if inside {
                            closest[l].min(dc)
                        } else {
                            closest[l]
                        };
                        // dc <= MAX_SUM always; the bound lets the table read vectorise.
                        wc[l] = ws[l] * gc[(dc as usize).min(MAX_SUM)];
                    }
                    all.add::<CARRY>(&ws, t.z, a, carried);
                    same.add::<CARRY>(&wc, t.z, a, carried);
                }
            }
            for l in 0..n {
                let x = x0 + l;
                let (same, all) = (same.lane::<CARRY>(l), all.lane::<CARRY>(l));
                let (z, a) = estimate(&same, &all, &[], self.inv_2r2);
                out_row[x] = z;
                if closest[l] != i32::MAX {
                    gap_row[x] = closest[l] as f32 / 3.0;
                }
                if CARRY {
                    a_row[x] = a;
                }
            }
        }
    }
}

/// [`Sums`] of every lane.
#[derive(Default)]
struct LaneSums {
    w: [f32; LANES],
    wz: [f32; LANES],
    wa_w: [f32; LANES],
    wa: [f32; LANES],
}

impl LaneSums {
    /// `Sums::add` in every lane with its weight `w` (one sample: `z`, and `a` where `carried`).
    #[inline(always)]
    #[allow(clippy::needless_range_loop)]
    fn add<const CARRY: bool>(&mut self, w: &[f32; LANES], z: f32, a: f32, carried: bool) {
        for l in 0..LANES {
            self.w[l] += w[l];
            self.wz[l] += w[l] * z;
        }
        if CARRY && carried {
            for l in 0..LANES {
                self.wa_w[l] += w[l];
                self.wa[l] += w[l] * a;
            }
        }
    }

    fn lane<const CARRY: bool>(&self, l: usize) -> Sums<CARRY> {
        Sums {
            w: self.w[l],
            wz: self.wz[l],
            wa_w: self.wa_w[l],
            wa: self.wa[l],
        }
    }
}
