//! # ifslab-experiments
//!
//! Everything a run does, as a library: a config in, a run folder out (checkpoints, resume,
//! `log.csv`, renders, zoom strips, loss plots, `summary.json`), with progress reported
//! through [`progress::Progress`] rather than drawn. The `ifslab` binary (`src/main.rs`,
//! `src/cmd/`) parses arguments and draws progress bars on top of it; sweeps and other
//! front ends call the same functions.
//!
//! - [`runs::inversion`]: image inversion runs (`ifslab invert`, `ifslab run`, `ifslab demo`);
//! - [`runs::landscape`]: loss landscapes of a run (`ifslab landscape`);
//! - [`plot`]: line charts, scatter plots and heat maps with a bundled font;
//! - [`progress`]: the progress callback;
//! - [`codes::resolve_code`]: a code from a file or a built-in name;
//! - [`sweep`]: many runs from one sweep file: locally, in shards, as a Slurm job array, and
//!   their collected report.
#![warn(missing_docs)]

pub mod codes;
pub mod plot;
pub mod progress;
pub mod runs;
pub mod sweep;
