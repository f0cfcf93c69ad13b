//! # ifslab
//!
//! The core of ifslab, a framework for the *fractal inverse problem*: given an image, a
//! point cloud or a texture, find the Iterated Function System that generates it.
//!
//! This crate holds what every inversion strategy shares:
//! - [`model`]: maps (affine, similitudes), parameterisations θ ↔ maps, code files, the
//!   classic and random codes;
//! - [`chaos`]: deterministic, parallel chaos-game point generators;
//! - [`isa`]: the instruction-set policy (decided once per run, hot loops compiled per
//!   instruction set);
//! - [`math`]: maths shared by models and renderers (fast trigonometry, dual numbers, the
//!   float-type traits);
//! - [`image`]: the one image type (grey, RGB or RGBA planes of `f32`; ↔ candle tensors,
//!   PNG files);
//! - [`render`]: the fast evaluation renderer (tens of millions of points at any zoom);
//! - [`loss`]: image losses (multi-scale MSE, D-SSIM, moments, LPIPS) on grey or colour
//!   images and the map regulariser, each with its gradient, composable as candle tensors;
//! - [`metrics`]: IoU, box-counting dimension and friends; [`metrics3d`]: voxel IoU with a
//!   tolerance and Chamfer distance of 3-D point sets.
//!
//! Strategies live in the `ifslab-strategies` crate and the `ifslab` command in
//! `ifslab-experiments`.
#![warn(missing_docs)]

pub mod budget;
pub mod chaos;
pub mod error;
pub mod image;
pub mod interrupt;
pub mod io;
pub mod isa;
pub mod loss;
pub mod math;
pub mod metrics;
pub mod metrics3d;
pub mod model;
pub mod progress;
pub mod render;

pub use error::{Error, Result};
