//! End-to-end tests of the `uwnr` binary's methods and options: the baselines, `eval`,
//! `convert`, options a method lacks, precision and depth units.
//!
//! The network weights used here are the small width-8 parity fixture of uwnr-model (random
//! weights): these tests check the tool's behaviour, not the rendering's look.

use std::path::Path;

use crate::common::{s, sample, stderr, uwnr, weights};

#[test]
fn baselines_render_without_the_network() {
    let dir = tempfile::tempdir().unwrap();
    // jerlov needs no reference; the same seed gives the same image, another seed another water.
    let render = |seed: &str, name: &str| {
        let out = dir.path().join(name);
        let o = uwnr(&[
            "render",
            s(&sample("clean-statues.jpg")),
            "--method",
            "jerlov",
            "--seed",
            seed,
            "--output",
            s(&out),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        image::open(&out).unwrap().to_rgb8()
    };
    let a = render("1", "a.png");
    let b = render("1", "b.png");
    let c = render("2", "c.png");
    assert_eq!(a.dimensions(), (321, 481));
    assert_eq!(a, b);
    assert_ne!(a, c);

    for method in ["uisa", "seathru", "reinhard"] {
        let out = dir.path().join(format!("{method}.png"));
        let o = uwnr(&[
            "render",
            s(&sample("clean-room.jpg")),
            "--reference",
            s(&sample("ref-green.png")),
            "--method",
            method,
            "--output",
            s(&out),
        ]);
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        let img = image::open(&out).unwrap();
        assert_eq!((img.width(), img.height()), (640, 480), "{method}");
    }

    // A reference-based method without a reference is a clear error.
    let o = uwnr(&[
        "render",
        s(&sample("clean-room.jpg")),
        "--method",
        "uisa",
        "--output",
        s(&dir.path().join("x.png")),
    ]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("needs a reference"), "{}", stderr(&o));
}

#[test]
fn eval_scores_pairs_and_reports_missing_partners() {
    let dir = tempfile::tempdir().unwrap();
    let pred = dir.path().join("pred");
    let target = dir.path().join("target");
    std::fs::create_dir_all(&pred).unwrap();
    std::fs::create_dir_all(&target).unwrap();
    // Identical pair, a pair whose prediction is shifted by a constant, a target without a
    // prediction, and an unreadable prediction.
    let img = image::open(sample("ref-green.png")).unwrap().to_rgb8();
    img.save(pred.join("same.png")).unwrap();
    img.save(target.join("same.png")).unwrap();
    let mut shifted = img.clone();
    for p in shifted.pixels_mut() {
        for c in p.0.iter_mut() {
            *c = c.saturating_add(10);
        }
    }
    shifted.save(pred.join("shift.png")).unwrap();
    img.save(target.join("shift.png")).unwrap();
    img.save(target.join("lonely.png")).unwrap();
    std::fs::write(pred.join("broken.png"), b"nope").unwrap();
    img.save(target.join("broken.png")).unwrap();

    let json = dir.path().join("scores.json");
    let csv = dir.path().join("scores.csv");
    let o = uwnr(&[
        "eval",
        "--pred",
        s(&pred),
        "--target",
        s(&target),
        "--json",
        s(&json),
        "--csv",
        s(&csv),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("lonely"), "{err}");
    assert!(err.contains("broken"), "{err}");
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(doc["count"], 2);
    let images = doc["images"].as_array().unwrap();
    let shift = images.iter().find(|r| r["image"] == "shift").unwrap();
    let psnr = shift["scores"]["psnr"].as_f64().unwrap();
    // Most pixels move by exactly 10/255; saturation near 255 makes a few move less.
    assert!(psnr > 28.1 && psnr < 35.0, "psnr {psnr}");
    let same = images.iter().find(|r| r["image"] == "same").unwrap();
    assert_eq!(same["scores"]["ssim"].as_f64().unwrap(), 1.0);
    let text = std::fs::read_to_string(&csv).unwrap();
    assert!(text.starts_with("image,psnr,ssim,uiqm,uciqe"), "{text}");
    assert_eq!(text.lines().count(), 3);
}

#[test]
fn eval_without_reference_reports_set_distances() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a");
    let b = dir.path().join("b");
    std::fs::create_dir_all(&a).unwrap();
    std::fs::create_dir_all(&b).unwrap();
    for (i, name) in ["clean-statues.jpg", "clean-room.jpg", "ref-blue.jpg"]
        .iter()
        .enumerate()
    {
        std::fs::copy(sample(name), a.join(format!("{i}.jpg"))).unwrap();
    }
    for (i, name) in ["ref-green.png", "ref-blue.jpg", "clean-room.jpg"]
        .iter()
        .enumerate()
    {
        std::fs::copy(
            sample(name),
            b.join(format!("{i}.{}", &name[name.len() - 3..])),
        )
        .unwrap();
    }
    let json = dir.path().join("s.json");
    let o = uwnr(&[
        "eval",
        "--images",
        s(&a),
        "--real",
        s(&b),
        "--json",
        s(&json),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let doc: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let fd = doc["sets"]["fd_ct"].as_f64().unwrap();
    assert!(fd.is_finite() && fd > 0.0, "{fd}");
    assert!(
        doc["sets"].get("fid").is_none(),
        "built-in features must not be called FID"
    );
    assert!(doc["mean"]["uiqm"].as_f64().unwrap().is_finite());
}

#[test]
fn convert_writes_half_precision_weights_that_render_alike() {
    let dir = tempfile::tempdir().unwrap();
    let full = dir.path().join("w8-f32.safetensors");
    let half = dir.path().join("w8-f16.safetensors");
    let o = uwnr(&["convert", s(&weights()), s(&full), "--dtype", "f32"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = uwnr(&["convert", s(&full), s(&half), "--dtype", "f16"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let full_size = std::fs::metadata(&full).unwrap().len();
    let half_size = std::fs::metadata(&half).unwrap().len();
    assert!(half_size * 10 < full_size * 6, "{half_size} vs {full_size}");
    let o = uwnr(&["info", "--weights", s(&half)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(String::from_utf8_lossy(&o.stdout).contains("F16"));

    let render = |w: &Path, out: &Path| {
        let o = uwnr(&[
            "render",
            s(&sample("clean-room.jpg")),
            "--reference",
            s(&sample("ref-green.png")),
            "--weights",
            s(w),
            "--output",
            s(out),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        image::open(out).unwrap().to_rgb8()
    };
    let a = render(&full, &dir.path().join("a.png"));
    let b = render(&half, &dir.path().join("b.png"));
    let max = a
        .as_raw()
        .iter()
        .zip(b.as_raw())
        .map(|(x, y)| x.abs_diff(*y))
        .max()
        .unwrap();
    assert!(max <= 3, "f16 weights change the render by up to {max}/255");

    let o = uwnr(&[
        "convert",
        s(&sample("ref-green.png")),
        s(&dir.path().join("x.safetensors")),
    ]);
    assert!(!o.status.success());
    assert_eq!(stderr(&o).trim().lines().count(), 1, "{}", stderr(&o));
}

#[test]
fn options_that_do_not_apply_to_the_method_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.png");
    let (clean, reference, w) = (
        sample("clean-statues.jpg"),
        sample("ref-blue.jpg"),
        weights(),
    );
    let base = |extra: &[&str]| {
        let mut args = vec![
            "render",
            s(&clean),
            "--reference",
            s(&reference),
            "--weights",
            s(&w),
            "--output",
            s(&out),
        ];
        args.extend_from_slice(extra);
        uwnr(&args)
    };
    let cases: [(&[&str], &str, &str); 7] = [
        (&["--water-type", "3C"], "--water-type", "uwnr"),
        (
            &["--method", "uisa", "--water-type", "3C"],
            "--water-type",
            "uisa",
        ),
        (
            &["--method", "jerlov", "--reinhard-space", "lab"],
            "--reinhard-space",
            "jerlov",
        ),
        (
            &["--method", "seathru", "--mean-only"],
            "--mean-only",
            "seathru",
        ),
        (
            &[
                "--method",
                "seathru",
                "--seathru",
                "given",
                "--background-depth",
                "3,4",
            ],
            "--background-depth",
            "--seathru given",
        ),
        (
            &["--method", "reinhard", "--beta-d", "1,1,1"],
            "--beta-d",
            "reinhard",
        ),
        (
            &["--method", "seathru", "--depth-scale", "1,2"],
            "--depth-scale",
            "reference",
        ),
    ];
    for (extra, flag, method) in cases {
        let o = base(extra);
        let err = stderr(&o);
        assert!(!o.status.success(), "{extra:?} was accepted");
        assert_eq!(
            err.trim().lines().count(),
            1,
            "{extra:?}: not one line: {err}"
        );
        assert!(
            err.contains(flag) && err.contains(method),
            "{extra:?}: {err}"
        );
        assert!(!out.exists(), "{extra:?} rendered");
    }
    // The enums refuse unknown values at parse time and accept the paper's spelling in any case.
    let o = base(&["--method", "jerlov", "--water-type", "4C"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("4C"), "{}", stderr(&o));
    let o = base(&["--method", "jerlov", "--water-type", "3c", "--seed", "1"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = base(&[
        "--method",
        "reinhard",
        "--reinhard-space",
        "cielab",
        "--mean-only",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn bf16_precision_renders_on_the_engine_and_burn_devices_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.png");
    let (clean, reference, w) = (
        sample("clean-statues.jpg"),
        sample("ref-blue.jpg"),
        weights(),
    );
    let args = |extra: &[&'static str]| {
        let mut a = vec![
            "render",
            s(&clean),
            "--reference",
            s(&reference),
            "--weights",
            s(&w),
            "--output",
            s(&out),
        ];
        a.extend_from_slice(extra);
        a
    };
    let o = uwnr(&args(&["--precision", "bf16"]));
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&out).unwrap();
    assert_eq!((img.width(), img.height()), (321, 481));
    std::fs::remove_file(&out).unwrap();
    let o = uwnr(&args(&["--precision", "bf16", "--device", "flex"]));
    assert!(!o.status.success());
    let err = stderr(&o);
    assert!(err.contains("renders run on the engine"), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "one line: {err}");
    assert!(!out.exists());
    // Rendering through burn is gone with the training framework: flex alone is refused too.
    let o = uwnr(&args(&["--device", "flex"]));
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("renders run on the engine"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn depth_units_and_trust_are_checked_and_metric_maps_render() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.png");
    let clean = sample("clean-room.jpg");
    let (w, h) = image::image_dimensions(&clean).unwrap();
    // 16-bit millimetres, 1 m at the bottom to 5 m at the top, with a hole.
    let mm = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(w, h, |x, y| {
        if x == 0 && y == 0 {
            image::Luma([0])
        } else {
            image::Luma([(5000 - 4000 * y / (h - 1)) as u16])
        }
    });
    let map = dir.path().join("mm.png");
    mm.save(&map).unwrap();
    // The same in float metres, as NumPy saves it.
    let npy = dir.path().join("m.npy");
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({h}, {w}), }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    bytes.extend((header.len() as u16).to_le_bytes());
    bytes.extend(header.as_bytes());
    for y in 0..h {
        for _ in 0..w {
            bytes.extend((5.0 - 4.0 * y as f32 / (h - 1) as f32).to_le_bytes());
        }
    }
    std::fs::write(&npy, bytes).unwrap();
    let (reference, wts) = (sample("ref-blue.jpg"), weights());
    let run = |extra: &[&str]| {
        let mut args = vec![
            "render",
            s(&clean),
            "--reference",
            s(&reference),
            "--weights",
            s(&wts),
            "--output",
            s(&out),
        ];
        args.extend_from_slice(extra);
        uwnr(&args)
    };
    let refused: [(&[&str], &str); 5] = [
        (
            &[
                "--depth",
                s(&map),
                "--depth-unit",
                "mm",
                "--depth-normalize",
            ],
            "--depth-normalize",
        ),
        (
            &["--depth", s(&map), "--depth-unit", "mm", "--depth-invert"],
            "--depth-invert",
        ),
        (&["--depth-unit", "furlongs"], "furlongs"),
        (&["--prior-trust", "9"], "trust"),
        (
            &["--method", "reinhard", "--prior-trust", "0.5"],
            "--prior-trust",
        ),
    ];
    for (extra, what) in refused {
        let o = run(extra);
        let err = stderr(&o);
        assert!(!o.status.success(), "{extra:?} was accepted");
        assert!(err.contains(what), "{extra:?}: {err}");
        assert!(!out.exists(), "{extra:?} rendered");
    }
    for extra in [
        &["--depth", s(&map), "--depth-unit", "mm"][..],
        &["--depth", s(&npy), "--depth-unit", "m"],
        &["--depth-scale", "2,6", "--prior-trust", "1"],
    ] {
        let o = run(extra);
        assert!(o.status.success(), "{extra:?}: {}", stderr(&o));
        assert_eq!(image::image_dimensions(&out).unwrap(), (w, h));
        std::fs::remove_file(&out).unwrap();
    }
    // A map with no measured depth is one clear line.
    let empty = dir.path().join("empty.png");
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::new(8, 8)
        .save(&empty)
        .unwrap();
    let o = run(&["--depth", s(&empty), "--depth-unit", "mm"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("no measured depth"), "{}", stderr(&o));
    assert!(!out.exists());
}
