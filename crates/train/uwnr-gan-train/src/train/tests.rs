use super::*;
use crate::model::{DiscriminatorConfig, GeneratorConfig, sample_z};
use crate::weights::load_generator;
use uwnr_run::folder::read_config_unchanged;

/// A config small enough for a few steps on 32x32 images in a debug test.
fn tiny() -> GanTrainConfig {
    GanTrainConfig {
        model: GanConfig {
            generator: GeneratorConfig {
                z_dim: 8,
                widths: vec![8, 16],
                hidden: 16,
                encoder_size: 16,
                ..GeneratorConfig::default()
            },
            discriminator: DiscriminatorConfig {
                width: 8,
                layers: 3,
            },
        },
        epochs: 2,
        batch_size: 2,
        crop: 32,
        lr: 2e-3,
        val_images: 2,
        run: RunSettings {
            val_sheet_pairs: 2,
            log_every_steps: 1,
            checkpoint_every_secs: 0,
            ..GanTrainConfig::default().run
        },
        ..GanTrainConfig::default()
    }
}

/// Writes `n` synthetic 32x32 images: clean ones are grey-level ramps with a bright square,
/// references are blue-green with a vertical falloff.
fn write_images(dir: &Path, n: usize, underwater: bool) {
    std::fs::create_dir_all(dir).unwrap();
    for k in 0..n {
        let (w, h) = (32, 32);
        let mut data = vec![0.0_f32; 3 * w * h];
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                let v = if underwater {
                    [
                        0.1,
                        0.5 - 0.2 * y as f32 / 32.0,
                        0.7 - 0.1 * k as f32 / n as f32,
                    ]
                } else {
                    let ramp = (x + y + 4 * k) as f32 / 80.0;
                    let sq = if (8..16).contains(&x) && (8..16).contains(&y) {
                        0.3
                    } else {
                        0.0
                    };
                    [ramp + sq, 0.5 * ramp + sq, 0.3 + sq]
                };
                for c in 0..3 {
                    data[c * w * h + i] = v[c].clamp(0.0, 1.0);
                }
            }
        }
        let img = Image::from_planar(w, h, 3, data).unwrap();
        uwnr_core::io::save_rgb(&dir.join(format!("{k:02}.png")), &img).unwrap();
    }
}

#[test]
fn gradients_reach_the_parameter_head_and_stay_on_their_side() {
    let d = Device::flex().autodiff();
    let cfg = tiny();
    let gan = cfg.model.init(&d).unwrap();
    let clean = Tensor::<4>::ones([2, 3, 32, 32], &d) * 0.6;
    let ramp: Vec<f32> = (0..2 * 32 * 32).map(|i| (i % 32) as f32 / 31.0).collect();
    let depth = Tensor::<4>::from_data(TensorData::new(ramp, [2, 1, 32, 32]), &d);
    let z = sample_z(3, 2, 8, &d);
    let (fake, _) = gan
        .generator
        .forward(clean.clone(), depth.clone(), z.clone())
        .unwrap();
    // Generator loss: gradients reach the head's weights and bias.
    let g_loss = GanLoss::NonSaturating.generator(gan.discriminator.forward(fake));
    let grads = g_loss.backward();
    for (name, g) in [
        (
            "head.weight",
            gan.generator
                .head
                .weight
                .val()
                .grad(&grads)
                .map(|g| g.abs().sum()),
        ),
        (
            "head.bias",
            gan.generator
                .head
                .bias
                .as_ref()
                .and_then(|b| b.val().grad(&grads))
                .map(|g| g.abs().sum()),
        ),
        (
            "encoder.0.weight",
            gan.generator.encoder[0]
                .weight
                .val()
                .grad(&grads)
                .map(|g| g.abs().sum()),
        ),
    ] {
        let g = g.unwrap_or_else(|| panic!("no gradient for {name}"));
        let v = to_vec(g).unwrap()[0];
        assert!(v > 0.0 && v.is_finite(), "{name}: |grad| sum {v}");
    }
    // Discriminator loss on a detached render: nothing for the generator.
    let (fake, _) = gan.generator.forward(clean, depth, z).unwrap();
    let real = Tensor::<4>::ones([2, 3, 32, 32], &d) * 0.3;
    let d_loss = GanLoss::LeastSquares.discriminator(
        gan.discriminator.forward(real),
        gan.discriminator.forward(fake.detach()),
    );
    let mut grads = d_loss.backward();
    assert!(GradientsParams::from_module(&mut grads, &gan.generator).is_empty());
    assert!(!GradientsParams::from_module(&mut grads, &gan.discriminator).is_empty());
}

#[test]
fn losses_match_hand_values() {
    let d = Device::flex();
    let t = |v: f32| Tensor::<4>::ones([1, 1, 1, 1], &d) * v;
    let v = |x: Tensor<1>| f64::from(to_vec(x).unwrap()[0]);
    // softplus(0) = ln 2; softplus(-2) = ln(1 + e^-2) = 0.126928.
    assert!(
        (v(GanLoss::NonSaturating.discriminator(t(0.0), t(0.0))) - 2.0 * 2f64.ln()).abs() < 1e-6
    );
    assert!((v(GanLoss::NonSaturating.generator(t(2.0))) - 0.126_928).abs() < 1e-5);
    // Large logits do not overflow: softplus(100) = 100.
    assert!((v(GanLoss::NonSaturating.generator(t(-100.0))) - 100.0).abs() < 1e-3);
    // LSGAN: 0.5 * ((0.5 - 1)^2 + 0.5^2) = 0.25; (0.5 - 1)^2 = 0.25.
    assert!((v(GanLoss::LeastSquares.discriminator(t(0.5), t(0.5))) - 0.25).abs() < 1e-6);
    assert!((v(GanLoss::LeastSquares.generator(t(0.5))) - 0.25).abs() < 1e-6);
}

#[test]
fn a_tiny_run_trains_both_players_validates_and_exports() {
    let dir = tempfile::tempdir().unwrap();
    let clean = dir.path().join("inair");
    let refs = dir.path().join("refs");
    write_images(&clean, 4, false);
    write_images(&refs.join("underwater"), 3, true);
    let run = dir.path().join("run");
    let opts = TrainOptions::new(vec![clean], run.clone(), Device::flex());
    let cfg = tiny();
    let mut messages = Vec::new();
    let s = train(&cfg, &opts, &[refs], &AtomicBool::new(false), &mut |e| {
        if let Event::Message(m) = e {
            messages.push(m.to_string());
        }
    })
    .unwrap();
    assert!(s.finished);
    assert_eq!(s.step, 4, "2 epochs of 4 images in batches of 2");
    let first = &s.losses[0].1;
    let last = &s.losses[3].1;
    assert!(first.iter().chain(last).all(|v| v.is_finite()));
    assert_ne!(first[0], last[0], "discriminator loss unchanged");
    assert_ne!(first[1], last[1], "generator loss unchanged");
    assert!((last[2] - last[0] - last[1]).abs() < 1e-9);
    assert!(
        messages.iter().any(|m| m.contains("built-in prior")),
        "{messages:?}"
    );
    // Validation ran (contact sheets, val.csv) and a best checkpoint exists.
    let val = std::fs::read_to_string(run.join("val.csv")).unwrap();
    assert_eq!(val.lines().count(), 3, "{val}");
    assert!(run.join("val").read_dir().unwrap().count() >= 2);
    assert!(s.best.is_some_and(|(p, _)| p.is_finite()));
    // The exported generator loads and renders.
    let g = load_generator(&s.last_weights, &Device::flex()).unwrap();
    assert_eq!(g.config, cfg.model.generator);
    assert!(s.best_weights.is_some());
}

#[test]
fn a_run_is_deterministic_per_seed() {
    let dir = tempfile::tempdir().unwrap();
    let clean = dir.path().join("inair");
    let refs = dir.path().join("refs");
    write_images(&clean, 2, false);
    write_images(&refs, 2, true);
    let cfg = GanTrainConfig {
        epochs: 1,
        val_images: 0,
        ..tiny()
    };
    let losses = |name: &str| {
        let opts = TrainOptions::new(vec![clean.clone()], dir.path().join(name), Device::flex());
        train(
            &cfg,
            &opts,
            std::slice::from_ref(&refs),
            &AtomicBool::new(false),
            &mut |_| {},
        )
        .unwrap()
        .losses
    };
    assert_eq!(losses("a"), losses("b"));
}

/// The config files of `tests/fixtures/`, as the code before `RunSettings` (commit 966515d)
/// wrote them (the defaults; a run with every run-level field changed), read back to configs
/// that write the same JSON. The defaults of now are those of then, so a new config is
/// written with the same keys and values as before.
#[test]
fn config_files_of_earlier_versions_read_back_unchanged() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let read = |name: &str| read_config_unchanged::<GanTrainConfig>(&dir.join(name));
    assert_eq!(
        read("config-default.json").unwrap(),
        GanTrainConfig::default()
    );
    let custom = read("config-custom.json").unwrap();
    assert_eq!((custom.run.seed, custom.val_images), (3, 2));
    let partial: GanTrainConfig = serde_json::from_str(r#"{"epochs": 3}"#).unwrap();
    assert_eq!(
        partial.run,
        GanTrainConfig::default().run,
        "the GAN's own defaults"
    );
    assert!(serde_json::from_str::<GanTrainConfig>(r#"{"max_pairs_per_dir": 2}"#).is_err());
}

#[test]
fn invalid_fields_are_named() {
    let d = GanTrainConfig::default;
    for (c, field) in [
        (GanTrainConfig { epochs: 0, ..d() }, "epochs"),
        (GanTrainConfig { crop: 16, ..d() }, "crop"),
        (GanTrainConfig { lr: 0.0, ..d() }, "lr"),
        (GanTrainConfig { g_steps: 0, ..d() }, "g_steps"),
        (
            GanTrainConfig {
                run: RunSettings {
                    prefetch_batches: 0,
                    ..d().run
                },
                ..d()
            },
            "prefetch_batches",
        ),
        (
            GanTrainConfig {
                total_steps: Some(0),
                ..d()
            },
            "total_steps",
        ),
    ] {
        match c.validate() {
            Err(GanError::InvalidTrainConfig { field: f, .. }) => assert_eq!(f, field),
            other => panic!("expected InvalidTrainConfig for {field}, got {other:?}"),
        }
    }
    GanTrainConfig::default().validate().unwrap();
    let back: GanTrainConfig = serde_json::from_str(&tiny().to_json().unwrap()).unwrap();
    assert_eq!(back, tiny());
}
