//! The reference-based building blocks against an independent NumPy / OpenCV / scikit-image
//! computation: `tests/fixtures/reference_values.json`, written by
//! `tools/baselines_reference.py` (run it from the repository root to regenerate).

use std::path::PathBuf;

use serde_json::Value;
use uwnr_baselines::background::{BackgroundPick, quadtree_background};
use uwnr_baselines::reinhard::{ColourSpace, transfer};
use uwnr_baselines::uisa::red_channel_transmission;
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, load_rgb};

/// Same pattern as `synthetic_clean` in the script.
const CLEAN_W: usize = 7;
const CLEAN_H: usize = 5;

fn manifest_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn fixture() -> Value {
    let path = manifest_dir().join("tests/fixtures/reference_values.json");
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn reference() -> Image {
    let path = manifest_dir().join("../../../assets/samples/ref-green.png");
    load_rgb(&path, &DecodeLimits::default()).unwrap()
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn synthetic_clean() -> Image {
    let n = CLEAN_W * CLEAN_H;
    let mut data = vec![0.0f32; 3 * n];
    for y in 0..CLEAN_H {
        for x in 0..CLEAN_W {
            let i = y * CLEAN_W + x;
            let (xf, yf) = (x as f64, y as f64);
            data[i] = (0.3 + 0.6 * xf / (CLEAN_W - 1) as f64) as f32;
            data[n + i] = (0.25 + 0.5 * yf / (CLEAN_H - 1) as f64) as f32;
            data[2 * n + i] = (0.2 + 0.3 * ((x + y) % 3) as f64 / 2.0) as f32;
        }
    }
    Image::from_planar(CLEAN_W, CLEAN_H, 3, data).unwrap()
}

#[test]
fn quadtree_background_matches_numpy() {
    let want = fixture();
    let img = reference();
    for (pick, key) in [
        (BackgroundPick::Mean, "mean"),
        (BackgroundPick::Brightest, "brightest"),
        (BackgroundPick::QuarterRank, "quarter_rank"),
    ] {
        let got = quadtree_background(&img, 0.01, pick).unwrap();
        let want = floats(&want["quadtree"][key]);
        for c in 0..3 {
            assert!(
                (got[c] - want[c]).abs() < 1e-6,
                "{key}: {got:?} vs {want:?}"
            );
        }
    }
}

#[test]
fn red_channel_prior_median_matches_opencv() {
    let want = fixture();
    let img = reference();
    let b = floats(&want["quadtree"]["mean"]);
    let background = [0, 1, 2].map(|c| b[c].clamp(1e-3, 1.0 - 1e-3));
    let t = red_channel_transmission(&img, background, 15, 0.1).unwrap();
    let mut v = t.data().to_vec();
    v.sort_by(f32::total_cmp);
    let got = f64::from(v[(v.len() - 1) / 2]);
    let want = want["red_channel_median_transmission"].as_f64().unwrap();
    assert!((got - want).abs() < 1e-5, "{got} vs {want}");
}

#[test]
fn reinhard_lab_matches_scikit_image() {
    let want = fixture();
    let expected = floats(&want["reinhard_lab"]["output_hwc"]);
    let out = transfer(&synthetic_clean(), &reference(), ColourSpace::Lab).unwrap();
    let got = out.to_interleaved();
    assert_eq!(got.len(), expected.len());
    let max = got
        .iter()
        .zip(&expected)
        .map(|(a, b)| (f64::from(*a) - b).abs())
        .fold(0.0, f64::max);
    assert!(max < 1e-4, "max difference {max}");
}
