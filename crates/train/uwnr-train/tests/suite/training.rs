//! End-to-end training on tiny synthetic pairs with a width-8 generator: the loss falls,
//! validation writes its outputs, a stopped and resumed run follows the uninterrupted one
//! exactly, and bad data gives clear errors or listed skips.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use uwnr_core::Image;
use uwnr_core::io::save_rgb;
use uwnr_model::{GeneratorConfig, read_weights};
use uwnr_run::checkpoint::{CHECKPOINTS_DIR, LAST};
use uwnr_run::pairs::discover_pairs;
use uwnr_run::{RunError, RunSettings};
use uwnr_train::Device;
use uwnr_train::config::{AugmentConfig, ColorCast, LossWeights};
use uwnr_train::data::{LoadOptions, load_data};
use uwnr_train::{Event, GENERATOR_FILE, TrainConfig, TrainError, TrainOptions, train};

/// A smooth clean image and its "underwater" version (a colour cast plus haze).
fn pair(w: usize, h: usize, k: usize) -> (Image, Image) {
    let mut clean = Image::filled(w, h, 3, 0.0);
    for c in 0..3 {
        let p = clean.plane_mut(c);
        for y in 0..h {
            for x in 0..w {
                let t = (x as f32 * (0.21 + 0.05 * c as f32) + y as f32 * 0.13 + k as f32).sin();
                p[y * w + x] = 0.5 + 0.4 * t;
            }
        }
    }
    let gain = [0.35, 0.8, 0.9];
    let haze = [0.05, 0.25, 0.3];
    let mut uw = clean.clone();
    for c in 0..3 {
        for v in uw.plane_mut(c) {
            *v = *v * gain[c] + haze[c];
        }
    }
    (clean, uw)
}

fn make_dir(root: &Path, n: usize, w: usize, h: usize, ext: &str) -> PathBuf {
    std::fs::create_dir_all(root.join("clean")).unwrap();
    std::fs::create_dir_all(root.join("underwater")).unwrap();
    for k in 0..n {
        let (c, u) = pair(w, h, k);
        let name = format!("{k:03}.{ext}");
        save_rgb(&root.join("clean").join(&name), &c).unwrap();
        save_rgb(&root.join("underwater").join(&name), &u).unwrap();
    }
    root.to_path_buf()
}

fn tiny_config(epochs: usize) -> TrainConfig {
    TrainConfig {
        model: GeneratorConfig::with_base_width(8),
        epochs,
        batch_size: 2,
        crop: 32,
        lr: 2e-3,
        run: RunSettings {
            seed: 5,
            log_every_steps: 1,
            checkpoint_every_secs: 0,
            val_every_epochs: 0,
            ..TrainConfig::default().run
        },
        ..TrainConfig::default()
    }
}

/// Trains with `cfg`, stopping after `stop_after` steps when given.
pub(crate) fn run(
    cfg: &TrainConfig,
    opts: &TrainOptions,
    stop_after: Option<usize>,
) -> uwnr_train::TrainSummary {
    let stop = AtomicBool::new(false);
    train(cfg, opts, &stop, &mut |e| {
        if let (Event::Step { step, .. }, Some(n)) = (e, stop_after)
            && step >= n
        {
            stop.store(true, Ordering::Relaxed);
        }
    })
    .unwrap()
}

#[test]
fn loss_falls_and_validation_writes_its_outputs() {
    let tmp = tempfile::tempdir().unwrap();
    let data = make_dir(&tmp.path().join("train"), 6, 40, 36, "png");
    let val = make_dir(&tmp.path().join("val"), 2, 40, 28, "png");
    let base = tiny_config(8);
    let cfg = TrainConfig {
        run: RunSettings {
            val_every_epochs: 4,
            val_sheet_pairs: 2,
            ..base.run
        },
        augment: AugmentConfig {
            color_cast: Some(ColorCast {
                probability: 0.5,
                ..ColorCast::default()
            }),
            ..AugmentConfig::default()
        },
        ..base
    };
    let mut opts = TrainOptions::new(vec![data], tmp.path().join("run"), Device::flex());
    opts.val = Some(val);
    opts.val_refs = vec![20.0];
    let s = run(&cfg, &opts, None);
    assert!(s.finished && !s.interrupted);
    assert_eq!(s.step, 8 * 3);
    let first: f64 = s.losses[..4].iter().map(|l| l.1.total).sum::<f64>() / 4.0;
    let last: f64 = s.losses[s.losses.len() - 4..]
        .iter()
        .map(|l| l.1.total)
        .sum::<f64>()
        / 4.0;
    assert!(last < 0.7 * first, "loss did not fall: {first} -> {last}");
    for (_, l) in &s.losses {
        let w = LossWeights::default();
        let total = w.reconstruction * l.reconstruction
            + w.perceptual * l.perceptual
            + w.dark_channel * l.dark_channel
            + w.light_field * l.light_field;
        assert!((total - l.total).abs() < 1e-5 * (1.0 + total));
        assert!(l.perceptual > 0.0 && l.light_field > 0.0 && l.dark_channel > 0.0);
    }
    let v = s.last_val.expect("validated");
    assert!(v.psnr.is_finite() && (0.0..=1.0).contains(&v.ssim));
    assert_eq!(v.per_pair.len(), 2);
    let run = tmp.path().join("run");
    for f in [
        "config.json",
        "data-report.txt",
        "metrics.csv",
        "val.csv",
        "curves.png",
    ] {
        assert!(run.join(f).is_file(), "{f} missing");
    }
    let val_rows = std::fs::read_to_string(run.join("val.csv")).unwrap();
    assert_eq!(val_rows.lines().count(), 1 + 2, "{val_rows}");
    assert!(run.join("val").join("step-0000012.png").is_file());
    let best = run.join(CHECKPOINTS_DIR).join("best").join(GENERATOR_FILE);
    let (g, cfg_back, _) = uwnr_train::load_generator(&best, &Device::flex()).unwrap();
    assert_eq!(cfg_back, cfg.model);
    drop(g);
    // 24 steps logged every step.
    let metrics = std::fs::read_to_string(run.join("metrics.csv")).unwrap();
    assert_eq!(metrics.lines().count(), 1 + 24);
    // A second run in the same folder without --resume is refused.
    let stop = AtomicBool::new(false);
    let err = train(&cfg, &opts, &stop, &mut |_| {}).unwrap_err();
    assert!(
        matches!(err, TrainError::Run(RunError::RunExists { .. })),
        "{err}"
    );
    // Resuming it with another config is refused too.
    let mut resume = opts.clone();
    resume.resume = true;
    let other = TrainConfig { epochs: 9, ..cfg };
    let err = train(&other, &resume, &stop, &mut |_| {}).unwrap_err();
    assert!(
        matches!(err, TrainError::Run(RunError::ConfigChanged { .. })),
        "{err}"
    );
}

#[test]
fn a_resumed_run_follows_the_uninterrupted_one() {
    let tmp = tempfile::tempdir().unwrap();
    let data = make_dir(&tmp.path().join("train"), 4, 40, 40, "png");
    let cfg = TrainConfig {
        augment: AugmentConfig {
            color_cast: Some(ColorCast::default()),
            ..AugmentConfig::default()
        },
        ..tiny_config(2)
    };
    let whole = TrainOptions::new(vec![data.clone()], tmp.path().join("a"), Device::flex());
    let a = run(&cfg, &whole, None);
    assert_eq!(a.step, 4);

    let mut split = TrainOptions::new(vec![data], tmp.path().join("b"), Device::flex());
    let b1 = run(&cfg, &split, Some(2));
    assert!(b1.interrupted && b1.step == 2);
    split.resume = true;
    let b2 = run(&cfg, &split, None);
    assert!(b2.finished && b2.step == 4 && b2.session_steps == 2);

    let resumed: Vec<_> = b1.losses.iter().chain(&b2.losses).collect();
    assert_eq!(resumed.len(), a.losses.len());
    for ((sa, la), (sb, lb)) in a.losses.iter().zip(resumed) {
        assert_eq!(sa, sb);
        for (x, y) in la.as_array().iter().zip(lb.as_array()) {
            assert!((x - y).abs() < 1e-6, "step {sa}: {la:?} vs {lb:?}");
        }
    }
    let weights = |dir: &str| {
        read_weights(
            &tmp.path()
                .join(dir)
                .join(CHECKPOINTS_DIR)
                .join(LAST)
                .join(GENERATOR_FILE),
        )
        .unwrap()
        .tensors
    };
    let (wa, wb) = (weights("a"), weights("b"));
    assert_eq!(wa.len(), wb.len());
    for (k, ta) in &wa {
        let tb = &wb[k];
        let diff = ta
            .data
            .iter()
            .zip(&tb.data)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0_f32, f32::max);
        assert!(diff < 1e-6, "{k}: {diff}");
    }
    // The metrics file of the resumed run has each step once.
    let m = std::fs::read_to_string(tmp.path().join("b").join("metrics.csv")).unwrap();
    let steps: Vec<&str> = m
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap())
        .collect();
    assert_eq!(steps, ["1", "2", "3", "4"]);
}

#[test]
fn bad_data_is_reported() {
    let tmp = tempfile::tempdir().unwrap();
    let opts = |dirs: Vec<PathBuf>| {
        let o = LoadOptions {
            crop: 32,
            small_images: Default::default(),
            depth: Default::default(),
            max_pairs_per_dir: None,
            limits: Default::default(),
        };
        load_data(&dirs, None, &o)
    };
    // Not a paired folder.
    let plain = tmp.path().join("plain");
    std::fs::create_dir_all(&plain).unwrap();
    assert!(matches!(
        opts(vec![plain]).unwrap_err(),
        TrainError::Run(RunError::NotAPairedFolder { .. })
    ));
    // Empty underwater folder.
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(empty.join("underwater")).unwrap();
    make_dir(&tmp.path().join("empty_src"), 1, 32, 32, "png");
    std::fs::create_dir_all(empty.join("clean")).unwrap();
    std::fs::copy(
        tmp.path().join("empty_src/clean/000.png"),
        empty.join("clean/000.png"),
    )
    .unwrap();
    let err = opts(vec![empty]).unwrap_err();
    assert!(
        matches!(&err, TrainError::Run(RunError::NoPairs { reason, .. }) if reason.contains("holds no images")),
        "{err}"
    );
    // Unpaired names and a corrupt file are skipped and listed; small images are upscaled.
    let mixed = make_dir(&tmp.path().join("mixed"), 3, 24, 40, "png");
    std::fs::write(mixed.join("underwater/lonely.png"), b"").unwrap();
    std::fs::write(mixed.join("underwater/001.png"), b"not a png").unwrap();
    let found = discover_pairs(&mixed, None).unwrap();
    assert_eq!(found.pairs.len(), 3);
    assert_eq!(found.skipped.len(), 1);
    let data = opts(vec![mixed]).unwrap();
    assert_eq!(data.pairs.len(), 2);
    assert_eq!(data.report.upscaled.len(), 2);
    assert!(
        data.pairs
            .iter()
            .all(|p| p.width() == 32 && p.height() >= 32)
    );
    let text = data.report.to_text();
    assert!(
        text.contains("lonely.png") && text.contains("001.png"),
        "{text}"
    );
    // Only corrupt files: an error.
    let broken = make_dir(&tmp.path().join("broken"), 1, 32, 32, "png");
    std::fs::write(broken.join("clean/000.png"), b"garbage").unwrap();
    let err = opts(vec![broken]).unwrap_err();
    assert!(
        matches!(err, TrainError::Run(RunError::NoPairs { .. })),
        "{err}"
    );
    // Fewer pairs than a batch.
    let few = make_dir(&tmp.path().join("few"), 1, 32, 32, "png");
    let cfg = tiny_config(1);
    let o = TrainOptions::new(vec![few], tmp.path().join("run-few"), Device::flex());
    let err = train(&cfg, &o, &AtomicBool::new(false), &mut |_| {}).unwrap_err();
    assert!(matches!(err, TrainError::Run(RunError::NoData(_))), "{err}");
    // Resuming a folder without a run.
    let mut o = TrainOptions::new(
        vec![tmp.path().join("mixed")],
        tmp.path().join("nothing"),
        Device::flex(),
    );
    o.resume = true;
    assert!(train(&cfg, &o, &AtomicBool::new(false), &mut |_| {}).is_err());
}

#[test]
fn a_failed_start_does_not_claim_the_run_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(empty.join("underwater")).unwrap();
    std::fs::create_dir_all(empty.join("clean")).unwrap();
    let run_dir = tmp.path().join("run");
    let cfg = tiny_config(1);
    let stop = AtomicBool::new(false);
    // Bad data: the start fails and leaves no run behind.
    let bad = TrainOptions::new(vec![empty], run_dir.clone(), Device::flex());
    assert!(train(&cfg, &bad, &stop, &mut |_| {}).is_err());
    assert!(!run_dir.join("config.json").exists());
    // A folder that a killed first session left (config, no checkpoint) is not a run either.
    std::fs::create_dir_all(&run_dir).unwrap();
    std::fs::write(run_dir.join("config.json"), "{}").unwrap();
    let mut resume = bad.clone();
    resume.resume = true;
    let err = train(&cfg, &resume, &stop, &mut |_| {}).unwrap_err();
    assert!(err.to_string().contains("no checkpoint"), "{err}");
    // The same command with good data starts the run.
    let data = make_dir(&tmp.path().join("data"), 2, 32, 32, "png");
    let good = TrainOptions::new(vec![data], run_dir.clone(), Device::flex());
    let s = run(&cfg, &good, None);
    assert!(s.finished);
    assert!(uwnr_run::folder::holds_run(&run_dir));
    // Now it holds a run: a fresh start is refused.
    let err = train(&cfg, &good, &stop, &mut |_| {}).unwrap_err();
    assert!(
        matches!(err, TrainError::Run(RunError::RunExists { .. })),
        "{err}"
    );
}
