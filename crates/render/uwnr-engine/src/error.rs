//! Typed errors of uwnr-engine.

/// Result with [`EngineError`].
pub type Result<T> = std::result::Result<T, EngineError>;

/// What can go wrong while building or running the engine.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum EngineError {
    /// A weight tensor has the wrong number of values for its layer.
    #[error("{layer}: expected {expected} values, got {got}")]
    WeightLength {
        layer: String,
        expected: usize,
        got: usize,
    },
    /// The widths of the network are not usable.
    #[error("invalid network widths: {0}")]
    InvalidWidths(String),
    /// The input does not fit the network.
    #[error("input: {0}")]
    Input(String),
    /// A requested instruction set is not supported by this CPU.
    #[error("instruction set {0:?} is not supported by this CPU")]
    UnsupportedIsa(crate::Isa),
}
