//! One module per subcommand: its clap `Args` and a `run` function.

pub mod codes;
pub mod demo;
pub mod fit_points;
pub mod flame;
pub mod invert;
pub mod landscape;
pub mod render;
pub mod run;
pub mod sample;
pub mod texture;
pub mod weights;

use std::path::Path;

use anyhow::Context;
use ifslab::model::{IfsCode, library};

/// A code from a file path or a built-in name.
pub fn resolve_code(spec: &str) -> anyhow::Result<IfsCode> {
    let path = Path::new(spec);
    if path.exists() {
        return IfsCode::load(path).with_context(|| format!("loading code file {spec}"));
    }
    library::builtin(spec)
        .map_err(|e| anyhow::anyhow!("`{spec}` is neither a code file nor a built-in code ({e})"))
}
