//! ONNX depth source against tiny models with a known function, written by
//! `tools/make_tiny_depth_onnx.py`: `disparity = sigmoid(sum_c W[c] * x[c] + B)` on the
//! ImageNet-normalised input. The expected maps are recomputed here in Rust.

use std::path::PathBuf;

use uwnr_core::Image;
use uwnr_core::resize::resize_bilinear;
use uwnr_depth::onnx::default_input_size;
use uwnr_depth::{DepthError, DepthSource};

/// Must match `W` and `B` in tools/make_tiny_depth_onnx.py.
const W: [f32; 3] = [0.8, -0.5, 0.3];
const B: f32 = 0.1;
/// ImageNet statistics as MiDaS / DPT / Depth Anything normalise their input (repeated here
/// so an accidental edit of the library's constants fails the tests).
const IMAGENET_MEAN: [f32; 3] = [0.485, 0.456, 0.406];
const IMAGENET_STD: [f32; 3] = [0.229, 0.224, 0.225];
/// Input size of tiny_fixed.onnx (width, height).
const FIXED_SIZE: (usize, usize) = (12, 8);
/// Agreement between tract and the Rust re-computation (f32 arithmetic in both).
const TOL: f32 = 1e-4;

fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("fixtures")
        .join(name)
}

/// A deterministic colourful test image whose channels vary differently along x and y.
fn test_image(width: usize, height: usize) -> Image {
    let mut data = Vec::with_capacity(3 * width * height);
    for c in 0..3 {
        for y in 0..height {
            for x in 0..width {
                let (fx, fy) = (x as f32 / width as f32, y as f32 / height as f32);
                let v = match c {
                    0 => 0.5 + 0.45 * (6.0 * fx + 2.0 * fy).sin(),
                    1 => fy * fy,
                    _ => 0.5 + 0.4 * (5.0 * fy - 3.0 * fx).cos(),
                };
                data.push(v);
            }
        }
    }
    Image::from_planar(width, height, 3, data).unwrap()
}

/// The map uwnr should produce, recomputed: resize, normalise, the tiny model's function,
/// resize back, min-max, `1 - n` (or `n` when `invert`).
fn expected(clean: &Image, input: (usize, usize), invert: bool) -> Vec<f32> {
    let x = resize_bilinear(clean, input.0, input.1).unwrap();
    let n = input.0 * input.1;
    let disparity: Vec<f32> = (0..n)
        .map(|i| {
            let lin: f32 = (0..3)
                .map(|c| W[c] * (x.plane(c)[i] - IMAGENET_MEAN[c]) / IMAGENET_STD[c])
                .sum::<f32>()
                + B;
            1.0 / (1.0 + (-lin).exp())
        })
        .collect();
    let disparity = Image::from_planar(input.0, input.1, 1, disparity).unwrap();
    let mut out = resize_bilinear(&disparity, clean.width(), clean.height())
        .unwrap()
        .into_data();
    let lo = out.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = out.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    for v in &mut out {
        let norm = (*v - lo) / (hi - lo);
        *v = if invert { norm } else { 1.0 - norm };
    }
    out
}

fn assert_close(got: &[f32], want: &[f32]) {
    assert_eq!(got.len(), want.len());
    let worst = got
        .iter()
        .zip(want)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0_f32, f32::max);
    assert!(worst < TOL, "max abs difference {worst}");
}

fn onnx(model: &str, invert: bool, input_size: Option<(usize, usize)>) -> DepthSource {
    DepthSource::Onnx {
        model: fixture(model),
        invert,
        input_size,
    }
}

#[test]
fn fixed_model_at_its_own_size_matches_the_recomputation() {
    let clean = test_image(FIXED_SIZE.0, FIXED_SIZE.1);
    let depth = onnx("tiny_fixed.onnx", false, None)
        .prepare()
        .unwrap()
        .depth_for(&clean, None)
        .unwrap();
    assert_eq!(depth.map.size(), clean.size());
    assert_eq!(depth.map.channels(), 1);
    assert_close(depth.map.data(), &expected(&clean, FIXED_SIZE, false));
    // The map spans [0, 1] exactly (up to rounding).
    let data = depth.map.data();
    let lo = data.iter().copied().fold(f32::INFINITY, f32::min);
    let hi = data.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    assert!(
        lo.abs() < 1e-6 && (hi - 1.0).abs() < 1e-6,
        "range [{lo}, {hi}]"
    );
}

#[test]
fn fixed_model_resizes_other_images_and_ignores_input_size() {
    let clean = test_image(50, 31);
    let prepared = onnx("tiny_fixed.onnx", true, Some((64, 64)))
        .prepare()
        .unwrap();
    let depth = prepared.depth_for(&clean, None).unwrap();
    assert_eq!(depth.map.size(), (50, 31));
    assert_close(depth.map.data(), &expected(&clean, FIXED_SIZE, true));
    assert!(
        depth.notes.iter().any(|n| n.contains("ran at 12x8")),
        "{:?}",
        depth.notes
    );
    assert!(
        depth.notes.iter().any(|n| n.contains("64x64 ignored")),
        "{:?}",
        depth.notes
    );
}

#[test]
fn dynamic_model_with_input_size() {
    let clean = test_image(40, 30);
    let depth = onnx("tiny_dynamic.onnx", false, Some((24, 16)))
        .prepare()
        .unwrap()
        .depth_for(&clean, None)
        .unwrap();
    assert_close(depth.map.data(), &expected(&clean, (24, 16), false));
}

#[test]
fn dynamic_model_default_size_follows_each_image() {
    let prepared = onnx("tiny_dynamic.onnx", false, None).prepare().unwrap();
    // Two aspect ratios through the same prepared plan.
    for (w, h) in [(45, 30), (30, 60)] {
        let clean = test_image(w, h);
        let input = default_input_size(w, h);
        let depth = prepared.depth_for(&clean, None).unwrap();
        assert_close(depth.map.data(), &expected(&clean, input, false));
        let note = format!("ran at {}x{}", input.0, input.1);
        assert!(
            depth.notes.iter().any(|n| n.contains(&note)),
            "{:?}",
            depth.notes
        );
    }
}

#[test]
fn invert_flips_the_map() {
    let clean = test_image(20, 14);
    let plain = onnx("tiny_dynamic.onnx", false, Some((20, 14)))
        .prepare()
        .unwrap()
        .depth_for(&clean, None)
        .unwrap();
    let inverted = onnx("tiny_dynamic.onnx", true, Some((20, 14)))
        .prepare()
        .unwrap()
        .depth_for(&clean, None)
        .unwrap();
    for (a, b) in plain.map.data().iter().zip(inverted.map.data()) {
        assert!((a + b - 1.0).abs() < 1e-6);
    }
}

#[test]
fn grey_images_are_replicated_to_rgb() {
    let rgb = test_image(16, 12);
    let grey = Image::from_planar(16, 12, 1, rgb.plane(0).to_vec()).unwrap();
    let replicated = Image::concat_channels(&[&grey, &grey, &grey]).unwrap();
    let prepared = onnx("tiny_dynamic.onnx", false, Some((16, 12)))
        .prepare()
        .unwrap();
    let a = prepared.depth_for(&grey, None).unwrap();
    let b = prepared.depth_for(&replicated, None).unwrap();
    assert_eq!(a.map, b.map);
}

#[test]
fn prepared_model_is_shared_across_threads() {
    let prepared = onnx("tiny_dynamic.onnx", false, Some((16, 16)))
        .prepare()
        .unwrap();
    let clean = test_image(33, 21);
    let want = expected(&clean, (16, 16), false);
    std::thread::scope(|s| {
        for _ in 0..3 {
            s.spawn(|| {
                let depth = prepared.depth_for(&clean, None).unwrap();
                assert_close(depth.map.data(), &want);
            });
        }
    });
}

#[test]
fn three_channel_output_is_rejected_at_prepare() {
    let err = onnx("tiny_bad_output.onnx", false, None)
        .prepare()
        .unwrap_err();
    assert!(
        matches!(err, DepthError::UnexpectedOutputShape { .. }),
        "{err}"
    );
    assert!(err.to_string().contains("[1, H, W]"), "{err}");
    assert!(err.to_string().contains("has shape [1, 3, "), "{err}");
}

#[test]
fn missing_model_is_a_clear_error() {
    let err = onnx("no_such_model.onnx", false, None)
        .prepare()
        .unwrap_err();
    assert!(matches!(err, DepthError::ModelNotFound { .. }), "{err}");
    assert!(err.to_string().contains("no_such_model.onnx"), "{err}");
}

#[test]
fn invalid_model_file_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("garbage.onnx");
    std::fs::write(&path, b"this is not a protobuf model").unwrap();
    let err = DepthSource::Onnx {
        model: path,
        invert: false,
        input_size: None,
    }
    .prepare()
    .unwrap_err();
    assert!(matches!(err, DepthError::ModelLoad { .. }), "{err}");
    assert!(err.to_string().contains("garbage.onnx"), "{err}");
}

#[test]
fn zero_input_size_is_rejected() {
    let err = onnx("tiny_dynamic.onnx", false, Some((0, 10)))
        .prepare()
        .unwrap_err();
    assert!(matches!(err, DepthError::InvalidInputSize { .. }), "{err}");
}
