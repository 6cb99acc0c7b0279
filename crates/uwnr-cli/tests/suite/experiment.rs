//! `uwnr experiment downstream` end to end on a few small images: three methods (the network
//! with the width-8 fixture weights, two baselines), one real training set, two test sets, tiny
//! enhancers; the results table must be well formed, and a second run must reuse everything.

use std::path::{Path, PathBuf};

use uwnr_core::Image;
use uwnr_core::io::save_rgb;

use crate::common::{s, sample, stderr, uwnr, weights};

/// A smooth colourful image.
fn image(w: usize, h: usize, k: usize) -> Image {
    let mut img = Image::filled(w, h, 3, 0.0);
    for c in 0..3 {
        let p = img.plane_mut(c);
        for y in 0..h {
            for x in 0..w {
                let t = (x as f32 * (0.15 + 0.04 * c as f32) + y as f32 * 0.11 + k as f32).sin();
                p[y * w + x] = 0.5 + 0.4 * t;
            }
        }
    }
    img
}

/// A blue-green, hazy copy.
fn underwater(img: &Image) -> Image {
    let mut uw = img.clone();
    for (c, (gain, haze)) in [(0.4, 0.05), (0.8, 0.2), (0.9, 0.15)]
        .into_iter()
        .enumerate()
    {
        for v in uw.plane_mut(c) {
            *v = *v * gain + haze;
        }
    }
    uw
}

fn paired(root: &Path, n: usize, offset: usize) -> PathBuf {
    for sub in ["clean", "underwater"] {
        std::fs::create_dir_all(root.join(sub)).unwrap();
    }
    for k in 0..n {
        let c = image(40, 32, k + offset);
        save_rgb(&root.join(format!("clean/{k:02}.png")), &c).unwrap();
        save_rgb(
            &root.join(format!("underwater/{k:02}.png")),
            &underwater(&c),
        )
        .unwrap();
    }
    root.to_path_buf()
}

/// `n` clean images of 48x40 in `root/clean`.
fn clean_images(root: &Path, n: usize) -> PathBuf {
    let clean = root.join("clean");
    std::fs::create_dir_all(&clean).unwrap();
    for k in 0..n {
        save_rgb(&clean.join(format!("c{k}.png")), &image(48, 40, 10 + k)).unwrap();
    }
    clean
}

/// A tiny enhancer config (width 8, one block, crops of 32) in `root/enhance.json`.
fn tiny_enhancer(root: &Path) -> PathBuf {
    let config = root.join("enhance.json");
    std::fs::write(
        &config,
        r#"{"model":{"width":8,"blocks":1,"dropout":0.0},"batch_size":2,"crop":32}"#,
    )
    .unwrap();
    config
}

#[test]
fn tiny_downstream_run_writes_a_well_formed_table() {
    let dir = tempfile::tempdir().unwrap();
    let clean = clean_images(dir.path(), 3);
    let real = paired(&dir.path().join("real-pairs"), 4, 20);
    let test_a = paired(&dir.path().join("test-a"), 2, 30);
    let test_b = paired(&dir.path().join("test-b"), 3, 40);
    let config = tiny_enhancer(dir.path());
    let out = dir.path().join("out");
    let (r1, r2) = (sample("ref-blue.jpg"), sample("ref-green.png"));
    let w = weights();
    let args = [
        "experiment",
        "downstream",
        "--clean",
        s(&clean),
        "--references",
        s(&r1),
        s(&r2),
        "--test",
        s(&test_a),
        s(&test_b),
        "--real",
        s(&real),
        "--out",
        s(&out),
        "--methods",
        "uwnr,jerlov,reinhard",
        "--per-image",
        "2",
        "--size",
        "32x32",
        "--budget",
        "10",
        "--enhance-config",
        s(&config),
        "--weights",
        s(&w),
        "--jobs",
        "2",
    ];
    let o = uwnr(&args);
    assert!(o.status.success(), "{}", stderr(&o));

    let md = std::fs::read_to_string(out.join("results.md")).unwrap();
    let rows: Vec<&str> = md.lines().filter(|l| l.starts_with("| ")).collect();
    // Score table: header + none + 3 methods + 1 real; cost table: header + 4 rows.
    assert_eq!(rows.len(), 11, "{md}");
    assert!(
        rows[0].contains("test-a PSNR") && rows[0].contains("test-b UCIQE"),
        "{md}"
    );
    for label in [
        "| no enhancement (input as is) |",
        "| synthetic: uwnr |",
        "| synthetic: jerlov |",
        "| synthetic: reinhard |",
        "| real pairs: real-pairs |",
    ] {
        let row = rows.iter().find(|r| r.starts_with(label)).expect(label);
        // 1 label + 4 metrics x 2 test sets, each a number.
        let cells: Vec<&str> = row
            .split('|')
            .map(str::trim)
            .filter(|c| !c.is_empty())
            .collect();
        assert_eq!(cells.len(), 9, "{row}");
        for c in &cells[1..] {
            let v: f64 = c
                .trim_matches('*')
                .parse()
                .unwrap_or_else(|_| panic!("{row}"));
            assert!(v.is_finite(), "{row}");
        }
    }
    // 3 clean images x 2 renders = 6 training pairs per method; a budget of 10 samples at batch
    // 2 is 5 steps for every set, whatever its size (the last epoch partial).
    assert!(md.contains("| uwnr | 6 | 0 | 5 |"), "{md}");
    assert!(md.contains("| real:real-pairs | 4 | – | 5 |"), "{md}");

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    assert_eq!(json["rows"].as_array().unwrap().len(), 5);
    assert_eq!(json["tests"][1]["pairs"], 3);
    assert_eq!(json["rows"][0]["scores"][0]["images"], 2);
    let sheet = image::open(out.join("examples.png")).unwrap();
    // 2 example images per test set, 2 test sets = 4 rows of thumbnails.
    assert!(sheet.height() > 4 * 160, "{}", sheet.height());

    // The same reference assignment for every method: the datasets' manifests name the same
    // (clean, reference) pairs.
    let refs_of = |m: &str| -> Vec<(String, String)> {
        let text =
            std::fs::read_to_string(out.join("data").join(m).join("manifest.jsonl")).unwrap();
        let mut v: Vec<(String, String)> = text
            .lines()
            .map(|l| {
                let r: serde_json::Value = serde_json::from_str(l).unwrap();
                (
                    r["clean_source"].to_string(),
                    r["reference_source"].to_string(),
                )
            })
            .collect();
        v.sort();
        v
    };
    assert_eq!(refs_of("uwnr"), refs_of("reinhard"));
    assert_eq!(refs_of("uwnr").len(), 6);

    // Running it again reuses every stage and gives the same table.
    let o = uwnr(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("from an earlier session"),
        "{}",
        stderr(&o)
    );
    assert_eq!(std::fs::read_to_string(out.join("results.md")).unwrap(), md);

    // A row killed before its first checkpoint (its config written, no checkpoint) starts again.
    let row = out.join("runs").join("jerlov");
    assert!(row.join("config.json").is_file());
    std::fs::remove_dir_all(row.join("checkpoints")).unwrap();
    let o = uwnr(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(row.join("checkpoints").join("last").is_dir());

    // Other settings in the same folder are refused, naming the field.
    let mut changed: Vec<&str> = args.to_vec();
    let at = changed.iter().position(|a| *a == "--budget").unwrap();
    changed[at + 1] = "24";
    let o = uwnr(&changed);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("budget"), "{}", stderr(&o));
}

#[test]
fn a_target_calibrates_the_water_anchored_set_only() {
    let dir = tempfile::tempdir().unwrap();
    let clean = clean_images(dir.path(), 2);
    let target = paired(&dir.path().join("target"), 2, 50);
    let test = paired(&dir.path().join("test"), 2, 30);
    let config = tiny_enhancer(dir.path());
    let out = dir.path().join("out");
    let (r1, r2) = (sample("ref-blue.jpg"), sample("ref-green.png"));
    // The bundled model (a water anchor) and a baseline.
    let o = uwnr(&[
        "experiment",
        "downstream",
        "--clean",
        s(&clean),
        "--references",
        s(&r1),
        s(&r2),
        "--test",
        s(&test),
        "--out",
        s(&out),
        "--methods",
        "uwnr,reinhard",
        "--per-image",
        "2",
        "--size",
        "32x32",
        "--budget",
        "4",
        "--enhance-config",
        s(&config),
        "--target",
        s(&target),
        "--jobs",
        "2",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let settings = |m: &str| -> serde_json::Value {
        let text = std::fs::read_to_string(out.join("data").join(m).join("dataset.json")).unwrap();
        serde_json::from_str::<serde_json::Value>(&text).unwrap()
    };
    let uwnr_set = settings("uwnr");
    assert_eq!(uwnr_set["target"]["kind"], "pairs", "{uwnr_set}");
    assert_eq!(uwnr_set["target"]["pairs"], 2, "{uwnr_set}");
    let reinhard_set = settings("reinhard");
    assert!(reinhard_set["target"].is_null(), "{reinhard_set}");
    // Without --camera every set goes through the matched camera, as `uwnr dataset`'s do.
    for set in [&uwnr_set, &reinhard_set] {
        assert_eq!(set["camera"]["jpeg_quality"], 80, "{set}");
    }
}

#[test]
fn the_camera_is_chosen_for_every_training_set() {
    let dir = tempfile::tempdir().unwrap();
    let clean = clean_images(dir.path(), 2);
    let test = paired(&dir.path().join("test"), 2, 30);
    let config = tiny_enhancer(dir.path());
    let out = dir.path().join("out");
    let r1 = sample("ref-blue.jpg");
    let o = uwnr(&[
        "experiment",
        "downstream",
        "--clean",
        s(&clean),
        "--references",
        s(&r1),
        "--test",
        s(&test),
        "--out",
        s(&out),
        "--methods",
        "uwnr,reinhard",
        "--per-image",
        "1",
        "--size",
        "32x32",
        "--budget",
        "2",
        "--enhance-config",
        s(&config),
        "--camera",
        "none",
        "--jobs",
        "2",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    for m in ["uwnr", "reinhard"] {
        let text = std::fs::read_to_string(out.join("data").join(m).join("dataset.json")).unwrap();
        let set: serde_json::Value = serde_json::from_str(&text).unwrap();
        // dataset.json records a camera only when one ran.
        assert!(set["camera"].is_null(), "{m}: {set}");
    }
    let bad = uwnr(&[
        "experiment",
        "downstream",
        "--clean",
        s(&clean),
        "--test",
        s(&test),
        "--out",
        s(&dir.path().join("out-bad")),
        "--methods",
        "jerlov",
        "--camera",
        "{\"jpeg_quality\": 101}",
    ]);
    assert!(!bad.status.success());
    assert!(stderr(&bad).contains("jpeg_quality"), "{}", stderr(&bad));
}
