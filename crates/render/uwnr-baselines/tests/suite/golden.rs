//! Golden-image regression tests: the bundled samples rendered by each baseline at a reduced size
//! with a fixed seed must match the committed PNGs (and parameter manifests) in `tests/golden/`.
//!
//! After an intended change, rewrite them with
//! `REGENERATE=1 cargo test -p uwnr-baselines --test suite golden` and look at the new images.

use std::path::{Path, PathBuf};

use serde_json::Value;
use uwnr_baselines::{
    AttenuationRatio, ColourSpace, JerlovParams, Method, ReferenceCoefficients, ReinhardParams,
    RenderInput, SeathruCoefficients, SeathruParams, UisaParams, WaterType, render,
};
use uwnr_core::Image;
use uwnr_core::io::{DecodeLimits, load_rgb, save_rgb, to_rgb8};
use uwnr_core::resize::resize_bilinear;

/// Size the clean sample (321x481) is reduced to.
const WIDTH: usize = 96;
const HEIGHT: usize = 144;
/// Seed of every golden render.
const SEED: u64 = 2022;
/// Largest accepted difference of one 8-bit value (platform `exp`/`ln` may differ in the last ulp).
const MAX_CODE_DIFF: u8 = 2;
/// Largest accepted mean absolute difference, in 8-bit codes.
const MAX_MEAN_CODE_DIFF: f64 = 0.05;
/// Tolerance on the numbers of the parameter manifests.
const PARAM_TOL: f64 = 1e-5;

fn manifest_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn sample(name: &str) -> Image {
    let path = manifest_dir().join("../../../assets/samples").join(name);
    load_rgb(&path, &DecodeLimits::default()).unwrap_or_else(|e| panic!("{e}"))
}

/// A vertical ramp: the top row is farthest (1), the bottom row nearest (0).
fn ramp_depth(w: usize, h: usize) -> Image {
    let data: Vec<f32> = (0..h)
        .flat_map(|y| std::iter::repeat_n(1.0 - y as f32 / (h - 1) as f32, w))
        .collect();
    Image::from_planar(w, h, 1, data).unwrap()
}

fn regenerate() -> bool {
    std::env::var("REGENERATE").is_ok_and(|v| v == "1")
}

/// Numbers equal within `PARAM_TOL`, everything else exactly.
fn json_close(a: &Value, b: &Value) -> bool {
    match (a, b) {
        (Value::Number(x), Value::Number(y)) => match (x.as_f64(), y.as_f64()) {
            (Some(x), Some(y)) => (x - y).abs() <= PARAM_TOL * (1.0 + x.abs()),
            _ => x == y,
        },
        (Value::Array(x), Value::Array(y)) => {
            x.len() == y.len() && x.iter().zip(y).all(|(x, y)| json_close(x, y))
        }
        (Value::Object(x), Value::Object(y)) => {
            x.len() == y.len()
                && x.iter()
                    .all(|(k, v)| y.get(k).is_some_and(|w| json_close(v, w)))
        }
        _ => a == b,
    }
}

fn check_golden(name: &str, method: &Method, reference: Option<&str>) {
    let clean = resize_bilinear(&sample("clean-statues.jpg"), WIDTH, HEIGHT).unwrap();
    let depth = ramp_depth(WIDTH, HEIGHT);
    let reference = reference.map(sample);
    let input = RenderInput {
        clean: &clean,
        depth: &depth,
        reference: reference.as_ref(),
    };
    let out = render(method, &input, SEED).unwrap_or_else(|e| panic!("{name}: {e}"));
    let dir = manifest_dir().join("tests/golden");
    let png = dir.join(format!("{name}.png"));
    let json = dir.join(format!("{name}.json"));
    if regenerate() {
        std::fs::create_dir_all(&dir).unwrap();
        save_rgb(&png, &out.image).unwrap();
        std::fs::write(
            &json,
            serde_json::to_string_pretty(&crate::value(&out.params)).unwrap() + "\n",
        )
        .unwrap();
        eprintln!("rewrote {}", png.display());
        return;
    }
    compare_png(name, &png, &out.image);
    let want: Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert!(
        json_close(&crate::value(&out.params), &want),
        "{name}: parameters changed\n got  {}\n want {want}",
        crate::value(&out.params)
    );
}

fn compare_png(name: &str, png: &Path, image: &Image) {
    let golden = load_rgb(png, &DecodeLimits::default())
        .unwrap_or_else(|e| panic!("{name}: {e} (run with REGENERATE=1 to create it)"));
    assert_eq!(golden.size(), image.size(), "{name}: size");
    let got = to_rgb8(image);
    let want = to_rgb8(&golden);
    let mut max = 0u8;
    let mut sum = 0u64;
    for (a, b) in got.iter().zip(&want) {
        let d = a.abs_diff(*b);
        max = max.max(d);
        sum += u64::from(d);
    }
    let mean = sum as f64 / got.len() as f64;
    assert!(
        max <= MAX_CODE_DIFF && mean <= MAX_MEAN_CODE_DIFF,
        "{name}: differs from {} (max {max} codes, mean {mean:.3})",
        png.display()
    );
}

#[test]
fn jerlov_random_water() {
    check_golden(
        "jerlov-random",
        &Method::Jerlov(JerlovParams::default()),
        None,
    );
}

#[test]
fn jerlov_type_3c_released_script_lighting() {
    let p = JerlovParams {
        water_type: Some(WaterType::C3),
        illuminate_scene: true,
        ..JerlovParams::default()
    };
    check_golden("jerlov-3c-lit", &Method::Jerlov(p), None);
}

#[test]
fn uisa_blue_reference() {
    check_golden(
        "uisa-blue",
        &Method::Uisa(UisaParams::default()),
        Some("ref-blue.jpg"),
    );
}

#[test]
fn uisa_green_reference_wavelength_only() {
    let p = UisaParams {
        attenuation_ratio: AttenuationRatio::Wavelength,
        ..UisaParams::default()
    };
    check_golden(
        "uisa-green-wavelength",
        &Method::Uisa(p),
        Some("ref-green.png"),
    );
}

#[test]
fn uisa_green_reference() {
    check_golden(
        "uisa-green",
        &Method::Uisa(UisaParams::default()),
        Some("ref-green.png"),
    );
}

#[test]
fn seathru_sampled() {
    check_golden(
        "seathru-sampled",
        &Method::Seathru(SeathruParams::default()),
        None,
    );
}

#[test]
fn seathru_from_blue_reference() {
    let p = SeathruParams {
        coefficients: SeathruCoefficients::FromReference(ReferenceCoefficients::default()),
        ..SeathruParams::default()
    };
    check_golden(
        "seathru-ref-blue",
        &Method::Seathru(p),
        Some("ref-blue.jpg"),
    );
}

#[test]
fn reinhard_lalphabeta_blue() {
    check_golden(
        "reinhard-blue",
        &Method::Reinhard(ReinhardParams::default()),
        Some("ref-blue.jpg"),
    );
}

#[test]
fn reinhard_lab_green() {
    let p = ReinhardParams {
        space: ColourSpace::Lab,
        ..ReinhardParams::default()
    };
    check_golden(
        "reinhard-lab-green",
        &Method::Reinhard(p),
        Some("ref-green.png"),
    );
}
