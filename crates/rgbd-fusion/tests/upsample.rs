//! The extended cross bilateral upsampling kernel against a slow, obviously-correct f64
//! reference written straight from its definition (proptest).

use proptest::prelude::*;
use rgbd_fusion::{upsample_depth, UpsampleParams};

/// `(Gs, Gs Gc, same segment, z, channel)` of one sample.
type Tap = (f32, f32, bool, f64, f64);

/// For every pixel p, every sample q of its window (each weight evaluated in f32 as the kernel
/// stores it, so both underflow alike; the sums in f64):
/// - `Gs = exp(-|p-q|^2 / 2 sigma_s^2)`, `Gc = exp(-(mean |colour_p - colour_q|)^2 / 2 sigma_c^2)`;
/// - `z0` = the Gs Gc-weighted mean of p's segment's samples, or the Gs-weighted mean of all
///   samples when p's segment holds none (NaN when there is no sample at all);
/// - the estimate: Gs Gc weights for p's segment, `Gs exp(-((z - z0)/z0)^2 / 2 sigma_r^2)` for
///   the others; the carried channel gets the same weights (samples without a value skipped).
#[allow(clippy::too_many_arguments)]
fn reference(
    sparse: &[f32],
    chan: &[f32],
    img: &[u8],
    labels: Option<&[i32]>,
    w: usize,
    h: usize,
    p: &UpsampleParams,
) -> Vec<(f64, f64)> {
    let lab = |i: usize| labels.map_or(0, |l| l[i]);
    let r = p.radius as i64;
    let (ss, sc, sr) = (p.sigma_s, p.sigma_c, p.sigma_r);
    let mut out = Vec::with_capacity(w * h);
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            let pi = (y * w as i64 + x) as usize;
            let mut taps = Vec::new(); // (gs, gs gc, same, z, a)
            for qy in (y - r).max(0)..=(y + r).min(h as i64 - 1) {
                for qx in (x - r).max(0)..=(x + r).min(w as i64 - 1) {
                    let qi = (qy * w as i64 + qx) as usize;
                    let z = f64::from(sparse[qi]);
                    if !(z.is_finite() && z > 0.0) {
                        continue;
                    }
                    let d2 = ((qx - x).pow(2) + (qy - y).pow(2)) as f32;
                    let gs = (-d2 / (2.0 * ss * ss)).exp();
                    let cd = (0..3)
                        .map(|c| f32::from(img[3 * pi + c].abs_diff(img[3 * qi + c])))
                        .sum::<f32>()
                        / 3.0;
                    let gc = (-cd * cd / (2.0 * sc * sc)).exp();
                    let same = lab(qi) == lab(pi);
                    taps.push((gs, gs * gc, same, z, f64::from(chan[qi])));
                }
            }
            let mean = |ws: &dyn Fn(&Tap) -> f32| {
                let (mut sw, mut swz, mut swa, mut sa) = (0.0, 0.0, 0.0, 0.0);
                for t in &taps {
                    let wt = f64::from(ws(t));
                    sw += wt;
                    swz += wt * t.3;
                    if t.4.is_finite() {
                        swa += wt;
                        sa += wt * t.4;
                    }
                }
                // A total below 1e-30 counts as no support (the kernel's f32 MIN_WEIGHT).
                let a = if swa > 1e-30 { sa / swa } else { f64::NAN };
                (sw > 1e-30).then(|| (swz / sw, a))
            };
            let same = |t: &Tap| if t.2 { t.1 } else { 0.0 };
            let Some(first) = mean(&same).or_else(|| mean(&|t| t.0)) else {
                out.push((f64::NAN, f64::NAN));
                continue;
            };
            let z0 = first.0 as f32;
            let full = |t: &Tap| {
                if t.2 {
                    t.1
                } else {
                    let dz = (t.3 as f32 - z0) / z0;
                    t.0 * (-dz * dz / (2.0 * sr * sr)).exp()
                }
            };
            out.push(mean(&full).unwrap_or(first));
        }
    }
    out
}

fn close(fast: f32, slow: f64, rel: f64) -> bool {
    (fast.is_nan() && slow.is_nan()) || (f64::from(fast) - slow).abs() <= rel * slow.abs() + 1e-5
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn kernel_equals_reference(
        w in 1usize..10, h in 1usize..7, radius in 1usize..4, with_labels in any::<bool>(),
        sigmas in (0.5f32..5.0, 2.0f32..40.0, 0.005f32..0.5),
        cells in proptest::collection::vec((0u8..4, 0.3f32..5.0, 0.0f32..100.0, 0i32..3), 60),
        pix in proptest::collection::vec(any::<u8>(), 3 * 60),
    ) {
        let n = w * h;
        // kind 0: no sample; 1: sample without channel value; else a sample with one.
        let sparse: Vec<f32> = cells[..n].iter().map(|c| if c.0 == 0 { f32::NAN } else { c.1 }).collect();
        let chan: Vec<f32> = cells[..n].iter().map(|c| if c.0 <= 1 { f32::NAN } else { c.2 }).collect();
        let labels: Vec<i32> = cells[..n].iter().map(|c| c.3).collect();
        let img = &pix[..3 * n];
        let p = UpsampleParams { radius, sigma_s: sigmas.0, sigma_c: sigmas.1, sigma_r: sigmas.2 };
        let lab = with_labels.then_some(&labels[..]);
        let fast = upsample_depth(&sparse, Some(&chan), img, lab, w, h, &p).unwrap();
        let slow = reference(&sparse, &chan, img, lab, w, h, &p);
        for (i, &(z, a)) in slow.iter().enumerate() {
            prop_assert!(close(fast.depth[i], z, 1e-4), "depth {}: {} vs {}", i, fast.depth[i], z);
            prop_assert!(close(fast.channel[i], a, 1e-4), "channel {}: {} vs {}", i, fast.channel[i], a);
        }
        let plain = upsample_depth(&sparse, None, img, lab, w, h, &p).unwrap();
        // Carrying a channel never changes the depth (bit for bit, NaN included).
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        prop_assert_eq!(bits(&plain.depth), bits(&fast.depth));
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    /// Without labels the filter runs 16 pixels at a time (`upsample/lanes.rs`); with every label
    /// equal it runs the one-pixel loop. Both define the same filter and must give the same
    /// bits: depth, carried channel and colour gap, rows of several blocks and a partial one.
    #[test]
    fn lanes_equal_the_one_pixel_filter(
        w in 1usize..70, h in 1usize..6, radius in 1usize..9,
        sigmas in (0.3f32..6.0, 2.0f32..40.0), density in 1u32..5, seed in any::<u64>(),
    ) {
        let n = w * h;
        let mut s = seed | 1;
        let mut next = || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            s
        };
        let sparse: Vec<f32> = (0..n)
            .map(|_| if next() % u64::from(density) == 0 { 0.3 + (next() % 5000) as f32 / 1000.0 } else { f32::NAN })
            .collect();
        let chan: Vec<f32> = (0..n)
            .map(|_| if next() % 5 == 0 { f32::NAN } else { (next() % 1000) as f32 - 300.0 })
            .collect();
        let img: Vec<u8> = (0..3 * n).map(|_| (next() % 256) as u8).collect();
        let zeros = vec![0i32; n];
        let p = UpsampleParams { radius, sigma_s: sigmas.0, sigma_c: sigmas.1, sigma_r: 0.02 };
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        for carried in [Some(&chan[..]), None] {
            let lanes = upsample_depth(&sparse, carried, &img, None, w, h, &p).unwrap();
            let one = upsample_depth(&sparse, carried, &img, Some(&zeros), w, h, &p).unwrap();
            prop_assert_eq!(bits(&lanes.depth), bits(&one.depth));
            prop_assert_eq!(bits(&lanes.channel), bits(&one.channel));
            prop_assert_eq!(bits(&lanes.color_gap), bits(&one.color_gap));
        }
    }
}
