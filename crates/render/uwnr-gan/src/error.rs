//! Errors of the GAN baseline's rendering: its config, weights and inputs.

use std::path::PathBuf;

/// What can go wrong loading or running the GAN baseline's generator.
#[derive(Debug, thiserror::Error)]
pub enum GanError {
    /// A model config cannot build a network.
    #[error("invalid GAN model config: {field}: {reason}")]
    InvalidConfig { field: &'static str, reason: String },
    /// Two inputs that must agree do not.
    #[error("{what}: expected {expected:?}, got {got:?}")]
    ShapeMismatch {
        what: &'static str,
        expected: Vec<usize>,
        got: Vec<usize>,
    },
    /// A weights file could not be written or read as the generator's.
    #[error("{path:?}: {reason}")]
    Weights { path: PathBuf, reason: String },
    /// An image operation failed.
    #[error(transparent)]
    Core(#[from] uwnr_core::CoreError),
}

/// Result with [`GanError`].
pub type Result<T> = std::result::Result<T, GanError>;
