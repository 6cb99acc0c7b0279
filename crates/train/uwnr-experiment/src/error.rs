//! Errors of the downstream experiment.

use std::path::PathBuf;

/// Why the experiment could not go on.
#[derive(Debug, thiserror::Error)]
pub enum ExperimentError {
    /// The spec cannot be run as given.
    #[error("{0}")]
    Invalid(String),
    /// The output folder holds an experiment made with other settings.
    #[error(
        "{} was made with other settings ({field} differs); use another --out or the same settings",
        out.display()
    )]
    SettingsDiffer {
        /// The output folder.
        out: PathBuf,
        /// The first setting that differs.
        field: String,
    },
    /// Generating a training set failed as a whole.
    #[error("training set {name}: {source}")]
    Dataset {
        /// The method.
        name: String,
        /// What failed.
        source: uwnr_dataset::DatasetError,
    },
    /// Training or scoring an enhancer failed.
    #[error("{name}: {source}")]
    Enhance {
        /// The row.
        name: String,
        /// What failed.
        source: uwnr_enhance::EnhanceError,
    },
    /// The stop flag was raised; everything done so far is kept.
    #[error("stopped; run the same command again to continue")]
    Stopped,
    /// Reading or writing a file.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What failed.
        source: std::io::Error,
    },
    /// An image operation.
    #[error(transparent)]
    Core(#[from] uwnr_core::CoreError),
    /// A figure could not be drawn.
    #[error("drawing {what}: {source}")]
    Figure {
        what: &'static str,
        source: uwnr_figures::FigureError,
    },
}

/// Result of this crate.
pub type Result<T> = std::result::Result<T, ExperimentError>;

impl ExperimentError {
    pub(crate) fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }
}
