//! Where the full-width generator's forward pass spends its time at one input size: each
//! layer kind per level (as `LayerBench` runs it, best of `RUNS`), their sum, and the whole
//! forward pass, so that time outside the measured layers shows as the difference.
//!
//! `cargo run --release -p uwnr-engine --example layer_profile -- [SIZE] [RUNS]` (default 1024, 3).

use std::time::Instant;

use uwnr_engine::{
    ConvAlgo, EngineOptions, Generator, GeneratorWeights, LayerBench, LayerKind, Means, Planar,
};

fn best_of(runs: usize, mut f: impl FnMut()) -> f64 {
    (0..runs)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64() * 1e3
        })
        .fold(f64::INFINITY, f64::min)
}

fn main() {
    let mut args = std::env::args().skip(1);
    let size: usize = args.next().map_or(1024, |s| s.parse().expect("size"));
    let runs: usize = args.next().map_or(3, |s| s.parse().expect("runs"));
    let mut opts = EngineOptions::default();
    match std::env::var("ALGO").as_deref() {
        Ok("direct") => opts.algo = ConvAlgo::Direct,
        Ok("f2") => opts.algo = ConvAlgo::WinogradF2,
        _ => {}
    }
    let kinds = [
        (LayerKind::Stride2, "stride2"),
        (LayerKind::Block3x3, "block3x3"),
        (LayerKind::SpatialAttention, "spatial_att"),
        (LayerKind::ChannelAttention, "channel_att"),
        (LayerKind::Up, "up3x3"),
    ];
    let mut total = 0.0;
    for (kind, name) in kinds {
        let mut row = Vec::new();
        for level in 0..4 {
            let mut layer = LayerBench::new(kind, opts, 64, level, size).expect("layer");
            layer.run();
            let ms = best_of(runs, || layer.run());
            total += ms;
            row.push(format!("{ms:8.1}"));
        }
        println!("{name:12} {}", row.join(" "));
    }
    println!("sum of layers {total:.1} ms");
    let weights = GeneratorWeights::random(7, 3, 64, 1);
    let g = Generator::with_options(&weights, opts).expect("generator");
    let x = Planar::zeros(7, size, size);
    g.forward(&x, Means::Own).expect("forward");
    // Per stage, the least time over the runs.
    let mut best: Vec<(String, f64)> = Vec::new();
    for _ in 0..runs {
        let stages = g.profile(&x).expect("profile");
        if best.is_empty() {
            best = stages
                .iter()
                .map(|(n, _)| (n.clone(), f64::INFINITY))
                .collect();
        }
        for ((_, b), (_, d)) in best.iter_mut().zip(&stages) {
            *b = b.min(d.as_secs_f64() * 1e3);
        }
    }
    for (name, ms) in &best {
        println!("{name:28} {ms:8.1}");
    }
    println!(
        "sum of stages {:.1} ms",
        best.iter().map(|(_, ms)| ms).sum::<f64>()
    );
    let ms = best_of(runs, || {
        g.forward(&x, Means::Own).expect("forward");
    });
    println!("forward {ms:.1} ms");
}
