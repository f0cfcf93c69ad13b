//! The library's errors as Python exceptions, carrying the library's own words: the whole
//! chain on one line (`{:#}`), as the command line prints it.

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
        // The library's typed error knows what it is under its context.
        if let Some(lib) = cause.downcast_ref::<ifslab_experiments::Error>() {
            if lib.is_interrupted() {
                return PyKeyboardInterrupt::new_err(message);
            }
            if lib.is_not_found() {
                return PyFileNotFoundError::new_err(message);
            }
        }
        // This crate's own calls into the strategies and the core.
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
