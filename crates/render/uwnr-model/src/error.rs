//! Typed errors of uwnr-model: every variant carries the facts (key, shapes, file) a user
//! needs to act on it (the workspace's convention: `uwnr_core::error`).

use std::path::PathBuf;

/// Result with [`ModelError`].
pub type Result<T> = std::result::Result<T, ModelError>;

/// Everything that can go wrong while building, loading, saving or running the generator.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// A [`GeneratorConfig`](crate::GeneratorConfig) field is out of range.
    #[error("invalid generator config: {field} = {value}: {reason}")]
    InvalidConfig {
        field: &'static str,
        value: usize,
        reason: String,
    },
    /// [`RenderOptions`](crate::RenderOptions) are inconsistent.
    #[error("invalid render options: {0}")]
    InvalidOptions(String),
    /// Reading or writing a file failed.
    #[error("{path:?}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The bytes are neither a safetensors file nor a PyTorch checkpoint.
    #[error(
        "{source_name}: not a weights file ({reason}); expected safetensors or a PyTorch .pth/.pk checkpoint"
    )]
    UnknownFormat { source_name: String, reason: String },
    /// A safetensors file could not be parsed or written.
    #[error("{source_name}: safetensors: {reason}")]
    Safetensors { source_name: String, reason: String },
    /// A PyTorch checkpoint could not be read.
    #[error("{source_name}: PyTorch checkpoint: {source}")]
    Checkpoint {
        source_name: String,
        #[source]
        source: uwnr_core::error::Cause,
    },
    /// A tensor the generator needs is absent from the weights.
    #[error("missing tensor {key:?} in the weights")]
    MissingKey { key: String },
    /// The weights hold a tensor the generator does not have (and it is not an unused norm).
    #[error("unexpected tensor {key:?} in the weights (not part of the UWNR generator)")]
    UnexpectedKey { key: String },
    /// A tensor has a different shape from the one the config implies.
    #[error("tensor {key:?} has shape {got:?}, expected {expected:?}")]
    ShapeMismatch {
        key: String,
        expected: Vec<usize>,
        got: Vec<usize>,
    },
    /// A tensor is stored in a dtype we do not read (only floating point is accepted).
    #[error("tensor {key:?} has dtype {dtype}, expected f32, f16, bf16 or f64")]
    UnsupportedDtype { key: String, dtype: String },
    /// A metadata entry of a weights file is malformed.
    #[error("metadata {key:?}: {source}")]
    Metadata {
        key: String,
        #[source]
        source: serde_json::Error,
    },
    /// An input image has the wrong number of channels.
    #[error("{what}: expected {expected} channel(s), got {got}")]
    Channels {
        what: &'static str,
        expected: usize,
        got: usize,
    },
    /// Input images that must share a size do not.
    #[error("{what} is {got:?} (w, h) but the clean image is {expected:?}")]
    ImageSize {
        what: &'static str,
        expected: (usize, usize),
        got: (usize, usize),
    },
    /// The tensor backend failed while reading data back.
    #[error("tensor backend: {0}")]
    Backend(String),
    /// The inference engine rejected the weights or the input.
    #[error("engine: {0}")]
    Engine(#[from] uwnr_engine::EngineError),
    /// An error from uwnr-core (image handling).
    #[error(transparent)]
    Core(#[from] uwnr_core::CoreError),
}
