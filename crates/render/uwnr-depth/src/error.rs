//! Typed errors of uwnr-depth.

use std::path::PathBuf;

use uwnr_core::CoreError;

/// Result with [`DepthError`].
pub type Result<T> = std::result::Result<T, DepthError>;

/// Everything that can go wrong while preparing or computing a depth map. Each variant carries
/// the facts a user needs to act on it.
#[derive(Debug, thiserror::Error)]
pub enum DepthError {
    /// Decoding a map or resizing failed (the core error names the file where there is one).
    #[error(transparent)]
    Core(#[from] CoreError),
    /// The clean image has no pixels.
    #[error("the clean image is empty ({width}x{height})")]
    EmptyImage { width: usize, height: usize },
    /// The clean image has a channel count the depth source cannot use.
    #[error("the clean image has {got} channels; expected 1 (grey) or 3 (RGB)")]
    Channels { got: usize },
    /// `Maps { path }` names nothing on disk.
    #[error("depth maps {path:?}: no such file or directory")]
    MapsNotFound { path: PathBuf },
    /// `Maps { path }` is a directory that could not be listed.
    #[error("depth maps {path:?}: cannot list the directory: {source}")]
    ReadDir {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A directory of maps is used but the caller gave no clean-image path to match by stem.
    #[error("depth maps {dir:?} is a directory: the clean image's path is needed to find its map")]
    NeedsCleanPath { dir: PathBuf },
    /// The clean-image path has no file stem to match a map by.
    #[error("clean image {clean:?} has no file name to match a depth map by")]
    NoStem { clean: PathBuf },
    /// No map in the directory has the clean image's stem.
    #[error(
        "no depth map for clean image {clean:?}: expected an image named {stem:?}.<ext> in {dir:?}"
    )]
    MissingMap {
        clean: PathBuf,
        dir: PathBuf,
        stem: String,
    },
    /// Several maps in the directory share the clean image's stem.
    #[error("clean image {clean:?} matches several depth maps: {candidates:?}; keep one")]
    AmbiguousMap {
        clean: PathBuf,
        candidates: Vec<PathBuf>,
    },
    /// A metric depth unit was combined with an option that only relative maps take.
    #[error("a metric depth unit cannot be combined with {option}: its values are distances")]
    MetricOptions { option: &'static str },
    /// A depth map holds no measured value (all holes).
    #[error("depth map {path:?} holds no measured depth (every value is 0 or not finite)")]
    NoMeasuredDepth { path: PathBuf },
    /// A depth map file that is not an image could not be read (`.npy`).
    #[error("depth map {path:?}: {reason}")]
    BadMapFile { path: PathBuf, reason: String },
    /// A depth model was given to a build without the `onnx` feature.
    #[error(
        "depth model {path:?}: this build reads no ONNX models (build with the `onnx` feature, on by default for the `uwnr` binary)"
    )]
    NoOnnx { path: PathBuf },
    /// The ONNX model file does not exist.
    #[error("depth model {path:?}: no such file")]
    ModelNotFound { path: PathBuf },
    /// The ONNX model file could not be parsed or optimised by tract.
    #[error("depth model {path:?}: cannot load it as an ONNX model: {reason}")]
    ModelLoad { path: PathBuf, reason: String },
    /// The model's input is not a single image tensor `[1, 3, H, W]`.
    #[error("depth model {path:?}: unsupported input: {reason}")]
    ModelInput { path: PathBuf, reason: String },
    /// `input_size` is zero in some dimension.
    #[error("depth model input size {width}x{height} is invalid")]
    InvalidInputSize { width: usize, height: usize },
    /// The model's output is not a single-channel map `[1, H, W]` or `[1, 1, H, W]`.
    #[error(
        "depth model {path:?}: output has shape {shape}; expected [1, H, W] or [1, 1, H, W] (one disparity map)"
    )]
    UnexpectedOutputShape { path: PathBuf, shape: String },
    /// Running the model failed.
    #[error("depth model {path:?}: inference failed: {reason}")]
    Inference { path: PathBuf, reason: String },
    /// The model produced NaN or infinite values.
    #[error("depth model {path:?}: output holds {count} non-finite values")]
    NonFiniteOutput { path: PathBuf, count: usize },
}
