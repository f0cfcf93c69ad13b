//! The core's error type: one enum, every message says what went wrong and what to do.

use std::path::PathBuf;

/// Result alias used throughout the core.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything the core can refuse or fail at.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A number in a code, a parameter vector or a config is NaN or infinite.
    #[error(
        "{what} contains a non-finite value ({value}) at {location}; every entry must be a finite number"
    )]
    NonFinite {
        /// Which object held the value.
        what: String,
        /// Where in that object (e.g. `map 2, matrix[1][0]`).
        location: String,
        /// The offending value.
        value: f64,
    },
    /// A map is not a contraction.
    #[error(
        "map {index} is not contractive: its largest singular value is {sigma_max:.6} (must be < 1). \
         Scale the map down, or set \"allow_non_contractive\": true for flame-like codes"
    )]
    NonContractive {
        /// Index of the offending map.
        index: usize,
        /// Its largest singular value (operator 2-norm).
        sigma_max: f64,
    },
    /// Array lengths or dimensions that do not agree.
    #[error("wrong shape: {0}")]
    Shape(String),
    /// Map probabilities that are negative or do not sum to one.
    #[error("invalid probabilities: {0}")]
    Probabilities(String),
    /// A parameter outside its allowed range.
    #[error("invalid parameter `{name}`: {message}")]
    InvalidParameter {
        /// The parameter's name as the user writes it.
        name: &'static str,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// A trajectory of the chaos game left every bound (a non-finite point).
    #[error(
        "trajectory {trajectory} diverged at step {step} (point became non-finite or left ±1e100); \
         the code is not contractive enough to have an attractor"
    )]
    Divergent {
        /// Trajectory index.
        trajectory: usize,
        /// Step at which the point stopped being finite.
        step: usize,
    },
    /// An empty input (no maps, no points, an empty image).
    #[error("empty input: {0}")]
    Empty(String),
    /// A named code that is not in the built-in library.
    #[error("unknown built-in code `{name}`; known codes: {known}")]
    UnknownCode {
        /// The name asked for.
        name: String,
        /// Comma-separated list of the known names.
        known: String,
    },
    /// A code file that is not valid JSON or does not follow the schema.
    #[error("cannot parse code file {path}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// What the parser said.
        message: String,
    },
    /// An image that could not be read or written.
    #[error("image error for {path}: {message}")]
    Image {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// Underlying I/O failure, with the file it concerned.
    #[error("I/O error on {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// Network weights (e.g. LPIPS) that are missing, unreadable or not of the expected layout.
    #[error("weights file {path}: {message}")]
    Weights {
        /// The file.
        path: PathBuf,
        /// What is wrong and how to fix it.
        message: String,
    },
    /// A `.flame` file (or flam3's palette library) that is not valid XML or does not
    /// follow the format.
    #[error("cannot read flame file {path} ({location}): {message}")]
    FlameFile {
        /// The file.
        path: PathBuf,
        /// Where in it: line and column, flame and transform.
        location: String,
        /// What is wrong and what is allowed.
        message: String,
    },
    /// A variation name that flam3 3.1.1 does not have.
    #[error(
        "unknown variation `{name}` in {path} ({location}); flam3 3.1.1's 99 variations are \
         supported (see `ifslab flame info --variations`)"
    )]
    UnknownVariation {
        /// The attribute name taken for a variation.
        name: String,
        /// The file.
        path: PathBuf,
        /// Flame and transform.
        location: String,
    },
    /// A segment pattern (control points and symmetry pairs) that cannot define an IFS.
    #[error("invalid segment pattern: {0}")]
    Pattern(String),
    /// A tensor operation (candle) failed.
    #[error("tensor operation failed: {0}")]
    Tensor(#[from] candle_core::Error),
    /// The GPU backend is not there or failed (`device = "cuda"`).
    #[error("GPU: {0}")]
    Device(String),

    /// A job whose buffers would not fit the memory budget ([`crate::budget`]).
    #[error("{0}")]
    OverBudget(String),

    /// A zoom window that needs more words of the code than allowed
    /// ([`crate::chaos::WindowWords`]); the evaluation renderer then draws it the plain way.
    #[error(
        "the zoom window needs more than {max_words} words of the code (the maps overlap a lot \
         there, or the window is deeper than f64 resolves): zoom less deep or allow more words"
    )]
    TooManyWords {
        /// The limit that was reached.
        max_words: usize,
    },

    /// A camera that cannot take a picture (a degenerate pose, no field of view, a
    /// non-finite number) or views that do not go together (images of different sizes).
    #[error("invalid camera: {0}")]
    Camera(String),

    /// Work its caller no longer wanted ([`crate::progress::Progress::cancelled`]).
    #[error("cancelled: {0}")]
    Cancelled(String),
}

impl Error {
    /// Shorthand for [`Error::InvalidParameter`].
    pub fn param(name: &'static str, message: impl Into<String>) -> Self {
        Error::InvalidParameter {
            name,
            message: message.into(),
        }
    }

    /// Shorthand for [`Error::Io`].
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}
