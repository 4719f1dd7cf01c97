//! The crate's error type: every failure names the file (when there is one) and what
//! was wrong. Nothing in this crate panics on bad input.

use std::path::PathBuf;

/// Errors of channel-data I/O, import and image formation.
#[derive(Debug, thiserror::Error)]
pub enum SignalError {
    /// The operating system refused a read or write.
    #[error("{path}: {source}")]
    Io {
        /// The file involved.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A file's content is malformed (bad NPY header, truncated data, bad JSON, …).
    #[error("{path}: {what}")]
    Format {
        /// The file involved.
        path: PathBuf,
        /// What was wrong, in words.
        what: String,
    },
    /// An argument or a setting is invalid (no file involved).
    #[error("invalid input: {0}")]
    Invalid(String),
}

impl SignalError {
    /// A [`SignalError::Format`] for `path`.
    pub fn format(path: impl Into<PathBuf>, what: impl Into<String>) -> Self {
        SignalError::Format {
            path: path.into(),
            what: what.into(),
        }
    }
    /// A [`SignalError::Io`] for `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        SignalError::Io {
            path: path.into(),
            source,
        }
    }
}

/// `Result` with [`SignalError`].
pub type Result<T> = std::result::Result<T, SignalError>;
