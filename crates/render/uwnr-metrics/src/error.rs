//! Typed errors of uwnr-metrics.

use std::path::PathBuf;

use uwnr_core::CoreError;

/// Result with [`MetricsError`].
pub type Result<T> = std::result::Result<T, MetricsError>;

/// Everything that can go wrong while measuring. Each variant carries the facts a user needs.
#[derive(Debug, thiserror::Error)]
pub enum MetricsError {
    /// Two images that must have the same shape do not (`(channels, height, width)`).
    #[error(
        "image shapes differ: {pred:?} (prediction) vs {target:?} (target), as (channels, height, width)"
    )]
    ShapeMismatch {
        pred: (usize, usize, usize),
        target: (usize, usize, usize),
    },
    /// A metric defined on RGB images was given another number of channels.
    #[error("{metric} needs an RGB image (3 channels), got {channels} channel(s)")]
    NotRgb {
        metric: &'static str,
        channels: usize,
    },
    /// An image is smaller than a metric's window or block.
    #[error("{metric} needs images of at least {min}x{min} pixels, got {width}x{height}")]
    TooSmall {
        metric: &'static str,
        width: usize,
        height: usize,
        min: usize,
    },
    /// `data_range` must be finite and positive.
    #[error("data range must be finite and > 0, got {0}")]
    InvalidDataRange(f64),
    /// A feature set has too few samples for the statistic.
    #[error("{what} needs at least {min} samples per set, got {got}")]
    TooFewSamples {
        what: &'static str,
        min: usize,
        got: usize,
    },
    /// Feature vectors of different lengths were mixed.
    #[error("feature vector {index} of {set} has {got} values, expected {expected}")]
    FeatureDimMismatch {
        set: &'static str,
        index: usize,
        expected: usize,
        got: usize,
    },
    /// An input (pixel, feature or statistic) is NaN or infinite.
    #[error("{what} contains a non-finite value (NaN or infinity)")]
    NonFinite { what: &'static str },
    /// The symmetric eigenvalue iteration did not converge (never expected for finite input).
    #[error("symmetric eigendecomposition of a {size}x{size} matrix did not converge")]
    NoConvergence { size: usize },
    /// An invalid parameter (subset count, block size, ...).
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
    /// Loading or running an ONNX feature network failed.
    #[error("ONNX feature network {path:?}: {reason}")]
    Onnx { path: PathBuf, reason: String },
    /// An ONNX feature network produced an output of an unexpected size.
    #[error("ONNX feature network {path:?} returned {got} values, expected {expected}")]
    OnnxOutput {
        path: PathBuf,
        expected: usize,
        got: usize,
    },
    /// An error from uwnr-core.
    #[error(transparent)]
    Core(#[from] CoreError),
}

/// `(channels, height, width)` of an image, for error messages.
pub(crate) fn shape_of(img: &uwnr_core::Image) -> (usize, usize, usize) {
    (img.channels(), img.height(), img.width())
}

/// Fails unless `pred` and `target` have the same shape.
pub(crate) fn check_same_shape(pred: &uwnr_core::Image, target: &uwnr_core::Image) -> Result<()> {
    if shape_of(pred) != shape_of(target) {
        return Err(MetricsError::ShapeMismatch {
            pred: shape_of(pred),
            target: shape_of(target),
        });
    }
    Ok(())
}

/// Fails unless `img` has 3 channels.
pub(crate) fn check_rgb(metric: &'static str, img: &uwnr_core::Image) -> Result<()> {
    if img.channels() != 3 {
        return Err(MetricsError::NotRgb {
            metric,
            channels: img.channels(),
        });
    }
    Ok(())
}

/// Fails unless `data_range` is finite and positive.
pub(crate) fn check_data_range(data_range: f64) -> Result<()> {
    if !(data_range.is_finite() && data_range > 0.0) {
        return Err(MetricsError::InvalidDataRange(data_range));
    }
    Ok(())
}

/// Fails when any pixel is NaN or infinite.
pub(crate) fn check_finite_image(what: &'static str, img: &uwnr_core::Image) -> Result<()> {
    if img.data().iter().any(|v| !v.is_finite()) {
        return Err(MetricsError::NonFinite { what });
    }
    Ok(())
}
