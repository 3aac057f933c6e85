//! The LC kernel against a slow, obviously-correct reference (proptest), and its behaviour on
//! scenes whose answer is known.

use std::collections::BTreeMap;

use proptest::prelude::*;
use rgbd_fusion::{lc_fuse, LcOutput, LcParams, Source};

/// Target colour at quarter-pixel position `pos` of row `y` (linear, rounded), as the definition.
fn target_at(target: &[u8], w: usize, y: usize, pos: i64, c: usize) -> u8 {
    let (x0, f) = ((pos / 4) as usize, (pos % 4) as f32 / 4.0);
    let a = f32::from(target[3 * (y * w + x0) + c]);
    let b = if f > 0.0 {
        f32::from(target[3 * (y * w + x0 + 1) + c])
    } else {
        a
    };
    ((1.0 - f) * a + f * b).round() as u8
}

/// The integer resampling equals the f32 definition for every pair of bytes and every phase.
#[test]
fn quarter_rows_equal_the_float_definition_for_every_byte_pair() {
    // Row a * 256 + b holds the pixels (a, b, 255 - a) and (b, a, 255 - b).
    let (w, h) = (2usize, 256 * 256);
    let mut img = Vec::with_capacity(w * h * 3);
    for a in 0..=255u8 {
        for b in 0..=255u8 {
            img.extend_from_slice(&[a, b, 255 - a, b, a, 255 - b]);
        }
    }
    let rows = rgbd_fusion::lc::quarter_rows(&img, w, h);
    let len = 4 * (w - 1) + 1;
    for y in 0..h {
        for pos in 0..len {
            let want: [u8; 3] = std::array::from_fn(|c| target_at(&img, w, y, pos as i64, c));
            assert_eq!(rows[y * len + pos], want, "row {y}, position {pos}");
        }
    }
}

fn dist(a: [u8; 3], b: [u8; 3], trunc: f64) -> f64 {
    let s: f64 = (0..3)
        .map(|c| (f64::from(a[c]) - f64::from(b[c])).abs())
        .sum();
    (s / 3.0).min(trunc)
}

/// Straight from the module docs: for every p, every q of its window, every hypothesis of q.
fn reference_lc(
    r_img: &[u8],
    t_img: &[u8],
    w: usize,
    h: usize,
    sources: &[(Vec<f32>, Vec<f32>)],
    p: &LcParams,
) -> Vec<(f32, f64, f64)> {
    let ds = sources
        .iter()
        .flat_map(|s| s.0.iter())
        .filter(|d| d.is_finite());
    let dmin = ds.clone().fold(f32::INFINITY, |a, &b| a.min(b));
    let px = |img: &[u8], i: usize| [img[3 * i], img[3 * i + 1], img[3 * i + 2]];
    let len = 4 * (w as i64 - 1) + 1;
    let rr = p.radius as i64;
    let mut out = vec![];
    for y in 0..h as i64 {
        for x in 0..w as i64 {
            let pi = (y * w as i64 + x) as usize;
            let mut omega: BTreeMap<usize, (f64, f64)> = BTreeMap::new();
            for yq in (y - rr).max(0)..=(y + rr).min(h as i64 - 1) {
                for xq in (x - rr).max(0)..=(x + rr).min(w as i64 - 1) {
                    let st = p.stride as i64;
                    if (yq - y) % st != 0 || (xq - x) % st != 0 {
                        continue;
                    }
                    let qi = (yq * w as i64 + xq) as usize;
                    for (disp, conf) in sources {
                        let (d, c) = (disp[qi], conf[qi]);
                        if !d.is_finite() || !(c > 0.0) {
                            continue;
                        }
                        let shift = (f32::from(p.target_sign) * 4.0 * d).round() as i64;
                        let (qpos, ppos) = (4 * xq + shift, 4 * x + shift);
                        if !(0..len).contains(&qpos) || !(0..len).contains(&ppos) {
                            continue;
                        }
                        let tq: [u8; 3] =
                            std::array::from_fn(|c| target_at(t_img, w, yq as usize, qpos, c));
                        let tp: [u8; 3] =
                            std::array::from_fn(|c| target_at(t_img, w, y as usize, ppos, c));
                        let sp = (((x - xq).pow(2) + (y - yq).pow(2)) as f64).sqrt();
                        let tr = f64::from(p.truncation);
                        let v = f64::from(c)
                            * (-sp / f64::from(p.gamma_s)).exp()
                            * (-dist(px(r_img, pi), px(r_img, qi), tr) / f64::from(p.gamma_c))
                                .exp()
                            * (-sp / f64::from(p.gamma_s)).exp()
                            * (-dist(tp, tq, tr) / f64::from(p.gamma_c)).exp()
                            * (-dist(px(r_img, pi), tp, tr) / f64::from(p.gamma_t)).exp();
                        let bin = ((d - dmin) / p.bin_width) as usize;
                        let e = omega.entry(bin).or_default();
                        e.0 += v;
                        e.1 += v * f64::from(d);
                    }
                }
            }
            let total: f64 = omega.values().map(|v| v.0).sum();
            let score = |b: usize| {
                [b.wrapping_sub(1), b, b + 1]
                    .iter()
                    .filter_map(|k| omega.get(k))
                    .fold((0.0, 0.0), |a, v| (a.0 + v.0, a.1 + v.1))
            };
            let mut scores: Vec<(f64, usize)> = omega.keys().map(|&b| (score(b).0, b)).collect();
            scores.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
            if total <= 0.0 || scores.is_empty() {
                out.push((f32::NAN, 0.0, 0.0));
                continue;
            }
            let (s, b) = scores[0];
            let runner = scores.get(1).map_or(0.0, |v| v.0);
            out.push(((score(b).1 / s) as f32, s / total, (s - runner) / s));
        }
    }
    out
}

/// LC with one unit-confidence source (the §2.4.2 refinement) and a `radius` window.
fn refine(r_img: &[u8], t_img: &[u8], w: usize, h: usize, d: &[f32], radius: usize) -> LcOutput {
    let src = [Source {
        disparity: d,
        confidence: None,
    }];
    // Dense window and gamma_s = 6 (the kernel under test, not the defaults).
    let p = LcParams {
        radius,
        gamma_s: 6.0,
        stride: 1,
        ..LcParams::default()
    };
    lc_fuse(r_img, t_img, w, h, &src, &p).unwrap()
}

/// A textured pair whose true disparity is `d(x)`; reference = right camera (target = x + d).
fn textured_pair(w: usize, h: usize, seed: u64, d: impl Fn(usize) -> f32) -> (Vec<u8>, Vec<u8>) {
    let tex = |u: f32, y: usize, c: usize| {
        let v = (u * 0.9 + y as f32 * 1.7 + c as f32 * 2.1 + seed as f32).sin()
            + (u * 0.37 - y as f32 * 0.55 + c as f32).cos();
        (128.0 + 60.0 * v).clamp(0.0, 255.0) as u8
    };
    let mut r = vec![0u8; w * h * 3];
    let mut t = vec![0u8; w * h * 3];
    for y in 0..h {
        for x in 0..w {
            for c in 0..3 {
                r[3 * (y * w + x) + c] = tex(x as f32, y, c);
                // The left (target) pixel x sees the surface point at right pixel x - d.
                t[3 * (y * w + x) + c] = tex(x as f32 - d(x), y, c);
            }
        }
    }
    (r, t)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn kernel_equals_reference(
        w in 3usize..9, h in 1usize..6, radius in 1usize..4, nsrc in 1usize..3, seed in 0u64..1000,
        left in any::<bool>(),
        vals in proptest::collection::vec((0.0f32..4.0, 0.0f32..1.0, 0u8..4), 2 * 9 * 6),
        pix in proptest::collection::vec(any::<u8>(), 2 * 3 * 9 * 6),
    ) {
        let n = w * h;
        let (r_img, t_img) = (pix[..3 * n].to_vec(), pix[3 * n..6 * n].to_vec());
        let sources: Vec<(Vec<f32>, Vec<f32>)> = (0..nsrc)
            .map(|k| {
                let v = &vals[k * n..(k + 1) * n];
                let d = v.iter().map(|t| if t.2 == 0 { f32::NAN } else { t.0 }).collect();
                let c = v.iter().map(|t| if t.2 == 1 { 0.0 } else { t.1 }).collect();
                (d, c)
            })
            .collect();
        let params = LcParams {
            radius,
            stride: 1 + (seed as usize / 3) % radius,
            bin_width: 0.25 + (seed % 3) as f32 * 0.25,
            target_sign: if left { -1 } else { 1 },
            gamma_c: 5.0 + (seed % 7) as f32 * 5.0,
            truncation: 20.0 + (seed % 5) as f32 * 20.0,
            ..LcParams::default()
        };
        let srcs: Vec<Source> = sources
            .iter()
            .map(|(d, c)| Source { disparity: d, confidence: Some(c) })
            .collect();
        let fast = lc_fuse(&r_img, &t_img, w, h, &srcs, &params).unwrap();
        let slow = reference_lc(&r_img, &t_img, w, h, &sources, &params);
        for (i, &(d, share, margin)) in slow.iter().enumerate() {
            if d.is_nan() {
                prop_assert!(fast.disparity[i].is_nan(), "pixel {}: {} vs NaN", i, fast.disparity[i]);
                continue;
            }
            if margin < 1e-4 {
                continue; // a near-tie: either winner is right
            }
            prop_assert!((fast.disparity[i] - d).abs() < 1e-4, "pixel {}: {} vs {}", i, fast.disparity[i], d);
            prop_assert!((f64::from(fast.plausibility[i]) - share).abs() < 1e-4);
        }
    }
}

#[test]
fn refinement_recovers_a_slanted_plane_from_noisy_outliers() {
    let (w, h) = (64, 24);
    let truth = |x: usize| 5.0 + 0.05 * x as f32;
    let (r_img, t_img) = textured_pair(w, h, 3, truth);
    // Every 7th pixel is an outlier 3 px off; the rest carry +-0.2 px noise.
    let noisy: Vec<f32> = (0..w * h)
        .map(|i| {
            let x = i % w;
            let e = if i % 7 == 0 {
                3.0
            } else {
                0.2 * ((i * 37 % 11) as f32 / 5.0 - 1.0)
            };
            truth(x) + e
        })
        .collect();
    let out = refine(&r_img, &t_img, w, h, &noisy, 4);
    let (mut before, mut after, mut cnt) = (0.0f32, 0.0f32, 0);
    for y in 4..h - 4 {
        for x in 4..w - 12 {
            let i = y * w + x;
            before += (noisy[i] - truth(x)).powi(2);
            after += (out.disparity[i] - truth(x)).powi(2);
            cnt += 1;
        }
    }
    let (before, after) = ((before / cnt as f32).sqrt(), (after / cnt as f32).sqrt());
    assert!(after < 0.5 * before, "RMS {before} -> {after}");
    assert!(after < 0.25, "RMS after {after}");
}

#[test]
fn confidence_decides_between_disagreeing_sources() {
    let (w, h) = (48, 16);
    let (r_img, t_img) = textured_pair(w, h, 1, |_| 6.0);
    let good = vec![6.0f32; w * h];
    let bad = vec![9.0f32; w * h];
    let (hi, lo) = (vec![1.0f32; w * h], vec![0.05f32; w * h]);
    let p = LcParams {
        radius: 3,
        gamma_t: 1000.0,
        ..LcParams::default()
    };
    // With the photometric term switched off (huge γt) only the confidences separate the two.
    for (cg, cb, want) in [(&hi, &lo, 6.0), (&lo, &hi, 9.0)] {
        let srcs = [
            Source {
                disparity: &good,
                confidence: Some(cg),
            },
            Source {
                disparity: &bad,
                confidence: Some(cb),
            },
        ];
        let out = lc_fuse(&r_img, &t_img, w, h, &srcs, &p).unwrap();
        assert!((out.disparity[8 * w + 20] - want).abs() < 1e-3);
    }
    // With equal confidences the colour-consistent one wins.
    let srcs = [
        Source {
            disparity: &good,
            confidence: None,
        },
        Source {
            disparity: &bad,
            confidence: None,
        },
    ];
    let out = lc_fuse(&r_img, &t_img, w, h, &srcs, &LcParams { radius: 3, ..p }).unwrap();
    assert!((out.disparity[8 * w + 20] - 6.0).abs() < 1e-3);
    let out = lc_fuse(
        &r_img,
        &t_img,
        w,
        h,
        &srcs,
        &LcParams {
            radius: 3,
            ..LcParams::default()
        },
    )
    .unwrap();
    assert!(
        (out.disparity[8 * w + 20] - 6.0).abs() < 1e-3,
        "{}",
        out.disparity[8 * w + 20]
    );
}

#[test]
fn holes_fill_from_neighbours_and_empty_input_is_nan() {
    let (w, h) = (16, 8);
    let (r_img, t_img) = textured_pair(w, h, 2, |_| 3.0);
    let mut d = vec![3.0f32; w * h];
    d[4 * w + 8] = f32::NAN;
    let out = refine(&r_img, &t_img, w, h, &d, 2);
    assert!((out.disparity[4 * w + 8] - 3.0).abs() < 1e-5);
    let none = vec![f32::NAN; w * h];
    let src = [Source {
        disparity: &none,
        confidence: None,
    }];
    let out = lc_fuse(&r_img, &t_img, w, h, &src, &LcParams::default()).unwrap();
    assert!(out.disparity.iter().all(|v| v.is_nan()));
}

#[test]
fn bad_arguments_name_themselves() {
    let (w, h) = (8, 4);
    let img = vec![0u8; w * h * 3];
    let d = vec![1.0f32; w * h];
    let src = [Source {
        disparity: &d,
        confidence: None,
    }];
    let p = LcParams::default();
    let err = |r: Result<_, rgbd_geom::RgbdError>| r.unwrap_err().to_string();
    assert!(err(lc_fuse(&img[1..], &img, w, h, &src, &p)).starts_with("reference"));
    assert!(err(lc_fuse(&img, &img[1..], w, h, &src, &p)).starts_with("target"));
    assert!(err(lc_fuse(&img, &img, w, h, &[], &p)).starts_with("sources"));
    let c = vec![2.0f32; w * h];
    let bad = [Source {
        disparity: &d,
        confidence: Some(&c),
    }];
    assert!(err(lc_fuse(&img, &img, w, h, &bad, &p)).starts_with("confidences"));
    let short = [Source {
        disparity: &d[1..],
        confidence: None,
    }];
    assert!(err(lc_fuse(&img, &img, w, h, &short, &p)).starts_with("disparities"));
    for bad in [
        LcParams { radius: 0, ..p },
        LcParams { gamma_s: 0.0, ..p },
        LcParams {
            bin_width: f32::NAN,
            ..p
        },
        LcParams {
            target_sign: 0,
            ..p
        },
    ] {
        assert!(lc_fuse(&img, &img, w, h, &src, &bad).is_err());
    }
    let wide = [0.0f32, 1e4].repeat(w * h / 2);
    let src = [Source {
        disparity: &wide,
        confidence: None,
    }];
    let fine = LcParams {
        bin_width: 1e-3,
        ..p
    };
    assert!(err(lc_fuse(&img, &img, w, h, &src, &fine)).starts_with("bin_width"));
    // Formerly a bin-count overflow (panic): a tiny bin width, an absurd disparity.
    let tiny = LcParams {
        bin_width: 1e-30,
        ..p
    };
    let varied = [0.0f32, 1.0].repeat(w * h / 2);
    let src = [Source {
        disparity: &varied,
        confidence: None,
    }];
    assert!(err(lc_fuse(&img, &img, w, h, &src, &tiny)).starts_with("bin_width"));
    let mut absurd = varied.clone();
    absurd[0] = -1e19;
    let src = [Source {
        disparity: &absurd,
        confidence: None,
    }];
    assert!(err(lc_fuse(&img, &img, w, h, &src, &p)).starts_with("disparities"));
}
