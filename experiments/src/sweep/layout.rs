//! What a sweep's output folder holds: its index, the folder of its runs, and the files a
//! run folder gets besides the run's own outputs. The runner ([`super::local`]), the packs
//! ([`super::pack`]) and `collect` all read these names from here.

use std::path::{Path, PathBuf};

/// The sweep's index in its output folder.
pub const PLAN_FILE: &str = "sweep.json";
/// The run folders' parent.
pub const RUNS_DIR: &str = "runs";
/// What a finished run folder holds besides the run's own outputs.
pub const RECORD_FILE: &str = "run.json";
/// What a failed attempt leaves in its partial folder.
pub const ERROR_FILE: &str = "error.txt";

/// The folder of a finished run.
pub fn run_dir(out: &Path, id: &str) -> PathBuf {
    out.join(RUNS_DIR).join(id)
}

/// The folder a run works in until it is finished.
pub fn partial_dir(out: &Path, id: &str) -> PathBuf {
    out.join(RUNS_DIR).join(format!(".{id}.partial"))
}
