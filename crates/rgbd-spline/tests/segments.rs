//! Segment fits, unions and merges (thesis §4.5, §4.7 eq. 4.8).

use rgbd_spline::{
    fit_grid, fit_mask, Criterion, FitKind, KnotGrid, NoiseModel, SeamTest, SegmentFits,
    DEFAULT_LAMBDA, KINECT_V1_NOISE,
};

const W: usize = 96;
const H: usize = 64;

/// Deterministic Gaussian-ish noise (sum of 4 uniforms, σ ≈ `sigma`).
fn noise(seed: u64, n: usize, sigma: f64) -> Vec<f64> {
    let mut s = seed.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut uni = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    (0..n)
        .map(|_| (uni() + uni() + uni() + uni()) * sigma * 3f64.sqrt())
        .collect()
}

/// Organised cloud of a pinhole camera (f = 100) seeing depth `z(u, v)`, plus noise along z.
fn cloud(z: impl Fn(f64, f64) -> f64, sigma: f64, seed: u64) -> Vec<f64> {
    let e = noise(seed, W * H, sigma);
    let mut out = Vec::with_capacity(W * H * 3);
    for v in 0..H {
        for u in 0..W {
            let d = z(u as f64, v as f64) + e[v * W + u];
            let (x, y) = ((u as f64 - 48.0) / 100.0, (v as f64 - 32.0) / 100.0);
            out.extend_from_slice(&[x * d, y * d, d]);
        }
    }
    out
}

fn halves() -> Vec<i32> {
    (0..W * H).map(|i| i32::from(i % W >= W / 2)).collect()
}

fn grid() -> KnotGrid {
    KnotGrid::new(W, H, 8.0, 3).unwrap()
}

fn fits(values: &[f64], labels: &[i32], c: Criterion) -> SegmentFits {
    SegmentFits::new(values, W, H, 3, labels, &grid(), DEFAULT_LAMBDA, c).unwrap()
}

#[test]
fn coplanar_union_merges_with_gcv_and_a_step_does_not() {
    let plane = |u: f64, v: f64| 2.0 + 0.004 * u - 0.003 * v;
    let step = |u: f64, _v: f64| if u < 48.0 { 2.0 } else { 2.3 } + 0.004 * u;
    for seed in 0..5 {
        let flat = cloud(plane, 0.002, seed);
        let s = fits(&flat, &halves(), Criterion::Gcv);
        let (e0, e1, eu) = (
            s.fit_error(0).unwrap(),
            s.fit_error(1).unwrap(),
            s.union_error(0, 1).unwrap(),
        );
        assert!(s.should_merge(0, 1).unwrap(), "seed {seed}: {e0} {e1} {eu}");
        // Raw MSE: the union is a restriction of the parts, so it never scores lower.
        let m = fits(&flat, &halves(), Criterion::Mse);
        assert!(!m.should_merge(0, 1).unwrap());
        let stepped = cloud(step, 0.002, seed);
        for c in [Criterion::Gcv, Criterion::Mse] {
            let s = fits(&stepped, &halves(), c);
            assert!(!s.should_merge(0, 1).unwrap());
            assert!(s.union_error(0, 1).unwrap() > 10.0 * s.fit_error(0).unwrap());
        }
    }
}

#[test]
fn union_equals_a_fit_of_the_union_from_scratch() {
    let pts = cloud(
        |u, v| 1.5 + 0.2 * ((u / 20.0).sin() + (v / 15.0).cos()),
        0.0,
        0,
    );
    // Three interleaved labels so that cells are shared.
    let labels: Vec<i32> = (0..W * H)
        .map(|i| ((i % W) / 5 + (i / W) / 7) as i32 % 3)
        .collect();
    let mut s = fits(&pts, &labels, Criterion::Gcv);
    let eu = s.union_error(0, 2).unwrap();
    let merged = s.merge(0, 2).unwrap();
    assert_eq!(eu, merged);
    assert_eq!(s.fit_error(0).unwrap(), merged);
    let mask: Vec<bool> = labels.iter().map(|&l| l != 1).collect();
    let direct = fit_mask(&pts, W, H, 3, Some(&mask), &grid(), DEFAULT_LAMBDA, true).unwrap();
    let via_union = s.fit(0).unwrap();
    assert_eq!(via_union.n, direct.n);
    assert!((via_union.sse - direct.sse).abs() < 1e-9 * (1.0 + direct.sse));
    assert!((via_union.dof.unwrap() - direct.dof.unwrap()).abs() < 1e-6);
    for (u, v) in [(10.0, 10.0), (50.0, 30.0), (90.0, 60.0)] {
        let a = via_union.surface.jet(u, v).unwrap();
        let b = direct.surface.jet(u, v).unwrap();
        for c in 0..3 {
            assert!((a.value[c] - b.value[c]).abs() < 1e-9);
        }
    }
    assert_eq!(s.find(2), Ok(0));
    assert!(s.current_labels().iter().all(|&l| l == 0 || l == 1));
    assert!(s.fit_error(2).is_err(), "merged segments are not live");
    assert!(s.union_error(0, 0).is_err());
    assert!(s.union_error(0, 7).is_err());
}

#[test]
fn tiny_segments_fall_back_to_a_linear_fit() {
    let pts = cloud(|u, v| 2.0 + 0.01 * u + 0.02 * v, 0.0, 0);
    let mut labels = vec![0; W * H];
    for v in 10..13 {
        for u in 20..23 {
            labels[v * W + u] = 1; // 9 pixels < 16 = (p+1)²
        }
    }
    labels[40 * W + 70] = 2; // a single pixel
    let s = fits(&pts, &labels, Criterion::Gcv);
    let f = s.fit(1).unwrap();
    assert_eq!(f.kind, FitKind::Linear);
    // z is linear in (u, v) but x = (u - 48) z / 100 is not: the linear fit leaves a residual.
    assert!(f.mse() < 1e-5 && f.mse().is_finite());
    let one = s.fit(2).unwrap();
    assert_eq!((one.kind, one.n), (FitKind::Linear, 1));
    assert!(one.sse < 1e-20);
    assert_eq!(
        s.fit_error(2).unwrap(),
        f64::INFINITY,
        "GCV of an interpolant"
    );
    let maps = s.maps(&pts).unwrap();
    assert!(maps.error.iter().all(|e| e.is_finite()));
}

#[test]
fn error_decreases_as_control_points_grow() {
    let z = |u: f64, v: f64| 2.0 + 0.3 * (u / 9.0).sin() * (v / 11.0).cos();
    let pts = cloud(z, 0.0, 0);
    let mut last = f64::INFINITY;
    for spacing in [32.0, 16.0, 8.0, 4.0] {
        let g = KnotGrid::new(W, H, spacing, 3).unwrap();
        let f = fit_grid(&pts, W, H, 3, &g, DEFAULT_LAMBDA, false).unwrap();
        assert!(
            f.mse() < last / 4.0,
            "spacing {spacing}: {} vs {last}",
            f.mse()
        );
        last = f.mse();
    }
    assert!(last < 1e-9);
}

#[test]
fn disk_mask_sphere_curvature() {
    // Sphere of radius 1 centred 1.8 m ahead fills the view; fit only a disk-shaped mask.
    let r = 1.0;
    let mut pts = Vec::with_capacity(W * H * 3);
    for v in 0..H {
        for u in 0..W {
            let d = [(u as f64 - 48.0) / 100.0, (v as f64 - 32.0) / 100.0, 1.0];
            let a = d[0] * d[0] + d[1] * d[1] + 1.0;
            let b = 1.8;
            let t = (b - (b * b - a * (1.8 * 1.8 - r * r)).sqrt()) / a;
            pts.extend_from_slice(&[d[0] * t, d[1] * t, t]);
        }
    }
    let labels: Vec<i32> = (0..W * H)
        .map(|i| {
            let (u, v) = ((i % W) as f64 - 48.0, (i / W) as f64 - 32.0);
            if u * u + v * v < 28.0 * 28.0 {
                0
            } else {
                -1
            }
        })
        .collect();
    let s = fits(&pts, &labels, Criterion::Gcv);
    let maps = s.maps(&pts).unwrap();
    let mut checked = 0;
    for v in 0..H {
        for u in 0..W {
            let (du, dv) = (u as f64 - 48.0, v as f64 - 32.0);
            let i = v * W + u;
            if du * du + dv * dv < 12.0 * 12.0 {
                assert!((maps.k1[i] - 1.0).abs() < 0.01 && (maps.k2[i] - 1.0).abs() < 0.01);
                assert!(maps.error[i] < 1e-5);
                checked += 1;
            } else if labels[i] < 0 {
                assert!(maps.k1[i].is_nan() && maps.error[i].is_nan());
            }
        }
    }
    assert!(checked > 400);
}

#[test]
fn bad_input_is_an_error() {
    let pts = cloud(|_, _| 2.0, 0.0, 0);
    let g = grid();
    let new =
        |v: &[f64], l: &[i32]| SegmentFits::new(v, W, H, 3, l, &g, DEFAULT_LAMBDA, Criterion::Gcv);
    assert!(new(&pts, &[0; 10]).is_err());
    assert!(new(&pts, &vec![-1; W * H]).is_err());
    assert!(new(&pts[..30], &halves()).is_err());
    let other = KnotGrid::new(W + 30, H, 8.0, 3).unwrap();
    assert!(fit_grid(&pts, W, H, 3, &other, DEFAULT_LAMBDA, false).is_err());
    assert!(fit_grid(&pts, W, H, 3, &g, f64::NAN, false).is_err());
    let nan = vec![f64::NAN; W * H * 3];
    let s = new(&nan, &halves());
    assert!(
        s.is_ok(),
        "segments without valid pixels are reported per segment"
    );
    assert!(s.unwrap().fit_error(0).is_err());
}

/// Organised cloud of depth `z(u, v)` with Kinect-like noise `σ = a z²` along z.
fn kinect_cloud(z: impl Fn(f64, f64) -> f64, a: f64, seed: u64) -> Vec<f64> {
    let e = noise(seed, W * H, 1.0);
    let mut out = Vec::with_capacity(W * H * 3);
    for v in 0..H {
        for u in 0..W {
            let z0 = z(u as f64, v as f64);
            let d = z0 + a * z0 * z0 * e[v * W + u];
            let (x, y) = ((u as f64 - 48.0) / 100.0, (v as f64 - 32.0) / 100.0);
            out.extend_from_slice(&[x * d, y * d, d]);
        }
    }
    out
}

fn seam_fits(values: &[f64], labels: &[i32], test: &SeamTest) -> SegmentFits {
    SegmentFits::with_test(
        values,
        W,
        H,
        3,
        labels,
        &grid(),
        DEFAULT_LAMBDA,
        Criterion::Seam,
        test,
    )
    .unwrap()
}

/// The seam test on the 96x64 test images: an 8-pixel test grid, Kinect v1 noise.
fn small_test() -> SeamTest {
    SeamTest {
        spacing: 8.0,
        ..SeamTest::default()
    }
}

#[test]
fn seam_test_merges_one_curved_surface_and_not_two_planes_at_an_angle() {
    let a = KINECT_V1_NOISE;
    // A cylinder-like bulge (radius ~0.6 m) and a gentle saddle, split in two.
    let curved: [&dyn Fn(f64, f64) -> f64; 2] =
        [&|u, _v| 1.8 - 0.3 * ((u - 48.0) / 40.0).cos(), &|u, v| {
            2.5 + 0.2 * ((u - 48.0) / 48.0).powi(2) - 0.15 * ((v - 32.0) / 32.0).powi(2)
        }];
    // Two planes meeting at ~100 degrees (a V along u) and a wall meeting a floor.
    let vee = |u: f64, _v: f64| 2.5 + 0.02 * (u - 48.0).abs();
    let wall_floor = |_u: f64, v: f64| {
        let down = (v - 32.0) / 100.0;
        if down > 0.0 {
            f64::min(2.5, 0.5 / down)
        } else {
            2.5
        }
    };
    let split_floor: Vec<i32> = (0..W * H)
        .map(|i| {
            let down = ((i / W) as f64 - 32.0) / 100.0;
            i32::from(down > 0.0 && 0.5 / down < 2.5)
        })
        .collect();
    for seed in 0..5 {
        for z in curved {
            let s = seam_fits(&kinect_cloud(z, a, seed), &halves(), &small_test());
            assert!(s.seam(0, 1).unwrap() > 0);
            assert!(s.should_merge(0, 1).unwrap(), "seed {seed}");
        }
        let s = seam_fits(&kinect_cloud(vee, a, seed), &halves(), &small_test());
        assert!(!s.should_merge(0, 1).unwrap(), "seed {seed}: V merged");
        let s = seam_fits(
            &kinect_cloud(wall_floor, a, seed),
            &split_floor,
            &small_test(),
        );
        assert!(
            !s.should_merge(0, 1).unwrap(),
            "seed {seed}: wall/floor merged"
        );
    }
}

#[test]
fn seam_test_tolerates_far_kinect_noise_only_with_the_right_model() {
    // A far wall at 4-5 m: Kinect noise σ ≈ 2.3-3.6 cm. With the Kinect model its halves merge;
    // the model of a sensor 10x quieter sees the noise as structure... but noise alone is never
    // structure across the seam, so that one merges too: the tolerance only bounds misfit.
    let far = |u: f64, v: f64| 4.0 + 0.01 * u + 0.002 * v;
    for seed in 0..5 {
        let pts = kinect_cloud(far, KINECT_V1_NOISE, seed);
        let s = seam_fits(&pts, &halves(), &small_test());
        assert!(s.should_merge(0, 1).unwrap(), "seed {seed}");
        // Per-pixel χ² of a part is about one noise variance (the model is calibrated).
        let e = s.fit_error(0).unwrap();
        assert!((0.5..1.2).contains(&e), "seed {seed}: χ²/n = {e}");
    }
}

#[test]
fn seam_numbers_are_eq_4_8() {
    let pts = kinect_cloud(
        |u, v| 2.0 + 0.1 * (u / 30.0).sin() + 0.003 * v,
        KINECT_V1_NOISE,
        3,
    );
    let labels: Vec<i32> = (0..W * H)
        .map(|i| ((i % W) / 20 + (i / W) / 25) as i32 % 3)
        .collect();
    // The exact union fit: its χ² is the merged segment's (the local one is checked below).
    let exact = SeamTest {
        window: None,
        ..small_test()
    };
    let mut s = seam_fits(&pts, &labels, &exact);
    assert_eq!(s.criterion, Criterion::Seam);
    assert_eq!(s.seam_test(), Some(&exact));
    let (n0, n2) = (s.size(0).unwrap() as f64, s.size(2).unwrap() as f64);
    let (e0, e2) = (s.fit_error(0).unwrap(), s.fit_error(2).unwrap());
    let eu = s.union_error(0, 2).unwrap();
    let seam = s.seam(0, 2).unwrap() as f64;
    assert!(seam > 0.0 && seam <= n0 + n2);
    let gain = e0 * n0 + e2 * n2 - eu * (n0 + n2);
    assert_eq!(s.should_merge(0, 2).unwrap(), gain > 0.0);
    let merged = s.merge(0, 2).unwrap();
    assert_eq!(merged, s.fit_error(0).unwrap());
    // The union's χ² = e_ij (n0 + n2) + tolerance·seam: the tolerance is spent by the merge.
    let chi_u = merged * (n0 + n2);
    assert!((chi_u - (eu * (n0 + n2) + seam)).abs() < 1e-6 * chi_u.max(1.0));
    assert!((gain - (seam - (chi_u - e0 * n0 - e2 * n2))).abs() < 1e-6 * chi_u.max(1.0));
    // Merged segments are not live; the other criteria report no seam.
    assert!(s.seam(0, 2).is_err());
    let g = fits(&pts, &labels, Criterion::Gcv);
    assert_eq!(g.seam(0, 2).unwrap(), 0);
    assert_eq!(g.seam_test(), None);
}

#[test]
fn seam_test_never_merges_segments_that_do_not_meet() {
    let pts = kinect_cloud(|_, _| 2.0, KINECT_V1_NOISE, 0);
    // Two patches of one plane, 40 pixels apart (5 cells of 8: no shared control point).
    let labels: Vec<i32> = (0..W * H)
        .map(|i| match i % W {
            u if u < 20 => 0,
            u if u >= 60 => 1,
            _ => -1,
        })
        .collect();
    let s = seam_fits(&pts, &labels, &small_test());
    assert_eq!(s.seam(0, 1).unwrap(), 0);
    assert!(!s.should_merge(0, 1).unwrap());
}

#[test]
fn seam_test_is_scale_invariant_with_a_scaled_noise_model() {
    let z = |u: f64, v: f64| 2.5 + 0.02 * (u - 48.0).abs() + 0.001 * v;
    let bulge = |u: f64, _v: f64| 1.8 - 0.3 * ((u - 48.0) / 40.0).cos();
    let labels: Vec<i32> = (0..W * H)
        .map(|i| ((i % W) / 24 + 4 * ((i / W) / 32)) as i32)
        .collect();
    for (shape, p) in [(0, 2.0), (1, 2.0), (0, 0.0), (1, 1.0)] {
        let pts = if shape == 0 {
            kinect_cloud(z, KINECT_V1_NOISE, 7)
        } else {
            kinect_cloud(bulge, KINECT_V1_NOISE, 7)
        };
        let test = SeamTest {
            noise: NoiseModel {
                scale: 0.01,
                power: p,
            },
            ..small_test()
        };
        for k in [0.001, 3.0, 1000.0] {
            // Depth in another unit (mm: k = 1000) with σ in that unit.
            let scaled: Vec<f64> = pts.iter().map(|x| x * k).collect();
            let test_k = SeamTest {
                noise: NoiseModel {
                    scale: 0.01 * f64::powf(k, 1.0 - p),
                    power: p,
                },
                ..test
            };
            let (s, sk) = (
                seam_fits(&pts, &labels, &test),
                seam_fits(&scaled, &labels, &test_k),
            );
            for i in 0..8usize {
                let (e, ek) = (s.fit_error(i).unwrap(), sk.fit_error(i).unwrap());
                assert!(
                    (e - ek).abs() <= 1e-6 * e.max(1e-3),
                    "{k} {p} {i}: {e} {ek}"
                );
                for j in i + 1..8 {
                    let (u, uk) = (s.union_error(i, j).unwrap(), sk.union_error(i, j).unwrap());
                    assert!(
                        u == uk || (u - uk).abs() <= 1e-6 * u.abs().max(1e-3),
                        "{k} {p} {i}-{j}"
                    );
                    assert_eq!(s.should_merge(i, j), sk.should_merge(i, j));
                }
            }
        }
    }
}

#[test]
fn seam_test_rejects_bad_parameters() {
    let pts = cloud(|_, _| 2.0, 0.0, 0);
    for t in [
        SeamTest {
            spacing: 0.0,
            ..SeamTest::default()
        },
        SeamTest {
            tolerance: f64::NAN,
            ..SeamTest::default()
        },
        SeamTest {
            noise: NoiseModel {
                scale: -1.0,
                power: 2.0,
            },
            ..SeamTest::default()
        },
    ] {
        let r = SegmentFits::with_test(
            &pts,
            W,
            H,
            3,
            &halves(),
            &grid(),
            DEFAULT_LAMBDA,
            Criterion::Seam,
            &t,
        );
        assert!(r.is_err());
    }
    // Segments without a positive depth: their test fit is reported per segment.
    let mut behind = cloud(|_, _| 2.0, 0.0, 0);
    for px in behind.chunks_mut(3).take(W * H / 2) {
        px[2] = -1.0;
    }
    let top_bottom: Vec<i32> = (0..W * H).map(|i| i32::from(i >= W * H / 2)).collect();
    let s = seam_fits(&behind, &top_bottom, &SeamTest::default());
    assert!(s.fit_error(0).is_err());
    assert!(s.fit_error(1).is_ok());
}

#[test]
fn test_only_decides_as_the_full_fits() {
    let pts = kinect_cloud(
        |u, v| 2.5 + 0.02 * (u - 48.0).abs() + 0.1 * (v / 20.0).sin(),
        KINECT_V1_NOISE,
        2,
    );
    let labels: Vec<i32> = (0..W * H)
        .map(|i| ((i % W) / 24 + 4 * ((i / W) / 32)) as i32)
        .collect();
    let t = small_test();
    let mut full = seam_fits(&pts, &labels, &t);
    let mut only = SegmentFits::test_only(&pts, W, H, 3, &labels, DEFAULT_LAMBDA, &t).unwrap();
    assert_eq!(only.grid, KnotGrid::new(W, H, t.spacing, 3).unwrap());
    for i in 0..8usize {
        assert_eq!(only.size(i), full.size(i));
        assert_eq!(only.fit_error(i), full.fit_error(i));
        for j in i + 1..8 {
            assert_eq!(only.union_error(i, j), full.union_error(i, j));
            assert_eq!(only.should_merge(i, j), full.should_merge(i, j));
        }
    }
    assert_eq!(only.merge(1, 2), full.merge(1, 2));
    assert_eq!(only.current_labels(), full.current_labels());
    assert_eq!(only.fit_error(1), full.fit_error(1));
    assert!(only.fit(1).is_err() && full.fit(1).is_ok());
    assert!(only.maps(&pts).is_err());
}

/// Labels of blocks `bw x bh` pixels (row-major block ids).
fn blocks(bw: usize, bh: usize) -> Vec<i32> {
    (0..W * H)
        .map(|i| ((i % W) / bw + (W / bw) * ((i / W) / bh)) as i32)
        .collect()
}

#[test]
fn local_union_fit_with_a_covering_window_is_the_exact_one() {
    let pts = kinect_cloud(
        |u, v| 2.5 + 0.02 * (u - 48.0).abs() + 0.1 * (v / 20.0).sin(),
        KINECT_V1_NOISE,
        5,
    );
    let labels = blocks(24, 32);
    let exact = SeamTest {
        window: None,
        ..small_test()
    };
    let whole = SeamTest {
        window: Some(1000),
        ..small_test()
    };
    let (mut e, mut l) = (
        seam_fits(&pts, &labels, &exact),
        seam_fits(&pts, &labels, &whole),
    );
    let check = |e: &SegmentFits, l: &SegmentFits, live: &[usize]| {
        for &i in live {
            for &j in live {
                if i == j {
                    continue;
                }
                let n = (e.size(i).unwrap() + e.size(j).unwrap()) as f64;
                let (ue, ul) = (e.union_error(i, j).unwrap(), l.union_error(i, j).unwrap());
                let chi = e.fit_error(i).unwrap() * n;
                assert!(
                    ue == ul || (ue - ul).abs() * n <= 1e-7 * chi.max(1.0),
                    "{i}-{j}: exact {ue}, local {ul}"
                );
                assert_eq!(e.seam(i, j), l.seam(i, j));
                assert_eq!(e.should_merge(i, j), l.should_merge(i, j));
            }
        }
    };
    check(&e, &l, &(0..8).collect::<Vec<_>>());
    // A merge stores the exact fit whatever the window: the same afterwards (up to the
    // summation order of the parallel solve, ~1e-13 relative).
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1e-300);
    for (i, j) in [(1, 2), (5, 1)] {
        let (a, b) = (e.merge(i, j).unwrap(), l.merge(i, j).unwrap());
        assert!(close(a, b), "merge {i}-{j}: exact {a}, local {b}");
    }
    let (a, b) = (e.fit_error(5).unwrap(), l.fit_error(5).unwrap());
    assert!(close(a, b), "fit_error 5: exact {a}, local {b}");
    check(&e, &l, &[0, 3, 4, 5, 6, 7]);
}

#[test]
fn local_union_fit_is_conservative_and_decides_as_the_exact_one() {
    // A smooth surface with a crease: unions across the crease and along the smooth part.
    let pts = kinect_cloud(
        |u, v| 2.5 + 0.02 * (u - 48.0).abs() + 0.1 * (v / 20.0).sin(),
        KINECT_V1_NOISE,
        6,
    );
    let labels = blocks(16, 16);
    let exact = SeamTest {
        window: None,
        ..small_test()
    };
    let e = seam_fits(&pts, &labels, &exact);
    let n_seg = (W / 16) * (H / 16);
    for r in [2usize, 3] {
        let l = seam_fits(
            &pts,
            &labels,
            &SeamTest {
                window: Some(r),
                ..small_test()
            },
        );
        let (mut tested, mut same) = (0, 0);
        for i in 0..n_seg {
            for j in i + 1..n_seg {
                let (ue, ul) = (e.union_error(i, j).unwrap(), l.union_error(i, j).unwrap());
                assert_eq!(ue.is_finite(), ul.is_finite(), "{i}-{j}");
                assert_eq!(e.seam(i, j), l.seam(i, j));
                if !ue.is_finite() {
                    continue;
                }
                // Fewer free control points: the union's χ² is not below the exact one (up to
                // the smoothness penalty, which the local fit trades differently).
                let n = (e.size(i).unwrap() + e.size(j).unwrap()) as f64;
                assert!(
                    (ul - ue) * n >= -1e-3 * ue.abs() * n - 1.0,
                    "{r} {i}-{j}: {ue} {ul}"
                );
                tested += 1;
                same += usize::from(e.should_merge(i, j) == l.should_merge(i, j));
            }
        }
        assert!(tested >= 30, "{tested}");
        assert_eq!(same, tested, "window {r}");
    }
}
