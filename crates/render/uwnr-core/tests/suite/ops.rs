//! The ports of PIL's and OpenCV's 8-bit resizes and OpenCV's Gaussian blur against the values
//! the real libraries produce (fixtures from `tools/lightfield_reference.py`). All must match
//! bit for bit.

use crate::common;

use common::{compare, fixtures, read_json, read_rgb8, workspace_root};
use uwnr_core::gaussian::cv_gaussian_blur_u8;
use uwnr_core::resize::{cv_resize_linear_scale_u8, cv_resize_linear_u8, pil_resize_bilinear_u8};

#[test]
fn ports_match_pil_and_opencv_exactly() {
    let dir = fixtures().join("ops");
    let manifest = read_json(&dir.join("manifest.json"));
    let cases = manifest["cases"].as_array().unwrap();
    assert!(cases.len() >= 15, "too few cases: {}", cases.len());
    let mut failures = Vec::new();
    for case in cases {
        let input_name = case["input"].as_str().unwrap();
        let input_path = if input_name.contains('/') {
            workspace_root().join(input_name)
        } else {
            dir.join(input_name)
        };
        let input = read_rgb8(&input_path);
        let expected = read_rgb8(&dir.join(case["expected"].as_str().unwrap()));
        let p = &case["params"];
        let size = |k: &str| p[k].as_u64().unwrap() as usize;
        let got = match case["op"].as_str().unwrap() {
            "pil_bilinear" => pil_resize_bilinear_u8(&input, size("width"), size("height")),
            "cv_linear" => cv_resize_linear_u8(&input, size("width"), size("height")),
            "cv_linear_scale" => cv_resize_linear_scale_u8(
                &input,
                p["fx"].as_f64().unwrap(),
                p["fy"].as_f64().unwrap(),
            ),
            "cv_gaussian" => cv_gaussian_blur_u8(&input, p["sigma"].as_f64().unwrap()),
            other => panic!("unknown op {other}"),
        }
        .unwrap();
        if (got.width, got.height) != (expected.width, expected.height) {
            failures.push(format!(
                "{}: size {}x{}, expected {}x{}",
                case["expected"], got.width, got.height, expected.width, expected.height
            ));
            continue;
        }
        let (mad, max) = compare(&got, &expected);
        println!("{}: mean abs diff {mad:.5}, max {max}", case["expected"]);
        if max != 0 {
            failures.push(format!(
                "{}: mean abs diff {mad}, max {max}",
                case["expected"]
            ));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}
