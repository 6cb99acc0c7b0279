use super::*;
use uwnr_run::folder::read_config_unchanged;

#[test]
fn default_is_the_released_recipe_with_crops() {
    let c = EnhanceTrainConfig::default();
    c.validate().unwrap();
    assert_eq!(c.model, ShallowUwnetConfig::default());
    assert_eq!((c.lr, c.lr_decay), (2e-4, 0.7));
    assert_eq!((c.batch_size, c.crop), (4, 256));
    assert_eq!((c.w_mse, c.w_perceptual), (1.0, 1.0));
}

#[test]
fn lr_decays_by_steps_of_epochs() {
    let c = EnhanceTrainConfig {
        lr: 1.0,
        lr_decay: 0.5,
        lr_step_epochs: 3,
        ..EnhanceTrainConfig::default()
    };
    let got: Vec<f64> = (0..8).map(|e| c.lr_at(e)).collect();
    assert_eq!(got, [1.0, 1.0, 1.0, 0.5, 0.5, 0.5, 0.25, 0.25]);
    let constant = EnhanceTrainConfig {
        lr_step_epochs: 0,
        ..c
    };
    assert_eq!(constant.lr_at(1000), 1.0);
    // The released default: x0.7 at epochs 50, 100, ...
    let d = EnhanceTrainConfig::default();
    assert_eq!(d.lr_at(49), 2e-4);
    assert!((d.lr_at(50) - 1.4e-4).abs() < 1e-15);
    assert!((d.lr_at(100) - 0.98e-4).abs() < 1e-15);
}

#[test]
fn json_round_trip_partial_files_and_unknown_fields() {
    let c = EnhanceTrainConfig {
        model: ShallowUwnetConfig {
            width: 8,
            ..ShallowUwnetConfig::default()
        },
        max_pairs_per_dir: Some(3),
        ..EnhanceTrainConfig::default()
    };
    let back: EnhanceTrainConfig = serde_json::from_str(&c.to_json().unwrap()).unwrap();
    assert_eq!(back, c);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("c.json");
    std::fs::write(&path, r#"{"epochs": 3, "model": {"width": 16}}"#).unwrap();
    let partial = EnhanceTrainConfig::from_json_file(&path).unwrap();
    assert_eq!((partial.epochs, partial.model.width), (3, 16));
    assert_eq!(partial.model.blocks, 3);
    assert_eq!(partial.batch_size, 4);
    for bad in [r#"{"epoch": 3}"#, r#"{"model": {"widht": 8}}"#, "[1]"] {
        std::fs::write(&path, bad).unwrap();
        let err = EnhanceTrainConfig::from_json_file(&path).unwrap_err();
        assert!(
            matches!(err, EnhanceError::ConfigFile { .. }),
            "{bad}: {err}"
        );
    }
}

#[test]
fn a_config_written_before_the_run_framework_still_reads_as_its_run() {
    // The config.json of a run started before checkpoint_every_steps, prefetch_batches and
    // val_sheet_pairs existed: it must read back equal to the same run's config now, so
    // that run resumes.
    let old = r#"{"model": {"width": 8, "blocks": 3, "dropout": 0.2}, "epochs": 3,
            "batch_size": 4, "crop": 256, "lr": 0.0002, "lr_decay": 0.7, "lr_step_epochs": 50,
            "w_mse": 1.0, "w_perceptual": 1.0, "seed": 7, "val_every_epochs": 5,
            "log_every_steps": 10, "checkpoint_every_secs": 900, "max_pairs_per_dir": null,
            "total_steps": null}"#;
    let read: EnhanceTrainConfig = serde_json::from_str(old).unwrap();
    let now = EnhanceTrainConfig {
        model: ShallowUwnetConfig {
            width: 8,
            ..ShallowUwnetConfig::default()
        },
        epochs: 3,
        ..EnhanceTrainConfig::default()
    };
    assert_eq!(read, now);
}

/// The config files of `tests/fixtures/`, as the code before `RunSettings` (commit 966515d)
/// wrote them (the defaults; a run with every run-level field changed; a downstream row),
/// read back to configs that write the same JSON. The defaults of now are those of then, so
/// a new config is written with the same keys and values as before.
#[test]
fn config_files_of_earlier_versions_read_back_unchanged() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    let read = |name: &str| read_config_unchanged::<EnhanceTrainConfig>(&dir.join(name));
    assert_eq!(
        read("config-default.json").unwrap(),
        EnhanceTrainConfig::default()
    );
    let custom = read("config-custom.json").unwrap();
    assert_eq!((custom.run.seed, custom.run.prefetch_batches), (11, 4));
    let row = read("config-downstream-run.json").unwrap();
    assert_eq!((row.run.seed, row.total_steps), (0, Some(1500)));
    let partial: EnhanceTrainConfig = serde_json::from_str(r#"{"epochs": 3}"#).unwrap();
    assert_eq!(
        partial.run,
        EnhanceTrainConfig::default().run,
        "its own defaults"
    );
}

#[test]
fn invalid_fields_are_named() {
    let d = EnhanceTrainConfig::default;
    for (c, field) in [
        (EnhanceTrainConfig { epochs: 0, ..d() }, "epochs"),
        (
            EnhanceTrainConfig {
                batch_size: 0,
                ..d()
            },
            "batch_size",
        ),
        (EnhanceTrainConfig { crop: 8, ..d() }, "crop"),
        (EnhanceTrainConfig { lr: -1.0, ..d() }, "lr"),
        (
            EnhanceTrainConfig {
                lr_decay: 1.5,
                ..d()
            },
            "lr_decay",
        ),
        (
            EnhanceTrainConfig {
                w_perceptual: f64::NAN,
                ..d()
            },
            "w_perceptual",
        ),
        (
            EnhanceTrainConfig {
                w_mse: 0.0,
                w_perceptual: 0.0,
                ..d()
            },
            "w_mse",
        ),
        (
            EnhanceTrainConfig {
                run: RunSettings {
                    log_every_steps: 0,
                    ..d().run
                },
                ..d()
            },
            "log_every_steps",
        ),
        (
            EnhanceTrainConfig {
                run: RunSettings {
                    prefetch_batches: 0,
                    ..d().run
                },
                ..d()
            },
            "prefetch_batches",
        ),
        (
            EnhanceTrainConfig {
                max_pairs_per_dir: Some(0),
                ..d()
            },
            "max_pairs_per_dir",
        ),
        (
            EnhanceTrainConfig {
                model: ShallowUwnetConfig {
                    width: 3,
                    ..ShallowUwnetConfig::default()
                },
                ..d()
            },
            "model",
        ),
    ] {
        match c.validate() {
            Err(EnhanceError::InvalidTrainConfig { field: f, .. }) => assert_eq!(f, field),
            other => panic!("expected InvalidTrainConfig for {field}, got {other:?}"),
        }
    }
}
