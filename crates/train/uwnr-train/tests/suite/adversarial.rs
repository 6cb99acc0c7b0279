//! The correction trained against real photos (`config.adversarial`): a step starts at the
//! uncorrected render and moves both networks; a run checkpoints the generator alone, logs its
//! own terms, and resumes exactly.

use std::path::Path;

use uwnr_core::Image;
use uwnr_core::io::save_rgb;
use uwnr_model::{Correction, GeneratorConfig, read_weights};
use uwnr_run::RunSettings;
use uwnr_run::checkpoint::{CHECKPOINTS_DIR, LAST};
use uwnr_train::config::{LossWeights, RenderStages};
use uwnr_train::{AdversarialConfig, Device, GENERATOR_FILE, TrainConfig, TrainOptions};

use crate::training::run;

/// Clean photos beside "real" photos of other scenes (green and hazy stripes).
fn make_dir(root: &Path, n: usize, side: usize) {
    for d in ["clean", "underwater"] {
        std::fs::create_dir_all(root.join(d)).unwrap();
    }
    for k in 0..n {
        let mut clean = Image::filled(side, side, 3, 0.0);
        let mut real = Image::filled(side, side, 3, 0.0);
        for c in 0..3 {
            for (i, v) in clean.plane_mut(c).iter_mut().enumerate() {
                let (x, y) = ((i % side) as f32, (i / side) as f32);
                *v = 0.5 + 0.4 * (x * (0.2 + 0.07 * c as f32) + y * 0.11 + k as f32).sin();
            }
            for (i, v) in real.plane_mut(c).iter_mut().enumerate() {
                let y = (i / side) as f32 / side as f32;
                *v = [0.1, 0.45, 0.4][c] + 0.15 * (1.0 - y) + 0.05 * ((i % 7) as f32 / 7.0);
            }
        }
        let name = format!("{k:03}.png");
        save_rgb(&root.join("clean").join(&name), &clean).unwrap();
        save_rgb(&root.join("underwater").join(&name), &real).unwrap();
    }
}

fn config(epochs: usize) -> TrainConfig {
    TrainConfig {
        model: GeneratorConfig {
            correction: Correction::Network,
            ..GeneratorConfig::anchored(8)
        },
        epochs,
        batch_size: 2,
        crop: 32,
        lr: 2e-3,
        loss: LossWeights {
            reconstruction: 0.0,
            perceptual: 0.0,
            dark_channel: 0.0,
            light_field: 0.0,
        },
        adversarial: Some(AdversarialConfig {
            weight: 0.1,
            ..AdversarialConfig::default()
        }),
        run: RunSettings {
            seed: 3,
            log_every_steps: 1,
            checkpoint_every_secs: 0,
            val_every_epochs: 0,
            ..TrainConfig::default().run
        },
        ..TrainConfig::default()
    }
}

fn generator_weights(run: &Path) -> std::collections::BTreeMap<String, Vec<f32>> {
    read_weights(&run.join(CHECKPOINTS_DIR).join(LAST).join(GENERATOR_FILE))
        .unwrap()
        .tensors
        .into_iter()
        .map(|(k, t)| (k, t.data))
        .collect()
}

#[test]
fn an_adversarial_run_moves_the_correction_and_resumes_exactly() {
    moves_and_resumes(&config(2));
}

#[test]
fn a_run_through_the_render_stages_resumes_exactly() {
    // The stages draw particles and noise from the run's seed and the step: a resumed run draws
    // what the uninterrupted one did.
    let mut cfg = config(2);
    if let Some(a) = cfg.adversarial.as_mut() {
        a.stages = Some(RenderStages {
            frame: 64,
            ..RenderStages::default()
        });
    }
    moves_and_resumes(&cfg);
}

fn moves_and_resumes(cfg: &TrainConfig) {
    let tmp = tempfile::tempdir().unwrap();
    let data = tmp.path().join("pairs");
    make_dir(&data, 4, 40);
    let cfg = cfg.clone();
    let whole = TrainOptions::new(vec![data.clone()], tmp.path().join("a"), Device::flex());
    let a = run(&cfg, &whole, None);
    assert!(a.finished && a.step == 4 && a.losses.is_empty());
    assert_eq!(a.adversarial.len(), 4);
    // The first step starts at the uncorrected render: the content term is exactly 0, and the
    // total is the weighted adversarial term.
    let first = a.adversarial[0].1;
    assert_eq!(first[2], 0.0, "{first:?}");
    assert!((first[4] - 0.1 * first[1]).abs() < 1e-6, "{first:?}");
    for (_, v) in &a.adversarial {
        assert!(v.iter().all(|x| x.is_finite()), "{v:?}");
    }
    // Later steps have moved the correction away from zero.
    assert!(a.adversarial[3].1[2] > 0.0, "{:?}", a.adversarial);
    let header = std::fs::read_to_string(tmp.path().join("a/metrics.csv")).unwrap();
    assert!(
        header.starts_with("step,epoch,lr,d_loss,adversarial,content,paired,total"),
        "{header}"
    );
    // The checkpoint's weights file is the generator alone, with a non-zero output conv.
    let wa = generator_weights(&tmp.path().join("a"));
    assert!(wa.keys().all(|k| !k.contains("discriminator")));
    let out = wa
        .iter()
        .find(|(k, _)| k.starts_with("out"))
        .expect("out conv");
    assert!(out.1.iter().any(|v| *v != 0.0), "{}", out.0);

    // Stopped after 2 steps and resumed: the same losses and the same weights.
    let mut split = TrainOptions::new(vec![data], tmp.path().join("b"), Device::flex());
    let b1 = run(&cfg, &split, Some(2));
    assert!(b1.interrupted && b1.step == 2);
    split.resume = true;
    let b2 = run(&cfg, &split, None);
    let resumed: Vec<_> = b1.adversarial.iter().chain(&b2.adversarial).collect();
    assert_eq!(resumed.len(), a.adversarial.len());
    for ((sa, va), (sb, vb)) in a.adversarial.iter().zip(resumed) {
        assert_eq!(sa, sb);
        for (x, y) in va.iter().zip(vb) {
            assert!((x - y).abs() < 1e-6, "step {sa}: {va:?} vs {vb:?}");
        }
    }
    let wb = generator_weights(&tmp.path().join("b"));
    for (k, ta) in &wa {
        let diff = ta
            .iter()
            .zip(&wb[k])
            .map(|(x, y)| (x - y).abs())
            .fold(0.0_f32, f32::max);
        assert!(diff < 1e-6, "{k}: {diff}");
    }
}

#[test]
fn a_step_updates_both_networks() {
    use burn::optim::AdamWConfig;
    use uwnr_train::GeneratorInit;
    use uwnr_train::loader::Batch;
    let cfg = config(1);
    let adv = cfg.adversarial.unwrap();
    let device = Device::flex().autodiff();
    // Built under the loop's seeding lock: the tests of this binary run in parallel, and a
    // network drawn from burn's generator meanwhile would change another run's initial weights.
    let critic = uwnr_train::init_seeded(1, &device, || {
        Ok::<_, String>(uwnr_train::Critic {
            generator: cfg.model.init(&device).map_err(|e| e.to_string())?,
            discriminator: adv.discriminator.init(&device).map_err(|e| e.to_string())?,
        })
    })
    .unwrap();
    let before = critic.clone();
    let (b, c) = (2, 32);
    let n = c * c;
    let plane = |f: &dyn Fn(usize) -> f32| (0..b * 3 * n).map(f).collect::<Vec<f32>>();
    let clean = plane(&|i| 0.5 + 0.3 * ((i % 13) as f32 / 13.0));
    let mut input = Vec::new();
    for s in 0..b {
        let one = &clean[s * 3 * n..(s + 1) * 3 * n];
        input.extend_from_slice(one); // clean
        input.extend(one.iter().map(|v| v * 0.5)); // light field
        input.extend(one.iter().map(|v| v * 0.6 + 0.1)); // anchor
    }
    let batch = Batch {
        epoch: 0,
        index: 0,
        size: b,
        crop: c,
        input,
        target: plane(&|i| 0.3 + 0.2 * ((i % 5) as f32 / 5.0)),
        depth: vec![0.5; b * n],
        water: [0.2, 0.5, 0.5, 0.8, 0.3, 0.2].repeat(b),
    };
    let criterion = uwnr_train::Criterion::new(&cfg, None);
    let mut optim = AdamWConfig::new().init();
    let (after, values) = uwnr_train::adversarial_step(
        critic,
        &mut optim,
        &criterion,
        &adv,
        &batch,
        (1e-3, 0),
        &device,
    )
    .unwrap();
    assert_eq!(values[2], 0.0, "{values:?}");
    let flat = |m: &uwnr_train::Critic, disc: bool| -> Vec<f32> {
        let w = if disc {
            m.discriminator.convs[0].weight.val()
        } else {
            m.generator.out.weight.val()
        };
        w.into_data().try_to_vec::<f32>().unwrap()
    };
    assert_ne!(
        flat(&before, true),
        flat(&after, true),
        "discriminator unchanged"
    );
    assert_ne!(
        flat(&before, false),
        flat(&after, false),
        "generator unchanged"
    );
}

#[test]
fn the_stages_change_what_the_discriminator_sees_but_not_the_gradient() {
    use burn::tensor::{Tensor, TensorData};
    use uwnr_train::loader::Batch;
    let device = Device::flex().autodiff();
    let (b, c) = (2, 32);
    let n = c * c;
    let values: Vec<f32> = (0..b * 3 * n)
        .map(|i| 0.2 + 0.6 * ((i % 17) as f32 / 17.0))
        .collect();
    let batch = Batch {
        epoch: 0,
        index: 0,
        size: b,
        crop: c,
        input: vec![0.0; b * 9 * n],
        target: vec![0.0; b * 3 * n],
        depth: (0..b * n).map(|i| (i % c) as f32 / c as f32).collect(),
        water: [0.1, 0.5, 0.6, 0.8, 0.3, 0.2].repeat(b),
    };
    let stages = RenderStages::default();
    let out = || {
        Tensor::<4>::from_data(TensorData::new(values.clone(), [b, 3, c, c]), &device)
            .require_grad()
    };
    let seen = |seed: u64| -> Vec<f32> {
        uwnr_train::through_stages(out(), &batch, &stages, seed, &device)
            .unwrap()
            .into_data()
            .try_to_vec::<f32>()
            .unwrap()
    };
    let (a, a2, other) = (seen(5), seen(5), seen(6));
    assert_eq!(a, a2, "drawn from the seed");
    assert_ne!(a, other, "another seed draws other particles and noise");
    let moved = a
        .iter()
        .zip(&values)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0_f32, f32::max);
    assert!(
        moved > 0.02,
        "the stages moved the renders by at most {moved}"
    );
    assert!(a.iter().all(|v| (0.0..=1.0).contains(v)));
    // On 8-bit levels, as the camera's output is.
    assert!(
        a.iter()
            .all(|v| ((v * 255.0).round() - v * 255.0).abs() < 1e-3)
    );
    // Straight-through: the gradient of a weighted sum is the weights.
    let x = out();
    let w: Vec<f32> = (0..b * 3 * n).map(|i| (i % 7) as f32 - 3.0).collect();
    let wt = Tensor::from_data(TensorData::new(w.clone(), [b, 3, c, c]), &device);
    let s = uwnr_train::through_stages(x.clone(), &batch, &stages, 5, &device).unwrap();
    let grads = (s * wt).sum().backward();
    let g = x
        .grad(&grads)
        .unwrap()
        .into_data()
        .try_to_vec::<f32>()
        .unwrap();
    assert_eq!(g, w);
}
