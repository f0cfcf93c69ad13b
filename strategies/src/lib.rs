//! # ifslab-strategies
//!
//! How IFS codes are found: generic optimisers apart from the problems they solve.
//!
//! - [`optim`]: the generic optimisers — [`optim::adam`], [`optim::hybrid`] (Adam with
//!   simulated-annealing phases), [`optim::annealing`], [`optim::noisy`], [`optim::gd`];
//! - [`registry`]: every optimiser a run can name (one line each), and
//!   [`strategy_config`], the `[strategy]` section of every problem's config that picks one;
//! - [`driver`]: what every iterative optimiser shares (the `Differentiable` problem
//!   interface, hyper-parameter `Params`, checkpoints, logs);
//! - [`problems`]: [`problems::image`] (image → IFS code with the differentiable splatter and
//!   any registered optimiser), [`problems::em`] (EM for similitude IFSs fitted to point
//!   clouds of any dimension), [`problems::fractal_coding`] (fractal-coding texture
//!   upsampling);
//! - [`recipe`]: ifslab's defaults and the papers' recipes (`paper = true`), as presets merged
//!   into configs where they leave keys out;
//! - [`plugins`]: strategies and map families added from another crate, without editing this
//!   one.
#![warn(missing_docs)]

pub mod driver;
pub mod error;
pub mod optim;
pub mod plugins;
pub mod problems;
pub mod recipe;
pub mod registry;
pub mod strategy_config;

pub use error::{Error, Result};
