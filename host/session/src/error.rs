//! Errors of reading or writing a session directory: each names the file and,
//! where there is one, the line.

use std::path::{Path, PathBuf};

/// What went wrong with a session file.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// The file could not be opened, read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The operating system's error.
        #[source]
        source: std::io::Error,
    },
    /// A line of the file is malformed (bad number, wrong field count, time
    /// going backwards, NaN, …).
    #[error("{}:{line}: {message}", path.display())]
    Line {
        /// The file.
        path: PathBuf,
        /// 1-based line number in the file.
        line: u64,
        /// What is wrong with it.
        message: String,
    },
    /// The file as a whole is unusable (missing columns, no rows, bad TOML, …).
    #[error("{}: {message}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong with it.
        message: String,
    },
}

impl SessionError {
    /// An I/O error on `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Self::Io {
            path: path.into(),
            source,
        }
    }
    /// A problem at `line` of `path`.
    pub fn line(path: impl Into<PathBuf>, line: u64, message: impl Into<String>) -> Self {
        Self::Line {
            path: path.into(),
            line,
            message: message.into(),
        }
    }
    /// A problem with the file `path` as a whole.
    pub fn file(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Self::File {
            path: path.into(),
            message: message.into(),
        }
    }
}

/// A TOML parse error of `path` as a [`SessionError`] naming the line.
pub fn toml_error(path: &Path, text: &str, e: &toml::de::Error) -> SessionError {
    let message = e.message().to_string();
    match e.span() {
        Some(span) => {
            let line = text[..span.start.min(text.len())].matches('\n').count() as u64 + 1;
            SessionError::line(path, line, message)
        }
        None => SessionError::file(path, message),
    }
}
