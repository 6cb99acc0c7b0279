//! Errors of training the GAN baseline: its configs, data, the loop, and everything loading
//! and rendering can report (`uwnr_gan::GanError`).

use std::path::PathBuf;

/// What can go wrong building, training, saving or loading the GAN baseline.
#[derive(Debug, thiserror::Error)]
pub enum GanError {
    /// A model config cannot build a network.
    #[error("invalid GAN model config: {field}: {reason}")]
    InvalidConfig { field: &'static str, reason: String },
    /// A training config field has an unusable value.
    #[error("invalid GAN training config: {field}: {reason}")]
    InvalidTrainConfig { field: &'static str, reason: String },
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
    /// A backend operation (reading a tensor back) failed.
    #[error("backend: {0}")]
    Backend(String),
    /// An image operation failed.
    #[error(transparent)]
    Core(#[from] uwnr_core::CoreError),
    /// A depth map could not be made.
    #[error(transparent)]
    Depth(#[from] uwnr_depth::DepthError),
    /// A metric could not be computed.
    #[error(transparent)]
    Metrics(#[from] uwnr_metrics::MetricsError),
    /// Data, run folder, checkpoints, logs and the loop ([`uwnr_run`]).
    #[error(transparent)]
    Run(#[from] uwnr_run::RunError),
}

impl From<uwnr_gan::GanError> for GanError {
    fn from(e: uwnr_gan::GanError) -> Self {
        use uwnr_gan::GanError as E;
        match e {
            E::InvalidConfig { field, reason } => Self::InvalidConfig { field, reason },
            E::ShapeMismatch {
                what,
                expected,
                got,
            } => Self::ShapeMismatch {
                what,
                expected,
                got,
            },
            E::Weights { path, reason } => Self::Weights { path, reason },
            E::Core(e) => Self::Core(e),
        }
    }
}

impl From<uwnr_run::InvalidSetting> for GanError {
    fn from(e: uwnr_run::InvalidSetting) -> Self {
        Self::InvalidTrainConfig {
            field: e.field,
            reason: e.reason,
        }
    }
}

/// Result with [`GanError`].
pub type Result<T> = std::result::Result<T, GanError>;

/// Reads a tensor back to the host as f32 values.
pub(crate) fn to_vec<const D: usize>(t: burn::tensor::Tensor<D>) -> Result<Vec<f32>> {
    t.into_data()
        .try_into_vec::<f32>()
        .map_err(|e| GanError::Backend(format!("reading a tensor: {e:?}")))
}
