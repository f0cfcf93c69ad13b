//! Fractal flames (Draves & Reckase): transforms with non-linear variations, coloured by
//! the transforms that produced each point, in flam3 3.1.1's model and `.flame` format.
//!
//! - [`variation`]: the 99 variations of flam3 3.1.1 — names, parameters, defaults;
//! - [`variations`]: their formulas (one file per family), written once over [`FlameScalar`] so
//!   the same code renders (`f64`) and differentiates ([`Dual`]);
//! - [`xform`]: a transform — pre-affine, weighted variations, post-affine, colour — with
//!   its Jacobian and vector–Jacobian products;
//! - [`genome`]: a whole flame with its camera and rendering settings;
//! - [`learnable`]: the learnable flames of Bannister & Nowrouzezahrai — layers of
//!   generators, final transform, quality blend and colours, their θ, and their export;
//! - [`palette`]: 256-entry palettes and flam3's palette library;
//! - [`format`]: `.flame` XML read and write;
//! - [`random`]: random flames in flam3-genome's style, affine codes as flames, the
//!   attractor's bounding box;
//!
//! Rendering lives in [`crate::render::flame`].
//!
//! ## References
//! - S. Draves, E. Reckase, "The Fractal Flame Algorithm", 2008.
//! - flam3 3.1.1 (`variations.c`, `parser.c`, `flam3.c`), the reference implementation
//!   whose formulas, defaults and conventions this module follows.

pub mod format;
pub mod genome;
pub mod learnable;
pub mod palette;
pub mod random;
pub mod scalar;
pub mod variation;
pub mod variations;
pub mod xform;

pub use format::{flames_to_string, parse_flames, read_flames, write_flames};
pub use genome::{FilterShape, Flame, Kernel, PaletteMode};
pub use palette::Palette;
pub use random::{Bounds, RandomFlameConfig, estimate_bounds, flame_from_affine, random_flame};
pub use scalar::{Dual, FlameScalar};

/// The variations' `sin`, `cos`, `sin_cos` and `atan2`, now [`crate::math::trig`] (kept at
/// this path, where they were first).
#[doc(hidden)]
pub use crate::math::trig as fast_math;
pub use variation::{Variation, VariationKind};
pub use xform::{Applied, Coefs, IDENTITY, PreparedXform, SmoothXform, Xform, affine_of, coefs_of};
