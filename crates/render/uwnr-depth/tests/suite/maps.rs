//! Depth maps from files: decoding (8-bit /255, 16-bit /65535), resizing to the clean image,
//! normalisation, inversion and matching by file stem.

use std::path::Path;

use uwnr_core::Image;
use uwnr_core::io::save_gray;
use uwnr_depth::{DepthError, DepthSource};

/// Writes a 16-bit grey PNG.
fn save_gray16(path: &Path, width: u32, height: u32, data: Vec<u16>) {
    image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_raw(width, height, data)
        .unwrap()
        .save(path)
        .unwrap();
}

/// An 8-bit-exact grey map: value `(x + 10 * y) / 255`.
fn grey_map(width: usize, height: usize) -> Image {
    let data = (0..height)
        .flat_map(|y| (0..width).map(move |x| (x + 10 * y) as f32 / 255.0))
        .collect();
    Image::from_planar(width, height, 1, data).unwrap()
}

fn maps(path: &Path, invert: bool, normalize: bool) -> DepthSource {
    DepthSource::Maps {
        path: path.to_path_buf(),
        invert,
        normalize,
        unit: uwnr_depth::DepthUnit::Relative,
    }
}

#[test]
fn single_8bit_map_is_code_over_255() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("d.png");
    let map = grey_map(6, 4);
    save_gray(&path, &map).unwrap();
    let clean = Image::filled(6, 4, 3, 0.5);
    let depth = maps(&path, false, false)
        .prepare()
        .unwrap()
        .depth_for(&clean, None)
        .unwrap();
    assert!(depth.notes.is_empty(), "{:?}", depth.notes);
    for (a, b) in depth.map.data().iter().zip(map.data()) {
        assert!((a - b).abs() < 1e-6);
    }
    // Invert gives 1 - d.
    let inverted = maps(&path, true, false)
        .prepare()
        .unwrap()
        .depth_for(&clean, None)
        .unwrap();
    for (a, b) in inverted.map.data().iter().zip(map.data()) {
        assert!((a - (1.0 - b)).abs() < 1e-6);
    }
}

#[test]
fn map_of_another_size_is_resized_with_a_note() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("d.png");
    save_gray(&path, &Image::filled(8, 6, 1, 0.4)).unwrap();
    let clean = Image::filled(5, 3, 3, 0.5);
    let depth = maps(&path, false, false)
        .prepare()
        .unwrap()
        .depth_for(&clean, None)
        .unwrap();
    assert_eq!(depth.map.size(), (5, 3));
    assert_eq!(depth.map.channels(), 1);
    // 0.4 * 255 = 102 exactly, and a constant survives the resize.
    assert!(
        depth
            .map
            .data()
            .iter()
            .all(|&v| (v - 102.0 / 255.0).abs() < 1e-6)
    );
    assert_eq!(depth.notes.len(), 1);
    assert!(
        depth.notes[0].contains("8x6 resized to 5x3"),
        "{:?}",
        depth.notes
    );
}

#[test]
fn metric_16bit_map_normalised() {
    // NYU-style millimetres: 500 mm .. 4500 mm.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("depth.png");
    let mm: Vec<u16> = vec![500, 1500, 2500, 4500];
    save_gray16(&path, 2, 2, mm);
    let clean = Image::filled(2, 2, 3, 0.5);

    let raw = maps(&path, false, false)
        .prepare()
        .unwrap()
        .depth_for(&clean, None)
        .unwrap();
    assert!((raw.map.data()[3] - 4500.0 / 65535.0).abs() < 1e-6);

    let norm = maps(&path, false, true)
        .prepare()
        .unwrap()
        .depth_for(&clean, None)
        .unwrap();
    let want = [0.0, 0.25, 0.5, 1.0];
    for (a, b) in norm.map.data().iter().zip(want) {
        assert!((a - b).abs() < 1e-5, "{a} vs {b}");
    }
    assert!(
        norm.notes.iter().any(|n| n.contains("normalised")),
        "{:?}",
        norm.notes
    );

    // Normalise, then invert.
    let both = maps(&path, true, true)
        .prepare()
        .unwrap()
        .depth_for(&clean, None)
        .unwrap();
    for (a, b) in both.map.data().iter().zip(want) {
        assert!((a - (1.0 - b)).abs() < 1e-5);
    }
}

#[test]
fn directory_is_matched_by_stem_with_any_extension() {
    let dir = tempfile::tempdir().unwrap();
    save_gray(&dir.path().join("a.png"), &Image::filled(4, 4, 1, 0.2)).unwrap();
    save_gray(&dir.path().join("b.png"), &Image::filled(4, 4, 1, 0.8)).unwrap();
    std::fs::write(dir.path().join("a.txt"), "not an image").unwrap();
    let prepared = maps(dir.path(), false, false).prepare().unwrap();
    let clean = Image::filled(4, 4, 3, 0.5);
    for (name, want) in [("a.jpg", 51.0 / 255.0), ("b.png", 204.0 / 255.0)] {
        let clean_path = Path::new("photos").join(name);
        let depth = prepared.depth_for(&clean, Some(&clean_path)).unwrap();
        assert!((depth.map.data()[0] - want).abs() < 1e-6, "{name}");
    }
}

#[test]
fn missing_partner_names_both_paths() {
    let dir = tempfile::tempdir().unwrap();
    save_gray(&dir.path().join("a.png"), &Image::filled(4, 4, 1, 0.2)).unwrap();
    let prepared = maps(dir.path(), false, false).prepare().unwrap();
    let clean = Image::filled(4, 4, 3, 0.5);
    let err = prepared
        .depth_for(&clean, Some(Path::new("photos/zebra.jpg")))
        .unwrap_err();
    assert!(matches!(err, DepthError::MissingMap { .. }), "{err}");
    let msg = err.to_string();
    assert!(msg.contains("photos/zebra.jpg"), "{msg}");
    assert!(msg.contains(&dir.path().display().to_string()), "{msg}");
    assert!(msg.contains("\"zebra\""), "{msg}");
}

#[test]
fn directory_needs_the_clean_path() {
    let dir = tempfile::tempdir().unwrap();
    let prepared = maps(dir.path(), false, false).prepare().unwrap();
    let err = prepared
        .depth_for(&Image::filled(4, 4, 3, 0.5), None)
        .unwrap_err();
    assert!(matches!(err, DepthError::NeedsCleanPath { .. }), "{err}");
}

#[test]
fn two_maps_with_one_stem_are_ambiguous() {
    let dir = tempfile::tempdir().unwrap();
    save_gray(&dir.path().join("a.png"), &Image::filled(4, 4, 1, 0.2)).unwrap();
    save_gray(&dir.path().join("a.jpg"), &Image::filled(4, 4, 1, 0.2)).unwrap();
    let prepared = maps(dir.path(), false, false).prepare().unwrap();
    let err = prepared
        .depth_for(&Image::filled(4, 4, 3, 0.5), Some(Path::new("a.png")))
        .unwrap_err();
    assert!(matches!(err, DepthError::AmbiguousMap { .. }), "{err}");
}

#[test]
fn missing_maps_path_fails_at_prepare() {
    let dir = tempfile::tempdir().unwrap();
    let err = maps(&dir.path().join("nothing"), false, false)
        .prepare()
        .unwrap_err();
    assert!(matches!(err, DepthError::MapsNotFound { .. }), "{err}");
}

#[test]
fn undecodable_map_is_a_core_error_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.png");
    std::fs::write(&path, b"not a png").unwrap();
    let err = maps(&path, false, false).prepare().unwrap_err();
    assert!(matches!(err, DepthError::Core(_)), "{err}");
    assert!(err.to_string().contains("broken.png"), "{err}");
}

#[test]
fn serde_round_trip_and_defaults() {
    let source: DepthSource = serde_json::from_str(r#"{"type": "Maps", "path": "d"}"#).unwrap();
    assert_eq!(source, maps(Path::new("d"), false, false));
    let builtin: DepthSource = serde_json::from_str(r#"{"type": "Builtin"}"#).unwrap();
    assert_eq!(builtin, DepthSource::default());
    let onnx = DepthSource::Onnx {
        model: "m.onnx".into(),
        invert: true,
        input_size: Some((518, 518)),
    };
    let json = serde_json::to_string(&onnx).unwrap();
    assert_eq!(serde_json::from_str::<DepthSource>(&json).unwrap(), onnx);
    assert!(serde_json::from_str::<DepthSource>(r#"{"type": "Midas"}"#).is_err());
}
