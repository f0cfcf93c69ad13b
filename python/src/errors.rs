//! The library's errors as Python exceptions, carrying the library's own words: the whole
//! `anyhow` chain on one line (`{:#}`), as the command line prints it.

use pyo3::create_exception;
use pyo3::exceptions::{PyException, PyFileNotFoundError, PyKeyboardInterrupt};
use pyo3::prelude::*;

create_exception!(
    ifslab,
    IfslabError,
    PyException,
    "An input or a run that the ifslab library refused; the message is the library's."
);

/// `e` as the Python exception that fits it: `KeyboardInterrupt` for a run stopped by an
/// interruption (its message says where the checkpoint is), `FileNotFoundError` for a file
/// that is not there, [`IfslabError`] for everything else.
pub fn to_py(e: anyhow::Error) -> PyErr {
    let message = format!("{e:#}");
    for cause in e.chain() {
        if let Some(ifslab_strategies::Error::Interrupted(_)) =
            cause.downcast_ref::<ifslab_strategies::Error>()
        {
            return PyKeyboardInterrupt::new_err(message);
        }
        let io = cause.downcast_ref::<std::io::Error>().or_else(|| {
            match cause.downcast_ref::<ifslab::Error>() {
                Some(ifslab::Error::Io { source, .. }) => Some(source),
                _ => None,
            }
        });
        if io.is_some_and(|io| io.kind() == std::io::ErrorKind::NotFound) {
            return PyFileNotFoundError::new_err(message);
        }
    }
    // `ifslab_experiments::codes::missing_file` is a message of its own.
    if message.contains("no such file: ") {
        return PyFileNotFoundError::new_err(message);
    }
    IfslabError::new_err(message)
}

/// A library result as a Python one.
pub trait IntoPy<T> {
    /// The error, if any, as [`to_py`] makes it.
    fn py(self) -> PyResult<T>;
}

impl<T, E: Into<anyhow::Error>> IntoPy<T> for Result<T, E> {
    fn py(self) -> PyResult<T> {
        self.map_err(|e| to_py(e.into()))
    }
}
