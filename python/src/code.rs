//! Code files (`ifslab-code/1`): read, validated and written by the library, crossing to
//! Python as JSON text (Python's `json` reads the shortest round-trip floats the library
//! writes back to the same bits).

use std::path::Path;

use anyhow::Context;
use ifslab::model::IfsCode;
use ifslab_experiments::codes::resolve_code;
use pyo3::prelude::*;

use crate::errors::IntoPy;

/// Where a code dict comes from, in error messages.
const DICT_ORIGIN: &str = "the code dict";

/// A code from `code`: JSON text of a code document when `is_json`, else a file name or a
/// built-in name (as the command line takes it).
pub fn resolve(code: &str, is_json: bool) -> anyhow::Result<IfsCode> {
    if is_json {
        Ok(IfsCode::from_json(code, Path::new(DICT_ORIGIN))?)
    } else {
        Ok(resolve_code(code)?)
    }
}

/// The validated code document of `code` (JSON text, a file or a built-in name) as JSON text.
#[pyfunction]
#[pyo3(signature = (code, is_json))]
pub fn code_json(code: &str, is_json: bool) -> PyResult<String> {
    Ok(resolve(code, is_json).py()?.to_json())
}

/// Reads and validates a code file; its document as JSON text.
#[pyfunction]
pub fn load_code(path: &str) -> PyResult<String> {
    let code = IfsCode::load(path)
        .with_context(|| format!("loading code file {path}"))
        .py()?;
    Ok(code.to_json())
}

/// Validates a code document (JSON text) and writes it as the command line writes codes
/// (pretty JSON, atomically).
#[pyfunction]
pub fn save_code(code: &str, path: &str) -> PyResult<()> {
    let code = IfsCode::from_json(code, Path::new(DICT_ORIGIN)).py()?;
    code.save(path).py()
}

/// The built-in codes' names.
#[pyfunction]
pub fn builtin_codes() -> Vec<String> {
    ifslab::model::library::names()
        .into_iter()
        .map(str::to_owned)
        .collect()
}
