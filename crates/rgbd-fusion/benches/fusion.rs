//! Criterion benches of the fusion kernels on a synthetic 480x270 textured slanted plane with two
//! noisy disparity sources: LC fusion (radius 5, stride 1 and 2) and the extended cross
//! bilateral upsampling of ToF-density samples (every 2nd pixel), region labels, mean-shift
//! filtering (half the 960 px radius) and the stereo cost-curve statistics (49 disparities).
//! The 960x540 comparisons against numpy / OpenCV live in benches/bench_fusion.py.

use criterion::{criterion_group, criterion_main, Criterion};
use rgbd_fusion::{
    cost_curve_stats, label_regions, lc_fuse, mean_shift_filter, upsample_depth, LcParams,
    MeanShiftParams, Source, UpsampleParams,
};

const W: usize = 480;
const H: usize = 270;

fn texture(u: f32, y: usize, c: usize) -> u8 {
    let v = (u * 0.7 + y as f32 * 1.3 + c as f32).sin() + (u * 0.21 - y as f32 * 0.4).cos();
    (128.0 + 60.0 * v).clamp(0.0, 255.0) as u8
}

fn truth(x: usize) -> f32 {
    10.0 + 0.02 * x as f32
}

fn inputs() -> (Vec<u8>, Vec<u8>, Vec<f32>, Vec<f32>) {
    let (mut r, mut t) = (vec![0u8; W * H * 3], vec![0u8; W * H * 3]);
    for y in 0..H {
        for x in 0..W {
            for c in 0..3 {
                r[3 * (y * W + x) + c] = texture(x as f32, y, c);
                t[3 * (y * W + x) + c] = texture(x as f32 - truth(x), y, c);
            }
        }
    }
    let noise = |i: usize, a: f32| a * (((i * 7919) % 101) as f32 / 50.0 - 1.0);
    let d1 = (0..W * H).map(|i| truth(i % W) + noise(i, 0.3)).collect();
    let d2 = (0..W * H)
        .map(|i| truth(i % W) + noise(i + 13, 1.5))
        .collect();
    (r, t, d1, d2)
}

fn bench(c: &mut Criterion) {
    let (r, t, d1, d2) = inputs();
    let sources = [
        Source {
            disparity: &d1,
            confidence: None,
        },
        Source {
            disparity: &d2,
            confidence: None,
        },
    ];
    for stride in [1, 2] {
        let p = LcParams {
            radius: 5,
            stride,
            ..LcParams::default()
        };
        c.bench_function(
            &format!("lc_fuse 480x270 2 sources r5 stride {stride}"),
            |b| b.iter(|| lc_fuse(&r, &t, W, H, &sources, &p).unwrap()),
        );
    }
    let sparse: Vec<f32> = (0..W * H)
        .map(|i| {
            if (i % W).is_multiple_of(2) && (i / W).is_multiple_of(2) {
                2.0 + 0.001 * (i % W) as f32
            } else {
                f32::NAN
            }
        })
        .collect();
    let (labels, _) = label_regions(&r, W, H, 2.0).unwrap();
    let p = UpsampleParams::default();
    c.bench_function("upsample_depth 480x270 with labels", |b| {
        b.iter(|| upsample_depth(&sparse, None, &r, Some(&labels), W, H, &p).unwrap())
    });
    c.bench_function("label_regions 480x270", |b| {
        b.iter(|| label_regions(&r, W, H, 2.0).unwrap())
    });
    let ms = MeanShiftParams {
        spatial_radius: 4.0,
        ..MeanShiftParams::default()
    };
    c.bench_function("mean_shift_filter 480x270 sp4 sr16", |b| {
        b.iter(|| mean_shift_filter(&r, W, H, &ms).unwrap())
    });
    let grey = |img: &[u8]| -> Vec<u8> {
        img.chunks_exact(3)
            .map(|p| ((u32::from(p[0]) + u32::from(p[1]) + u32::from(p[2])) / 3) as u8)
            .collect()
    };
    let (gr, gt) = (grey(&r), grey(&t));
    c.bench_function("cost_curve_stats 480x270 d0..48 7x7", |b| {
        b.iter(|| cost_curve_stats(&gr, &gt, &d2, W, H, 1, 48, 7).unwrap())
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
