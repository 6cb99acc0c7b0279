//! Sets `cfg(shared_data)` when the optional development data folder `../shared/data` (beside
//! the workspace) exists, so the tests that need it are listed as ignored, not silently passed,
//! where it is absent. The folder is looked for when the build script runs (a fresh build, or a
//! change to this file): one that appears later needs `touch build.rs` here. Watching the folder
//! itself would rebuild the crate on every build where it is absent.

use std::path::Path;

fn main() {
    println!("cargo::rustc-check-cfg=cfg(shared_data)");
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../../shared/data");
    println!("cargo::rerun-if-changed=build.rs");
    if dir.is_dir() {
        println!("cargo::rustc-cfg=shared_data");
    }
}
