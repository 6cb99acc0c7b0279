//! Generation: layout, determinism across job counts, resume after a crash, bad input.

use std::collections::HashSet;
use std::sync::atomic::AtomicBool;

use uwnr_core::io::{DecodeLimits, load_rgb};
use uwnr_dataset::manifest::{Settings, read_manifest};
use uwnr_dataset::{DatasetError, Event};

use crate::common::{assert_same_tree, inputs, opts, reinhard, run, spec};

#[test]
fn writes_k_pairs_per_clean_image_with_distinct_references() {
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 5, 4);
    let out = tmp.path().join("out");
    let s = run(&out, &spec(&clean, &refs, 3), &reinhard(), &opts(2));
    assert_eq!((s.planned, s.rendered, s.skipped), (15, 15, 0));
    assert!(s.complete && s.failures.is_empty());

    let m = read_manifest(&out.join("manifest.jsonl")).unwrap();
    assert!(m.bad_lines.is_empty() && !m.torn_tail);
    let records: Vec<_> = m.records.into_iter().map(|(_, r)| r).collect();
    assert_eq!(records.len(), 15);
    // In pair order, and each clean image drew 3 different references.
    assert!(records.windows(2).all(|w| w[0].index < w[1].index));
    for chunk in records.chunks(3) {
        let refs: HashSet<_> = chunk.iter().map(|r| r.reference_source.clone()).collect();
        assert_eq!(refs.len(), 3, "{chunk:?}");
        assert!(
            chunk
                .iter()
                .all(|r| r.clean_source == chunk[0].clean_source)
        );
    }
    // Files exist at the clean image's own size; the clean file is what was rendered.
    let limits = DecodeLimits::default();
    for r in &records {
        let source = load_rgb(std::path::Path::new(&r.clean_source), &limits).unwrap();
        for f in r.files() {
            let img = load_rgb(&out.join(f), &limits).unwrap();
            assert_eq!(img.size(), source.size(), "{f}");
        }
        let written = load_rgb(&out.join(&r.clean), &limits).unwrap();
        assert_eq!(written.data(), source.data(), "8-bit source kept exactly");
        assert_eq!(r.params.to_value()["method"], "reinhard");
    }
    assert!(out.join("preview.png").is_file());
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(html.contains("gallery/img00_0.jpg"), "{html}");
    assert!(out.join("gallery/img00_0.jpg").is_file());
    let settings = Settings::read(&out).unwrap();
    assert_eq!(settings.pairs_planned, 15);
}

#[test]
fn the_same_command_gives_identical_folders_whatever_the_job_count() {
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 7, 5);
    let sp = spec(&clean, &refs, 2);
    let (a, b, c) = (
        tmp.path().join("j1"),
        tmp.path().join("j2"),
        tmp.path().join("j4"),
    );
    run(&a, &sp, &reinhard(), &opts(1));
    run(&b, &sp, &reinhard(), &opts(2));
    run(&c, &sp, &reinhard(), &opts(4));
    assert_same_tree(&a, &b);
    assert_same_tree(&a, &c);
}

#[test]
fn a_crashed_run_resumes_to_the_same_folder() {
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 6, 4);
    let sp = spec(&clean, &refs, 2);
    let full = tmp.path().join("full");
    run(&full, &sp, &reinhard(), &opts(2));

    // What a kill leaves: part of the manifest, a torn last line, files of unfinished pairs
    // (one of them half-written under its temporary name), no gallery yet.
    let crashed = tmp.path().join("crashed");
    run(&crashed, &sp, &reinhard(), &opts(2));
    let text = std::fs::read_to_string(crashed.join("manifest.jsonl")).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let mut torn = lines[..5].join("\n");
    torn.push('\n');
    torn.push_str(&lines[5][..lines[5].len() / 2]);
    std::fs::write(crashed.join("manifest.jsonl"), torn).unwrap();
    std::fs::write(
        crashed.join("underwater/.img03_1.png.999-0.tmp"),
        b"partial",
    )
    .unwrap();
    std::fs::remove_file(crashed.join("underwater/img05_0.png")).unwrap();
    std::fs::remove_file(crashed.join("index.html")).unwrap();

    let mut notes = Vec::new();
    let stop = AtomicBool::new(false);
    let s = uwnr_dataset::generate(&crashed, &sp, &reinhard(), &opts(2), &stop, &mut |e| {
        if let Event::Note(n) = e {
            notes.push(n.to_string());
        }
    })
    .unwrap();
    assert_eq!((s.skipped, s.rendered), (5, 7));
    assert!(notes.iter().any(|n| n.contains("torn")), "{notes:?}");
    assert_same_tree(&full, &crashed);

    // Run again: nothing to do, nothing changes.
    let s = run(&crashed, &sp, &reinhard(), &opts(1));
    assert_eq!((s.skipped, s.rendered), (12, 0));
    assert_same_tree(&full, &crashed);
}

#[test]
fn resuming_with_other_settings_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 3, 3);
    let out = tmp.path().join("out");
    run(&out, &spec(&clean, &refs, 1), &reinhard(), &opts(1));
    let mut other = spec(&clean, &refs, 1);
    other.seed = 12;
    let stop = AtomicBool::new(false);
    let err = uwnr_dataset::generate(&out, &other, &reinhard(), &opts(1), &stop, &mut |_| {})
        .unwrap_err();
    assert!(
        matches!(&err, DatasetError::SettingsMismatch { field, .. } if field == "seed"),
        "{err}"
    );
}

#[test]
fn more_renders_than_references_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 2, 2);
    let stop = AtomicBool::new(false);
    let err = uwnr_dataset::generate(
        &tmp.path().join("out"),
        &spec(&clean, &refs, 3),
        &reinhard(),
        &opts(1),
        &stop,
        &mut |_| {},
    )
    .unwrap_err();
    assert!(err.to_string().contains("only 2 references"), "{err}");
}

#[test]
fn unreadable_inputs_are_listed_and_the_run_goes_on() {
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 4, 4);
    std::fs::write(clean.join("a/broken.png"), b"\x89PNG\r\n\x1a\n not really").unwrap();
    std::fs::write(refs.join("ref99.jpg"), b"\xff\xd8\xff truncated").unwrap();
    let out = tmp.path().join("out");
    // Three references per image out of five, one unreadable: every image still gets three.
    let s = run(&out, &spec(&clean, &refs, 3), &reinhard(), &opts(2));
    assert!(!s.complete);
    let sources: Vec<&str> = s.failures.iter().map(|f| f.source.as_str()).collect();
    assert!(
        sources.iter().any(|f| f.ends_with("broken.png")),
        "{sources:?}"
    );
    let clean_failure = s
        .failures
        .iter()
        .find(|f| f.source.ends_with("broken.png"))
        .unwrap();
    assert_eq!(clean_failure.ids.len(), 3);
    assert_eq!(s.rendered, 12);
    let m = read_manifest(&out.join("manifest.jsonl")).unwrap();
    assert!(m.records.iter().all(|(_, r)| {
        !r.reference_source
            .as_deref()
            .unwrap()
            .ends_with("ref99.jpg")
    }));
    // The failure list is on disk, and verify accounts for it.
    let failed = std::fs::read_to_string(out.join("failed.jsonl")).unwrap();
    assert!(failed.contains("broken.png"));
    let report = uwnr_dataset::verify(&out, &|_, _| {}).unwrap();
    assert!(report.ok(), "{:?}", report.problems);
    assert_eq!(report.failed, 3);
}

#[test]
fn the_camera_stage_is_applied_recorded_and_refused_on_resume_when_changed() {
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 3, 3);
    let (plain, with) = (tmp.path().join("plain"), tmp.path().join("camera"));
    run(&plain, &spec(&clean, &refs, 1), &reinhard(), &opts(1));
    let mut sp = spec(&clean, &refs, 1);
    sp.camera = uwnr_render::Camera::TYPICAL;
    run(&with, &sp, &reinhard(), &opts(2));
    // Recorded as set; absent without a camera.
    assert_eq!(
        Settings::read(&with).unwrap().camera,
        Some(uwnr_render::Camera::TYPICAL)
    );
    assert_eq!(Settings::read(&plain).unwrap().camera, None);
    // The underwater side went through it, the clean side did not.
    let limits = DecodeLimits::default();
    let m = read_manifest(&with.join("manifest.jsonl")).unwrap();
    let mut moved = 0;
    for (_, r) in m.records {
        let load = |root: &std::path::Path, f: &str| load_rgb(&root.join(f), &limits).unwrap();
        assert_eq!(load(&with, &r.clean), load(&plain, &r.clean));
        if load(&with, &r.underwater) != load(&plain, &r.underwater) {
            moved += 1;
        }
    }
    assert_eq!(moved, 3);
    // The same camera resumes (nothing to do); another one is refused.
    let s = run(&with, &sp, &reinhard(), &opts(1));
    assert_eq!((s.skipped, s.rendered), (3, 0));
    sp.camera.jpeg_quality = 90;
    let stop = AtomicBool::new(false);
    let err =
        uwnr_dataset::generate(&with, &sp, &reinhard(), &opts(1), &stop, &mut |_| {}).unwrap_err();
    assert!(
        matches!(&err, DatasetError::SettingsMismatch { field, .. } if field == "camera.jpeg_quality"),
        "{err}"
    );
}

#[test]
fn the_camera_on_the_clean_side_is_applied_as_set_and_refused_on_resume_when_changed() {
    use uwnr_render::CleanCamera;
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 3, 3);
    let mut sp = spec(&clean, &refs, 1);
    // The fixtures are about 20 px: the widest lens (sized at 256 px) gives them a sigma of
    // about 0.8 px, what the typical camera gives a 256 px pair.
    sp.camera = uwnr_render::Camera {
        blur: 10.0,
        ..uwnr_render::Camera::TYPICAL
    };
    let dir = |c: CleanCamera| tmp.path().join(format!("{c:?}"));
    for (jobs, c) in [CleanCamera::None, CleanCamera::Lens, CleanCamera::Camera]
        .into_iter()
        .enumerate()
    {
        sp.camera.clean = c;
        run(&dir(c), &sp, &reinhard(), &opts(1 + jobs % 2));
    }
    let read = |d: &std::path::Path| {
        serde_json::from_slice::<serde_json::Value>(&std::fs::read(d.join("dataset.json")).unwrap())
            .unwrap()
    };
    // Recorded when it does something (a record without it reads back as none).
    assert!(
        read(&dir(CleanCamera::None))["camera"]
            .get("clean")
            .is_none()
    );
    assert_eq!(read(&dir(CleanCamera::Lens))["camera"]["clean"], "lens");
    assert_eq!(read(&dir(CleanCamera::Camera))["camera"]["clean"], "camera");
    let limits = DecodeLimits::default();
    let manifest = |c| {
        read_manifest(&dir(c).join("manifest.jsonl"))
            .unwrap()
            .records
    };
    let plain = manifest(CleanCamera::None);
    for c in [CleanCamera::Lens, CleanCamera::Camera] {
        sp.camera.clean = c;
        for ((_, r), (_, r2)) in plain.iter().zip(&manifest(c)) {
            let load = |root: &std::path::Path, f: &str| load_rgb(&root.join(f), &limits).unwrap();
            let (none, this) = (dir(CleanCamera::None), dir(c));
            // The underwater sides are the same renders through the same camera.
            let underwater = load(&this, &r2.underwater);
            assert_eq!(load(&none, &r.underwater), underwater);
            // The clean side is the clean clean side through the camera as set, with the
            // underwater side's seed: for `camera`, exactly what the underwater side of the
            // clean image would be.
            let (c0, c2) = (load(&none, &r.clean), load(&this, &r2.clean));
            assert_ne!(c0, c2, "{c:?}");
            let seed = uwnr_render::Camera::seed(r2.seed);
            assert_eq!(
                c2,
                sp.camera.clean_side(&c0, seed).unwrap().quantised(),
                "{c:?}"
            );
            // The pair's strength is measured against the clean side as stored.
            let stored = uwnr_model::water::pair_psnr(&underwater, &c2).unwrap();
            assert!((r2.strength_db.unwrap() - stored).abs() < 1e-3, "{r2:?}");
        }
    }
    // Resuming with another clean side is refused.
    sp.camera.clean = CleanCamera::Lens;
    let stop = AtomicBool::new(false);
    let err = uwnr_dataset::generate(
        &dir(CleanCamera::Camera),
        &sp,
        &reinhard(),
        &opts(1),
        &stop,
        &mut |_| {},
    )
    .unwrap_err();
    assert!(
        matches!(&err, DatasetError::SettingsMismatch { field, .. } if field == "camera.clean"),
        "{err}"
    );
}

#[test]
fn the_clean_balance_is_calibrated_from_recorded_and_refused_on_resume_when_changed() {
    use uwnr_model::water::{CleanBalance, pair_psnr};
    use uwnr_render::{MethodSpec, Renderer, UwnrSpec};
    if uwnr_model::bundled_model_bytes().is_none() {
        eprintln!("skipped: this build has no bundled model (`cargo test --workspace` has it)");
        return;
    }
    // The photo as the clean side first (the balanced one, the default, below).
    let uwnr = |balance: CleanBalance| {
        Renderer::load(MethodSpec::Uwnr(UwnrSpec {
            effects: uwnr_model::WaterEffects::NONE,
            balance,
            // The fixed balance (v8's); the one following the water is tested below.
            balance_water_share: 0.0,
            clean_side: uwnr_render::CleanSide::Photo,
            ..UwnrSpec::default()
        }))
        .unwrap()
    };
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 3, 3);
    let mut sp = spec(&clean, &refs, 1);
    sp.target = Some(uwnr_dataset::WaterTarget::bundled().unwrap());
    let (none, bank) = (tmp.path().join("none"), tmp.path().join("bank"));
    run(&none, &sp, &uwnr(CleanBalance::NONE), &opts(1));
    run(&bank, &sp, &uwnr(CleanBalance::BANK), &opts(2));
    let read = |dir: &std::path::Path| {
        serde_json::from_slice::<serde_json::Value>(
            &std::fs::read(dir.join("dataset.json")).unwrap(),
        )
        .unwrap()
    };
    // Recorded in the method's settings when it runs; absent (the old form) when none.
    let (with, without) = (read(&bank), read(&none));
    assert_eq!(
        with["method_params"]["balance"],
        serde_json::json!(CleanBalance::BANK.0),
        "{with}"
    );
    assert!(
        without["method_params"].get("balance").is_none(),
        "{without}"
    );
    // The clean side is the photo itself either way; the water's strength was calibrated from
    // the balanced photo, and the pair records its distance from the photo as stored.
    let limits = DecodeLimits::default();
    let m = read_manifest(&bank.join("manifest.jsonl")).unwrap();
    for (_, r) in &m.records {
        let load = |root: &std::path::Path, f: &str| load_rgb(&root.join(f), &limits).unwrap();
        let (c, u) = (load(&bank, &r.clean), load(&bank, &r.underwater));
        assert_eq!(c, load(&none, &r.clean));
        let stored = pair_psnr(&u, &c).unwrap();
        assert!(
            (r.strength_db.unwrap() - stored).abs() < 1e-3,
            "{r:?} {stored}"
        );
        let from_balanced = pair_psnr(&u, &CleanBalance::BANK.apply(&c).unwrap()).unwrap();
        let target = r.params.to_value()["strength"]["target_db"]
            .as_f64()
            .unwrap() as f32;
        assert!(
            (from_balanced - target).abs() < (stored - target).abs() + 1e-3,
            "calibrated from the balanced photo: target {target}, from it {from_balanced}, \
             from the stored photo {stored}"
        );
    }
    // With the balanced photo as the clean side, the pair is made as a real pair is: its clean
    // side at the bank's white point, its strength the calibrated one, against that side.
    let side = tmp.path().join("side");
    let balanced_side = Renderer::load(MethodSpec::Uwnr(UwnrSpec {
        effects: uwnr_model::WaterEffects::NONE,
        balance_water_share: 0.0,
        clean_side: uwnr_render::CleanSide::Balanced,
        ..UwnrSpec::default()
    }))
    .unwrap();
    run(&side, &sp, &balanced_side, &opts(1));
    assert_eq!(read(&side)["method_params"]["clean_side"], "balanced");
    let m2 = read_manifest(&side.join("manifest.jsonl")).unwrap();
    for ((_, r), (_, r2)) in m.records.iter().zip(&m2.records) {
        let load = |root: &std::path::Path, f: &str| load_rgb(&root.join(f), &limits).unwrap();
        let photo = load(&bank, &r.clean);
        let c2 = load(&side, &r2.clean);
        let expected = CleanBalance::BANK.apply(&photo).unwrap().quantised();
        assert_eq!(c2, expected, "the stored clean side is the balanced photo");
        // The same render as with the photo stored (only the clean side differs).
        assert_eq!(load(&side, &r2.underwater), load(&bank, &r.underwater));
        let stored = pair_psnr(&load(&side, &r2.underwater), &c2).unwrap();
        assert!(
            (r2.strength_db.unwrap() - stored).abs() < 1e-3,
            "{r2:?} {stored}"
        );
        assert!(
            stored > r.strength_db.unwrap(),
            "nearer its clean side than the photo"
        );
    }

    // The same balance resumes (nothing to do); another one is refused, naming it.
    let s = run(&bank, &sp, &uwnr(CleanBalance::BANK), &opts(1));
    assert_eq!((s.skipped, s.rendered), (3, 0));
    let stop = AtomicBool::new(false);
    let err = uwnr_dataset::generate(
        &bank,
        &sp,
        &uwnr(CleanBalance::NONE),
        &opts(1),
        &stop,
        &mut |_| {},
    )
    .unwrap_err();
    assert!(
        matches!(&err, DatasetError::SettingsMismatch { field, .. } if field.contains("balance")),
        "{err}"
    );
}

#[test]
fn a_clean_balance_following_the_water_is_stored_recorded_and_refused_on_resume_when_changed() {
    use uwnr_model::water::{BANK_WATER_SHARE, CleanBalance, chromaticity};
    use uwnr_render::{MethodSpec, Renderer, UwnrSpec};
    if uwnr_model::bundled_model_bytes().is_none() {
        eprintln!("skipped: this build has no bundled model (`cargo test --workspace` has it)");
        return;
    }
    let load = |share: f32, clean_side| {
        Renderer::load(MethodSpec::Uwnr(UwnrSpec {
            effects: uwnr_model::WaterEffects::NONE,
            balance_water_share: share,
            clean_side,
            ..UwnrSpec::default()
        }))
        .unwrap()
    };
    let uwnr = |share: f32| load(share, uwnr_render::CleanSide::Balanced);
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 3, 3);
    let mut sp = spec(&clean, &refs, 3);
    sp.target = Some(uwnr_dataset::WaterTarget::bundled().unwrap());
    let out = tmp.path().join("follows");
    run(&out, &sp, &uwnr(BANK_WATER_SHARE), &opts(2));
    // The same pairs with the photo stored as the clean side.
    let photos = tmp.path().join("photos");
    run(
        &photos,
        &sp,
        &load(BANK_WATER_SHARE, uwnr_render::CleanSide::Photo),
        &opts(1),
    );
    let settings: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("dataset.json")).unwrap()).unwrap();
    assert_eq!(
        settings["method_params"]["balance_water_share"],
        serde_json::json!(BANK_WATER_SHARE),
        "{settings}"
    );
    // Each pair's clean side is the photo at the balance its own reference's water gives.
    let limits = DecodeLimits::default();
    let m = read_manifest(&out.join("manifest.jsonl")).unwrap();
    let mut balances = Vec::new();
    for (_, r) in &m.records {
        let reference = load_rgb(
            std::path::Path::new(r.reference_source.as_deref().unwrap()),
            &limits,
        )
        .unwrap();
        let balance =
            CleanBalance::BANK.following(BANK_WATER_SHARE, chromaticity(&reference).unwrap());
        let photo = load_rgb(&photos.join(&r.clean), &limits).unwrap();
        assert_eq!(
            load_rgb(&photos.join(&r.underwater), &limits).unwrap(),
            load_rgb(&out.join(&r.underwater), &limits).unwrap()
        );
        let stored = load_rgb(&out.join(&r.clean), &limits).unwrap();
        assert_eq!(stored, balance.apply(&photo).unwrap().quantised());
        balances.push(balance);
    }
    assert!(
        balances.iter().any(|b| *b != balances[0]),
        "the references differ, so do their balances: {balances:?}"
    );
    // The fixed balance is another dataset: refused on resume, naming the field.
    let stop = AtomicBool::new(false);
    let err =
        uwnr_dataset::generate(&out, &sp, &uwnr(0.0), &opts(1), &stop, &mut |_| {}).unwrap_err();
    assert!(
        matches!(&err, DatasetError::SettingsMismatch { field, .. } if field.contains("balance_water_share")),
        "{err}"
    );
}

#[test]
fn a_lit_clean_side_is_stored_recorded_and_refused_on_resume_when_changed() {
    use uwnr_model::WaterEffects;
    use uwnr_render::{CleanSide, MethodSpec, Renderer, UwnrSpec};
    if uwnr_model::bundled_model_bytes().is_none() {
        eprintln!("skipped: this build has no bundled model (`cargo test --workspace` has it)");
        return;
    }
    let light = WaterEffects {
        light_from_above: 0.6,
        ..WaterEffects::NONE
    };
    let uwnr = |clean_side| {
        Renderer::load(MethodSpec::Uwnr(UwnrSpec {
            effects: light,
            clean_side,
            ..UwnrSpec::default()
        }))
        .unwrap()
    };
    let tmp = tempfile::tempdir().unwrap();
    let (clean, refs) = inputs(tmp.path(), 3, 3);
    let sp = spec(&clean, &refs, 1);
    let (flat, lit) = (tmp.path().join("flat"), tmp.path().join("lit"));
    run(&flat, &sp, &uwnr(CleanSide::Balanced), &opts(1));
    run(&lit, &sp, &uwnr(CleanSide::Lit), &opts(2));
    let record = serde_json::from_slice::<serde_json::Value>(
        &std::fs::read(lit.join("dataset.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(record["method_params"]["clean_side"], "lit", "{record}");
    let limits = DecodeLimits::default();
    let load = |root: &std::path::Path, f: &str| load_rgb(&root.join(f), &limits).unwrap();
    let (m, m2) = (
        read_manifest(&flat.join("manifest.jsonl")).unwrap(),
        read_manifest(&lit.join("manifest.jsonl")).unwrap(),
    );
    assert_eq!(m.records.len(), 3);
    for ((_, r), (_, r2)) in m.records.iter().zip(&m2.records) {
        // The underwater side is the same; the clean side is the balanced one under the same
        // light (within the stored balanced side's rounding).
        assert_eq!(load(&flat, &r.underwater), load(&lit, &r2.underwater));
        let mut expected = load(&flat, &r.clean);
        let balanced = expected.clone();
        light.apply_light(&mut expected).unwrap();
        let got = load(&lit, &r2.clean);
        let worst = got
            .data()
            .iter()
            .zip(expected.data())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        // Half a level of the stored balanced side's rounding, times the light's largest gain
        // (1.3 at the top), and half a level of the lit side's own.
        assert!(worst <= (0.5 * 1.3 + 0.5 + 0.01) / 255.0, "{r2:?}: {worst}");
        let (w, h) = got.size();
        let row_mean = |img: &uwnr_core::Image, y: usize| {
            img.plane(1)[y * w..(y + 1) * w].iter().sum::<f32>() / w as f32
        };
        assert!(row_mean(&got, 0) > row_mean(&balanced, 0));
        assert!(row_mean(&got, h - 1) < row_mean(&balanced, h - 1));
    }
    // A resume with the balanced clean side is refused, naming the field.
    let stop = AtomicBool::new(false);
    let err = uwnr_dataset::generate(
        &lit,
        &sp,
        &uwnr(CleanSide::Balanced),
        &opts(1),
        &stop,
        &mut |_| {},
    )
    .unwrap_err();
    assert!(
        matches!(&err, DatasetError::SettingsMismatch { field, .. } if field.contains("clean_side")),
        "{err}"
    );
}
