//! # ifslab-experiments
//!
//! Everything a run does, as a library: a config in, a run folder out (checkpoints, resume,
//! `log.csv`, renders, zoom strips, loss plots, `summary.json`), with progress reported
//! through [`progress::Progress`] rather than drawn. The `ifslab` binary (`src/main.rs`,
//! `src/cmd/`) parses arguments and draws progress bars on top of it; sweeps and other
//! front ends call the same functions.
//!
//! - [`runs::RunConfig`]: any config `ifslab run` accepts, by its `problem` key, and the one
//!   call that runs it;
//! - [`runs::inversion`]: image inversion runs (`ifslab invert`, `ifslab run`, `ifslab demo`),
//!   checkpointed every `checkpoint_every` iterations;
//! - [`runs::points`]: point cloud → IFS of similitudes by EM, best-of-N fits and pool
//!   sweeps (`ifslab fit-points`, `problem = "points"`), each finished fit checkpointed;
//! - [`runs::texture`]: fractal-coding texture upsampling (`ifslab texture`,
//!   `problem = "texture"`; one encoding of seconds, not checkpointed) and the paper's tables
//!   and figures ([`runs::texture::repro`], resumable per texture);
//! - [`runs::landscape`]: loss landscapes of a run (`ifslab landscape`);
//! - [`plot`]: line charts, scatter plots, heat maps and vector fields with a bundled font;
//! - [`progress`]: the progress callback;
//! - [`error`]: the library's typed [`Error`] (every call returns [`Result`]), so a caller can
//!   match on what went wrong (`is_interrupted`, `is_not_found`, a file's `Io` or `Config`);
//! - [`codes::resolve_code`]: a code from a file or a built-in name;
//! - [`inputs::parse`]: every input format parsed from bytes (fuzz targets, regression corpus);
//! - [`serve`]: the zoom viewer's web server (`ifslab serve`);
//! - [`sweep`]: many runs from one sweep file: locally, in shards, as a Slurm job array, and
//!   their collected report.
#![warn(missing_docs)]

pub use error::{Error, Result};

pub mod codes;
pub mod error;
pub mod inputs;
pub mod plot;
pub mod progress;
pub mod runs;
pub mod serve;
pub mod suite;
pub mod sweep;
