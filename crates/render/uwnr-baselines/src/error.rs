//! Typed errors of uwnr-baselines.

use uwnr_core::CoreError;

/// Result with [`BaselineError`].
pub type Result<T> = std::result::Result<T, BaselineError>;

/// Everything that can go wrong when rendering a baseline. Each variant carries the facts a user
/// needs to fix the call.
#[derive(Debug, thiserror::Error)]
pub enum BaselineError {
    /// The method estimates the water from a real underwater image, and none was given.
    #[error("{method} needs a reference underwater image, and none was given")]
    MissingReference {
        /// The method that asked for it (`"uisa"`, `"seathru"`, `"reinhard"`).
        method: &'static str,
    },
    /// An input image has the wrong number of channels.
    #[error("{what} must have {expected} channel(s), it has {got}")]
    Channels {
        /// Which input (`"clean image"`, `"depth"`, `"reference"`).
        what: &'static str,
        /// Channels required.
        expected: usize,
        /// Channels found.
        got: usize,
    },
    /// An input image has no pixels.
    #[error("{what} is empty ({width}x{height})")]
    Empty {
        /// Which input.
        what: &'static str,
        /// Its width.
        width: usize,
        /// Its height.
        height: usize,
    },
    /// The depth map is not the size of the clean image.
    #[error("depth is {}x{} but the clean image is {}x{} (resize the depth first)", got.0, got.1, expected.0, expected.1)]
    DepthSize {
        /// `(width, height)` of the clean image.
        expected: (usize, usize),
        /// `(width, height)` of the depth map.
        got: (usize, usize),
    },
    /// The depth map holds NaN or infinite values.
    #[error("depth has {count} non-finite value(s)")]
    NonFiniteDepth {
        /// How many values are NaN or infinite.
        count: usize,
    },
    /// A parameter is outside the values the method accepts.
    #[error("invalid parameter {name} = {value}: {reason}")]
    InvalidParam {
        /// Parameter name as it appears in the params struct (dotted for nested fields).
        name: &'static str,
        /// The offending value, formatted.
        value: String,
        /// What it must satisfy.
        reason: &'static str,
    },
    /// An image operation of uwnr-core failed.
    #[error(transparent)]
    Core(#[from] CoreError),
}
