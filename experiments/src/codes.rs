//! Codes named on the command line or in configs.

use std::path::Path;

use crate::Error;
use crate::error::Context;
use ifslab::model::{IfsCode, library};

/// A code from a file path or a built-in name.
pub fn resolve_code(spec: &str) -> crate::Result<IfsCode> {
    let path = Path::new(spec);
    // A folder named like a built-in code (the output of an earlier `invert maple -o maple`,
    // or this run's own, made before the code is read) is no code file: the name wins.
    let folder_named_like_a_code = path.is_dir() && library::builtin(spec).is_ok();
    if path.exists() && !folder_named_like_a_code {
        return IfsCode::load(path).with_context(|| format!("loading code file {spec}"));
    }
    match library::builtin(spec) {
        Ok(code) => Ok(code),
        // A name with a folder or an extension was meant as a file: say it is missing
        // rather than list the built-in codes.
        Err(_) if looks_like_path(spec) => Err(missing_file(spec)),
        Err(e) => Err(Error::invalid(format!(
            "`{spec}` is neither a file here nor a built-in code ({e})"
        ))),
    }
}

/// Whether `spec` reads as a file's name (it has a folder or an extension) rather than a
/// built-in name.
pub fn looks_like_path(spec: &str) -> bool {
    spec.contains(['/', '\\']) || Path::new(spec).extension().is_some()
}

/// The error for a file that is not there: its name, and the folder a relative name was
/// looked for in.
pub fn missing_file(spec: &str) -> Error {
    let path = Path::new(spec);
    let message = if path.is_relative()
        && let Ok(cwd) = std::env::current_dir()
    {
        format!(
            "no such file: `{spec}` (looked for it in {})",
            cwd.display()
        )
    } else {
        format!("no such file: `{spec}`")
    };
    Error::NotFound {
        path: path.to_owned(),
        message,
    }
}
