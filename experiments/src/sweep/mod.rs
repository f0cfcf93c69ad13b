//! Sweeps: many runs from one file, run here (N at a time), split into shards over
//! machines, or submitted as a Slurm job array, and collected into one report.
//!
//! - [`config`]: the sweep file ([`SweepConfig`]): a base run config, overrides, axes,
//!   groups and Slurm resources;
//! - [`expand`]: the sweep as a [`Plan`] of validated runs with stable ids (a hash of the
//!   resolved config);
//! - [`shard`]: `--shard i/n`, a deterministic subset;
//! - [`layout`]: the names in a sweep's output folder (`sweep.json`, `runs/`, …);
//! - [`local`]: the runner (skip finished, resume interrupted, re-do failed; atomic run
//!   folders);
//! - [`slurm`]: the job-array script and its submission;
//! - [`collect`]: every run's summary in one table, aggregated, with plots and a Markdown
//!   report;
//! - [`pack`]: finished runs in one compressed file (`runs.jsonl.gz`), the compact form
//!   committed results are kept in, read by `collect`, the runner and `--adopt` as folders are.
//!
//! Sweeps know runs only through [`crate::runs::RunConfig`], so every problem `ifslab run`
//! accepts can be swept.

pub mod collect;
pub mod config;
pub mod expand;
pub mod layout;
pub mod local;
pub mod pack;
pub mod paired;
pub mod report;
pub mod shard;
pub mod slurm;

pub use config::SweepConfig;
pub use expand::{Plan, PlannedRun};
pub use local::{
    FinishedRuns, RunStatus, RunnerOptions, SweepOutcome, check_lpips_weights, run_sweep,
};
pub use shard::Shard;
