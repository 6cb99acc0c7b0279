//! Forward-pass time of the full-width UWNR generator (seeded random weights) on the engine
//! (f32, and with bf16 Winograd products) and on burn's flex backend, for
//! `tools/bench_inference.sh`:
//! `cargo run --release -p uwnr-train --example bench_inference -- [--runs N] [--sizes 256 512] [--no-flex]`.
//!
//! Threads come from rayon (`RAYON_NUM_THREADS`). Prints the median of the timed runs after one
//! warm-up, one `RESULT <path> <size> <ms>` line per measurement, and `PEAK <GFLOP/s>`: the FP32
//! FMA throughput of this machine on that many threads (independent FMA chains on the widest
//! vectors the CPU has). `BF16 native|emulated` says whether the bf16 engine ran on
//! `vdpbf16ps` or on its emulation.

// The peak measurement calls `std::arch` FMA intrinsics, which are unsafe.
#![allow(unsafe_code)]

use std::hint::black_box;
use std::time::Instant;

use burn::tensor::{Distribution, Tensor};
use rayon::prelude::*;
use uwnr_engine::{EngineOptions, Means, Planar, Precision};
use uwnr_model::network::engine_weights;
use uwnr_model::{GeneratorConfig, gmacs};
use uwnr_train::{Device, GeneratorInit, generator_to_tensors};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn time<F: FnMut()>(runs: usize, mut f: F) -> f64 {
    f(); // warm-up
    median(
        (0..runs)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64() * 1e3
            })
            .collect(),
    )
}

/// Chains of FMAs per thread (enough to cover the FMA latency on two pipes).
#[cfg(target_arch = "x86_64")]
const CHAINS: usize = 16;
/// AVX2 has 16 ymm registers: 12 chains plus the two operands fit without spills (16 chains
/// did not, and measured half the peak).
#[cfg(target_arch = "x86_64")]
const CHAINS_AVX2: usize = 12;
#[cfg(target_arch = "x86_64")]
const PEAK_ITERS: usize = 20_000_000;

/// `CHAINS` independent FMA chains of `PEAK_ITERS` steps on 16-lane vectors; every chain feeds
/// the result, so none can be optimised away.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn fma_chains_avx512(b: f32) -> f32 {
    use std::arch::x86_64::{_mm512_add_ps, _mm512_fmadd_ps, _mm512_reduce_add_ps, _mm512_set1_ps};
    let (b, c) = (_mm512_set1_ps(b), _mm512_set1_ps(1e-4));
    let mut acc = [_mm512_set1_ps(1.0); CHAINS];
    for _ in 0..PEAK_ITERS {
        for a in &mut acc {
            *a = _mm512_fmadd_ps(*a, b, c);
        }
    }
    let sum = acc
        .iter()
        .fold(_mm512_set1_ps(0.0), |s, &a| _mm512_add_ps(s, a));
    _mm512_reduce_add_ps(sum)
}

/// As [`fma_chains_avx512`] on 8-lane AVX2 vectors, with [`CHAINS_AVX2`] chains.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
fn fma_chains_avx2(b: f32) -> f32 {
    use std::arch::x86_64::{_mm256_add_ps, _mm256_fmadd_ps, _mm256_set1_ps, _mm256_storeu_ps};
    let (b, c) = (_mm256_set1_ps(b), _mm256_set1_ps(1e-4));
    let mut acc = [_mm256_set1_ps(1.0); CHAINS_AVX2];
    for _ in 0..PEAK_ITERS {
        for a in &mut acc {
            *a = _mm256_fmadd_ps(*a, b, c);
        }
    }
    let sum = acc
        .iter()
        .fold(_mm256_set1_ps(0.0), |s, &a| _mm256_add_ps(s, a));
    let mut out = [0.0f32; 8];
    // SAFETY: out holds 8 floats.
    unsafe { _mm256_storeu_ps(out.as_mut_ptr(), sum) };
    out.iter().sum()
}

/// Measured FP32 FMA peak in GFLOP/s on all of rayon's threads, with the widest vectors the
/// CPU has (AVX-512F, else AVX2+FMA).
fn peak_gflops() -> Option<f64> {
    #[cfg(target_arch = "x86_64")]
    {
        let lanes = if std::arch::is_x86_feature_detected!("avx512f") {
            16
        } else if std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
        {
            8
        } else {
            return None;
        };
        let threads = rayon::current_num_threads();
        let b = black_box(0.999_9f32);
        let t = Instant::now();
        let s: f32 = (0..threads)
            .into_par_iter()
            // SAFETY: the instruction set was detected above.
            .map(|_| unsafe {
                if lanes == 16 {
                    fma_chains_avx512(b)
                } else {
                    fma_chains_avx2(b)
                }
            })
            .sum();
        black_box(s);
        let chains = if lanes == 16 { CHAINS } else { CHAINS_AVX2 };
        let flops = (threads * PEAK_ITERS * chains * lanes * 2) as f64;
        Some(flops / t.elapsed().as_secs_f64() / 1e9)
    }
    #[cfg(not(target_arch = "x86_64"))]
    None
}

fn main() {
    let mut runs = 5;
    let mut sizes = vec![256, 512, 1024];
    let mut flex = true;
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut i = 0;
    while i < args.len() {
        match args[i].as_str() {
            "--runs" => {
                i += 1;
                runs = args.get(i).and_then(|v| v.parse().ok()).unwrap_or(runs);
            }
            "--no-flex" => flex = false,
            "--sizes" => {
                sizes.clear();
                while let Some(v) = args.get(i + 1).and_then(|v| v.parse().ok()) {
                    sizes.push(v);
                    i += 1;
                }
            }
            other => {
                eprintln!("unknown argument {other:?}");
                std::process::exit(2);
            }
        }
        i += 1;
    }
    let device = Device::flex();
    device.seed(0);
    let config = GeneratorConfig::default();
    let g = config.init(&device).expect("paper config");
    let tensors = generator_to_tensors(&g, &config).expect("tensors");
    let (weights, _) = engine_weights(&config, tensors).expect("engine weights");
    let engine = uwnr_engine::Generator::new(&weights).expect("engine");
    let bf16_opts = EngineOptions {
        precision: Precision::Bf16,
        ..EngineOptions::default()
    };
    let engine_bf16 = uwnr_engine::Generator::with_options(&weights, bf16_opts).expect("engine");
    println!(
        "threads {}, engine ISA {}",
        rayon::current_num_threads(),
        engine.options().isa.name()
    );
    println!(
        "BF16 {}",
        if bf16_opts.native_bf16() {
            "native"
        } else {
            "emulated"
        }
    );
    if let Some(p) = peak_gflops() {
        println!("PEAK {p:.1}");
    }
    for &size in &sizes {
        let gflop = 2.0 * gmacs(&config, size, size);
        let x = Planar {
            channels: 7,
            height: size,
            width: size,
            data: (0..7 * size * size)
                .map(|i| ((i * 7919) % 1000) as f32 / 1000.0)
                .collect(),
        };
        let ms = time(runs, || {
            black_box(engine.forward(&x, Means::Own).expect("forward"));
        });
        println!(
            "engine {size}x{size}: {ms:.1} ms, {:.0} GFLOP/s",
            gflop / ms * 1e3
        );
        println!("RESULT engine {size} {ms:.2}");
        let ms = time(runs, || {
            black_box(engine_bf16.forward(&x, Means::Own).expect("forward"));
        });
        println!(
            "engine bf16 {size}x{size}: {ms:.1} ms, {:.0} GFLOP/s",
            gflop / ms * 1e3
        );
        println!("RESULT engine-bf16 {size} {ms:.2}");
        if flex {
            let t =
                Tensor::<4>::random([1, 7, size, size], Distribution::Uniform(0.0, 1.0), &device);
            let ms = time(runs.min(3), || {
                let y = g.forward(t.clone());
                black_box(y.into_data());
            });
            println!(
                "flex {size}x{size}: {ms:.1} ms, {:.0} GFLOP/s",
                gflop / ms * 1e3
            );
            println!("RESULT flex {size} {ms:.2}");
        }
    }
}
