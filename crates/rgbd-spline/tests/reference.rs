//! The fast fit (per-cell blocks, runs, band Cholesky) against a slow, obviously-correct dense
//! least-squares reference, and the grid domain against the full-mask domain.

use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use proptest::prelude::*;
use rgbd_spline::fit::RIDGE;
use rgbd_spline::{fit_grid, fit_mask, KnotGrid};

/// Dense normal equations, one pixel at a time, over the control points of the touched cells;
/// the same second-difference penalty; ridge towards the data mean.
fn reference(
    vals: &[f64],
    mask: &[bool],
    w: usize,
    h: usize,
    c: usize,
    grid: &KnotGrid,
    lambda: f64,
) -> Vec<Vec<f64>> {
    let (nu, nv) = grid.ctrl_shape();
    let p = grid.degree;
    let valid = |i: usize| mask[i] && vals[i * c..(i + 1) * c].iter().all(|x| x.is_finite());
    let mut used = vec![false; nu * nv];
    let mut mean = vec![0.0; c];
    let mut n = 0.0;
    for i in (0..w * h).filter(|&i| valid(i)) {
        let (cu, cv, _, _) = grid.support((i % w) as f64, (i / w) as f64);
        for j in 0..=p {
            for q in 0..=p {
                used[(cv + j) * nu + cu + q] = true;
            }
        }
        for ch in 0..c {
            mean[ch] += vals[i * c + ch];
        }
        n += 1.0;
    }
    mean.iter_mut().for_each(|m| *m /= n);
    let mut ata = Mat::<f64>::zeros(nu * nv, nu * nv);
    let mut atb = Mat::<f64>::zeros(nu * nv, c);
    for i in (0..w * h).filter(|&i| valid(i)) {
        let (cu, cv, bu, bv) = grid.support((i % w) as f64, (i / w) as f64);
        let mut row = vec![(0usize, 0.0f64); 0];
        for j in 0..=p {
            for q in 0..=p {
                row.push(((cv + j) * nu + cu + q, bu.value[q] * bv.value[j]));
            }
        }
        for &(a, wa) in &row {
            for &(b, wb) in &row {
                ata[(a, b)] += wa * wb;
            }
            for ch in 0..c {
                atb[(a, ch)] += wa * (vals[i * c + ch] - mean[ch]);
            }
        }
    }
    let st = [1.0, -2.0, 1.0];
    let mut pen = |ids: [usize; 3]| {
        if ids.iter().all(|&x| used[x]) {
            for a in 0..3 {
                for b in 0..3 {
                    ata[(ids[a], ids[b])] += lambda * st[a] * st[b];
                }
            }
        }
    };
    for j in 0..nv {
        for i in 0..nu {
            if i + 2 < nu {
                pen([j * nu + i, j * nu + i + 1, j * nu + i + 2]);
            }
            if j + 2 < nv {
                pen([j * nu + i, (j + 1) * nu + i, (j + 2) * nu + i]);
            }
        }
    }
    for i in 0..nu * nv {
        ata[(i, i)] += if used[i] { RIDGE } else { 1.0 };
    }
    let sol = ata.llt(Side::Lower).unwrap().solve(&atb);
    // Surface values at every valid pixel.
    (0..w * h)
        .filter(|&i| valid(i))
        .map(|i| {
            let (cu, cv, bu, bv) = grid.support((i % w) as f64, (i / w) as f64);
            (0..c)
                .map(|ch| {
                    let mut s = mean[ch];
                    for j in 0..=p {
                        for q in 0..=p {
                            s += bu.value[q] * bv.value[j] * sol[((cv + j) * nu + cu + q, ch)];
                        }
                    }
                    s
                })
                .collect()
        })
        .collect()
}

fn lcg(seed: u64) -> impl FnMut() -> f64 {
    let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
    move || {
        s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (s >> 11) as f64 / (1u64 << 53) as f64
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]
    #[test]
    fn fast_fit_equals_dense_reference(
        w in 6usize..28, h in 6usize..28, spacing in 2.0f64..7.0, degree in 1usize..5,
        c in 1usize..4, seed in 0u64..10_000, keep in 0.3f64..1.0,
    ) {
        let mut rnd = lcg(seed);
        let vals: Vec<f64> = (0..w * h * c).map(|_| 1.0 + rnd()).collect();
        let mask: Vec<bool> = (0..w * h).map(|_| rnd() < keep).collect();
        let n = mask.iter().filter(|&&m| m).count();
        prop_assume!(n >= (degree + 1) * (degree + 1));
        let grid = KnotGrid::new(w, h, spacing, degree).unwrap();
        let lambda = 1e-3;
        let fast = fit_mask(&vals, w, h, c, Some(&mask), &grid, lambda, false).unwrap();
        let slow = reference(&vals, &mask, w, h, c, &grid, lambda);
        let pixels = (0..w * h).filter(|&i| mask[i]);
        for (i, want) in pixels.zip(&slow) {
            let j = fast.surface.jet((i % w) as f64, (i / w) as f64).unwrap();
            for (ch, y) in want.iter().enumerate() {
                prop_assert!((j.value[ch] - y).abs() < 1e-6,
                    "pixel {i} ch {ch}: {} vs {y}", j.value[ch]);
            }
        }
    }

    #[test]
    fn grid_domain_equals_full_mask_domain(
        w in 6usize..24, h in 6usize..24, spacing in 1.0f64..6.0, seed in 0u64..10_000,
    ) {
        let mut rnd = lcg(seed);
        let vals: Vec<f64> = (0..w * h * 3)
            .map(|i| if i % 17 == 0 { f64::NAN } else { rnd() })
            .collect();
        let grid = KnotGrid::new(w, h, spacing, 3).unwrap();
        let a = fit_grid(&vals, w, h, 3, &grid, 1e-6, true).unwrap();
        let b = fit_mask(&vals, w, h, 3, Some(&vec![true; w * h]), &grid, 1e-6, true).unwrap();
        prop_assert_eq!(a.n, b.n);
        prop_assert!((a.sse - b.sse).abs() <= 1e-9 * (1.0 + a.sse));
        for (x, y) in a.surface.ctrl.iter().zip(&b.surface.ctrl) {
            prop_assert!((x - y).abs() < 1e-9);
        }
    }
}
