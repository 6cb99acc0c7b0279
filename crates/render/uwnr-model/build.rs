//! Embeds the default model when it is in the source tree and the `bundled-model` feature is on:
//! sets `cfg(uwnr_bundled_model)` and `UWNR_BUNDLED_MODEL` (the file's path) for
//! `bundled::bundled_model_bytes`.

use std::path::PathBuf;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(uwnr_bundled_model)");
    let dir = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default())
        .join("../../../assets/model");
    let model = dir.join("uwnr-default.json");
    // The folder, so that adding the file later triggers a rebuild; the file, for its changes.
    println!("cargo::rerun-if-changed={}", dir.display());
    println!("cargo::rerun-if-changed={}", model.display());
    if std::env::var_os("CARGO_FEATURE_BUNDLED_MODEL").is_some() && model.is_file() {
        println!("cargo::rustc-cfg=uwnr_bundled_model");
        println!("cargo::rustc-env=UWNR_BUNDLED_MODEL={}", model.display());
    }
}
