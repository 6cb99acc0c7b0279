//! Per-kernel time of the engine at the full-width network's real shapes (input 256x256, so
//! levels of 128, 64, 32 and 16 px with 64..512 channels): the stride-2 conv, the block's fused
//! 3x3 (direct and Winograd), the decoder conv, spatial and channel attention, on every
//! instruction set this CPU supports, and the convolutions again with bf16 products.
//!
//! `cargo bench -p uwnr-engine --bench kernels` (not run by CI). Throughput is in
//! multiply-accumulates of the direct method, so Winograd shows as more "elements" per second.

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use uwnr_engine::{ConvAlgo, EngineOptions, Isa, LayerBench, LayerKind, Precision};

/// Width of the released network.
const BASE_WIDTH: usize = 64;
/// Input size the shapes are taken at.
const SIZE: usize = 256;

fn kernels(c: &mut Criterion) {
    let kinds = [
        (LayerKind::Stride2, ConvAlgo::Direct, "stride2"),
        (LayerKind::Block3x3, ConvAlgo::Direct, "block3x3_direct"),
        (LayerKind::Block3x3, ConvAlgo::Auto, "block3x3_winograd"),
        (LayerKind::Up, ConvAlgo::Direct, "up3x3_direct"),
        (LayerKind::Up, ConvAlgo::Auto, "up3x3_winograd"),
        (
            LayerKind::SpatialAttention,
            ConvAlgo::Direct,
            "spatial_attention_1x1",
        ),
        (
            LayerKind::ChannelAttention,
            ConvAlgo::Direct,
            "channel_attention",
        ),
    ];
    for (kind, algo, name) in kinds {
        let mut group = c.benchmark_group(name);
        group.sample_size(10);
        for isa in Isa::supported() {
            let opts = EngineOptions {
                isa,
                algo,
                precision: Precision::F32,
            };
            bench_levels(&mut group, kind, opts, isa.name());
        }
        group.finish();
    }
    // The same layers with bf16 products, on the best instruction set (`vdpbf16ps` where the
    // CPU has AVX512_BF16, the emulation otherwise), beside the f32 entries above.
    let bf16_kinds = [
        (LayerKind::Stride2, ConvAlgo::Direct, "stride2"),
        (LayerKind::Block3x3, ConvAlgo::Auto, "block3x3_winograd"),
        (LayerKind::Up, ConvAlgo::Auto, "up3x3_winograd"),
    ];
    for (kind, algo, name) in bf16_kinds {
        let mut group = c.benchmark_group(name);
        group.sample_size(10);
        let opts = EngineOptions {
            isa: Isa::best(),
            algo,
            precision: Precision::Bf16,
        };
        let label = if opts.native_bf16() {
            format!("{}-bf16", opts.isa.name())
        } else {
            format!("{}-bf16-emulated", opts.isa.name())
        };
        bench_levels(&mut group, kind, opts, &label);
        group.finish();
    }
}

/// One entry per encoder level of `kind` with `opts`, named `label/levelN`.
fn bench_levels(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    kind: LayerKind,
    opts: EngineOptions,
    label: &str,
) {
    for level in 0..4 {
        let Ok(mut layer) = LayerBench::new(kind, opts, BASE_WIDTH, level, SIZE) else {
            continue;
        };
        group.throughput(Throughput::Elements(layer.macs().max(1)));
        let id = BenchmarkId::new(label, format!("level{level}"));
        group.bench_function(id, |b| b.iter(|| layer.run()));
    }
}

criterion_group!(benches, kernels);
criterion_main!(benches);
