//! Segment fits, unions and merges (thesis §4.5, §4.7 eq. 4.8).

use rgbd_spline::{fit_grid, fit_mask, Criterion, FitKind, KnotGrid, SegmentFits, DEFAULT_LAMBDA};

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
