//! End-to-end tests of `uwnr enhance`: a tiny training run, applying weights to files and
//! folders, scoring a paired folder, and bad input.

use std::path::{Path, PathBuf};

use uwnr_core::Image;
use uwnr_core::io::save_rgb;

use crate::common::{files_in, s, stderr, uwnr};

/// Width-16 Shallow-UWnet weights with random values (uwnr-enhance's parity fixture).
fn enhancer_weights() -> PathBuf {
    crate::common::root().join("crates/train/uwnr-enhance/tests/fixtures/parity_w16.safetensors")
}

/// A smooth image and a cast, hazy copy of it.
fn pair(w: usize, h: usize, k: usize) -> (Image, Image) {
    let mut clean = Image::filled(w, h, 3, 0.0);
    for c in 0..3 {
        let p = clean.plane_mut(c);
        for y in 0..h {
            for x in 0..w {
                let t = (x as f32 * (0.2 + 0.05 * c as f32) + y as f32 * 0.13 + k as f32).sin();
                p[y * w + x] = 0.5 + 0.4 * t;
            }
        }
    }
    let mut uw = clean.clone();
    for (c, (gain, haze)) in [(0.35, 0.05), (0.8, 0.15), (0.9, 0.1)]
        .into_iter()
        .enumerate()
    {
        for v in uw.plane_mut(c) {
            *v = *v * gain + haze;
        }
    }
    (clean, uw)
}

/// `root/underwater/NNN.png` + `root/clean/NNN.png`.
fn paired_dir(root: &Path, n: usize, w: usize, h: usize) -> PathBuf {
    for sub in ["clean", "underwater"] {
        std::fs::create_dir_all(root.join(sub)).unwrap();
    }
    for k in 0..n {
        let (c, u) = pair(w, h, k);
        save_rgb(&root.join(format!("clean/{k:03}.png")), &c).unwrap();
        save_rgb(&root.join(format!("underwater/{k:03}.png")), &u).unwrap();
    }
    root.to_path_buf()
}

#[test]
fn train_writes_checkpoints_and_resume_keeps_the_config() {
    let dir = tempfile::tempdir().unwrap();
    let data = paired_dir(&dir.path().join("train"), 4, 40, 36);
    let val = paired_dir(&dir.path().join("val"), 1, 32, 32);
    let config = dir.path().join("tiny.json");
    std::fs::write(
        &config,
        r#"{"model": {"width": 8}, "epochs": 2, "crop": 32, "batch_size": 2,
            "log_every_steps": 1, "val_every_epochs": 1}"#,
    )
    .unwrap();
    let run = dir.path().join("run");
    let o = uwnr(&[
        "enhance",
        "train",
        "--data",
        s(&data),
        "--val",
        s(&val),
        "--run",
        s(&run),
        "--config",
        s(&config),
        "--lr",
        "0.001",
    ]);
    let err = stderr(&o);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("1 - SSIM"), "no stand-in warning: {err}");
    assert!(err.contains("finished at step 4"), "{err}");
    for f in ["last", "best"] {
        let w = run.join("checkpoints").join(f).join("enhancer.safetensors");
        assert!(w.is_file(), "{w:?} missing");
    }
    for f in ["config.json", "metrics.csv", "val.csv", "curves.png"] {
        assert!(run.join(f).is_file(), "{f} missing");
    }
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("config.json")).unwrap()).unwrap();
    assert_eq!(saved["lr"], 0.001);
    assert_eq!(saved["model"]["width"], 8);

    // Resuming with a changed setting is refused, naming it.
    let o = uwnr(&[
        "enhance",
        "train",
        "--data",
        s(&data),
        "--run",
        s(&run),
        "--resume",
        "--epochs",
        "3",
    ]);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert!(err.contains("epochs"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
}

#[test]
fn apply_writes_files_and_folders_and_lists_failures() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = dir.path().join("in");
    std::fs::create_dir_all(&inputs).unwrap();
    let (_, a) = pair(37, 21, 0);
    save_rgb(&inputs.join("a.png"), &a).unwrap();
    save_rgb(&inputs.join("c.jpg"), &a).unwrap();
    std::fs::write(inputs.join("b.png"), b"this is not a png").unwrap();

    // One file to one file, at its own size.
    let single = dir.path().join("one.png");
    let o = uwnr(&[
        "enhance",
        "apply",
        s(&inputs.join("a.png")),
        "--weights",
        s(&enhancer_weights()),
        "--output",
        s(&single),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&single).unwrap();
    assert_eq!((img.width(), img.height()), (37, 21));

    // A folder: the good images are written, the bad one is listed, the exit is non-zero.
    let out = dir.path().join("out");
    let o = uwnr(&[
        "enhance",
        "apply",
        s(&inputs),
        "--weights",
        s(&enhancer_weights()),
        "--output",
        s(&out),
    ]);
    let err = stderr(&o);
    assert!(
        !o.status.success(),
        "a failed item must make the exit non-zero"
    );
    assert!(err.contains("b.png"), "failure not listed: {err}");
    assert_eq!(files_in(&out), vec!["a.png", "c.png"]);
}

#[test]
fn a_corrupt_image_gives_one_line_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.png");
    std::fs::write(&bad, b"garbage").unwrap();
    let out = dir.path().join("out.png");
    let o = uwnr(&[
        "enhance",
        "apply",
        s(&bad),
        "--weights",
        s(&enhancer_weights()),
        "--output",
        s(&out),
    ]);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(
        err.starts_with("uwnr: error:") && err.contains("bad.png"),
        "{err}"
    );
    assert!(!out.exists());
    // Weights that are not an enhancer's.
    let o = uwnr(&[
        "enhance",
        "apply",
        s(&bad),
        "--weights",
        s(&crate::common::weights()),
        "--output",
        s(&out),
    ]);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert!(err.contains("loading enhancer weights"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
}

#[test]
fn eval_prints_the_table_and_the_means() {
    let dir = tempfile::tempdir().unwrap();
    let data = paired_dir(&dir.path().join("test"), 2, 48, 40);
    let json = dir.path().join("scores.json");
    let save = dir.path().join("saved");
    let o = uwnr(&[
        "enhance",
        "eval",
        "--weights",
        s(&enhancer_weights()),
        "--data",
        s(&data),
        "--save",
        s(&save),
        "--max-side",
        "24",
        "--json",
        s(&json),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(out.contains("PSNR") && out.contains("UCIQE"), "{out}");
    assert!(out.contains("000.png") && out.contains("001.png"), "{out}");
    assert!(out.lines().any(|l| l.starts_with("mean")), "{out}");
    assert!(stderr(&o).contains("downscaled"), "{}", stderr(&o));
    assert_eq!(files_in(&save), vec!["000.png", "001.png"]);
    let img = image::open(save.join("000.png")).unwrap();
    assert_eq!((img.width(), img.height()), (24, 20));
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let per = doc["report"]["per_image"].as_array().unwrap();
    assert_eq!(per.len(), 2);
    let mean = (per[0]["psnr"].as_f64().unwrap() + per[1]["psnr"].as_f64().unwrap()) / 2.0;
    assert!((doc["report"]["psnr"].as_f64().unwrap() - mean).abs() < 1e-9);

    // Without weights the input is scored, and labelled so.
    let o = uwnr(&["enhance", "eval", "--data", s(&data)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(out.contains("no enhancement"), "{out}");
    assert!(out.lines().any(|l| l.starts_with("mean")), "{out}");

    // A folder without pairs is one clear line.
    let o = uwnr(&["enhance", "eval", "--data", s(dir.path())]);
    let err = stderr(&o);
    assert!(!o.status.success());
    assert!(err.contains("no paired folders"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "{err}");
}
