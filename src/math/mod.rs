//! Maths shared by the models and the renderers, in one neutral place.
//!
//! - [`trig`]: `sin`, `cos`, `sin_cos`, `atan2` as fdlibm's polynomials with fused
//!   multiply–adds, `#[inline(always)]` so each hot loop's per-instruction-set copy
//!   ([`crate::isa`]) compiles them as its own (the flame variations' elementary functions);
//! - [`dual`]: forward-mode dual numbers (the flame variations' exact Jacobians);
//! - [`real`]: the float types generic code runs in — [`Real`] on the CPU, [`GpuScalar`]
//!   for the CUDA kernels.

pub mod dual;
pub mod real;
pub mod trig;

pub use dual::Dual;
pub use real::{GpuScalar, Real};
