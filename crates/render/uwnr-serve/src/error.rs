//! Errors of the server: each carries the HTTP status it is answered with and a message the
//! page shows as it is.

use std::path::PathBuf;

/// What went wrong, with the facts in fields.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    /// A path that could leave its root: `..`, absolute, empty, or a symlink whose target lies
    /// outside.
    #[error("{what} path {path:?} is not inside the {what} folder")]
    OutsideRoot { what: &'static str, path: String },
    /// An index past the end of a list.
    #[error("no {what} number {index} (there are {count})")]
    UnknownIndex {
        what: &'static str,
        index: usize,
        count: usize,
    },
    /// A relative path that names no listed image.
    #[error("no {what} image at {path:?}")]
    NotFound { what: &'static str, path: String },
    /// A folder given at start that cannot be used.
    #[error("{what} folder {path:?}: {reason}")]
    Root {
        what: &'static str,
        path: PathBuf,
        reason: String,
    },
    /// A request body larger than allowed; `limit` says which limit (an upload's is
    /// `--max-upload-mb`, any other body's is fixed).
    #[error("{what} is {got} bytes, more than the {max} bytes {limit}")]
    TooLarge {
        what: &'static str,
        got: u64,
        max: u64,
        limit: &'static str,
    },
    /// An image sent by the client (a dropped file) that cannot be decoded or exceeds the
    /// limits.
    #[error("{what}: {reason}")]
    BadImage { what: String, reason: String },
    /// A file of the server's own folders (or a dropped file it kept) that cannot be read or
    /// decoded: the server's failure, not the request's. The message names the file as the
    /// page knows it, never a temporary path.
    #[error("{what}: {reason}")]
    ServerFile { what: String, reason: String },
    /// Something needs more bytes than the server's whole memory budget.
    #[error(
        "{what} needs {bytes} bytes, more than this server's memory budget of {budget} bytes (--memory-mb)"
    )]
    TooBig {
        what: String,
        bytes: u64,
        budget: u64,
    },
    /// The memory budget is in use by other requests now.
    #[error(
        "the server is busy ({what} needs {bytes} bytes of memory in use by other requests); try again in a moment"
    )]
    NoMemory { what: String, bytes: u64 },
    /// A request refused by the local-only guard (Host, Origin, token).
    #[error("{0}")]
    Forbidden(String),
    /// A known path asked with a method it does not answer.
    #[error("{method} is not allowed here (allowed: {allow})")]
    MethodNotAllowed { method: String, allow: &'static str },
    /// A request the server cannot read (bad JSON, bad option, unknown route).
    #[error("{0}")]
    BadRequest(String),
    /// The render queue is full.
    #[error("the render queue is full ({capacity} renders waiting); try again in a moment")]
    Busy { capacity: usize },
    /// An unknown route or job.
    #[error("{0}")]
    Missing(String),
    /// A render that failed.
    #[error(transparent)]
    Render(#[from] uwnr_render::RenderError),
    /// Reading or writing a file.
    #[error("{context}: {source}")]
    Io {
        context: String,
        #[source]
        source: std::io::Error,
    },
}

impl ServeError {
    /// The HTTP status this error is answered with.
    #[must_use]
    pub fn status(&self) -> u16 {
        match self {
            Self::OutsideRoot { .. } | Self::Forbidden(_) => 403,
            Self::MethodNotAllowed { .. } => 405,
            Self::UnknownIndex { .. } | Self::NotFound { .. } | Self::Missing(_) => 404,
            Self::TooLarge { .. } | Self::TooBig { .. } => 413,
            Self::BadImage { .. } | Self::BadRequest(_) => 400,
            Self::Busy { .. } | Self::NoMemory { .. } => 503,
            Self::Root { .. } | Self::ServerFile { .. } | Self::Render(_) | Self::Io { .. } => 500,
        }
    }

    pub(crate) fn io(context: impl Into<String>) -> impl FnOnce(std::io::Error) -> Self {
        let context = context.into();
        move |source| Self::Io { context, source }
    }
}

/// Results of this crate.
pub type Result<T> = std::result::Result<T, ServeError>;
