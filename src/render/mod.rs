//! Renderers: points to pictures.
//!
//! - [`framing`]: which part of the plane an image shows — fit to the attractor with the
//!   papers' padding (longest side spans 75% of the frame), an explicit window, zoom views.
//! - [`raster`]: the evaluation renderer, streaming tens of millions of chaos-game points
//!   into binary-coverage (supersampled) or density images without storing them.
//! - [`image_io`]: 8/16-bit PNG output and grey image loading.
//!
//! The differentiable splatter and SDF rasteriser join here as `splat` and `sdf`.

pub mod framing;
pub mod image_io;
pub mod raster;

pub use framing::{FIT_FILL, View, Zoom, fit_window, zoom_window};
pub use raster::{Raster, RenderConfig, RenderMode, RenderStats, render};
