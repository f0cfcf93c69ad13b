//! The strategies' error type: one enum for the crate, messages that say what to change.

use std::path::PathBuf;

/// Result alias of the strategies crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything a strategy can refuse or fail at.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An error from the core (models, chaos game, renderers, code files).
    #[error(transparent)]
    Core(#[from] ifslab::Error),
    /// A hyper-parameter outside its allowed range.
    #[error("invalid parameter `{name}`: {message}")]
    InvalidParameter {
        /// The parameter's name as the user writes it.
        name: &'static str,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// Input data the strategy cannot work on (empty, NaN, wrong shape, too small).
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// A numerical degeneracy the strategy could not recover from.
    #[error("numerical failure: {0}")]
    Numerical(String),

    /// The run was stopped by a signal after checkpointing ([`ifslab::interrupt`]).
    #[error("{0}")]
    Interrupted(String),
    /// A file that could not be read, parsed or written.
    #[error("{path}: {message}")]
    File {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

impl Error {
    /// Shorthand for [`Error::InvalidParameter`].
    pub fn param(name: &'static str, message: impl Into<String>) -> Self {
        Error::InvalidParameter {
            name,
            message: message.into(),
        }
    }

    /// Shorthand for [`Error::File`].
    pub fn file(path: impl Into<PathBuf>, message: impl std::fmt::Display) -> Self {
        Error::File {
            path: path.into(),
            message: message.to_string(),
        }
    }
}
