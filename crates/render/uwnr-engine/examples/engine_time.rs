//! Times one forward pass of the full-width generator (random weights) on the engine:
//! `cargo run --release -p uwnr-engine --example engine_time -- [sizes...] [--direct | --f2] [--isa NAME] [--precision f32|bf16] [--runs N] [--layers] [--stages]`.
//! Prints milliseconds per image (best and median of the runs) and GFLOP/s against the kernel
//! MAC count. With `--precision bf16` it also prints the largest and mean absolute difference
//! of the output from the f32 engine's on the same input.
//! With `--layers`, also the best time of every layer of the network at each size (the
//! [`LayerBench`] shapes), to see where a forward pass spends its time. With `--stages`, the
//! best time of every stage of the whole forward pass ([`Generator::profile`]: each level's
//! stem, block, spatial and channel attention, each decoder conv and its shuffle, the output
//! layer), which also counts what the layer benches leave out (shuffles, skips, conversions).

use std::time::Instant;

use uwnr_engine::{
    ConvAlgo, EngineOptions, Generator, GeneratorWeights, Isa, LEVELS, LayerBench, LayerKind,
    Means, Planar, Precision,
};

/// Kernel multiply-accumulates of the paper's network per pixel of input (8.61 GMac at 256^2).
const MACS_PER_PIXEL: f64 = 8.61e9 / (256.0 * 256.0);

/// CPU time of every thread of this process, in seconds (Linux `schedstat`; 0 elsewhere):
/// on a shared machine it counts only the time this process ran, not the time it waited.
fn cpu_seconds() -> f64 {
    let Ok(tasks) = std::fs::read_dir("/proc/self/task") else {
        return 0.0;
    };
    tasks
        .filter_map(|t| t.ok())
        .filter_map(|t| std::fs::read_to_string(t.path().join("schedstat")).ok())
        .filter_map(|s| s.split_whitespace().next()?.parse::<f64>().ok())
        .sum::<f64>()
        / 1e9
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut sizes = Vec::new();
    let mut opts = EngineOptions::default();
    let mut runs = 5;
    let mut layers = false;
    let mut stages = false;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--direct" => opts.algo = ConvAlgo::Direct,
            "--f2" => opts.algo = ConvAlgo::WinogradF2,
            "--layers" => layers = true,
            "--stages" => stages = true,
            "--isa" => {
                let name = it.next().map(String::as_str).unwrap_or("");
                opts.isa = Isa::ALL
                    .into_iter()
                    .find(|i| i.name() == name)
                    .unwrap_or_else(|| {
                        eprintln!("unknown ISA {name:?}");
                        std::process::exit(2)
                    });
            }
            "--precision" => {
                opts.precision = match it.next().map(String::as_str) {
                    Some("f32") => Precision::F32,
                    Some("bf16") => Precision::Bf16,
                    other => {
                        eprintln!("--precision takes f32 or bf16, not {other:?}");
                        std::process::exit(2)
                    }
                }
            }
            "--runs" => runs = it.next().and_then(|v| v.parse().ok()).unwrap_or(runs),
            s => sizes.push(s.parse::<usize>().unwrap_or_else(|_| {
                eprintln!("not a size: {s:?}");
                std::process::exit(2)
            })),
        }
    }
    if sizes.is_empty() {
        sizes = vec![256, 512, 1024];
    }
    let weights = GeneratorWeights::random(7, 3, 64, 1);
    let g = match Generator::with_options(&weights, opts) {
        Ok(g) => g,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(1)
        }
    };
    let reference = (opts.precision != Precision::F32).then(|| {
        let f32_opts = EngineOptions {
            precision: Precision::F32,
            ..opts
        };
        Generator::with_options(&weights, f32_opts).expect("the f32 engine builds where bf16 does")
    });
    let precision = match opts.precision {
        Precision::F32 => "f32".to_string(),
        Precision::Bf16 if opts.native_bf16() => "bf16 (avx512bf16)".to_string(),
        Precision::Bf16 => "bf16 (emulated)".to_string(),
    };
    for size in sizes {
        let x = Planar {
            channels: 7,
            height: size,
            width: size,
            data: (0..7 * size * size)
                .map(|i| (i % 255) as f32 / 255.0)
                .collect(),
        };
        let mut times = Vec::with_capacity(runs);
        let mut best_cpu = f64::INFINITY;
        let mut out = None;
        for _ in 0..runs.max(1) {
            let (t, c) = (Instant::now(), cpu_seconds());
            let y = g.forward(&x, Means::Own);
            times.push(t.elapsed().as_secs_f64());
            best_cpu = best_cpu.min(cpu_seconds() - c);
            out = Some(y.expect("a valid input"));
        }
        times.sort_by(f64::total_cmp);
        let (best, median) = (times[0], times[times.len() / 2]);
        let gflops = 2.0 * MACS_PER_PIXEL * (size * size) as f64 / best / 1e9;
        println!(
            "{size}x{size} {:?} {} {precision}: {:.1} ms wall best, {:.1} ms median ({gflops:.0} GFLOP/s), {:.1} ms CPU",
            opts.algo,
            opts.isa.name(),
            best * 1e3,
            median * 1e3,
            best_cpu * 1e3
        );
        if let (Some(r), Some((y, _))) = (&reference, &out) {
            let (want, _) = r.forward(&x, Means::Own).expect("a valid input");
            let diffs: Vec<f32> = y
                .data
                .iter()
                .zip(&want.data)
                .map(|(a, b)| (a - b).abs())
                .collect();
            let max = diffs.iter().copied().fold(0.0f32, f32::max);
            let mean = diffs.iter().map(|&d| f64::from(d)).sum::<f64>() / diffs.len() as f64;
            println!(
                "  output vs f32 engine: max abs {max:.2e}, mean abs {mean:.2e} (output in (-1, 1))"
            );
        }
        if layers {
            layer_times(opts, size, runs);
        }
        if stages {
            stage_times(&g, &x, runs);
        }
    }
}

/// Best time of each layer of the full-width network at input `size`.
fn layer_times(opts: EngineOptions, size: usize, runs: usize) {
    let kinds = [
        (LayerKind::Stride2, "stride-2 3x3"),
        (LayerKind::Block3x3, "block 3x3"),
        (LayerKind::SpatialAttention, "spatial attention"),
        (LayerKind::ChannelAttention, "channel attention"),
        (LayerKind::Up, "up 3x3"),
    ];
    let mut total = 0.0;
    for (kind, name) in kinds {
        for level in 0..LEVELS {
            let Ok(mut layer) = LayerBench::new(kind, opts, 64, level, size) else {
                continue;
            };
            layer.run();
            let mut best = f64::INFINITY;
            for _ in 0..runs {
                let t = Instant::now();
                layer.run();
                best = best.min(t.elapsed().as_secs_f64());
            }
            total += best;
            let gflops = 2.0 * layer.macs() as f64 / best / 1e9;
            println!(
                "  {name:<18} level {level}: {:7.2} ms ({gflops:.0} GFLOP/s direct-equivalent)",
                best * 1e3
            );
        }
    }
    println!("  sum of layers: {:.1} ms", total * 1e3);
}

/// Best time of each stage of the forward pass of `g` on `x`.
fn stage_times(g: &Generator, x: &Planar, runs: usize) {
    let mut best: Vec<(String, f64)> = Vec::new();
    for _ in 0..runs.max(1) {
        let stages = g.profile(x).expect("a valid input");
        if best.is_empty() {
            best = stages
                .iter()
                .map(|(n, _)| (n.clone(), f64::INFINITY))
                .collect();
        }
        for ((_, b), (_, d)) in best.iter_mut().zip(&stages) {
            *b = b.min(d.as_secs_f64());
        }
    }
    for (name, secs) in &best {
        println!("  {name:<28} {:7.2} ms", secs * 1e3);
    }
    let total: f64 = best.iter().map(|(_, s)| s).sum();
    println!("  sum of stages: {:.1} ms", total * 1e3);
}
