//! Fréchet distance and KID against `tools/metrics_reference.py`: pytorch-fid's
//! `scipy.linalg.sqrtm` formula (`fd_sqrtm`), the same quantity through numpy's `eigvalsh`
//! (`fd_exact`), and the unbiased polynomial-kernel MMD² on whole sets (`kid_full`).
//!
//! Against `fd_exact`, `frechet_distance` agrees to ~1e-13 relative (tolerance 1e-9), and so
//! does `frechet_distance_from_stats` when n > d; from the statistics of sets with n < d it
//! meets eigenvalues that should be 0 and agrees to ~1e-9 (tolerance 1e-7). Against sqrtm the
//! agreement is ~1e-13 when n > d; when n < d, sqrtm of the singular product S1 S2 is itself
//! only accurate to about 1e-8 relative, hence 1e-6 there.

use crate::common;

use common::{Agreement, json};
use uwnr_metrics::{FeatureStats, frechet_distance, frechet_distance_from_stats, kid};

fn features(v: &serde_json::Value) -> Vec<Vec<f64>> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|row| {
            row.as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect()
        })
        .collect()
}

#[test]
fn frechet_distance_matches_pytorch_fid_formula() {
    let expected = json("frechet_expected.json");
    let cases = expected["cases"].as_array().unwrap();
    assert!(cases.len() >= 5);
    let mut agreement = Agreement::default();
    for case in cases {
        let name = case["name"].as_str().unwrap();
        let (a, b) = (features(&case["a"]), features(&case["b"]));
        let exact = case["fd_exact"].as_f64().unwrap();
        let sqrtm = case["fd_sqrtm"].as_f64().unwrap();
        let got = frechet_distance(&a, &b).unwrap();
        let stats = frechet_distance_from_stats(
            &FeatureStats::from_features(&a).unwrap(),
            &FeatureStats::from_features(&b).unwrap(),
        )
        .unwrap();
        assert!(got.is_finite() && stats.is_finite(), "{name}");
        let d = a[0].len();
        let full_rank = a.len().min(b.len()) > d;
        let route = if full_rank { "n > d" } else { "n < d" };
        agreement.check(
            &format!("features vs exact ({route})"),
            &format!("{name} features vs exact"),
            got,
            exact,
            1e-9,
        );
        // From rank-deficient statistics the square root meets eigenvalues that should be 0.
        let stats_tol = if full_rank { 1e-9 } else { 1e-7 };
        agreement.check(
            &format!("stats vs exact ({route})"),
            &format!("{name} stats vs exact"),
            stats,
            exact,
            stats_tol,
        );
        let sqrtm_tol = if full_rank { 1e-9 } else { 1e-6 };
        if name != "identical" {
            agreement.check(
                &format!("features vs sqrtm ({route})"),
                &format!("{name} vs sqrtm"),
                got,
                sqrtm,
                sqrtm_tol,
            );
        } else {
            assert!(got.abs() < 1e-9 && sqrtm.abs() < 1e-9, "{got} {sqrtm}");
        }
    }
    agreement.report("pytorch-fid formula");
}

#[test]
fn kid_on_whole_sets_matches_the_reference_estimator() {
    let expected = json("frechet_expected.json");
    let mut checked = 0;
    for case in expected["cases"].as_array().unwrap() {
        let Some(want) = case["kid_full"].as_f64() else {
            continue;
        };
        let (a, b) = (features(&case["a"]), features(&case["b"]));
        let (mean, std) = kid(&a, &b, 4, a.len(), 0).unwrap();
        common::assert_close(&format!("{} kid", case["name"]), mean, want, 1e-10);
        assert!(std < 1e-12, "{std}");
        checked += 1;
    }
    assert!(checked > 0);
}

#[test]
fn frechet_distance_is_symmetric_and_zero_on_identical_sets() {
    let expected = json("frechet_expected.json");
    for case in expected["cases"].as_array().unwrap() {
        let (a, b) = (features(&case["a"]), features(&case["b"]));
        let (ab, ba) = (
            frechet_distance(&a, &b).unwrap(),
            frechet_distance(&b, &a).unwrap(),
        );
        assert!((ab - ba).abs() <= 1e-9 * ab.max(1.0), "{ab} vs {ba}");
        assert!(frechet_distance(&a, &a).unwrap() < 1e-9);
    }
}
