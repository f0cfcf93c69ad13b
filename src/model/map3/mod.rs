//! Maps of space (R³): what the 3-D chaos game iterates and the multi-view splat
//! differentiates.
//!
//! The maps implement the traits of [`crate::model::map`] at `D = 3`: the forward
//! [`Map<3>`](crate::model::map::Map) and, to be trained through the multi-view splat
//! ([`crate::render::splat3d`]), [`DiffMap<3>`](crate::model::map::DiffMap) — a flat
//! parameter vector and the two vector–Jacobian products at a point, `(∂f/∂x)(x)ᵀ·λ` and
//! `(∂f/∂θ)(x)ᵀ·λ`, which the backward scan of [`crate::chaos::Tape3`] calls once per step.
//! [`Map3`] and [`DiffMap3`] are those traits' names in space, as
//! [`Map2`](crate::model::Map2) and [`DiffMap2`](crate::model::DiffMap2) are in the plane;
//! the flat layout and the finite-difference check are the same functions in both.
//!
//! Implementations:
//! - [`Affine3`]: the twelve coefficients of `x ↦ M·x + b` (row-major `M`, then `b`): the
//!   form codes are written in and ground truths are drawn with;
//! - [`SvdMap3`]: the chaotic-splatting paper's SVD parameterisation taken to 3-D,
//!   `M = R(q_U)·diag(c·sigmoid σ)·R(q_V)ᵀ`, `b = tanh β`, the rotations unit quaternions
//!   (any non-zero 4-vector, normalised when decoded): every θ is a contraction;
//! - [`Similitude3`]: `x ↦ s·R(q)·F·x + t` (`F` an optional mirror), the EM family in 3-D.
//!
//! [`vjp_check`] is the finite-difference check every implementation should pass.

mod affine3;
mod rotation;
mod similitude3;
mod svd3;

pub use affine3::{Affine3, fern_3d, sierpinski_tetrahedron};
pub use rotation::{quaternion_from_rotation, rotation_from_quaternion, rotation_jacobian};
pub use similitude3::Similitude3;
pub use svd3::{SVD3_PARAMS, SvdMap3};

pub use crate::model::map::{
    DiffMap, DiffMap3, Map, Map3, VjpCheck, flat_params, param_offsets, set_flat_params, vjp_check,
};
