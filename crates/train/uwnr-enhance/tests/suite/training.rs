//! End-to-end training on tiny synthetic pairs with a width-8 network: the loss falls,
//! validation and checkpoints write their files, a run stopped by `max_steps` and resumed
//! follows the uninterrupted one exactly, and bad data or a changed config give clear errors.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

use uwnr_enhance::train::ENHANCER_FILE;
use uwnr_enhance::{
    EnhanceError, EnhanceTrainConfig, EnhanceTrainOptions, EnhanceTrainSummary, ShallowUwnetConfig,
    train,
};
use uwnr_run::{Event, RunError, RunSettings};
use uwnr_train::Device;

use crate::common::make_dir;

fn tiny_config(epochs: usize) -> EnhanceTrainConfig {
    EnhanceTrainConfig {
        model: ShallowUwnetConfig {
            width: 8,
            ..ShallowUwnetConfig::default()
        },
        epochs,
        batch_size: 2,
        crop: 32,
        lr: 5e-3,
        run: RunSettings {
            seed: 5,
            log_every_steps: 1,
            checkpoint_every_secs: 0,
            val_every_epochs: 0,
            ..EnhanceTrainConfig::default().run
        },
        ..EnhanceTrainConfig::default()
    }
}

/// Runs a session; returns its summary and the `(step, total)` of every step.
fn run(
    cfg: &EnhanceTrainConfig,
    opts: &EnhanceTrainOptions,
    stop_after: Option<usize>,
) -> (EnhanceTrainSummary, Vec<(usize, f64)>, Vec<String>) {
    let stop = AtomicBool::new(false);
    let mut totals = Vec::new();
    let mut messages = Vec::new();
    let s = train(cfg, opts, &stop, &mut |e| match e {
        Event::Step { step, losses, .. } => {
            totals.push((step, losses[2]));
            if stop_after.is_some_and(|n| step >= n) {
                stop.store(true, Ordering::Relaxed);
            }
        }
        Event::Message(m) => messages.push(m.to_string()),
        _ => {}
    })
    .unwrap();
    (s, totals, messages)
}

/// `metrics.csv` without its timing column.
fn metrics_rows(run: &Path) -> Vec<String> {
    std::fs::read_to_string(run.join("metrics.csv"))
        .unwrap()
        .lines()
        .map(|l| l.rsplit_once(',').unwrap().0.to_string())
        .collect()
}

#[test]
fn loss_falls_and_the_run_writes_its_files() {
    let tmp = tempfile::tempdir().unwrap();
    let data = make_dir(&tmp.path().join("train"), 6, 40, 36);
    let val = make_dir(&tmp.path().join("val"), 2, 40, 28);
    let mut cfg = tiny_config(8);
    cfg.run.val_every_epochs = 4;
    let run_dir = tmp.path().join("run");
    let mut opts = EnhanceTrainOptions::new(vec![data], run_dir.clone(), Device::flex());
    opts.val = Some(val);
    let (s, totals, messages) = run(&cfg, &opts, None);
    assert!(s.finished && !s.interrupted);
    assert_eq!((s.step, totals.len()), (8 * 3, 24));
    assert!(
        messages.iter().any(|m| m.contains("1 - SSIM")),
        "no stand-in warning: {messages:?}"
    );
    let mean = |v: &[(usize, f64)]| v.iter().map(|t| t.1).sum::<f64>() / v.len() as f64;
    let (first, last) = (mean(&totals[..4]), mean(&totals[totals.len() - 4..]));
    assert!(last < 0.6 * first, "loss did not fall: {first} -> {last}");

    for f in [
        "config.json",
        "data-report.txt",
        "metrics.csv",
        "val.csv",
        "curves.png",
    ] {
        assert!(run_dir.join(f).is_file(), "{f} missing");
    }
    let metrics = std::fs::read_to_string(run_dir.join("metrics.csv")).unwrap();
    assert!(metrics.starts_with("step,epoch,lr,mse,perceptual,total,secs_per_step\n"));
    assert_eq!(metrics.lines().count(), 1 + 24);
    // Validated after epochs 4 and 8; the PSNR improved, so best is the last one or earlier.
    let val_rows = std::fs::read_to_string(run_dir.join("val.csv")).unwrap();
    assert_eq!(val_rows.lines().count(), 1 + 2, "{val_rows}");
    let (best_psnr, best_step) = s.best.expect("validated");
    assert!(best_psnr.is_finite() && [12, 24].contains(&best_step));
    assert_eq!(
        s.last_weights,
        run_dir.join("checkpoints/last").join(ENHANCER_FILE)
    );
    let best = s.best_weights.clone().expect("best checkpoint");
    for w in [&s.last_weights, &best] {
        let (_, c) = uwnr_enhance::weights::load(w, &Device::flex()).unwrap();
        assert_eq!(c, cfg.model);
    }

    // A second run in the same folder without resume is refused.
    let stop = AtomicBool::new(false);
    let err = train(&cfg, &opts, &stop, &mut |_| {}).unwrap_err();
    assert!(
        matches!(err, EnhanceError::Run(RunError::RunExists { .. })),
        "{err}"
    );
    // Resuming with another config names what changed.
    let mut resume = opts.clone();
    resume.resume = true;
    let other = EnhanceTrainConfig {
        epochs: 9,
        ..cfg.clone()
    };
    let err = train(&other, &resume, &stop, &mut |_| {}).unwrap_err();
    assert!(
        matches!(&err, EnhanceError::Run(RunError::ConfigChanged { fields, .. }) if fields == &["epochs"]),
        "{err}"
    );
    assert!(err.to_string().contains("epochs"), "{err}");
    // Resuming a finished run does nothing and keeps its files.
    let (again, totals, _) = run(&cfg, &resume, None);
    assert!(again.finished && again.session_steps == 0 && totals.is_empty());
    assert!((again.train_secs - s.train_secs).abs() < 1e-9);
    assert_eq!(again.best, s.best);
}

#[test]
fn a_resumed_run_follows_the_uninterrupted_one() {
    let tmp = tempfile::tempdir().unwrap();
    // Pairs smaller than the crop are reflect-padded.
    let data = make_dir(&tmp.path().join("train"), 4, 40, 24);
    let cfg = tiny_config(3);
    let whole = EnhanceTrainOptions::new(vec![data.clone()], tmp.path().join("a"), Device::flex());
    let (a, ta, _) = run(&cfg, &whole, None);
    assert_eq!(a.step, 6);
    let report = std::fs::read_to_string(tmp.path().join("a/data-report.txt")).unwrap();
    assert!(report.contains("4 pairs padded"), "{report}");

    let mut split = EnhanceTrainOptions::new(vec![data], tmp.path().join("b"), Device::flex());
    split.max_steps = Some(3);
    let (b1, t1, _) = run(&cfg, &split, None);
    assert!(!b1.finished && !b1.interrupted && b1.step == 3);
    assert!(b1.last_weights.is_file());
    split.max_steps = None;
    split.resume = true;
    let (b2, t2, messages) = run(&cfg, &split, None);
    assert!(b2.finished && b2.step == 6 && b2.session_steps == 3);
    assert!(messages.iter().any(|m| m.contains("resuming at step 3")));
    // The training time adds up over sessions and is the one the checkpoint records.
    assert!(b1.train_secs > 0.0 && b2.train_secs > b1.train_secs);
    let state = uwnr_run::checkpoint::read_state(&tmp.path().join("b/checkpoints/last")).unwrap();
    assert!((state.train_secs - b2.train_secs).abs() < 1e-9);

    let resumed: Vec<(usize, f64)> = t1.into_iter().chain(t2).collect();
    assert_eq!(resumed, ta, "the resumed run's losses differ");
    let (ma, mb) = (
        metrics_rows(&tmp.path().join("a")),
        metrics_rows(&tmp.path().join("b")),
    );
    assert_eq!(ma.len(), 1 + 6);
    assert_eq!(ma, mb);
    let (wa, _) = uwnr_model::read_tensor_file(&a.last_weights).unwrap();
    let (wb, _) = uwnr_model::read_tensor_file(&b2.last_weights).unwrap();
    assert_eq!(wa.len(), wb.len());
    for (k, ta) in &wa {
        assert_eq!(ta.data, wb[k].data, "{k}");
    }
}

#[test]
fn the_stop_flag_ends_with_a_checkpoint() {
    let tmp = tempfile::tempdir().unwrap();
    let data = make_dir(&tmp.path().join("train"), 4, 32, 32);
    let opts = EnhanceTrainOptions::new(vec![data], tmp.path().join("run"), Device::flex());
    let (s, totals, _) = run(&tiny_config(5), &opts, Some(3));
    assert!(s.interrupted && !s.finished && s.step == 3 && totals.len() == 3);
    let state = uwnr_run::checkpoint::read_state(&tmp.path().join("run/checkpoints/last")).unwrap();
    assert_eq!((state.step, state.epoch, state.batch_in_epoch), (3, 1, 1));
}

#[test]
fn bad_data_gives_clear_errors() {
    let tmp = tempfile::tempdir().unwrap();
    let cfg = tiny_config(1);
    let attempt = |dirs: Vec<std::path::PathBuf>, name: &str| {
        let o = EnhanceTrainOptions::new(dirs, tmp.path().join(name), Device::flex());
        train(&cfg, &o, &AtomicBool::new(false), &mut |_| {}).unwrap_err()
    };
    // Not a paired folder.
    let plain = tmp.path().join("plain");
    std::fs::create_dir_all(&plain).unwrap();
    let err = attempt(vec![plain], "r1");
    assert!(
        matches!(err, EnhanceError::Run(RunError::NotAPairedFolder { .. })),
        "{err}"
    );
    // No names in common.
    let unpaired = make_dir(&tmp.path().join("unpaired"), 2, 32, 32);
    std::fs::rename(unpaired.join("clean/000.png"), unpaired.join("clean/x.png")).unwrap();
    std::fs::rename(unpaired.join("clean/001.png"), unpaired.join("clean/y.png")).unwrap();
    let err = attempt(vec![unpaired], "r2");
    assert!(
        matches!(err, EnhanceError::Run(RunError::NoPairs { .. })),
        "{err}"
    );
    // Only corrupt files.
    let broken = make_dir(&tmp.path().join("broken"), 2, 32, 32);
    for k in ["000", "001"] {
        std::fs::write(broken.join(format!("underwater/{k}.png")), b"garbage").unwrap();
    }
    let err = attempt(vec![broken], "r3");
    assert!(
        err.to_string().contains("no pair could be decoded"),
        "{err}"
    );
    // Fewer pairs than a batch, with a corrupt file and a lonely name listed in the report.
    let few = make_dir(&tmp.path().join("few"), 2, 32, 32);
    std::fs::write(few.join("underwater/001.png"), b"not a png").unwrap();
    std::fs::write(few.join("underwater/lonely.png"), b"").unwrap();
    let mut report = String::new();
    let o = EnhanceTrainOptions::new(vec![few], tmp.path().join("r4"), Device::flex());
    let err = train(&cfg, &o, &AtomicBool::new(false), &mut |e| {
        if let Event::Message(m) = e {
            report.push_str(m);
        }
    })
    .unwrap_err();
    assert!(
        matches!(err, EnhanceError::Run(RunError::NoData(_))),
        "{err}"
    );
    assert!(
        report.contains("lonely.png") && report.contains("001.png"),
        "{report}"
    );
    // A start that failed leaves no run folder behind.
    assert!(!tmp.path().join("r4").exists());
    // Resuming a folder without a run.
    let good = make_dir(&tmp.path().join("good"), 2, 32, 32);
    let mut o = EnhanceTrainOptions::new(vec![good], tmp.path().join("nothing"), Device::flex());
    o.resume = true;
    assert!(train(&cfg, &o, &AtomicBool::new(false), &mut |_| {}).is_err());
}

/// A VGG19-shaped weights file (the six convs the perceptual loss uses) with small random
/// values, under torchvision's keys.
fn tiny_vgg(path: &Path) {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let mut tensors = uwnr_model::TensorMap::new();
    for (index, cin, cout) in uwnr_train::vgg::VGG19_CONVS {
        let mut random = |n: usize, scale: f32| -> Vec<f32> {
            (0..n)
                .map(|_| (rng.random::<f32>() - 0.5) * scale)
                .collect()
        };
        tensors.insert(
            format!("features.{index}.weight"),
            uwnr_model::NamedTensor {
                shape: vec![cout, cin, 3, 3],
                data: random(cout * cin * 9, 0.1),
            },
        );
        tensors.insert(
            format!("features.{index}.bias"),
            uwnr_model::NamedTensor {
                shape: vec![cout],
                data: random(cout, 0.01),
            },
        );
    }
    uwnr_model::write_tensor_file(
        path,
        &tensors,
        uwnr_model::WeightsDtype::F32,
        &Default::default(),
    )
    .unwrap();
}

#[test]
fn vgg19_weights_replace_the_stand_in() {
    let tmp = tempfile::tempdir().unwrap();
    let data = make_dir(&tmp.path().join("train"), 4, 32, 32);
    let vgg = tmp.path().join("vgg19.safetensors");
    tiny_vgg(&vgg);
    let cfg = EnhanceTrainConfig {
        w_perceptual: 0.5,
        ..tiny_config(1)
    };
    let mut opts =
        EnhanceTrainOptions::new(vec![data.clone()], tmp.path().join("run"), Device::flex());
    opts.vgg19 = Some(vgg);
    let stop = AtomicBool::new(false);
    let mut steps = Vec::new();
    let mut messages = Vec::new();
    train(&cfg, &opts, &stop, &mut |e| match e {
        Event::Step { losses, .. } => steps.push((losses[0], losses[1], losses[2])),
        Event::Message(m) => messages.push(m.to_string()),
        _ => {}
    })
    .unwrap();
    assert_eq!(steps.len(), 2);
    assert!(
        messages.iter().any(|m| m.contains("VGG19 perceptual")),
        "{messages:?}"
    );
    assert!(
        !messages.iter().any(|m| m.contains("warning")),
        "{messages:?}"
    );
    for (mse, per, total) in steps {
        assert!(per > 0.0 && mse > 0.0);
        assert!((total - (mse + 0.5 * per)).abs() < 1e-5 * (1.0 + total));
    }
    // A file that is not VGG19 weights is an error naming it.
    let mut bad = EnhanceTrainOptions::new(vec![data], tmp.path().join("run-bad"), Device::flex());
    bad.vgg19 = Some(tmp.path().join("missing.safetensors"));
    let err = train(&cfg, &bad, &stop, &mut |_| {}).unwrap_err();
    assert!(err.to_string().contains("missing.safetensors"), "{err}");
}
