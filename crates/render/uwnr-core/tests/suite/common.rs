//! Helpers shared by the integration tests.

use std::path::{Path, PathBuf};

use uwnr_core::resize::U8Image;

/// `crates/render/uwnr-core/tests/fixtures`.
pub fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("fixtures")
}

/// The workspace root (manifests list sources relative to it).
pub fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../..")
}

/// Reads an 8-bit RGB PNG fixture as interleaved u8.
pub fn read_rgb8(path: &Path) -> U8Image {
    let img = image::open(path)
        .unwrap_or_else(|e| panic!("{path:?}: {e}"))
        .to_rgb8();
    let (w, h) = img.dimensions();
    U8Image::new(w as usize, h as usize, 3, img.into_raw()).unwrap()
}

/// Reads a JSON manifest.
pub fn read_json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path:?}: {e}"));
    serde_json::from_str(&text).unwrap()
}

/// (mean absolute difference, max absolute difference) in u8 code values.
pub fn compare(a: &U8Image, b: &U8Image) -> (f64, u8) {
    assert_eq!(
        (a.width, a.height, a.channels),
        (b.width, b.height, b.channels)
    );
    let mut sum = 0_u64;
    let mut max = 0_u8;
    for (&x, &y) in a.data.iter().zip(&b.data) {
        let d = x.abs_diff(y);
        sum += u64::from(d);
        max = max.max(d);
    }
    (sum as f64 / a.data.len() as f64, max)
}
