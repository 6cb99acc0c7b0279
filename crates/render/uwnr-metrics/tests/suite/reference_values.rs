//! PSNR, SSIM, UIQM and UCIQE against the values of `tools/metrics_reference.py`
//! (scikit-image 0.26 / scipy for PSNR and SSIM; re-implementations of the FUnIE-GAN UIQM and
//! xueleichen UCIQE scripts, themselves checked against the original code to ~1e-9).
//!
//! Tolerances: PSNR and SSIM are computed from the same f32 pixels in f64 by the same
//! formulas, so they agree to rounding (1e-9 here; the requirement is 1e-3). UIQM and UCIQE sort
//! and sum tens of thousands of values; summation order differs from numpy's pairwise sums,
//! so they agree to about 1e-12 relative; the tests allow 1e-8.

use crate::common;

use common::{Agreement, json, load_png};
use uwnr_metrics::{
    SsimOptions, UiqmConfig, psnr, psnr_gray, ssim, ssim_gray, ssim_with, uciqe_components,
    uiqm_with,
};

const FULL_REFERENCE_TOL: f64 = 1e-9;
const NO_REFERENCE_TOL: f64 = 1e-8;

#[test]
fn psnr_and_ssim_match_skimage() {
    let expected = json("metrics_expected.json");
    let pairs = expected["full_reference"].as_array().unwrap();
    assert!(pairs.len() >= 4);
    let mut agreement = Agreement::default();
    for case in pairs {
        let target = load_png(case["target"].as_str().unwrap());
        let pred = load_png(case["pred"].as_str().unwrap());
        let name = case["pred"].as_str().unwrap();
        let want = |k: &str| case[k].as_f64().unwrap();
        let checks = [
            ("psnr", psnr(&pred, &target, 1.0).unwrap()),
            ("psnr_gray", psnr_gray(&pred, &target, 1.0).unwrap()),
            ("ssim", ssim(&pred, &target, 1.0).unwrap()),
            ("ssim_gray", ssim_gray(&pred, &target, 1.0).unwrap()),
            (
                "ssim_uniform7",
                ssim_with(&pred, &target, &SsimOptions::skimage_default(1.0)).unwrap(),
            ),
        ];
        for (key, got) in checks {
            agreement.check(
                key,
                &format!("{name} {key}"),
                got,
                want(key),
                FULL_REFERENCE_TOL,
            );
        }
    }
    agreement.report("skimage");
}

#[test]
fn uiqm_and_uciqe_match_the_reference_scripts() {
    let expected = json("metrics_expected.json");
    let images = expected["no_reference"].as_object().unwrap();
    assert!(images.len() >= 5);
    let mut agreement = Agreement::default();
    for (name, want) in images {
        let img = load_png(name);
        for (preset, cfg) in [
            ("uiqm_funie_gan", UiqmConfig::funie_gan()),
            ("uiqm_shallow_uwnet", UiqmConfig::shallow_uwnet()),
        ] {
            let got = uiqm_with(&img, &cfg).unwrap();
            let w = &want[preset];
            for (key, value) in [
                ("uicm", got.uicm),
                ("uism", got.uism),
                ("uiconm", got.uiconm),
                ("uiqm", got.uiqm),
            ] {
                let what = format!("{name} {preset} {key}");
                agreement.check(
                    &format!("{preset} {key}"),
                    &what,
                    value,
                    w[key].as_f64().unwrap(),
                    NO_REFERENCE_TOL,
                );
            }
        }
        let got = uciqe_components(&img).unwrap();
        let w = &want["uciqe"];
        for (key, value) in [
            ("sigma_c", got.sigma_c),
            ("con_l", got.con_l),
            ("mu_s", got.mu_s),
            ("uciqe", got.uciqe),
        ] {
            let what = format!("{name} uciqe {key}");
            agreement.check(
                &format!("uciqe {key}"),
                &what,
                value,
                w[key].as_f64().unwrap(),
                NO_REFERENCE_TOL,
            );
        }
    }
    agreement.report("reference scripts");
}

#[test]
fn full_reference_metrics_are_symmetric_on_real_images() {
    let a = load_png("room_120x90.png");
    let b = load_png("room_120x90_pred.png");
    assert_eq!(psnr(&a, &b, 1.0).unwrap(), psnr(&b, &a, 1.0).unwrap());
    let (ab, ba) = (ssim(&a, &b, 1.0).unwrap(), ssim(&b, &a, 1.0).unwrap());
    assert!((ab - ba).abs() < 1e-14, "{ab} vs {ba}");
    assert!((ssim(&a, &a, 1.0).unwrap() - 1.0).abs() < 1e-12);
}
