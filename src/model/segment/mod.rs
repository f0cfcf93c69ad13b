//! Segment maps: an IFS drawn from control points (Scott's differentiable IFS).
//!
//! A [`Pattern`] holds control points `P = {p₀, …, p_{n−1}}` in the plane, a symmetry
//! pattern `L` of [`Pair`]s `(source segment, target segment)` — each pair of point indices —
//! and a [`BaseFigure`]. Every pair defines the similitude ([`SegmentMap`], `z ↦ w·z + t` in
//! complex notation) taking its source segment onto its target segment; those maps are the
//! IFS. The points are the parameters an optimiser moves; [`Pattern::maps_backward`] carries
//! gradients from the maps back to them (hand-written vector–Jacobian products, checked
//! against finite differences in `tests/segment.rs`).
//!
//! - [`map`]: the segment-to-segment similitude and its chain rule;
//! - [`pattern`]: the validated pattern (indices in range, no zero-length segment,
//!   contractive maps, finite points);
//! - [`file`]: the JSON file `ifslab-pattern/1`;
//! - [`library`]: `koch`, `carpet`, `carpet-square`.
//!
//! The SDF renderer (`render::sdf`) draws a pattern and differentiates the drawing.
//!
//! ## References
//! - Scott, *Differentiable Iterated Function Systems*, Differentiable Almost Everything
//!   workshop, ICML 2024.

pub(crate) mod complex;
pub mod file;
pub mod library;
pub mod map;
pub mod pattern;

pub use file::{PATTERN_FORMAT, PatternFile};
pub use library::{BUILTIN_PATTERNS, builtin, resolve_pattern};
pub use map::SegmentMap;
pub use pattern::{BaseFigure, Pair, Pattern, PrimitiveKind};
