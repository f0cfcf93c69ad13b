//! The differentiable SDF rasteriser of segment-map IFSs (Scott's differentiable IFS): the
//! base figure of a [`Pattern`](crate::model::segment::Pattern) under every word of its
//! maps up to depth K, each pixel coloured `exp(−d²/σ²)` by its distance `d` to the nearest
//! primitive, with a hand-written reverse pass to the control points.
//!
//! - [`primitive`]: distances to segments, disks and squares on two points, and their
//!   gradients with respect to the points;
//! - [`words`]: the word tree (composed maps, leaf primitives, bottom-up bounding disks) and
//!   its chain rule;
//! - [`raster`]: the tiled branch-and-bound forward pass, the image, the reverse pass;
//! - [`SdfRenderer`]: the raster as a [`Renderer`](crate::render::Renderer) (a pattern to its
//!   intensity and/or distance planes, deterministic).
//!
//! The paper evaluates every pixel against every primitive (a pixels × primitives tensor,
//! its depth limited by GPU memory); here each tile walks the word tree as a bounding-volume
//! hierarchy, so the work per pixel is a few dozen primitives and memory does not grow
//! with pixels × primitives: the depth is limited by time.
//!
//! ## References
//! - Scott, *Differentiable Iterated Function Systems*, Differentiable Almost Everything
//!   workshop, ICML 2024.
//! - Mihai & Hare, *Differentiable Drawing and Sketching*, arXiv:2103.16194 (pixels from
//!   distances).

pub mod primitive;
pub mod raster;
mod renderer;
pub mod words;

pub use raster::{NONE, SdfRaster, SdfRenderConfig, SdfStats, SdfView, TILE, intensity};
pub use renderer::SdfRenderer;
pub use words::{MAX_PRIMITIVES, WordTree};
