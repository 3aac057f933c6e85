//! Criterion benches of the census SGM on a synthetic 960x540 textured scene (a slanted
//! background and a nearer box, 128 disparities): the default 8-path call on every kernel build
//! the processor has, the 4- and 5-path variants, and the statistics option. The comparison
//! against OpenCV's SGBM (same pair, same run) lives in benches/bench_stereo.py.

use criterion::{criterion_group, criterion_main, Criterion};
use rgbd_stereo::{sgm_with, Kernel, Paths, Reference, SgmParams};

const W: usize = 960;
const H: usize = 540;

fn texture(u: f32, y: usize) -> u8 {
    let v = (u * 0.7 + y as f32 * 1.3).sin()
        + (u * 0.21 - y as f32 * 0.4).cos()
        + ((u * 0.05).sin() * 3.0 + y as f32 * 0.11).sin();
    (128.0 + 40.0 * v).clamp(0.0, 255.0) as u8
}

/// Disparity of the scene at a left-image pixel: a slanted plane with a box 40 px nearer.
fn truth(x: usize, y: usize) -> f32 {
    let near = (300..600).contains(&x) && (150..400).contains(&y);
    20.0 + 0.03 * x as f32 + if near { 40.0 } else { 0.0 }
}

fn pair() -> (Vec<u8>, Vec<u8>) {
    let mut l = vec![0u8; W * H];
    let mut r = vec![0u8; W * H];
    for y in 0..H {
        for x in 0..W {
            l[y * W + x] = texture(x as f32, y);
            // The right view sees the left's pixel x at x - d: sample the left texture there.
            r[y * W + x] = texture(x as f32 + truth(x, y), y);
        }
    }
    (l, r)
}

fn bench(c: &mut Criterion) {
    let (l, r) = pair();
    let mut g = c.benchmark_group("sgm_960x540_d128");
    g.sample_size(10);
    let p = SgmParams::new(127);
    for k in Kernel::available() {
        g.bench_function(format!("8 paths {k:?}"), |b| {
            b.iter(|| sgm_with(&l, &r, W, H, Reference::Left, &p, k).unwrap())
        });
    }
    let best = Kernel::best();
    for paths in [Paths::Four, Paths::Five] {
        let q = SgmParams { paths, ..p.clone() };
        g.bench_function(format!("{paths:?} paths {best:?}"), |b| {
            b.iter(|| sgm_with(&l, &r, W, H, Reference::Left, &q, best).unwrap())
        });
    }
    let q = SgmParams {
        stats: true,
        ..p.clone()
    };
    g.bench_function(format!("8 paths + stats {best:?}"), |b| {
        b.iter(|| sgm_with(&l, &r, W, H, Reference::Left, &q, best).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
