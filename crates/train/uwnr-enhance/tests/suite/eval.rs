//! Scoring a paired test folder: the unenhanced baseline, a network, saved outputs, downscaling
//! and folder errors.

use uwnr_core::io::{DecodeLimits, load_rgb};
use uwnr_enhance::{EnhanceError, ShallowUwnetConfig, evaluate_dir};
use uwnr_run::RunError;
use uwnr_train::Device;

use crate::common::make_dir;

#[test]
fn scores_the_input_and_a_network_alike() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = make_dir(&tmp.path().join("test"), 3, 40, 32);
    std::fs::write(dir.join("underwater/lonely.png"), b"").unwrap();
    let d = Device::flex();
    let limits = DecodeLimits::default();

    // No enhancement: the input is scored, and its scores match the metrics crate's on the
    // files themselves.
    let none = evaluate_dir(None, &dir, &d, None, None, &limits).unwrap();
    assert_eq!(none.per_image.len(), 3);
    assert_eq!(none.skipped.len(), 1);
    assert!(none.skipped[0].contains("lonely.png"));
    let uw = load_rgb(&dir.join("underwater/001.png"), &limits).unwrap();
    let clean = load_rgb(&dir.join("clean/001.png"), &limits).unwrap();
    let s = &none.per_image[1];
    assert_eq!(s.name, "001.png");
    assert_eq!(s.psnr, uwnr_metrics::psnr(&uw, &clean, 1.0).unwrap());
    assert_eq!(s.ssim, uwnr_metrics::ssim(&uw, &clean, 1.0).unwrap());
    assert_eq!(s.uiqm, uwnr_metrics::uiqm(&uw).unwrap());
    assert_eq!(s.uciqe, uwnr_metrics::uciqe(&uw).unwrap());
    let mean = none.per_image.iter().map(|s| s.psnr).sum::<f64>() / 3.0;
    assert!((none.psnr - mean).abs() < 1e-12);
    assert!(none.per_image.iter().all(|s| s.downscaled_from.is_none()));

    // A network: outputs are saved, and scoring the saved files gives the same numbers.
    let net = ShallowUwnetConfig {
        width: 8,
        ..ShallowUwnetConfig::default()
    }
    .init(&d)
    .unwrap();
    let out = tmp.path().join("out");
    let with = evaluate_dir(Some(&net), &dir, &d, Some(&out), None, &limits).unwrap();
    assert_eq!(with.per_image.len(), 3);
    assert_ne!(with.psnr, none.psnr);
    for s in &with.per_image {
        assert!(s.psnr.is_finite() && (-1.0..=1.0).contains(&s.ssim));
        assert!(s.uiqm.is_finite() && s.uciqe.is_finite());
    }
    let saved = load_rgb(&out.join("002.png"), &limits).unwrap();
    let clean = load_rgb(&dir.join("clean/002.png"), &limits).unwrap();
    assert_eq!(saved.size(), (40, 32));
    assert_eq!(
        with.per_image[2].psnr,
        uwnr_metrics::psnr(&saved, &clean, 1.0).unwrap()
    );

    // Downscaling is recorded and keeps the aspect.
    let small = evaluate_dir(None, &dir, &d, Some(&out), Some(20), &limits).unwrap();
    assert_eq!(small.per_image[0].downscaled_from, Some((40, 32)));
    let saved = load_rgb(&out.join("000.png"), &limits).unwrap();
    assert_eq!(saved.size(), (20, 16));
}

#[test]
fn folder_errors_are_clear() {
    let tmp = tempfile::tempdir().unwrap();
    let d = Device::flex();
    let limits = DecodeLimits::default();
    let eval = |dir: &std::path::Path| evaluate_dir(None, dir, &d, None, None, &limits);
    // Not a paired folder.
    let plain = tmp.path().join("plain");
    std::fs::create_dir_all(&plain).unwrap();
    let err = eval(&plain).unwrap_err();
    assert!(
        matches!(err, EnhanceError::Run(RunError::NotAPairedFolder { .. })),
        "{err}"
    );
    // Empty folders.
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(empty.join("underwater")).unwrap();
    std::fs::create_dir_all(empty.join("clean")).unwrap();
    let err = eval(&empty).unwrap_err();
    assert!(err.to_string().contains("holds no images"), "{err}");
    // No name in common.
    let unpaired = make_dir(&tmp.path().join("unpaired"), 1, 32, 32);
    std::fs::rename(
        unpaired.join("clean/000.png"),
        unpaired.join("clean/other.png"),
    )
    .unwrap();
    let err = eval(&unpaired).unwrap_err();
    assert!(
        matches!(err, EnhanceError::Run(RunError::NoPairs { .. })),
        "{err}"
    );
    // A corrupt file stops the evaluation and names the file.
    let broken = make_dir(&tmp.path().join("broken"), 2, 32, 32);
    std::fs::write(broken.join("underwater/001.png"), b"not a png").unwrap();
    let err = eval(&broken).unwrap_err();
    assert!(err.to_string().contains("001.png"), "{err}");
    // Pairs of different sizes.
    let sizes = make_dir(&tmp.path().join("sizes"), 1, 32, 32);
    let other = make_dir(&tmp.path().join("sizes-src"), 1, 40, 32);
    std::fs::copy(other.join("clean/000.png"), sizes.join("clean/000.png")).unwrap();
    let err = eval(&sizes).unwrap_err();
    assert!(
        matches!(err, EnhanceError::Run(RunError::BadImage { .. })),
        "{err}"
    );
}
