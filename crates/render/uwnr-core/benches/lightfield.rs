//! Cost of the light-field map per reference, with its stages, at the sizes uwnr meets.
//!
//! `cargo bench -p uwnr-core --bench lightfield`

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use uwnr_core::Image;
use uwnr_core::gaussian::cv_gaussian_blur_u8;
use uwnr_core::lightfield::{LF_SIGMAS, light_field, light_field_raw_u8};
use uwnr_core::resize::{U8Image, cv_resize_linear_scale_u8, resize_bilinear};

/// A smooth colour pattern standing in for a reference photo.
fn reference(width: usize, height: usize) -> Image {
    let mut data = Vec::with_capacity(width * height * 3);
    for c in 0..3 {
        for y in 0..height {
            for x in 0..width {
                let v =
                    ((x as f32 * 0.031 + c as f32).sin() * (y as f32 * 0.017).cos() + 1.0) / 2.0;
                data.push(v);
            }
        }
    }
    Image::from_planar(width, height, 3, data).unwrap()
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("light_field");
    for (w, h) in [(256, 256), (400, 300), (1280, 720)] {
        let img = reference(w, h);
        group.throughput(Throughput::Elements(1));
        group.bench_with_input(
            BenchmarkId::new("render_map", format!("{w}x{h}")),
            &img,
            |b, img| b.iter(|| light_field(img).unwrap()),
        );
    }
    let crop = U8Image::from_image(&reference(256, 256));
    group.bench_function("raw_map_256_u8", |b| {
        b.iter(|| light_field_raw_u8(&crop).unwrap())
    });
    let small = cv_resize_linear_scale_u8(&crop, 0.3, 0.3).unwrap();
    for sigma in LF_SIGMAS {
        group.bench_with_input(BenchmarkId::new("gaussian_77", sigma), &sigma, |b, &s| {
            b.iter(|| cv_gaussian_blur_u8(&small, s).unwrap())
        });
    }
    group.finish();

    let mut group = c.benchmark_group("resize_bilinear");
    let big = reference(1280, 720);
    group.throughput(Throughput::Elements((1280 * 720) as u64));
    group.bench_function("1280x720_to_640x360", |b| {
        b.iter(|| resize_bilinear(&big, 640, 360).unwrap())
    });
    group.bench_function("256x256_to_1280x720", |b| {
        let lf = reference(256, 256);
        b.iter(|| resize_bilinear(&lf, 1280, 720).unwrap())
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
