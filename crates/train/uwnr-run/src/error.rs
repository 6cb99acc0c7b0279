//! Typed errors of the run machinery. A task's own error type takes them through `From`.

use std::path::PathBuf;

/// Result with [`RunError`].
pub type Result<T> = std::result::Result<T, RunError>;

/// What can go wrong finding data, keeping a run folder or running the loop.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
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
    /// An image could not be used.
    #[error("{path:?}: {reason}")]
    BadImage { path: PathBuf, reason: String },
    /// A run's config file could not be read as one.
    #[error("{path:?}: not a valid training config: {reason}")]
    ConfigFile { path: PathBuf, reason: String },
    /// `--resume` was given a config that differs from the run's own.
    #[error(
        "{path:?}: the run was started with another config ({} differ{}); a resumed run keeps its config.json",
        fields.join(", "),
        if fields.len() == 1 { "s" } else { "" }
    )]
    ConfigChanged { path: PathBuf, fields: Vec<String> },
    /// A checkpoint is missing, unreadable or from another run.
    #[error("{path:?}: checkpoint: {reason}")]
    Checkpoint { path: PathBuf, reason: String },
    /// The run folder already holds a run and `--resume` was not asked for.
    #[error(
        "{dir:?} already holds a training run (pass --resume to continue it, or choose another run folder)"
    )]
    RunExists { dir: PathBuf },
    /// A loss became NaN or infinite.
    #[error("loss is not finite at step {step}: {terms}")]
    NonFiniteLoss { step: usize, terms: String },
    /// The batch producer failed or stopped early.
    #[error("data loader: {0}")]
    Loader(String),
    /// A figure (curves, contact sheet) could not be drawn.
    #[error("drawing a figure: {0}")]
    Figure(String),
    /// An error from the image core.
    #[error(transparent)]
    Core(#[from] uwnr_core::CoreError),
}

impl RunError {
    /// An [`RunError::Io`] for `path`, for `map_err`.
    pub(crate) fn io(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> Self + '_ {
        move |source| Self::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}
