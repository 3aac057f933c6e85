//! Criterion benches of the spline kernels at the sizes. benches/bench_spline.py compares
//! the same fits against scipy's LSQBivariateSpline in one run.

use criterion::{criterion_group, criterion_main, Criterion as Bench};
use rgbd_spline::maps::surface_maps_box;
use rgbd_spline::{fit_grid, fit_mask, Criterion, KnotGrid, Region, SegmentFits, DEFAULT_LAMBDA};
use std::hint::black_box;
use std::time::{Duration, Instant};

/// CPU time of this process (all threads) from /proc/self/stat (USER_HZ = 100 ticks per second).
fn process_cpu() -> Option<Duration> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which may hold spaces) start at field 3.
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks: u64 = f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?;
    Some(Duration::from_millis(ticks * 10))
}

/// Times `f` by wall clock, or by the process' CPU time when `SPLINE_BENCH_CPU` is set (a shared,
/// loaded machine: other processes then inflate wall time but not CPU time; 10 ms resolution,
/// each sample runs for at least 100 ms of CPU time).
fn timed<R>(b: &mut criterion::Bencher, mut f: impl FnMut() -> R) {
    if std::env::var_os("SPLINE_BENCH_CPU").is_none() {
        b.iter(f);
        return;
    }
    b.iter_custom(|iters| {
        let (t0, w0) = (process_cpu(), Instant::now());
        // Whole batches of `iters` until at least 100 ms of CPU time (the clock ticks at 10 ms).
        let mut done = 0u64;
        loop {
            for _ in 0..iters {
                black_box(f());
            }
            done += iters;
            let spent = match (t0, process_cpu()) {
                (Some(a), Some(z)) => z.saturating_sub(a),
                _ => w0.elapsed(),
            };
            if spent >= Duration::from_millis(100) {
                return spent.mul_f64(iters as f64 / done as f64);
            }
        }
    })
}

/// Organised cloud of a smooth surface seen by a 640x480-class pinhole camera.
fn cloud(w: usize, h: usize) -> Vec<f32> {
    let mut out = Vec::with_capacity(w * h * 3);
    for v in 0..h {
        for u in 0..w {
            let z = 2.0 + 0.3 * (u as f64 / 40.0).sin() * (v as f64 / 30.0).cos();
            let (x, y) = (
                (u as f64 - w as f64 / 2.0) / 525.0,
                (v as f64 - h as f64 / 2.0) / 525.0,
            );
            out.extend_from_slice(&[(x * z) as f32, (y * z) as f32, z as f32]);
        }
    }
    out
}

fn bench_segment(c: &mut Bench) {
    let (w, h) = (640, 480);
    let pts = cloud(w, h);
    // 10k pixels, 10x10 cells: as scipy's 10x10 interior knots.
    let mask: Vec<bool> = (0..w * h)
        .map(|i| (200..300).contains(&(i % w)) && (100..200).contains(&(i / w)))
        .collect();
    let grid = KnotGrid::new(w, h, 10.0, 3).unwrap();
    c.bench_function("fit_mask 10k px, 10x10 cells", |b| {
        timed(b, || {
            fit_mask(
                black_box(&pts),
                w,
                h,
                3,
                Some(&mask),
                &grid,
                DEFAULT_LAMBDA,
                true,
            )
            .unwrap()
        })
    });
    // As the Python API: no degrees of freedom, then the maps of the segment's box.
    c.bench_function("fit_mask 10k px, 10x10 cells, no dof", |b| {
        timed(b, || {
            fit_mask(
                black_box(&pts),
                w,
                h,
                3,
                Some(&mask),
                &grid,
                DEFAULT_LAMBDA,
                false,
            )
            .unwrap()
        })
    });
    let frame = Region {
        u0: 200,
        u1: 300,
        v0: 100,
        v1: 200,
    };
    let box_pts: Vec<f32> = (frame.v0..frame.v1)
        .flat_map(|v| pts[(v * w + frame.u0) * 3..(v * w + frame.u1) * 3].to_vec())
        .collect();
    let fit = fit_mask(&pts, w, h, 3, Some(&mask), &grid, DEFAULT_LAMBDA, false).unwrap();
    c.bench_function("box maps 10k px", |b| {
        timed(b, || {
            surface_maps_box(black_box(&box_pts), None, frame, w, h, &fit).unwrap()
        })
    });
    // 300 segments of 32x32 pixels (20 x 15 tiles), 16-pixel spacing.
    let labels: Vec<i32> = (0..w * h)
        .map(|i| ((i / w) / 32 * 20 + (i % w) / 32) as i32)
        .collect();
    let g16 = KnotGrid::new(w, h, 16.0, 3).unwrap();
    c.bench_function("SegmentFits 640x480, 300 segments", |b| {
        timed(b, || {
            SegmentFits::new(
                black_box(&pts),
                w,
                h,
                3,
                &labels,
                &g16,
                DEFAULT_LAMBDA,
                Criterion::Gcv,
            )
            .unwrap()
        })
    });
    for (name, crit) in [("mse", Criterion::Mse), ("seam", Criterion::Seam)] {
        c.bench_function(&format!("SegmentFits 640x480, 300 segments, {name}"), |b| {
            timed(b, || {
                SegmentFits::new(
                    black_box(&pts),
                    w,
                    h,
                    3,
                    &labels,
                    &g16,
                    DEFAULT_LAMBDA,
                    crit,
                )
                .unwrap()
            })
        });
    }
    c.bench_function("SegmentFits::test_only 640x480, 300 segments", |b| {
        timed(b, || {
            SegmentFits::test_only(
                black_box(&pts),
                w,
                h,
                3,
                &labels,
                DEFAULT_LAMBDA,
                &Default::default(),
            )
            .unwrap()
        })
    });
    // The seam test on the 565 pairs of 4-adjacent tiles.
    let tiles = SegmentFits::new(
        &pts,
        w,
        h,
        3,
        &labels,
        &g16,
        DEFAULT_LAMBDA,
        Criterion::Seam,
    )
    .unwrap();
    let adj: Vec<(usize, usize)> = (0..300usize)
        .filter(|i| i % 20 != 19)
        .map(|i| (i, i + 1))
        .chain((0..280).map(|i| (i, i + 20)))
        .collect();
    c.bench_function("should_merge seam, 565 adjacent tile pairs", |b| {
        timed(b, || {
            adj.iter()
                .filter(|&&(i, j)| tiles.should_merge(i, j).unwrap())
                .count()
        })
    });
    // Two adjacent 5k-pixel segments (71x71 squares).
    let pair: Vec<i32> = (0..w * h)
        .map(|i| {
            let (u, v) = (i % w, i / w);
            match (u, v) {
                (100..171, 100..171) => 0,
                (171..242, 100..171) => 1,
                _ => -1,
            }
        })
        .collect();
    let fits =
        SegmentFits::new(&pts, w, h, 3, &pair, &g16, DEFAULT_LAMBDA, Criterion::Gcv).unwrap();
    c.bench_function("union_error 2 x 5k px", |b| {
        timed(b, || fits.union_error(black_box(0), 1).unwrap())
    });
}

fn bench_view(c: &mut Bench) {
    let (w, h) = (320, 320);
    let pts = cloud(w, h);
    for s in [16.0, 8.0] {
        let grid = KnotGrid::new(w, h, s, 3).unwrap();
        c.bench_function(&format!("fit_grid 320x320 s={s}"), |b| {
            timed(b, || {
                fit_grid(black_box(&pts), w, h, 3, &grid, DEFAULT_LAMBDA, false).unwrap()
            })
        });
        let fit = fit_grid(&pts, w, h, 3, &grid, DEFAULT_LAMBDA, false).unwrap();
        c.bench_function(&format!("fit_grid + maps 320x320 s={s}"), |b| {
            timed(b, || {
                let fit = fit_grid(black_box(&pts), w, h, 3, &grid, DEFAULT_LAMBDA, false).unwrap();
                rgbd_spline::surface_maps(&pts, w, h, 3, None, |_| Some(&fit))
            })
        });
        c.bench_function(&format!("maps 320x320 s={s}"), |b| {
            timed(b, || {
                rgbd_spline::surface_maps(black_box(&pts), w, h, 3, None, |_| Some(&fit))
            })
        });
    }
}

criterion_group!(benches, bench_segment, bench_view);
criterion_main!(benches);
