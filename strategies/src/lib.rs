//! # ifslab-strategies
//!
//! Inversion strategies: each family in its own folder, each variant in its own file.
//!
//! - [`em`]: expectation–maximisation for similitude IFSs fitted to point clouds (any dimension).
//! - [`fractal_coding`]: fractal-coding texture upsampling (partitioned IFS per texel).
#![warn(missing_docs)]

pub mod em;
pub mod error;
pub mod fractal_coding;

pub use error::{Error, Result};
