use super::*;

fn spec(budget: usize) -> DownstreamSpec {
    DownstreamSpec {
        clean: vec![],
        references: vec![],
        tests: vec![],
        real: vec![],
        out: PathBuf::new(),
        per_image: 4,
        size: Size::Native,
        seed: 3,
        depth: DepthSource::default(),
        depth_policy: uwnr_render::DepthPolicy::default(),
        train: EnhanceTrainConfig::default(),
        budget,
        eval_max_side: None,
        examples: 0,
        jobs: 1,
        device: Device::default(),
        vgg19: None,
        limits: DecodeLimits::default(),
        target: None,
        camera: uwnr_render::Camera::default(),
    }
}

#[test]
fn every_row_gets_the_same_number_of_steps() {
    let s = spec(6000);
    for (pairs, epochs) in [(1172, 6), (2415, 3), (4, 1500)] {
        let cfg = row_config(&s, pairs);
        assert_eq!(cfg.total_steps, Some(1500), "{pairs} pairs");
        assert_eq!(cfg.epochs, epochs, "{pairs} pairs");
        assert!(cfg.epochs * (pairs / 4) >= 1500);
        assert_eq!(cfg.run.seed, 3);
    }
    assert_eq!(row_config(&s, 1172).lr_step_epochs, 2);
    assert_eq!(row_config(&spec(1), 10).total_steps, Some(1));
}

#[test]
fn short_names_are_unique() {
    let dirs: Vec<PathBuf> = ["a/lsui", "b/lsui", "c/uieb-val", "d/lsui"]
        .iter()
        .map(PathBuf::from)
        .collect();
    assert_eq!(
        short_names(&dirs),
        vec!["lsui", "lsui-2", "uieb-val", "lsui-3"]
    );
}

#[test]
fn the_target_is_recorded_only_when_set() {
    let mut s = spec(6000);
    let without = settings(&s, &[]).unwrap();
    assert!(without.get("target").is_none());
    s.target = Some(uwnr_dataset::WaterTarget::bundled().unwrap());
    let with = settings(&s, &[]).unwrap();
    assert_eq!(with["target"]["source"], "bundled");
    assert!(with["target"]["entries"].as_u64().unwrap() > 0);
    // A folder made without a target refuses a run with one.
    let dir = std::env::temp_dir().join(format!("uwnr-settings-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    check_settings(&dir, &without).unwrap();
    check_settings(&dir, &without).unwrap();
    assert!(matches!(
        check_settings(&dir, &with),
        Err(ExperimentError::SettingsDiffer { ref field, .. }) if field == "target"
    ));
    std::fs::remove_dir_all(&dir).unwrap();
}
