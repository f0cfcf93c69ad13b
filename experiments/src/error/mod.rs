//! The library's error type: one enum for `ifslab_experiments`, so a caller can match on what
//! went wrong; messages that say what to change. `anyhow` stays in the `ifslab` binary only.
//!
//! The words are the ones the command line has always printed: a message with the context
//! it was reached in ([`Context`]) is a [`Error::Context`] link whose [`source`] is the error
//! it happened in, so `{:?}` through `anyhow` (what `ifslab` prints: the message, then
//! `Caused by:` and each cause) and `{:#}` (the chain on one line, `a: b: c`) read as before.
//! That is also why [`Display`](fmt::Display) is written here rather than derived: the
//! alternate form (`{:#}`) appends the causes, as `anyhow`'s does.
//!
//! [`source`]: std::error::Error::source

use std::error::Error as StdError;
use std::fmt;
use std::path::{Path, PathBuf};

/// What drawing a chart on a bitmap can fail at ([`crate::plot`]).
pub type PlotError = plotters::drawing::DrawingAreaErrorKind<
    <plotters::backend::BitMapBackend<'static> as plotters::backend::DrawingBackend>::ErrorType,
>;

/// Result alias of the experiments library.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Everything the experiments library can refuse or fail at.
#[derive(Debug)]
#[non_exhaustive]
pub enum Error {
    /// An error from the core (models, chaos game, renderers, code files, budgets); its own
    /// words.
    Core(ifslab::Error),
    /// An error from a strategy or a problem (a fit, an encoding, an interrupted run); its own
    /// words.
    Strategies(ifslab_strategies::Error),
    /// A file or folder that could not be read, written, created, moved or locked. The message
    /// names the path and what was being done (`reading runs/x/summary.json`); the cause is
    /// the OS error.
    Io {
        /// The file or folder.
        path: PathBuf,
        /// What was being done to it, with its name.
        message: String,
        /// The OS error.
        source: std::io::Error,
    },
    /// An OS error the library puts no words of its own to (a socket, a thread, a child
    /// process, and the few file operations whose message has always been the OS's alone),
    /// in the OS's words.
    Os(std::io::Error),
    /// A config, sweep file, index or manifest (TOML or JSON) that is malformed or refused.
    /// The message names the file; the cause, when there is one, says what is wrong in it.
    Config {
        /// The file (or the origin the text was given under).
        path: PathBuf,
        /// What it is not (`config.toml is not valid TOML`).
        message: String,
        /// What the parser or the check said.
        source: Option<Box<Error>>,
    },
    /// A file named on the command line or in a config that is not there
    /// ([`crate::codes::missing_file`]).
    NotFound {
        /// The name as it was given.
        path: PathBuf,
        /// The name, and the folder a relative name was looked for in.
        message: String,
    },
    /// A run folder another process is writing (it holds the folder's lock,
    /// [`crate::runs::lock_run_dir`]).
    Locked {
        /// The folder.
        path: PathBuf,
        /// Whose it is and what to do.
        message: String,
    },
    /// An input, an option or a combination of them that the library refuses; the message
    /// says what is allowed.
    InvalidInput(String),
    /// A program the library runs (`sbatch`) that failed or answered what it should not.
    Tool {
        /// The program.
        tool: &'static str,
        /// What it did, in its words where it gave some.
        message: String,
    },
    /// Work stopped by a signal ([`ifslab::interrupt`]): the runs under way stopped at a
    /// checkpoint, and the message says how to continue.
    Interrupted(String),
    /// JSON that could not be read or written, in `serde_json`'s words.
    Json(serde_json::Error),
    /// TOML that could not be read, in `toml`'s words.
    Toml(toml::de::Error),
    /// A value that could not be written as TOML, in `toml`'s words.
    TomlWrite(toml::ser::Error),
    /// An image that could not be decoded or encoded, in `image`'s words.
    Image(image::ImageError),
    /// A thread pool that could not be started, in `rayon`'s words.
    ThreadPool(rayon::ThreadPoolBuildError),
    /// A chart that could not be drawn, in `plotters`' words.
    Plot(PlotError),
    /// An error with what was being done when it happened: the message, then the error.
    Context {
        /// What was being done (`loading code file maple.json`).
        message: String,
        /// The error it happened in.
        source: Box<Error>,
    },
}

impl Error {
    /// Shorthand for [`Error::InvalidInput`].
    pub fn invalid(message: impl Into<String>) -> Self {
        Error::InvalidInput(message.into())
    }

    /// Shorthand for [`Error::Io`].
    pub fn io(
        path: impl Into<PathBuf>,
        message: impl Into<String>,
        source: std::io::Error,
    ) -> Self {
        Error::Io {
            path: path.into(),
            message: message.into(),
            source,
        }
    }

    /// Shorthand for [`Error::Config`] without a cause.
    pub fn config(path: impl Into<PathBuf>, message: impl Into<String>) -> Self {
        Error::Config {
            path: path.into(),
            message: message.into(),
            source: None,
        }
    }

    /// This error with `message` (what was being done) in front of it.
    pub fn context(self, message: impl fmt::Display) -> Self {
        Error::Context {
            message: message.to_string(),
            source: Box::new(self),
        }
    }

    /// The error under every [`Error::Context`] and [`Error::Config`] link: what went wrong in
    /// the first place.
    pub fn root(&self) -> &Error {
        let mut e = self;
        loop {
            match e {
                Error::Context { source, .. }
                | Error::Config {
                    source: Some(source),
                    ..
                } => e = source,
                _ => return e,
            }
        }
    }

    /// The core's error this one is, under its context, if it is one (also through a
    /// strategy's).
    pub fn as_core(&self) -> Option<&ifslab::Error> {
        match self.root() {
            Error::Core(e) | Error::Strategies(ifslab_strategies::Error::Core(e)) => Some(e),
            _ => None,
        }
    }

    /// Whether this is work stopped by a signal: a strategy's
    /// [`ifslab_strategies::Error::Interrupted`] or the library's [`Error::Interrupted`],
    /// under any context.
    pub fn is_interrupted(&self) -> bool {
        matches!(
            self.root(),
            Error::Interrupted(_) | Error::Strategies(ifslab_strategies::Error::Interrupted(_))
        )
    }

    /// Whether this is work its caller no longer wanted (the core's
    /// [`ifslab::Error::Cancelled`]), under any context.
    pub fn is_cancelled(&self) -> bool {
        matches!(self.as_core(), Some(ifslab::Error::Cancelled(_)))
    }

    /// Whether this is a file that is not there: [`Error::NotFound`], or an OS error of kind
    /// [`NotFound`](std::io::ErrorKind::NotFound) anywhere in the chain (the library's, the
    /// core's, or one inside a JSON or image error).
    pub fn is_not_found(&self) -> bool {
        let not_found = |io: &std::io::Error| io.kind() == std::io::ErrorKind::NotFound;
        let root = self.root();
        let direct = match root {
            Error::NotFound { .. } => true,
            Error::Io { source, .. } | Error::Os(source) => not_found(source),
            _ => match root.as_core() {
                Some(ifslab::Error::Io { source, .. }) => not_found(source),
                _ => false,
            },
        };
        direct || chain(root).any(|c| c.downcast_ref::<std::io::Error>().is_some_and(not_found))
    }

    /// The error's own message, without its causes.
    fn fmt_own(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Core(e) => fmt::Display::fmt(e, f),
            Error::Strategies(e) => fmt::Display::fmt(e, f),
            Error::Os(e) => fmt::Display::fmt(e, f),
            Error::Json(e) => fmt::Display::fmt(e, f),
            Error::Toml(e) => fmt::Display::fmt(e, f),
            Error::TomlWrite(e) => fmt::Display::fmt(e, f),
            Error::Image(e) => fmt::Display::fmt(e, f),
            Error::ThreadPool(e) => fmt::Display::fmt(e, f),
            Error::Plot(e) => fmt::Display::fmt(e, f),
            Error::Io { message, .. }
            | Error::Config { message, .. }
            | Error::NotFound { message, .. }
            | Error::Context { message, .. }
            | Error::Tool { message, .. }
            | Error::Locked { message, .. }
            | Error::InvalidInput(message)
            | Error::Interrupted(message) => f.write_str(message),
        }
    }
}

/// The causes of `e`, from its own [`source`](StdError::source) on.
fn chain<'a>(
    e: &'a (dyn StdError + 'static),
) -> impl Iterator<Item = &'a (dyn StdError + 'static)> {
    std::iter::successors(e.source(), |&c| c.source())
}

impl fmt::Display for Error {
    /// The message; with `{:#}`, the message and every cause after it, joined by `: `.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        // The wrapped errors are given no `#`: their own causes follow here, once.
        write!(f, "{}", Own(self))?;
        if f.alternate() {
            for cause in chain(self) {
                write!(f, ": {cause}")?;
            }
        }
        Ok(())
    }
}

/// An error's own message, as plain `{}`.
struct Own<'a>(&'a Error);

impl fmt::Display for Own<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.fmt_own(f)
    }
}

impl StdError for Error {
    /// The wrapped errors are transparent (their causes are this one's); a link with a
    /// message has the error it happened in as its cause.
    fn source(&self) -> Option<&(dyn StdError + 'static)> {
        match self {
            Error::Core(e) => e.source(),
            Error::Strategies(e) => e.source(),
            Error::Os(e) => e.source(),
            Error::Json(e) => e.source(),
            Error::Toml(e) => e.source(),
            Error::TomlWrite(e) => e.source(),
            Error::Image(e) => e.source(),
            Error::ThreadPool(e) => e.source(),
            Error::Plot(e) => e.source(),
            Error::Io { source, .. } => Some(source),
            Error::Config { source, .. } => source.as_deref().map(|e| e as _),
            Error::Context { source, .. } => Some(&**source),
            Error::NotFound { .. }
            | Error::Locked { .. }
            | Error::Tool { .. }
            | Error::InvalidInput(_)
            | Error::Interrupted(_) => None,
        }
    }
}

macro_rules! from {
    ($($variant:ident($ty:ty)),* $(,)?) => {$(
        impl From<$ty> for Error {
            fn from(e: $ty) -> Self {
                Error::$variant(e)
            }
        }
    )*};
}

from!(
    Core(ifslab::Error),
    Strategies(ifslab_strategies::Error),
    Os(std::io::Error),
    Json(serde_json::Error),
    Toml(toml::de::Error),
    TomlWrite(toml::ser::Error),
    Image(image::ImageError),
    ThreadPool(rayon::ThreadPoolBuildError),
    Plot(PlotError),
);

/// What was being done, put in front of an error or given to a missing value, as
/// `anyhow::Context` does it: the message is the new error's, the old one its cause.
pub trait Context<T> {
    /// The error (or the missing value) with `message` in front.
    fn context(self, message: impl fmt::Display) -> Result<T>;
    /// The error (or the missing value) with the message `f` makes in front; `f` runs only on
    /// an error.
    fn with_context<C: fmt::Display>(self, f: impl FnOnce() -> C) -> Result<T>;
    /// The error as [`Error::Config`]: the file `path` is not what it should be (`message`),
    /// and the error says why.
    fn config_context<C: fmt::Display>(self, path: &Path, f: impl FnOnce() -> C) -> Result<T>;
}

impl<T, E: Into<Error>> Context<T> for std::result::Result<T, E> {
    fn context(self, message: impl fmt::Display) -> Result<T> {
        self.map_err(|e| e.into().context(message))
    }

    fn with_context<C: fmt::Display>(self, f: impl FnOnce() -> C) -> Result<T> {
        self.map_err(|e| e.into().context(f()))
    }

    fn config_context<C: fmt::Display>(self, path: &Path, f: impl FnOnce() -> C) -> Result<T> {
        self.map_err(|e| Error::Config {
            path: path.to_owned(),
            message: f().to_string(),
            source: Some(Box::new(e.into())),
        })
    }
}

/// A missing value is an [`Error::InvalidInput`] with the message.
impl<T> Context<T> for Option<T> {
    fn context(self, message: impl fmt::Display) -> Result<T> {
        self.ok_or_else(|| Error::InvalidInput(message.to_string()))
    }

    fn with_context<C: fmt::Display>(self, f: impl FnOnce() -> C) -> Result<T> {
        self.ok_or_else(|| Error::InvalidInput(f().to_string()))
    }

    fn config_context<C: fmt::Display>(self, path: &Path, f: impl FnOnce() -> C) -> Result<T> {
        self.ok_or_else(|| Error::config(path, f().to_string()))
    }
}

/// An OS error on a file as [`Error::Io`], naming the file and what was being done to it.
pub trait IoContext<T> {
    /// `doing` and the path (`.doing("reading", path)`: "reading runs/x/log.csv").
    fn doing(self, doing: &str, path: &Path) -> Result<T>;
    /// The message `f` makes, for a message that is not "doing path".
    fn io_context<C: fmt::Display>(self, path: &Path, f: impl FnOnce() -> C) -> Result<T>;
}

impl<T> IoContext<T> for std::io::Result<T> {
    fn doing(self, doing: &str, path: &Path) -> Result<T> {
        self.map_err(|e| Error::io(path, format!("{doing} {}", path.display()), e))
    }

    fn io_context<C: fmt::Display>(self, path: &Path, f: impl FnOnce() -> C) -> Result<T> {
        self.map_err(|e| Error::io(path, f().to_string(), e))
    }
}

/// `return Err(Error::InvalidInput(format!(...)))`.
macro_rules! bail {
    ($($arg:tt)*) => {
        return Err($crate::error::Error::InvalidInput(format!($($arg)*)))
    };
}

/// `return Err(Error::Config { path, message: format!(...), source: None })`.
macro_rules! bail_config {
    ($path:expr, $($arg:tt)*) => {
        return Err($crate::error::Error::config($path, format!($($arg)*)))
    };
}

/// `bail!` unless the condition holds.
macro_rules! ensure {
    ($cond:expr, $($arg:tt)*) => {
        if !$cond {
            $crate::error::bail!($($arg)*);
        }
    };
}

pub(crate) use {bail, bail_config, ensure};

#[cfg(test)]
mod tests;
