//! Forward-pass time and peak memory of the full-width UWNR generator (11.57M parameters) on
//! the flex CPU device at 256, 512 and 1024 px square.
//!
//! `cargo bench -p uwnr-train --bench generator`. The PyTorch reference for the same sizes is
//! `python3 tools/torch_bench.py` (2 threads, no_grad). Peak memory is the high-water mark of
//! heap bytes allocated during one forward, from a counting global allocator.

use std::alloc::{GlobalAlloc, Layout, System};
use std::hint::black_box;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use burn::tensor::{Distribution, Tensor};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use uwnr_model::{GeneratorConfig, gmacs};
use uwnr_train::{Device, GeneratorInit};

/// Square sizes benchmarked.
const SIZES: [usize; 3] = [256, 512, 1024];

/// Counts live heap bytes and their high-water mark.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: forwards to the system allocator; only adds counters.
#[allow(unsafe_code)]
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let live = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(live, Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            if new_size > layout.size() {
                let grow = new_size - layout.size();
                let live = LIVE.fetch_add(grow, Ordering::Relaxed) + grow;
                PEAK.fetch_max(live, Ordering::Relaxed);
            } else {
                LIVE.fetch_sub(layout.size() - new_size, Ordering::Relaxed);
            }
        }
        p
    }
}

#[global_allocator]
static ALLOC: Counting = Counting;

const MIB: f64 = 1024.0 * 1024.0;

fn forward(c: &mut Criterion) {
    let device = Device::flex();
    device.seed(0);
    let config = GeneratorConfig::default();
    let generator = config.init(&device).expect("default config is valid");

    // Parameters are materialised lazily, on first use: a tiny forward first, so the peaks
    // below are activations only.
    let warm = Tensor::<4>::zeros([1, 7, 32, 32], &device);
    drop(generator.forward(warm));
    device.sync().expect("sync");

    // One measured forward per size: heap high-water mark above the weights.
    for size in SIZES {
        let x = Tensor::<4>::random([1, 7, size, size], Distribution::Uniform(0.0, 1.0), &device);
        let base = LIVE.load(Ordering::Relaxed);
        PEAK.store(base, Ordering::Relaxed);
        let t = Instant::now();
        let y = generator.forward(x);
        device.sync().expect("sync");
        let ms = t.elapsed().as_secs_f64() * 1e3;
        drop(y);
        let peak = PEAK.load(Ordering::Relaxed) - base;
        println!(
            "forward {size}x{size}: {:.2} GMac, first run {ms:.0} ms, peak heap above weights {:.0} MiB",
            gmacs(&config, size, size),
            peak as f64 / MIB
        );
    }

    let mut group = c.benchmark_group("generator_forward_flex");
    group.sample_size(10);
    for size in SIZES {
        let x = Tensor::<4>::random([1, 7, size, size], Distribution::Uniform(0.0, 1.0), &device);
        group.throughput(Throughput::Elements((size * size) as u64));
        group.bench_with_input(BenchmarkId::from_parameter(size), &x, |b, x| {
            b.iter(|| {
                let y = generator.forward(black_box(x.clone()));
                device.sync().expect("sync");
                y
            });
        });
    }
    group.finish();
}

criterion_group!(benches, forward);
criterion_main!(benches);
