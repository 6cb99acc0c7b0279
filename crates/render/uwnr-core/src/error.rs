//! Typed errors of uwnr-core.

use std::path::PathBuf;

/// Result with [`CoreError`].
pub type Result<T> = std::result::Result<T, CoreError>;

/// Everything that can go wrong in uwnr-core. Each variant carries the facts a user needs.
#[derive(Debug, thiserror::Error)]
pub enum CoreError {
    /// Two images or buffers that must agree in size do not.
    #[error("size mismatch: expected {expected:?}, got {got:?}")]
    ShapeMismatch {
        expected: (usize, usize, usize),
        got: (usize, usize, usize),
    },
    /// An image has zero width or height.
    #[error("empty image ({width}x{height})")]
    Empty { width: usize, height: usize },
    /// Reading or writing a file failed.
    #[error("{path:?}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file could not be decoded as an image.
    #[error("{path:?}: not a readable image: {reason}")]
    Decode { path: PathBuf, reason: String },
    /// An image's header claims dimensions beyond the configured limits.
    #[error("{path:?}: image is {width}x{height}, above the limit of {max_pixels} pixels")]
    TooLarge {
        path: PathBuf,
        width: u64,
        height: u64,
        max_pixels: u64,
    },
    /// An image's header claims a width or height beyond the configured per-side limit.
    #[error(
        "{path:?}: image is {width}x{height}, above the limit of {max_dimension} pixels per side"
    )]
    DimensionTooLarge {
        path: PathBuf,
        width: u64,
        height: u64,
        max_dimension: u32,
    },
    /// Encoding or writing an output image failed.
    #[error("{path:?}: cannot write image: {reason}")]
    Encode { path: PathBuf, reason: String },
    /// An invalid argument to a library function.
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
}
