//! Throughput of every metric on 256x256 and 1024x1024 RGB images, and of the distribution
//! distances on feature sets of the sizes they meet in practice.
//!
//! Run: `cargo bench -p uwnr-metrics --bench metrics` (add `-- --quick` for a short run).

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use uwnr_core::Image;
use uwnr_metrics::{
    ColorTextureFeatures, FeatureExtractor, FeatureStats, frechet_distance,
    frechet_distance_from_stats, kid, psnr, psnr_gray, ssim, uciqe, uiqm,
};

const SIDES: [usize; 2] = [256, 1024];

/// A deterministic textured RGB image (no RNG dependency in the bench).
fn textured(side: usize, phase: f32) -> Image {
    let mut img = Image::filled(side, side, 3, 0.0);
    for c in 0..3 {
        for (i, v) in img.plane_mut(c).iter_mut().enumerate() {
            let (x, y) = ((i % side) as f32, (i / side) as f32);
            let hash = ((i as u32).wrapping_mul(2_654_435_761) >> 24) as f32 / 255.0;
            *v = (0.45 + 0.3 * (x * 0.05 + phase + c as f32).sin() * (y * 0.03).cos() + 0.1 * hash)
                .clamp(0.0, 1.0);
        }
    }
    img
}

fn features(n: usize, d: usize, shift: f64) -> Vec<Vec<f64>> {
    (0..n)
        .map(|i| {
            (0..d)
                .map(|j| {
                    (((i * 31 + j * 17) % 97) as f64 / 97.0 - 0.5) * (1.0 + 0.01 * j as f64) + shift
                })
                .collect()
        })
        .collect()
}

fn image_metrics(c: &mut Criterion) {
    let mut group = c.benchmark_group("image_metrics");
    group.sample_size(10);
    for side in SIDES {
        let a = textured(side, 0.0);
        let b = textured(side, 0.3);
        group.throughput(Throughput::Elements((side * side) as u64));
        group.bench_with_input(BenchmarkId::new("psnr", side), &side, |bench, _| {
            bench.iter(|| psnr(black_box(&a), black_box(&b), 1.0).unwrap());
        });
        group.bench_with_input(BenchmarkId::new("psnr_gray", side), &side, |bench, _| {
            bench.iter(|| psnr_gray(black_box(&a), black_box(&b), 1.0).unwrap());
        });
        group.bench_with_input(BenchmarkId::new("ssim", side), &side, |bench, _| {
            bench.iter(|| ssim(black_box(&a), black_box(&b), 1.0).unwrap());
        });
        group.bench_with_input(BenchmarkId::new("uiqm", side), &side, |bench, _| {
            bench.iter(|| uiqm(black_box(&a)).unwrap());
        });
        group.bench_with_input(BenchmarkId::new("uciqe", side), &side, |bench, _| {
            bench.iter(|| uciqe(black_box(&a)).unwrap());
        });
        let fx = ColorTextureFeatures::new();
        group.bench_with_input(
            BenchmarkId::new("color_texture_features", side),
            &side,
            |bench, _| {
                bench.iter(|| fx.extract(black_box(&a)).unwrap());
            },
        );
    }
    group.finish();
}

fn distances(c: &mut Criterion) {
    let mut group = c.benchmark_group("distances");
    group.sample_size(10);
    // FD-ct on 500 images per side (stats route, d = 155).
    let (a, b) = (features(500, 155, 0.0), features(500, 155, 0.1));
    group.bench_function("frechet_n500_d155", |bench| {
        bench.iter(|| frechet_distance(black_box(&a), black_box(&b)).unwrap());
    });
    // FID-sized features with a small evaluation set (sample route, n < d).
    let (a, b) = (features(200, 2048, 0.0), features(200, 2048, 0.1));
    group.bench_function("frechet_n200_d2048", |bench| {
        bench.iter(|| frechet_distance(black_box(&a), black_box(&b)).unwrap());
    });
    // Cached 512-d statistics (stats route: one eigendecomposition with vectors, one without).
    let (sa, sb) = (
        FeatureStats::from_features(&features(600, 512, 0.0)).unwrap(),
        FeatureStats::from_features(&features(600, 512, 0.1)).unwrap(),
    );
    group.bench_function("frechet_stats_d512", |bench| {
        bench.iter(|| frechet_distance_from_stats(black_box(&sa), black_box(&sb)).unwrap());
    });
    let (a, b) = (features(1000, 2048, 0.0), features(1000, 2048, 0.1));
    group.bench_function("kid_100x1000_d2048", |bench| {
        bench.iter(|| kid(black_box(&a), black_box(&b), 100, 1000, 0).unwrap());
    });
    group.finish();
}

criterion_group!(benches, image_metrics, distances);
criterion_main!(benches);
