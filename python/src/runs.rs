//! Runs through the run API the command line and the sweeps call: a config ([`RunConfig`],
//! from a dict or a TOML file) run into a folder by [`RunConfig::run`], with the GIL
//! released, progress reported to Python and Ctrl-C stopping the run at its next checkpoint.

use std::path::{Path, PathBuf};

use anyhow::Context;
use ifslab_experiments::runs::RunConfig;
use ifslab_experiments::runs::inversion::CONFIG_FILE;
use pyo3::prelude::*;

use crate::errors::IntoPy;
use crate::progress::PyProgress;

/// Where a config dict comes from, in error messages (relative file names in it are read
/// from the working folder).
const DICT_ORIGIN: &str = "the Python config";

/// The config of a run: `config` is JSON text of a config table (`source = "dict"`), the
/// name of a TOML file (`"file"`, `overrides` as `ifslab run --set` takes them), or a run
/// folder to resume (`"resume"`: its resolved `config.toml`).
fn config_of(source: &str, config: &str, overrides: &[String]) -> anyhow::Result<RunConfig> {
    match source {
        "dict" => {
            let value: serde_json::Value =
                serde_json::from_str(config).context("the config dict is not JSON")?;
            let mut table = toml::Table::try_from(value)
                .context("the config dict does not fit a TOML table")?;
            for o in overrides {
                let (key, value) = ifslab_experiments::runs::config::parse_override(o)?;
                ifslab_experiments::sweep::expand::set_dotted(&mut table, &key, value)
                    .with_context(|| format!("applying `{o}`"))?;
            }
            Ok(RunConfig::from_table(table, Path::new(DICT_ORIGIN))?)
        }
        "file" => Ok(RunConfig::load_with(Path::new(config), overrides)?),
        "resume" => {
            let dir = Path::new(config);
            RunConfig::load_resolved(&dir.join(CONFIG_FILE))
                .with_context(|| format!("reading the run in {}", dir.display()))
        }
        other => anyhow::bail!("unknown config source `{other}`"),
    }
}

/// The resolved config (every default written out) of a config, as JSON text: what a run
/// folder's `config.toml` will hold.
#[pyfunction]
#[pyo3(signature = (source, config, overrides=Vec::new()))]
pub fn resolve_config(source: &str, config: &str, overrides: Vec<String>) -> PyResult<String> {
    let cfg = config_of(source, config, &overrides).py()?;
    let table = cfg.to_table().py()?;
    serde_json::to_string(&table).py()
}

/// Runs a config (see [`config_of`]) into `dir` (with `resume`, continues the interrupted
/// run there); the [`RunReport`](ifslab_experiments::runs::RunReport) as JSON text.
#[pyfunction]
#[pyo3(signature = (source, config, dir, resume=false, overrides=Vec::new(), progress=None))]
pub fn run(
    py: Python<'_>,
    source: &str,
    config: &str,
    dir: PathBuf,
    resume: bool,
    overrides: Vec<String>,
    progress: Option<Py<PyAny>>,
) -> PyResult<String> {
    let cfg = config_of(source, config, &overrides).py()?;
    // A run interrupted earlier in this process left the library's stop flag set: withdraw
    // it, unless another run (another Python thread) is still stopping on it.
    if !ifslab::interrupt::clear() {
        return Err(crate::errors::IfslabError::new_err(
            "another run in this Python process is stopping at its checkpoint after an \
             interruption: start this one once it has returned",
        ));
    }
    let watch = PyProgress::new(progress, true);
    let reporter = watch.boxed();
    let report = py.detach(move || cfg.run(&dir, resume, reporter));
    let report = watch.finish(report.py())?;
    serde_json::to_string(&report).py()
}
