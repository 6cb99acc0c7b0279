//! Errors of dataset generation, verification and merging.

use std::path::PathBuf;

/// What can go wrong before or around a dataset run (per-pair failures are not errors: they are
/// listed in the run's [`crate::Summary`] and the run goes on).
#[derive(Debug, thiserror::Error)]
pub enum DatasetError {
    /// Reading or writing a file or folder failed.
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The inputs or options cannot make a dataset.
    #[error("{0}")]
    Invalid(String),
    /// The output folder holds a dataset made with other settings.
    #[error(
        "{} holds a dataset made with a different {field} ({existing} there, {requested} now): \
         use another output folder, or the same command as before to resume"
    , out.display())]
    SettingsMismatch {
        out: PathBuf,
        field: String,
        existing: String,
        requested: String,
    },
    /// A metadata file of the dataset is unreadable.
    #[error("{}: {reason}", path.display())]
    Corrupt { path: PathBuf, reason: String },
    /// An image operation failed.
    #[error(transparent)]
    Core(#[from] uwnr_core::CoreError),
    /// Drawing the preview failed.
    #[error("drawing the preview: {0}")]
    Figure(#[from] uwnr_figures::FigureError),
}

/// Result with [`DatasetError`].
pub type Result<T> = std::result::Result<T, DatasetError>;

/// An I/O error on `path`.
pub(crate) fn io_err(path: &std::path::Path) -> impl FnOnce(std::io::Error) -> DatasetError + '_ {
    move |source| DatasetError::Io {
        path: path.to_path_buf(),
        source,
    }
}
