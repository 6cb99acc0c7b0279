//! Shared helpers of the integration tests: fixture paths and 8-bit PNG loading.

use std::path::PathBuf;

use uwnr_core::Image;

/// `tests/fixtures/<name>` of this crate.
pub fn fixture(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests")
        .join("fixtures")
        .join(name)
}

/// Reads a fixture JSON file.
pub fn json(name: &str) -> serde_json::Value {
    let text = std::fs::read_to_string(fixture(name)).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// An 8-bit RGB PNG as u8 / 255 in f32, the way uwnr's decoder and the reference script read it.
pub fn load_png(name: &str) -> Image {
    let rgb = image::open(fixture(name)).unwrap().to_rgb8();
    let (w, h) = rgb.dimensions();
    let hwc: Vec<f32> = rgb.as_raw().iter().map(|&v| f32::from(v) / 255.0).collect();
    Image::from_interleaved(w as usize, h as usize, 3, &hwc).unwrap()
}

/// `|got - want| <= tol * max(1, |want|)`, with a message naming the quantity.
pub fn assert_close(what: &str, got: f64, want: f64, tol: f64) {
    let err = (got - want).abs();
    assert!(
        err <= tol * want.abs().max(1.0),
        "{what}: got {got}, want {want} (error {err:e}, tolerance {tol:e})"
    );
}

/// Largest error seen per quantity (relative, absolute below 1, as [`assert_close`] measures),
/// printed with `--nocapture` to report agreement.
#[derive(Default)]
pub struct Agreement(std::collections::BTreeMap<String, f64>);

impl Agreement {
    /// Checks `got` against `want` like [`assert_close`] and records the relative error.
    pub fn check(&mut self, key: &str, what: &str, got: f64, want: f64, tol: f64) {
        assert_close(what, got, want, tol);
        let rel = (got - want).abs() / want.abs().max(1.0);
        let e = self.0.entry(key.to_string()).or_insert(0.0);
        *e = e.max(rel);
    }

    /// Prints one line per quantity.
    pub fn report(&self, title: &str) {
        for (k, v) in &self.0 {
            println!("{title}: {k} max error {v:.2e} (relative; absolute below 1)");
        }
    }
}
