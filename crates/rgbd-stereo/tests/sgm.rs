//! The streamed, multiversioned aggregation against an obviously-correct full-volume reference
//! (every path over the whole `H x W x D` volume in i64), and the whole matcher on pairs with a
//! known disparity.

use proptest::prelude::*;
use rgbd_stereo::census::census;
use rgbd_stereo::{
    aggregated_with, sgm, sgm_with, CensusReference, Kernel, Paths, Reference, SgmParams, Subpixel,
    DIRECTIONS,
};

/// The summed path costs, naively: the cost volume, then each path's recursion in full.
fn naive_sum(r_img: &[u8], t_img: &[u8], w: usize, h: usize, p: &SgmParams) -> Vec<u16> {
    let nd = p.disparities();
    let cr = census(
        r_img,
        w,
        h,
        p.census_width,
        p.census_height,
        p.census_reference,
    );
    let ct = census(
        t_img,
        w,
        h,
        p.census_width,
        p.census_height,
        p.census_reference,
    );
    let cmax = i64::from(p.max_cost());
    let idx = |x: usize, y: usize, k: usize| (y * w + x) * nd + k;
    let mut cost = vec![0i64; w * h * nd];
    for y in 0..h {
        for x in 0..w {
            for k in 0..nd {
                let d = p.min_disparity + k;
                // The smallest over the target rows within the vertical tolerance.
                let v = p.vertical_tolerance;
                cost[idx(x, y, k)] = if x >= d {
                    (y.saturating_sub(v)..=(y + v).min(h - 1))
                        .map(|ty| i64::from((cr[y * w + x] ^ ct[ty * w + x - d]).count_ones()))
                        .min()
                        .unwrap()
                } else {
                    cmax
                };
            }
        }
    }
    let p2_of = |a: u8, b: u8| -> i64 {
        let di = f32::from(a.abs_diff(b));
        if p.p2_contrast > 0.0 {
            let v = (f32::from(p.p2) / (1.0 + di / p.p2_contrast)).round() as i64;
            v.max(i64::from(p.p1) + 1)
        } else {
            i64::from(p.p2)
        }
    };
    let mut sum = vec![0i64; w * h * nd];
    for (i, &(dx, dy)) in DIRECTIONS.iter().enumerate() {
        if !p.paths.uses(i) {
            continue;
        }
        let mut l = vec![0i64; w * h * nd];
        let ys: Vec<usize> = if dy >= 0 {
            (0..h).collect()
        } else {
            (0..h).rev().collect()
        };
        let xs: Vec<usize> = if dx >= 0 {
            (0..w).collect()
        } else {
            (0..w).rev().collect()
        };
        for &y in &ys {
            for &x in &xs {
                let (px, py) = (x as isize - dx, y as isize - dy);
                let inside = px >= 0 && py >= 0 && px < w as isize && py < h as isize;
                for k in 0..nd {
                    let c = cost[idx(x, y, k)];
                    l[idx(x, y, k)] = if !inside {
                        c
                    } else {
                        let (px, py) = (px as usize, py as usize);
                        let prev = |k: usize| l[idx(px, py, k)];
                        let m = (0..nd).map(prev).min().unwrap();
                        let p2 = p2_of(r_img[y * w + x], r_img[py * w + px]);
                        let mut best = prev(k).min(m + p2);
                        if k > 0 {
                            best = best.min(prev(k - 1) + i64::from(p.p1));
                        }
                        if k + 1 < nd {
                            best = best.min(prev(k + 1) + i64::from(p.p1));
                        }
                        c + best - m
                    };
                }
            }
        }
        for (s, v) in sum.iter_mut().zip(&l) {
            *s += v;
        }
    }
    // Only the searchable disparities are kept (the matcher reports 0 for the others).
    sum.iter()
        .enumerate()
        .map(|(i, &v)| {
            let (x, k) = ((i / nd) % w, i % nd);
            if x >= p.min_disparity + k {
                u16::try_from(v).unwrap()
            } else {
                0
            }
        })
        .collect()
}

fn noise_image(w: usize, h: usize, seed: u64) -> Vec<u8> {
    let mut s = seed
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    (0..w * h)
        .map(|_| {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 56) as u8
        })
        .collect()
}

/// A random texture and its view shifted by `d` pixels (the right view sees x at x - d).
fn shifted_pair(w: usize, h: usize, d: usize, seed: u64) -> (Vec<u8>, Vec<u8>) {
    let wide = noise_image(w + d, h, seed);
    let mut l = vec![0u8; w * h];
    let mut r = vec![0u8; w * h];
    for y in 0..h {
        for x in 0..w {
            l[y * w + x] = wide[y * (w + d) + x];
            r[y * w + x] = wide[y * (w + d) + x + d];
        }
    }
    (l, r)
}

fn paths_of(i: u8) -> Paths {
    [Paths::Four, Paths::Five, Paths::Eight][usize::from(i % 3)]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]

    #[test]
    fn streamed_sum_equals_the_full_volume(
        w in 6usize..28, h in 1usize..9, dmin in 0usize..3, nd in 2usize..9,
        p1 in 1u16..20, extra in 1u16..200, contrast in prop_oneof![Just(0.0f32), 1.0f32..40.0],
        paths in 0u8..3, cw in prop_oneof![Just(3usize), Just(5), Just(9)], mean in any::<bool>(),
        // 3 rows: strings of up to 32 bits (kept as u32); 7 rows with 9 columns: 62 or 63.
        ch in prop_oneof![Just(3usize), Just(7)],
        seed in any::<u64>(), right in any::<bool>(),
        lr in prop_oneof![Just(None), (0u16..3).prop_map(Some)], uniqueness in 0u8..20,
        median in prop_oneof![Just(1usize), Just(3), Just(5)], speckle in 0usize..6,
        vertical in 0usize..3,
    ) {
        let max_disparity = dmin + nd - 1;
        prop_assume!(max_disparity < w);
        let p = SgmParams {
            min_disparity: dmin,
            p1,
            p2: p1 + extra,
            p2_contrast: contrast,
            paths: paths_of(paths),
            census_width: cw,
            census_height: ch,
            census_reference: if mean { CensusReference::Mean } else { CensusReference::Center },
            lr_tolerance: lr,
            uniqueness,
            median,
            speckle_size: speckle,
            vertical_tolerance: vertical,
            ..SgmParams::new(max_disparity)
        };
        let l = noise_image(w, h, seed);
        let r = noise_image(w, h, seed ^ 0x9e37);
        let reference = if right { Reference::Right } else { Reference::Left };
        // The problem as solved: a right reference is matched on mirrored, swapped images.
        let flip = |img: &[u8]| -> Vec<u8> {
            img.chunks_exact(w).flat_map(|row| row.iter().rev().copied()).collect()
        };
        let want = if right {
            naive_sum(&flip(&r), &flip(&l), w, h, &p)
        } else {
            naive_sum(&l, &r, w, h, &p)
        };
        let mut maps = Vec::new();
        for k in Kernel::available() {
            let got = aggregated_with(&l, &r, w, h, reference, &p, k).unwrap();
            prop_assert_eq!(&got, &want, "kernel {:?}", k);
            let out = sgm_with(&l, &r, w, h, reference, &SgmParams { stats: true, ..p.clone() }, k)
                .unwrap();
            maps.push(out);
        }
        for m in &maps[1..] {
            let same = |a: &[f32], b: &[f32]| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
            prop_assert!(same(&m.disparity, &maps[0].disparity));
            prop_assert!(same(m.best.as_ref().unwrap(), maps[0].best.as_ref().unwrap()));
            prop_assert!(same(m.second.as_ref().unwrap(), maps[0].second.as_ref().unwrap()));
        }
    }
}

#[test]
fn a_constant_shift_is_found_on_both_views() {
    let (w, h, d) = (80, 40, 7);
    let (l, r) = shifted_pair(w, h, d, 3);
    for reference in [Reference::Left, Reference::Right] {
        for subpixel in [Subpixel::Parabola, Subpixel::Equiangular, Subpixel::Off] {
            let p = SgmParams {
                subpixel,
                ..SgmParams::new(20)
            };
            let out = sgm(&l, &r, w, h, reference, &p).unwrap();
            let mut right_count = 0;
            let mut searched = 0;
            for y in 0..h {
                for x in 0..w {
                    // The left view's first d columns have no match (and the right view's last d).
                    let matchable = match reference {
                        Reference::Left => x >= 20,
                        Reference::Right => x + 20 < w,
                    };
                    if !matchable {
                        continue;
                    }
                    searched += 1;
                    let v = out.disparity[y * w + x];
                    right_count += usize::from((v - d as f32).abs() < 0.5);
                }
            }
            assert!(
                right_count * 100 >= searched * 97,
                "{reference:?} {subpixel:?}: {right_count}/{searched}"
            );
        }
    }
}

#[test]
fn the_first_columns_have_no_search_and_bad_input_is_refused() {
    let (w, h) = (40, 10);
    let (l, r) = shifted_pair(w, h, 3, 1);
    let p = SgmParams {
        min_disparity: 4,
        stats: true,
        ..SgmParams::new(12)
    };
    let out = sgm(&l, &r, w, h, Reference::Left, &p).unwrap();
    for y in 0..h {
        for x in 0..4 {
            assert!(out.disparity[y * w + x].is_nan());
            assert!(out.best.as_ref().unwrap()[y * w + x].is_nan());
        }
    }
    let e = sgm(&l, &r[1..], w, h, Reference::Left, &p).unwrap_err();
    assert!(e.to_string().starts_with("right: got 399 elements"), "{e}");
    let e = sgm(&l, &r, w, h, Reference::Left, &SgmParams::new(40)).unwrap_err();
    assert!(
        e.to_string().contains("less than the image width 40"),
        "{e}"
    );
    let big = SgmParams {
        p2: 5000,
        ..SgmParams::new(8)
    };
    assert!(sgm(&l, &r, w, h, Reference::Left, &big).is_err());
    let e = sgm(&[], &[], 1 << 17, 0, Reference::Left, &p).unwrap_err();
    assert!(e.to_string().starts_with("left: got width"), "{e}");
}
