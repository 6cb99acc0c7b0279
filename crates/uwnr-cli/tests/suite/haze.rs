//! The `haze` control, a method added in `uwnr-render` alone, reaches `uwnr render` and
//! `uwnr dataset` with its settings from `--method-config`.

use crate::common::{s, sample, stderr, uwnr};

#[test]
fn haze_renders_with_its_config_and_refuses_other_methods_flags() {
    let dir = tempfile::tempdir().unwrap();
    let clean = sample("clean-statues.jpg");
    let plain = dir.path().join("plain.png");
    let o = uwnr(&["render", s(&clean), "--method", "haze", "-o", s(&plain)]);
    assert!(o.status.success(), "{}", stderr(&o));

    // A thick blue veil: every pixel far enough to be the veil within 1 code value.
    let config = dir.path().join("haze.json");
    std::fs::write(
        &config,
        r#"{"method":"haze","veil":[0.0,0.0,1.0],"beta":[10.0,10.0,10.0],"depth_scale_m":1000}"#,
    )
    .unwrap();
    let depth = dir.path().join("far.png");
    image::GrayImage::from_pixel(321, 481, image::Luma([255u8]))
        .save(&depth)
        .unwrap();
    let blue = dir.path().join("blue.png");
    let o = uwnr(&[
        "render",
        s(&clean),
        "--method",
        "haze",
        "--method-config",
        s(&config),
        "--depth",
        s(&depth),
        "-o",
        s(&blue),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = image::open(&blue).unwrap().to_rgb8();
    assert!(img.pixels().all(|p| p.0 == [0, 0, 255]), "the veil is all");
    let plain = image::open(&plain).unwrap().to_rgb8();
    assert_ne!(
        plain.as_raw(),
        img.as_raw(),
        "the config changed the render"
    );

    let o = uwnr(&[
        "render",
        s(&clean),
        "--method",
        "haze",
        "--water-type",
        "3C",
        "-o",
        s(&dir.path().join("x.png")),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("--water-type does not apply to --method haze"),
        "{}",
        stderr(&o)
    );
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, r#"{"method":"haze","veil":[2.0,0.0,0.0]}"#).unwrap();
    let o = uwnr(&[
        "render",
        s(&clean),
        "--method",
        "haze",
        "--method-config",
        s(&bad),
        "-o",
        s(&dir.path().join("y.png")),
    ]);
    assert!(!o.status.success());
    assert!(
        stderr(&o).contains("veil 2 is outside [0, 1]"),
        "{}",
        stderr(&o)
    );
    assert!(!dir.path().join("y.png").exists());
}

#[test]
fn a_haze_dataset_records_its_settings_and_each_pair_its_parameters() {
    let dir = tempfile::tempdir().unwrap();
    let clean = dir.path().join("clean");
    std::fs::create_dir(&clean).unwrap();
    std::fs::copy(sample("clean-statues.jpg"), clean.join("a.jpg")).unwrap();
    let out = dir.path().join("out");
    let o = uwnr(&[
        "dataset",
        "--clean",
        s(&clean),
        "--method",
        "haze",
        "--per-image",
        "2",
        "--size",
        "64x48",
        "--output",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let settings: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("dataset.json")).unwrap()).unwrap();
    assert_eq!(settings["method"], "haze");
    assert_eq!(settings["method_params"]["depth_scale_m"], 5.0);
    let manifest = std::fs::read_to_string(out.join("manifest.jsonl")).unwrap();
    assert_eq!(manifest.lines().count(), 2);
    let line: serde_json::Value = serde_json::from_str(manifest.lines().next().unwrap()).unwrap();
    assert_eq!(line["params"]["method"], "haze", "{line}");
    let o = uwnr(&["dataset", "verify", s(&out)]);
    assert!(o.status.success(), "{}", stderr(&o));
}
