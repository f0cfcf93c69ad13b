//! Which instruction set the chaos game's hot loop runs with, chosen once per run.
//!
//! [`Map2::apply`](crate::model::Map2::apply) for affine maps is four `f64::mul_add`s. A
//! default x86-64 build may not assume the CPU has FMA, so each `mul_add` compiles to a call
//! into the runtime's `fma` routine (which then picks a hardware or software fused
//! multiply–add), with the caller's floating-point registers spilled around every call.
//! The streaming loop ([`PointStream`](super::PointStream)) is therefore compiled twice:
//! once as the build targets, once with the `avx2`, `fma`, `bmi1` and `bmi2` target
//! features (every CPU with AVX2 since 2013 has all four), where each `mul_add` is a single
//! `vfmadd` instruction and variable shifts are one instruction. The second copy runs when
//! the CPU reports all four.
//!
//! A fused multiply–add is exactly rounded however it is computed (instruction, or the
//! runtime's exact software routine), so the two copies give the same points bit for bit
//! (tested in `tests/chaos.rs` and `tests/render.rs`).

use crate::error::{Error, Result};

/// The instruction set a hot loop is compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Isa {
    /// What the build targets (baseline x86-64: `mul_add` is a call).
    Portable,
    /// x86-64 with AVX2, FMA and BMI1/2: `mul_add` is one instruction.
    Fma,
}

impl Isa {
    /// The fastest instruction set this CPU supports.
    pub fn detect() -> Isa {
        if Isa::Fma.is_available() {
            Isa::Fma
        } else {
            Isa::Portable
        }
    }

    /// Whether this CPU can run code compiled for `self`.
    pub fn is_available(self) -> bool {
        match self {
            Isa::Portable => true,
            Isa::Fma => has_fma(),
        }
    }

    /// `self`, or an error naming what the CPU lacks.
    pub fn checked(self) -> Result<Isa> {
        if self.is_available() {
            Ok(self)
        } else {
            Err(Error::param(
                "isa",
                format!(
                    "this CPU cannot run the {self:?} code path (it lacks AVX2, FMA or BMI2); use Isa::Portable or Isa::detect()"
                ),
            ))
        }
    }
}

#[cfg(target_arch = "x86_64")]
fn has_fma() -> bool {
    std::arch::is_x86_feature_detected!("avx2")
        && std::arch::is_x86_feature_detected!("fma")
        && std::arch::is_x86_feature_detected!("bmi1")
        && std::arch::is_x86_feature_detected!("bmi2")
}

#[cfg(not(target_arch = "x86_64"))]
fn has_fma() -> bool {
    false
}
