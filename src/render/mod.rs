//! Renderers: points to pictures.
//!
//! - [`view`]: which part of the plane an image shows (its [`Window`](crate::model::Window))
//!   — fit to the attractor with the papers' padding (longest side spans 75% of the frame),
//!   an explicit window, zoom views.
//! - [`raster`]: the evaluation renderer, streaming tens of millions of chaos-game points
//!   into binary-coverage (supersampled) or density images without storing them.
//! - [`image_io`]: 8/16-bit PNG output and grey image loading.
//!
//! - [`splat`]: the differentiable Gaussian point splatter (fused chaos game + splat with a
//!   hand-written reverse pass), also as a candle `CustomOp1`.
//!
//! - [`splat3d`]: the differentiable multi-view splat — a 3-D chaos game projected by
//!   cameras (pinhole or orthographic, NeRF poses, turntables, `transforms.json`) and
//!   splatted per view by the 2-D splat's kernel, with its reverse pass to the maps.
//!
//! - [`flame`]: the fractal flame renderer (flam3's algorithm: colour + density
//!   histogram, density estimation, log tone map), deterministic and parallel.
//! - [`flame_diff`]: the differentiable flame pipeline of *Learnable Fractal Flames*
//!   (sampler → splatter → painter → compositor, RGB), with its reverse pass.
//!
//! - [`sdf`]: the differentiable SDF rasteriser of segment-map IFSs (distance to the
//!   nearest primitive of every word up to depth K, tiled branch-and-bound over the word
//!   tree, reverse pass to the control points).
//!
//! The differentiable renderers — [`splat::Splat`], [`sdf::SdfRenderer`],
//! [`flame_diff::FlameRenderer`], [`splat3d::MultiViewSplat`] — implement one trait,
//! [`Renderer`] (scene and sampling state → image, `∂L/∂image` → `∂L/∂θ`; [`renderer`]).

pub mod flame;
pub mod flame_diff;
pub mod image_io;
pub mod raster;
pub mod renderer;
pub mod sdf;
pub mod splat;
pub mod splat3d;
pub mod view;

pub use raster::{Raster, RenderConfig, RenderMode, RenderStats, render, render_with_isa};
pub use renderer::{Draws, Planes, Renderer, Sampler, value_and_grad};
/// [`view`]'s former name.
#[doc(hidden)]
pub use view as framing;
pub use view::{FIT_FILL, View, Zoom, fit_window, zoom_window};
