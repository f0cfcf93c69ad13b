//! # ifslab-strategies
//!
//! Inversion strategies: each family in its own folder, each variant in its own file.
//!
//! - [`driver`]: what every iterative strategy shares (problem interface, checkpoints, logs);
//! - [`registry`]: every strategy a run can name (one line each);
//! - [`adam`], [`hybrid`], [`annealing`], [`noisy`], [`gd`]: gradient and annealing strategies;
//! - [`image`]: image → IFS code with the differentiable splatter and any of those strategies;
//! - [`em`]: expectation–maximisation for similitude IFSs fitted to point clouds (any dimension).
//! - [`fractal_coding`]: fractal-coding texture upsampling (partitioned IFS per texel).
#![warn(missing_docs)]

pub mod adam;
pub mod annealing;
pub mod driver;
pub mod em;
pub mod error;
pub mod fractal_coding;
pub mod gd;
pub mod hybrid;
pub mod image;
pub mod noisy;
pub mod registry;

pub use error::{Error, Result};
