//! Typed errors of uwnr-core, and the workspace's convention for errors.
//!
//! An error's message is its whole line, its cause included (`"{path:?}: {source}"`), so that
//! `to_string()` anywhere (a failure record, Python's exception, the page's answer) says what
//! went wrong; an error that wraps another keeps it as `#[source]` as well, for a program to
//! inspect. A chain printed whole ([`one_line`]) therefore leaves out a cause its message already
//! ends with. A `reason: String` is a message the crate composes, or the text of an error whose
//! own chain its `Display` would drop (tract's `anyhow` errors, printed with `{:#}`).

use std::path::PathBuf;

/// The cause an error keeps when it wraps another crate's error.
pub type Cause = Box<dyn std::error::Error + Send + Sync + 'static>;

/// An error chain's messages (outermost first) in one line, joined by `": "`: a message that
/// the line already ends with (a cause its error's message includes) is left out.
#[must_use]
pub fn one_line(messages: impl IntoIterator<Item = String>) -> String {
    let mut line = String::new();
    for m in messages {
        if line.is_empty() {
            line = m;
        } else if !m.is_empty() && !line.ends_with(&m) {
            line.push_str(": ");
            line.push_str(&m);
        }
    }
    line
}

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
    #[error("{path:?}: not a readable image: {source}")]
    Decode {
        path: PathBuf,
        #[source]
        source: Cause,
    },
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
    #[error("{path:?}: cannot write image: {source}")]
    Encode {
        path: PathBuf,
        #[source]
        source: Cause,
    },
    /// An invalid argument to a library function.
    #[error("invalid argument: {0}")]
    InvalidArgument(String),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chain_is_one_line_without_the_causes_its_messages_include() {
        let io = std::io::Error::other("Not a directory (os error 20)");
        let e = CoreError::Io {
            path: "out/x.png".into(),
            source: io,
        };
        let chain = || {
            let mut m = vec!["writing x".to_string(), e.to_string()];
            let mut s = std::error::Error::source(&e);
            while let Some(c) = s {
                m.push(c.to_string());
                s = c.source();
            }
            m
        };
        assert_eq!(
            one_line(chain()),
            "writing x: \"out/x.png\": Not a directory (os error 20)"
        );
        // A cause the message does not include is kept.
        assert_eq!(one_line(["a".into(), "b".into(), "c".into()]), "a: b: c");
    }
}
