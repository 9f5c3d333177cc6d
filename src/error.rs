//! The library's one error type. Every variant that concerns a file names it, so a user
//! reading a one-line message knows which input to fix.

use std::path::PathBuf;

/// Everything that can go wrong in posereg, structured so the CLI can print one clear line.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The operating system refused a read or write.
    #[error("{path}: {err}")]
    Io {
        /// The file involved.
        path: PathBuf,
        /// What the OS said.
        err: std::io::Error,
    },
    /// A file was read but its content is unusable (corrupt, truncated, wrong shape, NaNs ...).
    #[error("{path}: {problem}")]
    BadFile {
        /// The file involved.
        path: PathBuf,
        /// What is wrong with it, in words.
        problem: String,
    },
    /// Inputs that are individually fine but do not fit together, or bad parameters.
    #[error("{0}")]
    InvalidInput(String),
    /// No usable GPU adapter (or none matching the user's request).
    #[error("no GPU adapter: {0}")]
    NoAdapter(String),
    /// A buffer or dispatch exceeds what the device allows.
    #[error("{what} needs {needed} bytes but the device allows at most {limit} ({limit_name})")]
    DeviceLimit {
        /// What was being allocated.
        what: String,
        /// Bytes requested.
        needed: u64,
        /// Bytes allowed.
        limit: u64,
        /// Which wgpu limit applies.
        limit_name: &'static str,
    },
    /// The GPU reported an error (validation, out of memory, lost device).
    #[error("GPU error: {0}")]
    Gpu(String),
}

/// Result with the library's [`Error`].
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// A problem with the content of `path`.
    pub fn bad_file(path: impl Into<PathBuf>, problem: impl Into<String>) -> Self {
        Error::BadFile {
            path: path.into(),
            problem: problem.into(),
        }
    }

    /// An I/O failure on `path`.
    pub fn io(path: impl Into<PathBuf>, err: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            err,
        }
    }
}
