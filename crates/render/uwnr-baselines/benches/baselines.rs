//! Time of each baseline on 256x256 and 1024x1024 clean images (400x300 reference, the size of
//! the RUIE references). Run with `cargo bench -p uwnr-baselines`; criterion reports the time per
//! render and the throughput in pixels per second.

use std::hint::black_box;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use uwnr_baselines::{
    JerlovParams, Method, ReferenceCoefficients, ReinhardParams, RenderInput, SeathruCoefficients,
    SeathruParams, UisaParams, render,
};
use uwnr_core::Image;

/// Clean image sides benchmarked.
const SIDES: [usize; 2] = [256, 1024];
/// Reference size (RUIE's 400x300).
const REFERENCE_SIZE: (usize, usize) = (400, 300);

/// A deterministic textured image (no generator needed): smooth gradients with a fine pattern.
fn texture(w: usize, h: usize, c: usize, tint: [f32; 3]) -> Image {
    let mut data = vec![0.0f32; w * h * c];
    for ch in 0..c {
        for y in 0..h {
            for x in 0..w {
                let smooth = 0.5 * (x + y) as f32 / (w + h) as f32;
                let fine = ((x * 31 + y * 17 + ch * 7) % 23) as f32 / 92.0;
                data[(ch * h + y) * w + x] = ((smooth + fine + 0.2) * tint[ch.min(2)]).min(1.0);
            }
        }
    }
    Image::from_planar(w, h, c, data).expect("consistent size")
}

fn methods() -> Vec<(&'static str, Method)> {
    vec![
        ("jerlov", Method::Jerlov(JerlovParams::default())),
        ("uisa", Method::Uisa(UisaParams::default())),
        ("seathru-sampled", Method::Seathru(SeathruParams::default())),
        (
            "seathru-from-reference",
            Method::Seathru(SeathruParams {
                coefficients: SeathruCoefficients::FromReference(ReferenceCoefficients::default()),
                ..SeathruParams::default()
            }),
        ),
        ("reinhard", Method::Reinhard(ReinhardParams::default())),
    ]
}

fn bench(c: &mut Criterion) {
    let reference = texture(REFERENCE_SIZE.0, REFERENCE_SIZE.1, 3, [0.2, 0.7, 0.9]);
    let mut group = c.benchmark_group("baselines");
    group.sample_size(10);
    for side in SIDES {
        let clean = texture(side, side, 3, [1.0, 0.9, 0.8]);
        let depth = texture(side, side, 1, [1.0; 3]);
        let input = RenderInput {
            clean: &clean,
            depth: &depth,
            reference: Some(&reference),
        };
        group.throughput(Throughput::Elements((side * side) as u64));
        for (name, method) in methods() {
            group.bench_with_input(BenchmarkId::new(name, side), &input, |b, input| {
                b.iter(|| render(black_box(&method), black_box(input), 7).expect("render"));
            });
        }
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
