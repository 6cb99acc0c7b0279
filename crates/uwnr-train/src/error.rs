//! Typed errors of uwnr-train.

use std::path::PathBuf;

/// Result with [`TrainError`].
pub type Result<T> = std::result::Result<T, TrainError>;

/// Everything that can go wrong while preparing or running training.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    /// A figure (curves, contact sheet) could not be drawn.
    #[error("drawing a figure: {0}")]
    Figure(String),
    /// A config field has an unusable value.
    #[error("invalid config: {field}: {reason}")]
    InvalidConfig { field: &'static str, reason: String },
    /// A config file could not be parsed.
    #[error("{path:?}: not a valid training config: {reason}")]
    Config { path: PathBuf, reason: String },
    /// `--resume` was given a config that differs from the run's own.
    #[error(
        "{path:?}: the run was started with another config (a resumed run keeps its config.json)"
    )]
    ConfigChanged { path: PathBuf },
    /// Reading or writing a file failed.
    #[error("{path:?}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A data folder does not have the paired layout.
    #[error(
        "{dir:?}: no paired folders: expected `underwater/` + `clean/` (or UIEB's `raw-890/` + `reference-890/`)"
    )]
    NotAPairedFolder { dir: PathBuf },
    /// A data folder holds no usable pairs.
    #[error("{dir:?}: no usable image pairs ({reason})")]
    NoPairs { dir: PathBuf, reason: String },
    /// No training data at all.
    #[error("no training pairs: {0}")]
    NoData(String),
    /// An image or depth map could not be used.
    #[error("{path:?}: {reason}")]
    BadImage { path: PathBuf, reason: String },
    /// A VGG19 weights file is unusable.
    #[error("{path:?}: VGG19 weights: {reason}")]
    Vgg { path: PathBuf, reason: String },
    /// A checkpoint is missing, unreadable or from another run.
    #[error("{path:?}: checkpoint: {reason}")]
    Checkpoint { path: PathBuf, reason: String },
    /// The run folder already holds a run and `--resume` was not asked for.
    #[error(
        "{dir:?} already holds a training run (pass --resume to continue it, or choose another run folder)"
    )]
    RunExists { dir: PathBuf },
    /// The loss became NaN or infinite.
    #[error("loss is not finite at step {step}: {terms}")]
    NonFiniteLoss { step: usize, terms: String },
    /// The data loader thread stopped.
    #[error("data loader: {0}")]
    Loader(String),
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
