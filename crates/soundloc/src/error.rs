//! The library's one error type.
//!
//! Every variant carries enough context to say *which* file, stage or option is wrong and
//! *what* is wrong with it; messages are written for the person running the command.

use std::path::PathBuf;

/// Result alias used throughout the library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything that can go wrong in soundloc.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Error {
    /// An I/O failure on a named file.
    #[error("{}: {err}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the OS said (part of the message, not chained again as a source).
        err: std::io::Error,
    },
    /// A file was read but its content is wrong (bad magic, truncated, wrong sizes, NaN...).
    #[error("{}: {message}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong with it, and where.
        message: String,
    },
    /// A WAV or FLAC stream ended before the length its header declares (a file cut
    /// short, a recorder stopped early); the frames before the cut were delivered.
    #[error("{}: {message}", path.display())]
    Truncated {
        /// The file.
        path: PathBuf,
        /// How much is missing.
        message: String,
    },
    /// A configuration value is out of range or inconsistent with the others.
    #[error("invalid configuration: {0}")]
    Config(String),
    /// Inputs that do not fit together (channel counts, sample rates, bins...).
    #[error("{0}")]
    Mismatch(String),
    /// The input is too short or empty for the requested analysis.
    #[error("{0}")]
    TooShort(String),
    /// A stream ended before its first correlation window was complete: no results. An
    /// error for a recording; a live session stopped early treats it as "no results"
    /// (the CLI on Ctrl-C, Python's `flush`).
    #[error("{0}")]
    NoWindow(String),
    /// A numerical failure (non-finite data, a matrix that is not positive definite...).
    #[error("{stage}: {message}")]
    Numerical {
        /// The pipeline stage.
        stage: &'static str,
        /// What failed.
        message: String,
    },
    /// A call the object's present state does not allow (input after a stream's end).
    #[error("{0}")]
    State(String),
    /// A compute device (CUDA) problem: missing library, no GPU, kernel compile error...
    #[error("device: {0}")]
    Device(String),
}

impl Error {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            err: source,
        }
    }
    /// A content error in `path`.
    pub fn format(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Format {
            path: path.into(),
            message: message.into(),
        }
    }
    /// A stream cut short (see [`Error::Truncated`]).
    pub fn truncated(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Truncated {
            path: path.into(),
            message: message.into(),
        }
    }
    /// A numerical error in `stage`.
    pub fn numerical(stage: &'static str, message: impl Into<String>) -> Self {
        Error::Numerical {
            stage,
            message: message.into(),
        }
    }
}
