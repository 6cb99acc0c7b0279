//! The default model shipped inside uwnr's binaries: `assets/model/uwnr-default.safetensors`,
//! embedded at build time when it exists and the `bundled-model` feature is on (see `build.rs`).
//! The command-line tool and the Python package both take it from here, so they render with the
//! same weights.

/// How the bundled weights are named in messages and dataset settings.
pub const BUNDLED_MODEL_NAME: &str = "bundled model";

/// The bundled weights (safetensors bytes), or `None` in a build without them.
#[must_use]
pub fn bundled_weights() -> Option<&'static [u8]> {
    #[cfg(uwnr_bundled_model)]
    {
        Some(include_bytes!(env!("UWNR_BUNDLED_MODEL")))
    }
    #[cfg(not(uwnr_bundled_model))]
    {
        None
    }
}
