//! The engine's generator against [`uwnr_engine::reference::generator`] (unfused, f64 sums).

use uwnr_engine::reference::{self, max_abs_diff};
use uwnr_engine::{
    ConvAlgo, EngineError, EngineOptions, Generator, GeneratorWeights, Isa, Means, Planar,
    Precision,
};

/// Max abs difference allowed between the engine and the reference on the output.
const TOL: f32 = 1e-4;

fn input(channels: usize, h: usize, w: usize, seed: u64) -> Planar {
    let mut s = seed;
    let data = (0..channels * h * w)
        .map(|_| {
            s = s
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (s >> 40) as f32 / (1u64 << 24) as f32
        })
        .collect();
    Planar {
        channels,
        height: h,
        width: w,
        data,
    }
}

fn all_options() -> Vec<EngineOptions> {
    Isa::supported()
        .into_iter()
        .flat_map(|isa| {
            [ConvAlgo::Auto, ConvAlgo::Direct, ConvAlgo::WinogradF2].map(|algo| EngineOptions {
                isa,
                algo,
                precision: Precision::F32,
            })
        })
        .collect()
}

#[test]
fn generator_matches_the_reference_on_every_variant() {
    // Widths 8 and 16 (the latter puts Winograd on most layers), 7 and 9 input planes,
    // square and non-square sizes.
    let cases = [(7, 3, 8, 16, 16), (7, 3, 16, 32, 48), (9, 4, 8, 48, 32)];
    for (i, &(cin, cout, base, h, w)) in cases.iter().enumerate() {
        let weights = GeneratorWeights::random(cin, cout, base, i as u64 + 3);
        let x = input(cin, h, w, i as u64 + 11);
        let (want, want_means) = reference::generator(&weights, &x, None);
        for opts in all_options() {
            let g = Generator::with_options(&weights, opts).unwrap();
            let (got, means) = g.forward(&x, Means::Own).unwrap();
            assert_eq!((got.channels, got.height, got.width), (cout, h, w));
            let diff = max_abs_diff(&got.data, &want.data);
            assert!(diff < TOL, "case {i} {opts:?}: {diff}");
            for (k, (m, e)) in means.iter().zip(&want_means).enumerate() {
                let d = max_abs_diff(m, e);
                assert!(d < TOL, "case {i} {opts:?} mean {k}: {d}");
            }
        }
    }
}

#[test]
fn given_means_and_attention_inputs_follow_the_reference() {
    let weights = GeneratorWeights::random(7, 3, 8, 5);
    let x = input(7, 32, 32, 1);
    let other: Vec<Vec<f32>> = (0..4).map(|k| vec![0.25; 8 << k]).collect();
    let (want, _) = reference::generator(&weights, &x, Some(&other));
    let g = Generator::new(&weights).unwrap();
    let (got, used) = g.forward(&x, Means::Given(&other)).unwrap();
    assert!(max_abs_diff(&got.data, &want.data) < TOL);
    assert_eq!(used, other);
    let (own, _) = g.forward(&x, Means::Own).unwrap();
    assert!(
        max_abs_diff(&own.data, &got.data) > 1e-3,
        "the given means are used"
    );
    // Block k's attention input pools to the k-th mean when earlier means are the network's.
    let (_, means) = g.forward(&x, Means::Own).unwrap();
    for k in 0..4 {
        let a = g.channel_attention_input(&x, &means[..k]).unwrap();
        assert_eq!(a.channels, 8 << k);
        assert_eq!(a.height, 32 >> (k + 1));
        let d = max_abs_diff(&reference::channel_means(&a), &means[k]);
        assert!(d < 1e-6, "block {k}: {d}");
    }
    assert!(g.channel_attention_input(&x, &means).is_err());
}

#[test]
fn bad_inputs_and_weights_are_rejected() {
    let weights = GeneratorWeights::random(7, 3, 8, 5);
    let g = Generator::new(&weights).unwrap();
    assert!(matches!(
        g.forward(&input(7, 24, 32, 0), Means::Own),
        Err(EngineError::Input(_))
    ));
    assert!(matches!(
        g.forward(&input(6, 32, 32, 0), Means::Own),
        Err(EngineError::Input(_))
    ));
    let short: Vec<Vec<f32>> = vec![vec![0.0; 8]; 4];
    assert!(
        g.forward(&input(7, 32, 32, 0), Means::Given(&short))
            .is_err()
    );
    let mut bad = weights.clone();
    bad.downs[2].block.conk3.bias.pop();
    assert!(matches!(
        Generator::new(&bad),
        Err(EngineError::WeightLength { .. })
    ));
    let narrow = GeneratorWeights::random(7, 3, 4, 1);
    assert!(matches!(
        Generator::new(&narrow),
        Err(EngineError::InvalidWidths(_))
    ));
}

/// Bounds on the bf16 engine's output against the f32 engine's, on random weights (output in
/// (-1, 1)). The rounding of the Winograd operands (relative 2^-8 each) is amplified by the
/// F(4x4) transforms (entries up to 5 in `B`, 8 in `A`) and passes through every level, so a
/// few outputs move by several hundredths; the typical move is a few thousandths (measured on
/// the full-width network at 256 px: max 8.4e-2, mean 4.3e-3).
const BF16_MAX: f32 = 0.15;
const BF16_MEAN: f64 = 1e-2;

#[test]
fn bf16_generator_stays_near_the_f32_one_on_every_variant() {
    // Width 16 puts Winograd on every block and decoder conv; width 32 the deeper shapes.
    let cases = [(7, 3, 16, 48, 32), (7, 3, 32, 32, 64)];
    for (i, &(cin, cout, base, h, w)) in cases.iter().enumerate() {
        let weights = GeneratorWeights::random(cin, cout, base, i as u64 + 21);
        let x = input(cin, h, w, i as u64 + 31);
        let (want, _) = reference::generator(&weights, &x, None);
        for isa in Isa::supported() {
            let f32_opts = EngineOptions {
                isa,
                algo: ConvAlgo::Auto,
                precision: Precision::F32,
            };
            let opts = EngineOptions {
                precision: Precision::Bf16,
                ..f32_opts
            };
            let exact = Generator::with_options(&weights, f32_opts).unwrap();
            let (exact, _) = exact.forward(&x, Means::Own).unwrap();
            // The f32 path is unchanged by the option's existence.
            assert!(max_abs_diff(&exact.data, &want.data) < TOL);
            let g = Generator::with_options(&weights, opts).unwrap();
            assert_eq!(g.options().precision, Precision::Bf16);
            let (got, _) = g.forward(&x, Means::Own).unwrap();
            let max = max_abs_diff(&got.data, &exact.data);
            let mean = got
                .data
                .iter()
                .zip(&exact.data)
                .map(|(a, b)| f64::from((a - b).abs()))
                .sum::<f64>()
                / got.data.len() as f64;
            let kernel = if opts.native_bf16() {
                "native"
            } else {
                "emulated"
            };
            assert!(
                max < BF16_MAX && mean < BF16_MEAN,
                "case {i} {isa:?} {kernel}: max {max}, mean {mean}"
            );
            assert!(max > 1e-5, "case {i} {isa:?} {kernel}: bf16 equals f32");
        }
    }
}
