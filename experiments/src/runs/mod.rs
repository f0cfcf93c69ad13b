//! Runs as library calls: config → run folder.
//!
//! - [`config`]: [`RunConfig`], any config `ifslab run` accepts (its `problem` key picks the
//!   problem), and [`RunConfig::run`], the one entry every front end calls;
//! - [`inversion`]: image inversion runs;
//! - [`landscape`]: loss landscapes of an image-inversion run folder.

pub mod config;
pub mod inversion;
pub mod landscape;

pub use config::{RunConfig, RunReport};
