//! Exact geometry of the ray caster: planes at known depth, orthographic views, normals, splats.
mod common;

use common::{grey, pinhole, Builder};
use rgbd_geom::Pose;
use rgbd_render::{render_depth, render_gbuffer, render_points, Projection, View};

#[test]
fn fronto_parallel_plane_has_exact_depth() {
    let scene = Builder::new().wall(2.5, 10.0, 0).scene(vec![grey(0.5)]);
    let view = pinhole(64, 48, 50.0);
    let d = render_depth(&scene, &view).unwrap();
    assert!(d.iter().all(|&z| (z - 2.5).abs() < 1e-6), "{:?}", &d[..4]);
}

#[test]
fn slanted_plane_matches_analytic_depth() {
    // Plane z = 2 + 0.5 x: along the ray (x0 z, y0 z, z): z = 2 / (1 - 0.5 x0).
    let mut b = Builder::new();
    let pts = [[-5.0f32, -5.0], [5.0, -5.0], [5.0, 5.0], [-5.0, 5.0]];
    b.quad(pts.map(|[x, y]| [x, y, 2.0 + 0.5 * x]), 0);
    let scene = b.scene(vec![grey(0.5)]);
    let view = pinhole(40, 30, 40.0);
    let g = render_gbuffer(&scene, &view).unwrap();
    for r in 0..30 {
        for c in 0..40 {
            let x0 = (c as f64 - 19.5) / 40.0;
            let want = 2.0 / (1.0 - 0.5 * x0);
            let got = g.depth[r * 40 + c] as f64;
            assert!(
                (got - want).abs() < 1e-5 * want,
                "({r},{c}) {got} vs {want}"
            );
        }
    }
    // Normal faces the camera: (0.5, 0, -1)/|.|
    let n = &g.normal[0..3];
    let k = 1.0 / 1.25f32.sqrt();
    assert!((n[0] - 0.5 * k).abs() < 1e-5 && n[1].abs() < 1e-5 && (n[2] + k).abs() < 1e-5);
    assert!(g.prim.iter().all(|&p| p == 0 || p == 1) && g.object.iter().all(|&o| o == 0));
}

#[test]
fn orthographic_and_posed_views() {
    let scene = Builder::new().wall(3.0, 1.0, 0).scene(vec![grey(0.5)]);
    // Camera 1 m in front of the origin looking along +z: the wall is 4 m away.
    let pose = Pose::new(
        [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        [0.0, 0.0, 1.0],
    )
    .unwrap();
    let ortho = View::new(
        Projection::Orthographic {
            sx: 10.0,
            sy: 10.0,
            cx: 15.5,
            cy: 15.5,
        },
        32,
        32,
        &pose,
    )
    .unwrap();
    let d = render_depth(&scene, &ortho).unwrap();
    // +-1 m at 10 px/m: columns 6..=25 are inside (|c - 15.5| / 10 < 1).
    for c in 0..32 {
        let inside = ((c as f64 - 15.5) / 10.0).abs() < 1.0;
        let z = d[16 * 32 + c];
        assert_eq!(z.is_finite(), inside, "col {c}");
        if inside {
            assert!((z - 4.0).abs() < 1e-6);
        }
    }
}

#[test]
fn splats_cover_their_disk_and_keep_the_nearest() {
    let view = pinhole(21, 21, 10.0);
    // Two points on the axis: the nearer wins; radius 0.2 m at 1 m and 10 px focal = 2 px.
    let (d, idx) = render_points(&[0.0, 0.0, 2.0, 0.0, 0.0, 1.0], 0.2, &view).unwrap();
    assert_eq!(idx[10 * 21 + 10], 1);
    assert!((d[10 * 21 + 10] - 1.0).abs() < 1e-6);
    let covered = idx.iter().filter(|&&i| i == 1).count();
    assert_eq!(covered, 13, "disk of radius 2 px covers 13 pixel centres");
    assert!(render_points(&[0.0; 4], 0.1, &view).is_err());
    assert!(render_points(&[0.0; 3], 0.0, &view).is_err());
}
