//! Typed errors of uwnr-train.

use std::path::PathBuf;

/// Result with [`TrainError`].
pub type Result<T> = std::result::Result<T, TrainError>;

/// Everything that can go wrong while preparing or running training.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// A config field has an unusable value.
    #[error("invalid config: {field}: {reason}")]
    InvalidConfig { field: &'static str, reason: String },
    /// A config file could not be parsed.
    #[error("{path:?}: not a valid training config: {reason}")]
    Config { path: PathBuf, reason: String },
    /// Reading or writing a file failed.
    #[error("{path:?}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// An image or depth map could not be used.
    #[error("{path:?}: {reason}")]
    BadImage { path: PathBuf, reason: String },
    /// A VGG19 weights file is unusable.
    #[error("{path:?}: VGG19 weights: {reason}")]
    Vgg { path: PathBuf, reason: String },
    /// Data, run folder, checkpoints, logs and the loop ([`uwnr_run`]).
    #[error(transparent)]
    Run(#[from] uwnr_run::RunError),
    /// An error from the image core.
    #[error(transparent)]
    Core(#[from] uwnr_core::CoreError),
    /// An error from the model crate.
    #[error(transparent)]
    Model(#[from] uwnr_model::ModelError),
    /// An error from a depth source.
    #[error(transparent)]
    Depth(#[from] uwnr_depth::DepthError),
}

impl From<uwnr_run::InvalidSetting> for TrainError {
    fn from(e: uwnr_run::InvalidSetting) -> Self {
        Self::InvalidConfig {
            field: e.field,
            reason: e.reason,
        }
    }
}
