//! IFS models: maps, their parameterisations, probabilities, code files, and the codes
//! that come with the library (classic ones and random ones).
//!
//! - [`map`]: the map traits in any dimension — [`Map`], what generators iterate, and
//!   [`DiffMap`], what a differentiable renderer's reverse pass needs (a flat parameter
//!   vector, vector–Jacobian products at a point) — with [`Map2`]/[`DiffMap2`] their names in
//!   the plane, the flat layout of a set of maps, and the finite-difference check.
//! - [`affine`]: 2-D affine maps (the renderers' map) and dimension-generic ones.
//! - [`diff_map`]: the plane's differentiable maps [`Affine2`] and [`Similitude2`], and
//!   [`AffinePart`], the affine map the regulariser sees in a non-affine one.
//! - [`param`]: raw vector θ ↔ maps, with the chain rule and projection.
//! - [`similitude`]: `s·R·x + t` in any dimension (EM's family).
//! - [`probs`]: uniform, ∝|det| with a floor, explicit.
//! - [`code`]: the JSON code file, validated on load.
//! - [`library`]: Sierpiński, fern, Koch, carpet, dragon, … by name.
//! - [`random`]: the Anderson–Farrell random-code sampler.
//! - [`segment`]: segment maps — control points and a symmetry pattern of segment pairs,
//!   each pair a similitude (Scott's differentiable IFS), with the chain rule to the points.
//! - [`map3`]: maps of space (affine, the SVD parameterisation in 3-D, similitudes) with
//!   their vector–Jacobian products, what the multi-view splat trains.
//! - [`flame`]: fractal flames — flam3's 99 variations, transforms with exact Jacobians,
//!   `.flame` files.

pub mod affine;
pub mod code;
pub mod diff_map;
pub mod flame;
pub mod library;
pub mod map;
pub mod map3;
pub mod param;
pub mod probs;
pub mod random;
pub mod segment;
pub mod similitude;

pub use affine::{Affine2, AffineN};
#[allow(deprecated)] // the former name, kept for code written against it
pub use code::{Framing, IfsCode, Window};
pub use diff_map::{AffinePart, Similitude2};
pub use map::{DiffMap, DiffMap2, Map, Map2};
pub use param::{Naive, ParamKind, Parameterisation, Svd};
pub use probs::ProbabilityRule;
pub use similitude::Similitude;
