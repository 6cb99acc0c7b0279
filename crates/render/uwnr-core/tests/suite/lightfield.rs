//! The light-field map against the released Python code run with the real PIL and OpenCV
//! (fixtures and manifest from `tools/lightfield_reference.py`). The bundled samples are always
//! checked; the sources under `../shared/data` in a test of their own that the test runner lists
//! as ignored when that folder is absent (the build script looks for it).
//!
//! Losslessly stored sources (PNG) must match bit for bit. JPEG sources are decoded by the
//! `image` crate (zune-jpeg), whose IDCT, chroma upsampling and YCbCr conversion differ from the
//! libjpeg-turbo inside Pillow by up to 4 code values on about 15% of the pixels of a 4:2:0
//! JPEG; the min-max normalisation of the map amplifies that on dark, low-contrast images, so
//! JPEG sources get a looser bound.

use crate::common;

use common::{compare, fixtures, read_json, read_rgb8, workspace_root};
use uwnr_core::io::{DecodeLimits, load_rgb};
use uwnr_core::lightfield::{
    LF_REFERENCE_SIZE, LightFieldMap, light_field, light_field_for, light_field_raw,
    light_field_raw_u8, light_field_raw_u8_with, light_field_u8, light_field_u8_with,
    log10_u8_values,
};
use uwnr_core::resize::U8Image;

/// Required agreement for JPEG sources (decoder differences, see the module doc): mean absolute
/// difference in code values (/255).
const JPEG_MAX_MEAN_ABS_DIFF: f64 = 4.0;

fn manifest() -> serde_json::Value {
    read_json(&fixtures().join("lightfield").join("manifest.json"))
}

#[test]
fn log10_matches_numpy_float16() {
    let expected: Vec<f64> = manifest()["log10_u8"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(log10_u8_values(), expected);
}

/// Prefix of the manifest's sources that live in the optional data folder.
const SHARED_DATA: &str = "../shared/data/";

#[test]
fn maps_of_the_bundled_samples_match_the_released_code() {
    let (checked, lossless) = check_maps(|source| !source.starts_with(SHARED_DATA));
    assert!(checked >= 4, "the bundled samples must always be checked");
    assert!(lossless >= 2, "the PNG samples must always be checked");
}

#[test]
#[cfg_attr(
    not(shared_data),
    ignore = "needs ../shared/data (absent when this crate was built)"
)]
fn maps_of_the_shared_data_match_the_released_code() {
    let (checked, _) = check_maps(|source| source.starts_with(SHARED_DATA));
    assert!(checked >= 10, "{checked} maps checked");
}

/// Checks the maps whose source passes `select`; returns how many were checked and how many of
/// those from lossless sources. A selected source that is missing fails the test.
fn check_maps(select: impl Fn(&str) -> bool) -> (usize, usize) {
    let manifest = manifest();
    let maps = manifest["maps"].as_array().unwrap();
    let (mut checked, mut exact) = (0, 0);
    let mut lossless_checked = 0;
    let mut worst_jpeg_mad = 0.0_f64;
    let mut worst_jpeg_max = 0_u8;
    let mut failures = Vec::new();
    for entry in maps {
        let source = entry["source"].as_str().unwrap();
        if !select(source) {
            continue;
        }
        let path = workspace_root().join(source);
        assert!(path.exists(), "{source} not found");
        let reference = load_rgb(&path, &DecodeLimits::default()).unwrap();
        let input = U8Image::from_image(&reference);
        let got = match entry["kind"].as_str().unwrap() {
            "render" => light_field_u8(&input),
            "raw" => light_field_raw_u8(&input),
            other => panic!("unknown kind {other}"),
        }
        .unwrap();
        let expected = read_rgb8(
            &fixtures()
                .join("lightfield")
                .join(entry["expected"].as_str().unwrap()),
        );
        let (mad, max) = compare(&got, &expected);
        println!("{source}: mean abs diff {mad:.5} /255, max {max} /255");
        checked += 1;
        exact += usize::from(max == 0);
        let lossless = source.to_ascii_lowercase().ends_with(".png");
        if lossless {
            lossless_checked += 1;
            if max != 0 {
                failures.push(format!("{source}: lossless source, max abs diff {max}"));
            }
        } else {
            worst_jpeg_mad = worst_jpeg_mad.max(mad);
            worst_jpeg_max = worst_jpeg_max.max(max);
            if mad > JPEG_MAX_MEAN_ABS_DIFF {
                failures.push(format!("{source}: mean abs diff {mad}"));
            }
        }
    }
    println!(
        "{checked} maps checked ({exact} bit-exact, {lossless_checked} from PNG); JPEG sources: \
         worst mean abs diff {worst_jpeg_mad:.5} /255, worst max abs diff {worst_jpeg_max} /255"
    );
    assert!(failures.is_empty(), "{failures:#?}");
    (checked, lossless_checked)
}

#[test]
fn float_api_wraps_the_u8_procedure() {
    let path = workspace_root().join("assets/samples/ref-green.png");
    let reference = load_rgb(&path, &DecodeLimits::default()).unwrap();
    let lf = light_field(&reference).unwrap();
    assert_eq!(lf.size(), (LF_REFERENCE_SIZE, LF_REFERENCE_SIZE));
    assert_eq!(lf.channels(), 3);
    let expected = light_field_u8(&U8Image::from_image(&reference)).unwrap();
    assert_eq!(U8Image::from_image(&lf), expected);

    let raw = light_field_raw(&reference).unwrap();
    assert_eq!(raw.size(), reference.size());

    let fed = light_field_for(&reference, 320, 192).unwrap();
    assert_eq!(fed.size(), (320, 192));
    assert!(fed.data().iter().all(|v| (0.0..=1.0).contains(v)));
}

#[test]
fn map_does_not_depend_on_reference_resolution() {
    // The same scene at two resolutions gives nearly the same render-time map.
    let path = workspace_root().join("assets/samples/ref-blue.jpg");
    let reference = load_rgb(&path, &DecodeLimits::default()).unwrap();
    let half = uwnr_core::resize::resize_bilinear(&reference, 200, 150).unwrap();
    let a = light_field_u8(&U8Image::from_image(&reference)).unwrap();
    let b = light_field_u8(&U8Image::from_image(&half)).unwrap();
    let (mad, _) = compare(&a, &b);
    assert!(mad < 2.0, "mean abs diff {mad}");
}

fn uniform_u8(w: usize, h: usize, rgb: [u8; 3]) -> U8Image {
    let data = (0..w * h).flat_map(|_| rgb).collect();
    U8Image::new(w, h, 3, data).unwrap()
}

fn mean_u8(img: &U8Image) -> f64 {
    img.data.iter().map(|&v| f64::from(v)).sum::<f64>() / img.data.len() as f64
}

#[test]
fn absolute_map_of_uniform_images_follows_log10() {
    // A flat image has flat blurs, so every map value is
    // floor(((1 + 3 log10 v) / 3 - 1/3) / (log10 255 + 1e-4 / 1) * 255) with float16 logs.
    let table = log10_u8_values();
    for v in [0_u8, 1, 9, 40, 128, 200, 255] {
        let img = uniform_u8(40, 30, [v, v, v]);
        let map = light_field_raw_u8_with(&img, LightFieldMap::Absolute).unwrap();
        let lum = (1.0 + 3.0 * table[usize::from(v)]) / 3.0;
        let (lo, hi) = (1.0 / 3.0, (1.0 + 3.0 * table[255]) / 3.0);
        let expected = ((lum - lo) / (hi - lo + 1e-4) * 255.0) as u8;
        assert!(
            map.data.iter().all(|&m| m == expected),
            "v = {v}: expected {expected}, got {:?}",
            &map.data[..3]
        );
    }
    // The paper's min-max map of a flat image is all zeros whatever its brightness.
    let paper = light_field_raw_u8(&uniform_u8(40, 30, [200, 200, 200])).unwrap();
    assert!(paper.data.iter().all(|&m| m == 0));
}

#[test]
fn absolute_map_keeps_brightness_the_paper_map_drops() {
    let path = workspace_root().join("assets/samples/ref-green.png");
    let reference = U8Image::from_image(&load_rgb(&path, &DecodeLimits::default()).unwrap());
    // The same scene with a global gain of 0.5: an offset in log space.
    let darker = U8Image::new(
        reference.width,
        reference.height,
        3,
        reference.data.iter().map(|&v| v / 2).collect(),
    )
    .unwrap();
    let paper = (
        light_field_u8(&reference).unwrap(),
        light_field_u8(&darker).unwrap(),
    );
    let (paper_mad, _) = compare(&paper.0, &paper.1);
    let absolute = (
        light_field_u8_with(&reference, LightFieldMap::Absolute).unwrap(),
        light_field_u8_with(&darker, LightFieldMap::Absolute).unwrap(),
    );
    // log10(2) / log10(255) * 255 = 32 code values darker.
    let drop = mean_u8(&absolute.0) - mean_u8(&absolute.1);
    assert!((drop - 32.0).abs() < 4.0, "absolute map dropped by {drop}");
    assert!(paper_mad < 6.0, "paper map moved by {paper_mad}");
    assert_eq!(
        light_field_u8_with(&reference, LightFieldMap::Paper).unwrap(),
        paper.0
    );
}

#[test]
fn map_names_parse() {
    for m in [LightFieldMap::Paper, LightFieldMap::Absolute] {
        assert_eq!(m.name().parse::<LightFieldMap>().unwrap(), m);
        assert_eq!(
            serde_json::to_string(&m).unwrap(),
            format!("\"{}\"", m.name())
        );
    }
    assert!("brightness".parse::<LightFieldMap>().is_err());
}
