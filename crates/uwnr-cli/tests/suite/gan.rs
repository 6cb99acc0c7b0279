//! End-to-end tests of the GAN baseline on the command line: `uwnr gan train` (a tiny run, its
//! files, resume), then its generator in `uwnr render --method uwgan` (deterministic per seed,
//! no reference needed) and `uwnr dataset --method uwgan`, and bad input.

use std::path::{Path, PathBuf};

use uwnr_core::Image;
use uwnr_core::io::save_rgb;

use crate::common::{files_in, s, sample, stderr, uwnr};

/// A smooth test image; `k` shifts its pattern, `cast` tints it (references).
fn image(w: usize, h: usize, k: usize, cast: [f32; 3]) -> Image {
    let mut img = Image::filled(w, h, 3, 0.0);
    for (c, gain) in cast.into_iter().enumerate() {
        let p = img.plane_mut(c);
        for y in 0..h {
            for x in 0..w {
                let t = (x as f32 * (0.21 + 0.04 * c as f32) + y as f32 * 0.17 + k as f32).sin();
                p[y * w + x] = gain * (0.5 + 0.4 * t);
            }
        }
    }
    img
}

/// `n` images in `dir`, named `NNN.png`.
fn folder(dir: &Path, n: usize, cast: [f32; 3]) -> PathBuf {
    std::fs::create_dir_all(dir).unwrap();
    for k in 0..n {
        save_rgb(&dir.join(format!("{k:03}.png")), &image(48, 40, k, cast)).unwrap();
    }
    dir.to_path_buf()
}

/// Trains a tiny GAN for 2 epochs (4 steps, the first session stopped after 1 and resumed);
/// returns the run folder.
fn trained(root: &Path) -> PathBuf {
    let clean = folder(&root.join("clean"), 4, [1.0, 1.0, 1.0]);
    let refs = folder(&root.join("refs"), 3, [0.2, 0.7, 0.8]);
    let config = root.join("tiny.json");
    std::fs::write(
        &config,
        r#"{"model": {"generator": {"z_dim": 4, "widths": [4, 8], "hidden": 8, "encoder_size": 16},
                      "discriminator": {"width": 4, "layers": 2}},
            "epochs": 2, "crop": 32, "batch_size": 2, "log_every_steps": 1,
            "val_images": 2, "val_sheet_pairs": 2, "checkpoint_every_secs": 0}"#,
    )
    .unwrap();
    let run = root.join("run");
    let args = |extra: &[&str]| {
        let mut v = vec![
            "gan",
            "train",
            "--clean",
            s(&clean),
            "--references",
            s(&refs),
            "--run",
            s(&run),
        ];
        v.extend_from_slice(extra);
        uwnr(&v)
    };
    let o = args(&["--config", s(&config), "--max-steps", "1", "--seed", "3"]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("paused") && err.contains("step 1"), "{err}");
    // A changed setting on resume is refused in one line, naming it.
    let o = args(&["--resume", "--epochs", "3"]);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert!(err.contains("epochs"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    let o = args(&["--resume"]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("finished at step 4"), "{err}");
    assert!(err.contains("best colour-moment PSNR"), "{err}");
    for f in ["config.json", "metrics.csv", "val.csv", "curves.png"] {
        assert!(run.join(f).is_file(), "{f} missing");
    }
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("config.json")).unwrap()).unwrap();
    assert_eq!(saved["seed"], 3);
    let metrics = std::fs::read_to_string(run.join("metrics.csv")).unwrap();
    assert!(
        metrics.starts_with("step,epoch,lr,d_loss,g_loss,total"),
        "{metrics}"
    );
    assert_eq!(
        metrics.lines().count(),
        5,
        "a header and one row per step: {metrics}"
    );
    run
}

#[test]
fn a_trained_generator_renders_deterministically_and_makes_datasets() {
    let dir = tempfile::tempdir().unwrap();
    let run = trained(dir.path());
    let weights = run.join("checkpoints/last/generator.safetensors");
    assert!(weights.is_file());
    let clean = sample("clean-room.jpg");
    let render = |seed: &str, out: &Path, extra: &[&str]| {
        let mut v = vec![
            "render",
            s(&clean),
            "--method",
            "uwgan",
            "--weights",
            s(&weights),
            "--seed",
            seed,
            "-o",
            s(out),
        ];
        v.extend_from_slice(extra);
        uwnr(&v)
    };
    let (a, b, c) = (
        dir.path().join("a.png"),
        dir.path().join("b.png"),
        dir.path().join("c.png"),
    );
    let o = render("5", &a, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    // A reference is not needed, and one given is ignored with a note.
    let reference = sample("ref-green.png");
    let o = render("5", &b, &["-r", s(&reference)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("uses no reference"), "{}", stderr(&o));
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
    let o = render("6", &c, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (ia, ic) = (
        uwnr_core::io::load_rgb(&a, &Default::default()).unwrap(),
        uwnr_core::io::load_rgb(&c, &Default::default()).unwrap(),
    );
    let src = uwnr_core::io::load_rgb(&clean, &Default::default()).unwrap();
    assert_eq!(ia.size(), src.size(), "rendered at the photo's own size");
    assert_ne!(ia, ic, "another seed draws another water");

    // Options of other methods are refused, as is bf16.
    let o = render("5", &dir.path().join("x.png"), &["--water-type", "3C"]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("--water-type does not apply"),
        "{}",
        stderr(&o)
    );
    let o = render("5", &dir.path().join("x.png"), &["--precision", "bf16"]);
    assert!(!o.status.success());
    assert!(!dir.path().join("x.png").exists());

    // A dataset: references ignored with a note, the generator's fingerprint recorded, each
    // pair's water parameters in the manifest, and the same seed gives the same files.
    let cleans = folder(&dir.path().join("dclean"), 3, [1.0, 0.9, 0.8]);
    let make = |out: &Path| {
        uwnr(&[
            "dataset",
            "--clean",
            s(&cleans),
            "--references",
            s(&dir.path().join("refs")),
            "--method",
            "uwgan",
            "--weights",
            s(&weights),
            "-k",
            "2",
            "--seed",
            "9",
            "-o",
            s(out),
        ])
    };
    let (d1, d2) = (dir.path().join("d1"), dir.path().join("d2"));
    for d in [&d1, &d2] {
        let o = make(d);
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(stderr(&o).contains("uses no reference"), "{}", stderr(&o));
    }
    let uw = files_in(&d1.join("underwater"));
    assert_eq!(uw.len(), 6, "{uw:?}");
    for f in &uw {
        assert_eq!(
            std::fs::read(d1.join("underwater").join(f)).unwrap(),
            std::fs::read(d2.join("underwater").join(f)).unwrap(),
            "{f}"
        );
    }
    let settings = std::fs::read_to_string(d1.join("dataset.json")).unwrap();
    assert!(
        settings.contains("uwgan") && settings.contains("fnv1a64:"),
        "{settings}"
    );
    let manifest = std::fs::read_to_string(d1.join("manifest.jsonl")).unwrap();
    assert!(manifest.contains("\"backlight\""), "{manifest}");
    let o = uwnr(&["dataset", "verify", s(&d1)]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn bad_generator_weights_give_one_line_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.safetensors");
    std::fs::write(&bad, b"not safetensors at all").unwrap();
    let out = dir.path().join("out.png");
    for weights in [bad, dir.path().join("missing.safetensors")] {
        let o = uwnr(&[
            "render",
            s(&sample("clean-room.jpg")),
            "--method",
            "uwgan",
            "--weights",
            s(&weights),
            "-o",
            s(&out),
        ]);
        let err = stderr(&o);
        assert!(!o.status.success());
        assert!(err.contains("UWGAN generator"), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(!out.exists());
    }
}
