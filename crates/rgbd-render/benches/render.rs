//! Criterion benches of the ray caster on a ~100k-triangle room scene: first-hit depth at
//! 960x540, colour with 2x2 supersampling, and a 512x424 ToF frame with 2x2 sub-samples and
//! multipath. Python-side comparisons against trimesh/Open3D live in benches/bench_render.py.

use criterion::{criterion_group, criterion_main, Criterion};
use rgbd_geom::Pose;
use rgbd_render::{
    render_color, render_depth, simulate_tof, Material, Pattern, PointLight, Projection, Scene,
    TofOptions, View,
};

/// A 6 x 4 x 3 m room (12 triangles) holding a UV sphere of `rings x segments x 2` triangles.
fn scene(rings: usize, segments: usize) -> Scene {
    let mut v: Vec<f32> = vec![];
    let mut t: Vec<u32> = vec![];
    let mut obj: Vec<u32> = vec![];
    for i in 0..=rings {
        let th = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let ph = std::f32::consts::TAU * j as f32 / segments as f32;
            v.extend([
                0.8 * th.sin() * ph.cos(),
                0.8 * th.cos(),
                3.0 + 0.8 * th.sin() * ph.sin(),
            ]);
        }
    }
    for i in 0..rings {
        for j in 0..segments {
            let a = (i * segments + j) as u32;
            let b = (i * segments + (j + 1) % segments) as u32;
            let (c, d) = (a + segments as u32, b + segments as u32);
            t.extend([a, b, c, b, d, c]);
            obj.extend([0, 0]);
        }
    }
    let base = (v.len() / 3) as u32;
    for &x in &[-3.0f32, 3.0] {
        for &y in &[-1.5f32, 1.5] {
            for &z in &[-0.5f32, 6.0] {
                v.extend([x, y, z]);
            }
        }
    }
    let quads = [
        [0, 1, 3, 2],
        [4, 6, 7, 5],
        [0, 4, 5, 1],
        [2, 3, 7, 6],
        [0, 2, 6, 4],
        [1, 5, 7, 3],
    ];
    for q in quads {
        t.extend([
            base + q[0],
            base + q[1],
            base + q[2],
            base + q[0],
            base + q[2],
            base + q[3],
        ]);
        obj.extend([1, 1]);
    }
    let m = |p| Material {
        albedo: [0.7, 0.6, 0.5],
        albedo_ir: 0.6,
        pattern: p,
        contrast: 0.8,
    };
    Scene::new(
        &v,
        &t,
        &obj,
        vec![
            m(Pattern::Noise {
                scale: 0.05,
                seed: 1,
            }),
            m(Pattern::Checker { period: 0.3 }),
        ],
        vec![PointLight {
            position: [0.5, -1.2, 1.0],
            intensity: [3.0; 3],
        }],
        [0.1; 3],
    )
    .unwrap()
}

fn bench(c: &mut Criterion) {
    let s = scene(224, 224); // 100352 + 12 triangles
    let pose = Pose::identity();
    let stereo = View::new(
        Projection::Perspective {
            fx: 727.0,
            fy: 727.0,
            cx: 479.5,
            cy: 269.5,
        },
        960,
        540,
        &pose,
    )
    .unwrap();
    let tof = View::new(
        Projection::Perspective {
            fx: 366.0,
            fy: 366.0,
            cx: 255.5,
            cy: 211.5,
        },
        512,
        424,
        &pose,
    )
    .unwrap();
    let opts = TofOptions {
        frequency_hz: 120e6,
        subsamples: 2,
        multipath_rays: 8,
        noise: true,
        power: 4000.0,
        read_noise: 2.0,
        shot_noise: 0.4,
        ambient: 10.0,
        amplitude_threshold: 5.0,
        wrap_phase: false,
        seed: 0,
    };
    let mut g = c.benchmark_group("render");
    g.sample_size(10);
    g.bench_function("bvh_build_100k", |b| b.iter(|| scene(224, 224)));
    g.bench_function("depth_960x540", |b| b.iter(|| render_depth(&s, &stereo)));
    g.bench_function("color_960x540_ss2", |b| {
        b.iter(|| render_color(&s, &stereo, 2, true).unwrap())
    });
    g.bench_function("tof_512x424_ss2_mp8", |b| {
        b.iter(|| simulate_tof(&s, &tof, &opts).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
