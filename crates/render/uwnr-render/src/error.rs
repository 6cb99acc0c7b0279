//! Errors of choosing, loading and running a render method (the workspace's convention:
//! `uwnr_core::error`).

use uwnr_core::error::Cause;

/// What went wrong, with the facts in fields.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// A method name that is not one of `MethodKind::ALL`.
    #[error("unknown method {name:?} (one of {known})")]
    UnknownMethod { name: String, known: String },
    /// An option the method does not have.
    #[error("option {option:?} does not apply to method {method} (its options: {known})")]
    UnknownOption {
        method: &'static str,
        option: String,
        known: String,
    },
    /// Options of the right names with values the method cannot take.
    #[error("options of method {method}: {reason}")]
    BadOptions {
        method: &'static str,
        reason: String,
    },
    /// A render of a method that needs a reference was given none.
    #[error("method {method} needs a reference (a real underwater image)")]
    NeedsReference { method: &'static str },
    /// Settings out of range, or inputs of the wrong shape.
    #[error("{0}")]
    Invalid(String),
    /// Weights that cannot be read or do not fit.
    #[error("loading weights {source_name}: {source}")]
    Weights {
        source_name: String,
        #[source]
        source: Cause,
    },
    /// A render that failed (`context`: which method or stage).
    #[error("{context}: {source}")]
    Failed {
        context: String,
        #[source]
        source: Cause,
    },
}

/// Results of this crate.
pub type Result<T> = std::result::Result<T, RenderError>;
