//! Training throughput (samples per second) of the full-width generator (base width 64) at
//! 128x128 and 256x256 crops: forward, the default loss (L1, 1 - SSIM stand-in, dark channel,
//! the paper's light-field term), backward and an AdamW step, on synthetic batches (no data
//! loading). `tools/torch_train_bench.py` times the same step in PyTorch.
//!
//! A second group times the loader's batch preparation (crop, flip, rotation, colour cast and
//! the light field of each crop), which runs beside the training step.
//!
//! `cargo bench -p uwnr-train --bench train` (flex); with `--features tch` and
//! `UWNR_BENCH_DEVICE=tch`, on libtorch. `-- prepare` runs only the loader group.

use burn::optim::AdamWConfig;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;
use uwnr_model::GeneratorConfig;
use uwnr_train::{Device, GeneratorInit, device_from_name};

use uwnr_core::Image;
use uwnr_train::data::PairData;
use uwnr_train::loader::{Batch, BatchSpec};
use uwnr_train::{AugmentConfig, ColorCast, Criterion as Loss, TrainConfig, train_step};

/// (batch, crop) cases: the sizes of the calibration run and of the paper.
const CASES: [(usize, usize); 2] = [(4, 128), (1, 256)];

fn batch(size: usize, crop: usize, seed: u64) -> Batch {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let n = crop * crop;
    Batch {
        epoch: 0,
        index: 0,
        size,
        crop,
        input: (0..size * 7 * n).map(|_| rng.random::<f32>()).collect(),
        target: (0..size * 3 * n).map(|_| rng.random::<f32>()).collect(),
        depth: Vec::new(),
        water: vec![0.0; size * 6],
    }
}

fn bench(c: &mut Criterion) {
    let name = std::env::var("UWNR_BENCH_DEVICE").unwrap_or_else(|_| "flex".into());
    let device: Device = device_from_name(&name).expect("device").autodiff();
    let cfg = TrainConfig::default();
    let loss = Loss::new(&cfg, None);
    let mut group = c.benchmark_group(format!("train_step_{name}"));
    group.sample_size(10);
    for (b, s) in CASES {
        device.seed(1);
        let mut model = Some(GeneratorConfig::default().init(&device).expect("model"));
        let mut optim = AdamWConfig::new()
            .with_epsilon(1e-8)
            .with_weight_decay(1e-6)
            .init();
        let data = batch(b, s, 2);
        group.throughput(Throughput::Elements(b as u64));
        group.bench_function(format!("{b}x{s}"), |bencher| {
            bencher.iter(|| {
                let m = model.take().expect("model");
                let (m, v) = train_step(m, &mut optim, &loss, &data, 2e-4, &device).expect("step");
                model = Some(m);
                v.total
            });
        });
    }
    group.finish();
}

fn random_image(w: usize, h: usize, c: usize, rng: &mut ChaCha8Rng) -> Image {
    let data = (0..w * h * c).map(|_| rng.random::<f32>()).collect();
    Image::from_planar(w, h, c, data).expect("image")
}

fn prepare(c: &mut Criterion) {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let pairs: Vec<PairData> = (0..8)
        .map(|i| {
            let clean = random_image(320, 320, 3, &mut rng);
            let uw = random_image(320, 320, 3, &mut rng);
            let d = random_image(320, 320, 1, &mut rng);
            PairData::pack(&format!("{i}"), &clean, &uw, &d).expect("pack")
        })
        .collect();
    let mut group = c.benchmark_group("prepare_batch");
    group.sample_size(10);
    for (b, s) in CASES {
        let spec = BatchSpec {
            pairs: Arc::new(pairs.clone()),
            seed: 1,
            batch_size: b,
            crop: s,
            augment: AugmentConfig {
                color_cast: Some(ColorCast::default()),
                ..AugmentConfig::default()
            },
            light_field: uwnr_core::lightfield::LightFieldMap::Paper,
            variant: uwnr_model::Variant::Paper,
            detail_retention: false,
            anchor: uwnr_model::AnchorKind::Reinhard,
        };
        group.throughput(Throughput::Elements(b as u64));
        group.bench_function(format!("{b}x{s}"), |bencher| {
            bencher.iter(|| spec.batch(0, 0).expect("batch").input.len());
        });
    }
    group.finish();
}

criterion_group!(benches, bench, prepare);
criterion_main!(benches);
