//! Criterion benches of the geometry kernels at the sizes the pipelines use.
//! The Python script benches/bench_geom.py compares the same operations against OpenCV.

use criterion::{criterion_group, criterion_main, Criterion};
use rgbd_geom::{
    reproject_depth, undistort_image, undistort_map, Camera, Distortion, ImageRef, Interpolation,
    Intrinsics, Pose, ReprojectOptions, UNDISTORT_MAX_ITER, UNDISTORT_TOL,
};
use std::hint::black_box;

fn hd_camera() -> Camera {
    Camera::new(
        Intrinsics::new(1400.0, 1400.0, 959.5, 539.5, 1920, 1080).unwrap(),
        Distortion::from_opencv(&[-0.28, 0.07, 1e-4, -2e-4, -0.008]).unwrap(),
    )
}

fn bench_projection(c: &mut Criterion) {
    let cam = hd_camera();
    let n = 1_000_000;
    let pts: Vec<f64> = (0..n)
        .flat_map(|i| {
            let t = i as f64 / n as f64;
            [(t * 97.0).sin() * 0.6, (t * 53.0).cos() * 0.4, 1.0 + t]
        })
        .collect();
    let pose = Pose::new(
        [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        [0.05, 0.0, 0.0],
    )
    .unwrap();
    c.bench_function("project_points_1M_distorted", |b| {
        b.iter(|| cam.project_points(black_box(&pts), &pose).unwrap())
    });
}

fn bench_undistort(c: &mut Criterion) {
    let cam = hd_camera();
    let ideal = cam.intrinsics;
    c.bench_function("undistort_map_1920x1080", |b| {
        b.iter(|| undistort_map(black_box(&cam), &ideal, None))
    });
    let map = undistort_map(&cam, &ideal, None);
    let img: Vec<f32> = (0..ideal.len() * 3).map(|i| (i % 251) as f32).collect();
    let view = ImageRef::new(&img, 1920, 1080, 3).unwrap();
    c.bench_function("remap_linear_1920x1080x3", |b| {
        b.iter(|| rgbd_geom::remap(black_box(view), &map, 1920, Interpolation::Linear).unwrap())
    });
    c.bench_function("undistort_image_linear_1920x1080x3", |b| {
        b.iter(|| {
            undistort_image(black_box(view), &cam, &ideal, None, Interpolation::Linear).unwrap()
        })
    });
}

fn bench_reproject(c: &mut Criterion) {
    let tof = Camera::new(
        Intrinsics::new(504.0, 504.0, 319.5, 287.5, 640, 576).unwrap(),
        Distortion::from_opencv(&[0.55, -0.02, 2e-5, -7e-5, -0.003, 0.89, 0.086, -0.014]).unwrap(),
    );
    let color = Camera::new(
        Intrinsics::new(612.0, 612.0, 639.5, 359.5, 1280, 720).unwrap(),
        Distortion::from_opencv(&[0.33, -2.49, -1.6e-4, -1.3e-4, 1.45, 0.21, -2.3, 1.38]).unwrap(),
    );
    let depth: Vec<f32> = (0..tof.intrinsics.len())
        .map(|i| 1.0 + (i % 640) as f32 / 640.0)
        .collect();
    let pose = Pose::new(
        [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
        [-0.032, -0.002, 0.004],
    )
    .unwrap();
    let opts = ReprojectOptions {
        splat_radius: 1,
        max_iter: UNDISTORT_MAX_ITER,
        tol: UNDISTORT_TOL,
    };
    c.bench_function("reproject_tof_640x576_to_1280x720", |b| {
        b.iter(|| reproject_depth(black_box(&depth), &tof, &color, &pose, None, opts).unwrap())
    });
}

criterion_group!(benches, bench_projection, bench_undistort, bench_reproject);
criterion_main!(benches);
