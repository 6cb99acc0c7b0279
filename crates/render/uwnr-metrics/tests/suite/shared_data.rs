//! Sanity checks on real underwater photos from `../shared/data` (listed as ignored by the test
//! runner when the folder is absent, as in a fresh clone: the build script looks for it): on EUVP "underwater_dark" pairs the enhanced
//! images score higher UIQM and UCIQE than the raw ones on average, and FD-ct separates raw
//! from enhanced photos far more than it separates two halves of the raw set.

use std::path::{Path, PathBuf};

use uwnr_core::Image;
use uwnr_metrics::{
    ColorTextureFeatures, FeatureExtractor, extract_all, frechet_distance, uciqe, uiqm,
};

/// Pairs used; EUVP images are 256x256, so this stays well under a second per metric.
const PAIRS: usize = 40;

/// The EUVP pairs; the test only runs when the build found `../shared/data`, so a missing
/// subfolder is a failure, not a skip.
fn data_dir() -> PathBuf {
    let dir =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../../shared/data/paired/euvp-dark");
    assert!(
        dir.join("underwater").is_dir() && dir.join("clean").is_dir(),
        "{} not found",
        dir.display()
    );
    dir
}

fn load(path: &Path) -> Image {
    let rgb = image::open(path).unwrap().to_rgb8();
    let (w, h) = rgb.dimensions();
    let hwc: Vec<f32> = rgb.as_raw().iter().map(|&v| f32::from(v) / 255.0).collect();
    Image::from_interleaved(w as usize, h as usize, 3, &hwc).unwrap()
}

fn pairs(dir: &Path) -> (Vec<Image>, Vec<Image>) {
    let mut names: Vec<_> = std::fs::read_dir(dir.join("underwater"))
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .filter(|n| dir.join("clean").join(n).is_file())
        .collect();
    names.sort();
    // Every 50th pair spreads the sample over the set.
    let chosen: Vec<_> = names.iter().step_by(50).take(PAIRS).collect();
    let raw = chosen
        .iter()
        .map(|n| load(&dir.join("underwater").join(n)))
        .collect();
    let clean = chosen
        .iter()
        .map(|n| load(&dir.join("clean").join(n)))
        .collect();
    (raw, clean)
}

fn mean(v: impl Iterator<Item = f64>) -> f64 {
    let all: Vec<f64> = v.collect();
    all.iter().sum::<f64>() / all.len() as f64
}

#[test]
#[cfg_attr(
    not(shared_data),
    ignore = "needs ../shared/data (absent when this crate was built)"
)]
fn enhanced_photos_score_higher_and_fd_ct_separates_the_sets() {
    let dir = data_dir();
    let (raw, clean) = pairs(&dir);
    assert_eq!(raw.len(), PAIRS);

    let uiqm_raw = mean(raw.iter().map(|i| uiqm(i).unwrap()));
    let uiqm_clean = mean(clean.iter().map(|i| uiqm(i).unwrap()));
    let uciqe_raw = mean(raw.iter().map(|i| uciqe(i).unwrap()));
    let uciqe_clean = mean(clean.iter().map(|i| uciqe(i).unwrap()));
    println!(
        "EUVP-dark, {PAIRS} pairs: UIQM raw {uiqm_raw:.3} enhanced {uiqm_clean:.3}; UCIQE raw {uciqe_raw:.3} enhanced {uciqe_clean:.3}"
    );
    assert!(uiqm_clean > uiqm_raw);
    assert!(uciqe_clean > uciqe_raw);

    let fx = ColorTextureFeatures::new();
    let f_raw = extract_all(&fx, &raw).unwrap();
    let f_clean = extract_all(&fx, &clean).unwrap();
    let half = PAIRS / 2;
    let between = frechet_distance(&f_raw, &f_clean).unwrap();
    let within = frechet_distance(&f_raw[..half], &f_raw[half..]).unwrap();
    println!(
        "FD-ct raw vs enhanced {between:.4}, raw half vs half {within:.4} (d = {})",
        fx.dim()
    );
    assert!(between.is_finite() && within.is_finite());
    assert!(between > within, "{between} vs {within}");
}
