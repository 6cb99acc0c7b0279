//! Errors of the enhancement network, its training and its evaluation.

use std::path::PathBuf;

/// What can go wrong building, loading or running Shallow-UWnet.
#[derive(Debug, thiserror::Error)]
pub enum EnhanceError {
    /// The config cannot build a network.
    #[error("invalid Shallow-UWnet config: {0}")]
    InvalidConfig(String),
    /// A tensor the network needs is not in the weights file.
    #[error("{source_name}: missing tensor {key:?} (is this a Shallow-UWnet weights file?)")]
    MissingKey { source_name: String, key: String },
    /// A tensor has the wrong shape.
    #[error("{source_name}: tensor {key:?} has shape {got:?}, the network needs {expected:?}")]
    ShapeMismatch {
        source_name: String,
        key: String,
        expected: Vec<usize>,
        got: Vec<usize>,
    },
    /// The file holds tensors the network does not have.
    #[error("{source_name}: unexpected tensor {key:?} (weights of another network?)")]
    UnexpectedKey { source_name: String, key: String },
    /// Reading or writing weights, or a backend operation, failed.
    #[error(transparent)]
    Model(#[from] uwnr_model::ModelError),
    /// An image operation failed.
    #[error(transparent)]
    Core(#[from] uwnr_core::CoreError),
    /// A training config field has an unusable value.
    #[error("invalid enhancer training config: {field}: {reason}")]
    InvalidTrainConfig { field: &'static str, reason: String },
    /// A training config file could not be read as one.
    #[error("{path:?}: not a valid enhancer training config: {reason}")]
    ConfigFile { path: PathBuf, reason: String },
    /// A pair of images cannot be scored or trained on.
    #[error("{path:?}: {reason}")]
    BadPair { path: PathBuf, reason: String },
    /// Data, run folder, checkpoints, logs and the loop ([`uwnr_run`]).
    #[error(transparent)]
    Run(#[from] uwnr_run::RunError),
    /// VGG19 weights for the perceptual term (uwnr-train's loss).
    #[error(transparent)]
    Train(#[from] uwnr_train::TrainError),
    /// A metric could not be computed.
    #[error(transparent)]
    Metrics(#[from] uwnr_metrics::MetricsError),
}

/// Result with [`EnhanceError`].
pub type Result<T> = std::result::Result<T, EnhanceError>;

impl From<uwnr_run::InvalidSetting> for EnhanceError {
    fn from(e: uwnr_run::InvalidSetting) -> Self {
        Self::InvalidTrainConfig {
            field: e.field,
            reason: e.reason,
        }
    }
}
