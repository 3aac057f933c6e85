use super::*;

/// A wide camera (~65° across), so a floor and a wall both show in a 64 x 48 image.
const CAM: Pinhole = Pinhole {
    fx: 50.0,
    fy: 50.0,
    cx: 31.5,
    cy: 23.5,
};

/// Depth of the plane `n . p = d` seen through `CAM` (`w x h`).
fn plane(n: [f64; 3], d: f64, w: usize, h: usize) -> Vec<f32> {
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            let ray = [(x - CAM.cx) / CAM.fx, (y - CAM.cy) / CAM.fy, 1.0];
            (d / (n[0] * ray[0] + n[1] * ray[1] + n[2] * ray[2])) as f32
        })
        .collect()
}

#[test]
fn plane_normals_are_exact_and_oriented() {
    let len = (0.2f64 * 0.2 + 0.5 * 0.5 + 1.0).sqrt();
    let n = [0.2 / len, -0.5 / len, -1.0 / len]; // faces the camera
    let depth = plane(n, -2.0, 64, 48);
    for toward in [true, false] {
        let out = normals(&depth, None, 64, 48, &CAM, 3, toward).unwrap();
        let s = if toward { 1.0 } else { -1.0 };
        for px in out.chunks(3) {
            for k in 0..3 {
                assert!((px[k] as f64 - s * n[k]).abs() < 1e-4, "{px:?} vs {n:?}");
            }
        }
    }
}

/// The reference's normal by brute force: moments `[a², ab, a, b², b, 1, a/z, b/z, 1/z]` of
/// the window's valid points in normalised coordinates, the adjugate solve, then the
/// orientation (`n_z >= 0`, then `n . p >= 0` where the depth is valid).
fn naive_normal(depth: &[f32], w: usize, h: usize, x: usize, y: usize, r: usize) -> [f64; 3] {
    let rays = Rays::new(w, h, &CAM);
    let mut s = [0.0f64; 9];
    for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
        for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
            let z = depth[yy * w + xx];
            if !is_valid(z) {
                continue;
            }
            let (a, b, q) = (rays.a[xx], rays.b[yy], 1.0 / z as f64);
            let m = [a * a, a * b, a, b * b, b, 1.0, q * a, q * b, q];
            for k in 0..9 {
                s[k] += m[k];
            }
        }
    }
    let [saa, sab, sa, sbb, sb, s1, ta, tb, t1] = s;
    let c0 = sbb * s1 - sb * sb;
    let c1 = -sab * s1 + sa * sb;
    let c2 = sab * sb - sa * sbb;
    let c3 = saa * s1 - sa * sa;
    let c4 = -saa * sb + sab * sa;
    let c5 = saa * sbb - sab * sab;
    let det = saa * c0 + sab * c1 + sa * c2;
    let f2 = CAM.fx * CAM.fy;
    if s1 < 2.5 || det < MIN_SPREAD_PX4 / (f2 * f2) * s1 * s1 * s1 {
        return [f64::NAN; 3];
    }
    let n = [
        c0 * ta + c1 * tb + c2 * t1,
        c1 * ta + c3 * tb + c4 * t1,
        c2 * ta + c4 * tb + c5 * t1,
    ];
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let mut sign = if n[2] < 0.0 { -1.0 } else { 1.0 };
    let at_pixel = n[0] * rays.a[x] + n[1] * rays.b[y] + n[2];
    if is_valid(depth[y * w + x]) && sign * at_pixel < 0.0 {
        sign = -sign;
    }
    n.map(|v| sign * v / len)
}

/// A wavy surface (`w x h`), with holes where `hole(x, y)`.
fn wavy(w: usize, h: usize, hole: impl Fn(usize, usize) -> bool) -> Vec<f32> {
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if hole(x, y) {
                f32::NAN
            } else {
                2.0 + 0.3 * (x as f32 * 0.2).sin() + 0.01 * y as f32 + 0.1 * (y as f32).cos()
            }
        })
        .collect()
}

#[test]
fn sliding_sums_match_brute_force_with_holes() {
    let (w, h) = (37, 101); // more than two bands, odd sizes
                            // Holes everywhere; in a few rows only (rows whose windows are whole take the
                            // closed-form path); none.
    let scattered = wavy(w, h, |x, y| {
        (y * w + x) * 7919 % 13 < 4 || (y > 60 && y < 75 && x < 20)
    });
    let few_rows = wavy(w, h, |x, y| (y == 30 || y == 77) && x % 3 == 0);
    let none = wavy(w, h, |_, _| false);
    for (depth, r) in [1, 3, 10, 40]
        .into_iter()
        .flat_map(|r| [(&scattered, r), (&few_rows, r), (&none, r)])
    {
        let out = normals(depth, None, w, h, &CAM, r, false).unwrap();
        for y in 0..h {
            for x in 0..w {
                let n = naive_normal(depth, w, h, x, y, r);
                let got = &out[(y * w + x) * 3..][..3];
                if n[0].is_nan() {
                    assert!(got[0].is_nan(), "({x}, {y}) r {r}");
                    continue;
                }
                for k in 0..3 {
                    assert!(
                        (got[k] as f64 - n[k]).abs() < 1e-5,
                        "({x}, {y}) r {r}: {got:?} {n:?}"
                    );
                }
            }
        }
    }
}

#[test]
fn whole_windows_give_the_same_sums_both_ways() {
    let (w, h, r) = (53, 40, 4);
    let depth = wavy(w, h, |_, _| false);
    let support = Support::new(&depth, None, w, h, &CAM);
    let mut win = Window::new(r, w);
    for yy in 0..=2 * r {
        slide_columns(&mut win.cols, r, support.row(Some(yy)), support.row(None));
    }
    let y = r; // the window covers rows 0..=2r, all whole
    let mut general = win.sums.clone();
    window_row(
        &win.cols,
        &win.xs_pad,
        2 * r + 1,
        &mut win.prefix,
        &mut general,
    );
    let rows = run_moments(0, 2 * r);
    let mut full = win.sums.clone();
    let n = 2 * r + 1;
    window_row_full(
        &win.cols,
        &win.xs_pad,
        n,
        rows,
        &win.columns,
        &mut win.prefix,
        &mut full,
    );
    assert_eq!(general, full, "row {y}");
    assert_eq!(full[0][0], ((r + 1) * n) as f64); // clipped at the left border
    assert_eq!(full[0][w / 2], (n * n) as f64);
}

#[test]
fn every_simd_path_gives_the_same_bits() {
    use std::sync::atomic::Ordering;
    // Floor, wall and holes (both window paths), some pixels near angle rounding bounds.
    let (w, h) = (64, 48);
    let floor = plane([0.0, 1.0, 0.0], 1.2, w, h);
    let wall = plane([0.05, 0.02, 1.0], 5.0, w, h);
    let depth: Vec<f32> = (0..w * h)
        .map(|i| {
            let (f, wl) = (floor[i], wall[i]);
            let z = if f > 0.0 && f < wl { f } else { wl };
            if (i * 7919) % 97 < 3 && i / w > 30 {
                f32::NAN
            } else {
                z * (1.0 + 0.002 * ((i % 7) as f32))
            }
        })
        .collect();
    let run = |cap: u8| {
        SIMD_CAP.store(cap, Ordering::Relaxed);
        let out = hha(&depth, None, w, h, &CAM).unwrap();
        let n = normals(&depth, None, w, h, &CAM, 10, true).unwrap();
        SIMD_CAP.store(2, Ordering::Relaxed);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        (
            out.image,
            out.gravity,
            out.floor_cm,
            bits(&out.normals),
            bits(&n),
        )
    };
    let reference = run(0);
    assert_eq!(run(1), reference);
    assert_eq!(run(2), reference);
}

#[test]
fn holes_are_skipped_and_isolated_pixels_have_no_normal() {
    let mut depth = vec![f32::NAN; 64 * 48];
    depth[10 * 64 + 10] = 2.0;
    let out = normals(&depth, None, 64, 48, &CAM, 3, true).unwrap();
    assert!(out.iter().all(|v| v.is_nan()));
    // A single row of points is collinear in the image: no plane.
    let mut depth = vec![f32::NAN; 64 * 48];
    depth[640..704].fill(2.0);
    let out = normals(&depth, None, 64, 48, &CAM, 3, true).unwrap();
    assert!(out.iter().all(|v| v.is_nan()));
}

#[test]
fn jacobi_finds_the_smallest_eigenvector() {
    let y = [0.0, 1.0, 0.0];
    let e = smallest_direction([[2.0, 1.0, 0.0], [1.0, 2.0, 0.0], [0.0, 0.0, 5.0]], y);
    let s = std::f64::consts::FRAC_1_SQRT_2;
    assert!(
        (e[0] + s).abs() < 1e-12 && (e[1] - s).abs() < 1e-12 && e[2] == 0.0,
        "{e:?}"
    );
    // A single wall (normals along z): the tied x-y eigenspace keeps the previous estimate.
    let e = smallest_direction([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 9.0]], y);
    assert_eq!(e, y);
    let prev = [0.6, 0.8, 0.0];
    let e = smallest_direction([[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 9.0]], prev);
    assert!((e[0] - 0.6).abs() < 1e-12 && (e[1] - 0.8).abs() < 1e-12);
}

#[test]
fn rotation_takes_y0_to_gravity() {
    for g in [
        [0.0, 1.0, 0.0],
        [0.3, 0.9, -0.1],
        [0.0, -1.0, 0.0],
        [1.0, 0.0, 0.0],
    ] {
        let n: f64 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
        let g = g.map(|v: f64| v / n.sqrt());
        let r = rotation_to(g);
        for i in 0..3 {
            assert!((r[i][1] - g[i]).abs() < 1e-12, "{r:?} {g:?}");
        }
    }
}

#[test]
fn millimetres_and_empty_depth_are_refused() {
    let mm = vec![2500.0f32; 16];
    let e = hha(&mm, None, 4, 4, &CAM).unwrap_err().to_string();
    assert!(e.contains("millimetres"), "{e}");
    let none = vec![f32::NAN; 16];
    let e = hha(&none, None, 4, 4, &CAM).unwrap_err().to_string();
    assert!(e.starts_with("depth: got no valid depth"), "{e}");
}

#[test]
fn floor_and_wall_give_gravity_down() {
    // Floor 1.2 m below the camera (y = 1.2) and a wall at z = 8 in front.
    let (w, h) = (64, 48);
    let floor = plane([0.0, 1.0, 0.0], 1.2, w, h);
    let wall = plane([0.0, 0.0, 1.0], 8.0, w, h);
    let depth: Vec<f32> = floor
        .iter()
        .zip(&wall)
        .map(|(&f, &wl)| if f > 0.0 && f < wl { f } else { wl })
        .collect();
    let out = hha(&depth, None, w, h, &CAM).unwrap();
    // Windows straddling the crease tilt the estimate a little in so small an image.
    let tilt = out.gravity[1].clamp(-1.0, 1.0).acos().to_degrees();
    assert!(tilt < 2.0, "{:?}", out.gravity);
    assert!((out.floor_cm + 120.0).abs() < 20.0, "{}", out.floor_cm);
    // Floor pixels: angle ~0 (+38); wall: angle ~90 (+38); wall disparity 31000/800.
    let last = (h - 1) * w + w / 2;
    assert!(
        out.image[last * 3 + 2].abs_diff(38) <= 2,
        "{}",
        out.image[last * 3 + 2]
    );
    assert!(out.image[(w / 2) * 3 + 2].abs_diff(128) <= 2);
    assert_eq!(out.image[(w / 2) * 3], 39);
}
