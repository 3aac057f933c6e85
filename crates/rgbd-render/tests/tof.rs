//! Each ToF error source moves the error the way the physics says.
mod common;

use common::{finite_mean, grey, ideal, pinhole, Builder};
use rgbd_render::simulate_tof;

#[test]
fn ideal_sensor_measures_truth() {
    let scene = Builder::new().wall(3.0, 10.0, 0).scene(vec![grey(0.5)]);
    let f = simulate_tof(&scene, &pinhole(32, 24, 30.0), &ideal()).unwrap();
    for (m, t) in f.depth.iter().zip(&f.truth) {
        assert!((m - t).abs() < 1e-5 && (t - 3.0).abs() < 1e-6, "{m} {t}");
    }
    // Amplitude follows power * albedo * cos / d^2 (cos = 1 at the centre).
    let c = 12 * 32 + 16;
    let r = (3.0f32 * 3.0 + (0.5 / 30.0f32).powi(2) * 9.0 * 2.0).sqrt();
    let want = 4000.0 * 0.5 * (3.0 / r) / (r * r);
    assert!(
        (f.amplitude[c] / want - 1.0).abs() < 1e-3,
        "{} vs {want}",
        f.amplitude[c]
    );
}

#[test]
fn wrapped_phase_folds_range() {
    let scene = Builder::new().wall(2.0, 10.0, 0).scene(vec![grey(0.5)]);
    let mut o = ideal();
    o.wrap_phase = true;
    let f = simulate_tof(&scene, &pinhole(8, 8, 100.0), &o).unwrap();
    let unamb = 299_792_458.0 / (2.0 * 120e6); // 1.249 m
    let radial = 2.0 * (1.0f64 + 2.0 * (0.5f64 / 100.0).powi(2)).sqrt();
    let want = (radial % unamb) * 2.0 / radial;
    assert!(
        (f.depth[3 * 8 + 3] as f64 - want).abs() < 1e-4,
        "{} vs {want}",
        f.depth[27]
    );
}

#[test]
fn mixed_pixels_only_at_depth_edges() {
    // Foreground half-plane x < 0 at 1.5 m in front of a wall at 3 m.
    let mut b = Builder::new();
    b.wall(3.0, 10.0, 0);
    b.quad(
        [
            [-10.0, -10.0, 1.5],
            [0.013, -10.0, 1.5],
            [0.013, 10.0, 1.5],
            [-10.0, 10.0, 1.5],
        ],
        0,
    );
    let scene = b.scene(vec![grey(0.5)]);
    let view = pinhole(40, 10, 40.0);
    let mut o = ideal();
    o.subsamples = 4;
    let f = simulate_tof(&scene, &view, &o).unwrap();
    let err: Vec<f32> = f
        .depth
        .iter()
        .zip(&f.truth)
        .map(|(m, t)| (m - t).abs())
        .collect();
    for r in 0..10 {
        for c in 0..40 {
            let e = err[r * 40 + c];
            if (c as i32 - 20).abs() > 1 {
                // Sub-rays of one pixel see slightly different ranges even on a plane.
                assert!(e < 1e-3, "({r},{c}) error {e} away from the edge");
            }
        }
        // The edge pixel lies between the two depths.
        let e = err[r * 40 + 20].max(err[r * 40 + 19]);
        assert!(e > 0.05, "row {r}: no flying pixel at the edge ({e})");
    }
}

#[test]
fn multipath_biases_corners_away_from_the_camera() {
    // A plane alone cannot light itself: no multipath bias. Add a side wall (x = 1, z in
    // [1, 3]) meeting the back wall (z = 3) in a concave corner at column ~24.5.
    let view = pinhole(30, 30, 30.0);
    let mut o = ideal();
    o.multipath_rays = 64;
    // At 20 MHz every detour is shorter than half a modulation wavelength, so multipath can
    // only lengthen the measured range; at 120 MHz long detours wrap around and can pull it
    // either way, but the corner bias stays positive on average.
    o.frequency_hz = 20e6;
    let mut b = Builder::new();
    b.wall(3.0, 10.0, 0);
    let flat = simulate_tof(&b.scene(vec![grey(0.8)]), &view, &o).unwrap();
    assert!(flat
        .depth
        .iter()
        .zip(&flat.truth)
        .all(|(m, t)| (m - t).abs() < 1e-5));
    b.quad(
        [
            [1.0, -10.0, 1.0],
            [1.0, 10.0, 1.0],
            [1.0, 10.0, 3.0],
            [1.0, -10.0, 3.0],
        ],
        0,
    );
    let scene = b.scene(vec![grey(0.8)]);
    let cols = |f: &rgbd_render::TofFrame, c0: usize, c1: usize| {
        finite_mean(
            (0..30)
                .flat_map(|r| (c0..c1).map(move |c| r * 30 + c))
                .map(|k| f.depth[k] - f.truth[k]),
        )
    };
    let f = simulate_tof(&scene, &view, &o).unwrap();
    let back_wall = |k: usize| k % 30 < 24;
    assert!(
        (0..900)
            .filter(|&k| back_wall(k))
            .all(|k| f.depth[k] - f.truth[k] > -1e-5),
        "multipath only lengthens paths at 20 MHz"
    );
    let near = cols(&f, 19, 24);
    assert!(near > 0.003, "corner bias {near}");
    // A darker side wall reflects less: less bias.
    let dark = simulate_tof(&b.scene_with(vec![grey(0.8), grey(0.2)], 1), &view, &o).unwrap();
    let near_dark = cols(&dark, 19, 24);
    assert!(
        near_dark > 0.0 && near_dark < 0.5 * near,
        "dark side wall {near_dark} vs {near}"
    );
    o.frequency_hz = 120e6;
    let f = simulate_tof(&scene, &view, &o).unwrap();
    let near = cols(&f, 20, 24);
    assert!(near > 0.002, "120 MHz corner bias {near}");
}

#[test]
fn noise_rises_as_albedo_falls_and_dark_pixels_drop_out() {
    let mut b = Builder::new();
    b.quad(
        [
            [-10.0, -10.0, 3.0],
            [0.0, -10.0, 3.0],
            [0.0, 10.0, 3.0],
            [-10.0, 10.0, 3.0],
        ],
        0,
    );
    b.quad(
        [
            [0.0, -10.0, 3.0],
            [10.0, -10.0, 3.0],
            [10.0, 10.0, 3.0],
            [0.0, 10.0, 3.0],
        ],
        1,
    );
    let view = pinhole(40, 40, 40.0);
    let mut o = ideal();
    o.noise = true;
    let rms = |scene: &rgbd_render::Scene, o: &rgbd_render::TofOptions, left: bool| {
        let f = simulate_tof(scene, &view, o).unwrap();
        let mut e = vec![];
        for r in 0..40 {
            for c in if left { 2..18 } else { 22..38 } {
                let k = r * 40 + c;
                e.push((f.depth[k] - f.truth[k]) as f64);
            }
        }
        let valid: Vec<f64> = e.iter().cloned().filter(|x| x.is_finite()).collect();
        let r = (valid.iter().map(|x| x * x).sum::<f64>() / valid.len().max(1) as f64).sqrt();
        (r, valid.len())
    };
    let scene = b.scene(vec![grey(0.8), grey(0.1)]);
    let (bright, _) = rms(&scene, &o, true);
    let (dark, _) = rms(&scene, &o, false);
    assert!(
        dark > 1.8 * bright && bright > 1e-4,
        "rms bright {bright}, dark {dark}"
    );
    o.amplitude_threshold = 100.0; // between the two amplitudes (~355 vs ~44)
    let (_, n_bright) = rms(&scene, &o, true);
    let (_, n_dark) = rms(&scene, &o, false);
    assert_eq!(n_bright, 16 * 40);
    assert_eq!(n_dark, 0);
}

#[test]
fn deterministic_and_seeded() {
    let scene = Builder::new().wall(3.0, 10.0, 0).scene(vec![grey(0.5)]);
    let view = pinhole(16, 16, 16.0);
    let mut o = ideal();
    o.noise = true;
    o.multipath_rays = 4;
    let a = simulate_tof(&scene, &view, &o).unwrap();
    let b = simulate_tof(&scene, &view, &o).unwrap();
    assert_eq!(a, b);
    o.seed = 1;
    assert_ne!(a.depth, simulate_tof(&scene, &view, &o).unwrap().depth);
    o.subsamples = 0;
    assert!(simulate_tof(&scene, &view, &o)
        .unwrap_err()
        .to_string()
        .contains("subsamples"));
}
