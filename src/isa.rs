//! The instruction-set policy: which instruction set a hot loop runs with, decided once per
//! run, and the hot loops compiled once per instruction set.
//!
//! A default x86-64 build may not assume the CPU has FMA or AVX2, so every `f64::mul_add`
//! compiles to a call into the runtime's `fma` routine (with the caller's floating-point
//! registers spilled around it) and no AVX2 instruction can be emitted. Every hot loop of
//! the crate is therefore compiled twice: once as the build targets ([`Isa::Portable`]),
//! once with the `avx2`, `fma`, `bmi1` and `bmi2` target features ([`Isa::Fma`]; every CPU
//! with AVX2 since 2013 has all four), where each `mul_add` is one `vfmadd` instruction. The
//! maths inside a loop (affine maps, [`crate::math::trig`], the flame variations) is
//! `#[inline(always)]`, so it is compiled as part of each copy.
//!
//! The rules, which every renderer follows:
//! - **one decision per run**: an [`Isa`] value is picked where a run (a render, a forward
//!   pass, an encoding) starts — [`Isa::detect`], or the caller's choice checked by
//!   [`Isa::checked`] — and handed down; nothing below that point asks the CPU again;
//! - **per-ISA copies of the loop**, chosen by one `match` on that value outside the loop:
//!   a `#[target_feature(enable = "avx2,fma,bmi1,bmi2")]` function for [`Isa::Fma`] whose
//!   body is the same `#[inline(always)]` loop as the portable one;
//! - code that is generic over the instruction set below the loop (the flame variations,
//!   compiled out of line per instruction set) takes a type-level token ([`IsaLevel`]):
//!   [`PortableIsa`], or [`FmaIsa`], which only the checked paths can make;
//! - **the same bits on every path**: a fused multiply–add is exactly rounded however it
//!   is computed (one instruction, or the runtime's exact software routine), neither copy
//!   contracts a multiply and an add that the source keeps apart, and the SIMD loops do the
//!   scalar loops' operations lane by lane in the same order. So the two copies of every
//!   loop give the same results bit for bit (tested per renderer: `tests/chaos.rs`,
//!   `tests/render.rs`, `tests/splat.rs`, `tests/flame_diff.rs`, `tests/flame_render.rs`).

use std::sync::atomic::{AtomicU8, Ordering};

use crate::error::{Error, Result};

/// The instruction set a hot loop is compiled for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Isa {
    /// What the build targets (baseline x86-64: `mul_add` is a call, no AVX2).
    Portable,
    /// x86-64 with AVX2, FMA and BMI1/2: `mul_add` is one instruction, 8-lane `f32` loops.
    Fma,
}

impl Isa {
    /// The fastest instruction set this CPU supports (asked of the CPU once per process,
    /// then a load of the cached answer).
    pub fn detect() -> Isa {
        static DETECTED: AtomicU8 = AtomicU8::new(0);
        match DETECTED.load(Ordering::Relaxed) {
            1 => Isa::Portable,
            2 => Isa::Fma,
            _ => {
                let isa = if has_fma() { Isa::Fma } else { Isa::Portable };
                DETECTED.store(if isa == Isa::Fma { 2 } else { 1 }, Ordering::Relaxed);
                isa
            }
        }
    }

    /// Whether this CPU can run code compiled for `self`.
    pub fn is_available(self) -> bool {
        match self {
            Isa::Portable => true,
            Isa::Fma => Isa::detect() == Isa::Fma,
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

/// An instruction set known at compile time: which copy of a hot loop is running. Code
/// generic over it picks its out-of-line helpers by `Self::ISA`, a constant, so the choice
/// costs nothing in the loop.
pub trait IsaLevel: Copy + Send + Sync + std::fmt::Debug + 'static + sealed::Sealed {
    /// The instruction set.
    const ISA: Isa;
}

/// The portable copy's token.
#[derive(Clone, Copy, Debug, Default)]
pub struct PortableIsa;

/// The [`Isa::Fma`] copy's token: a value exists only where the CPU was found to have AVX2,
/// FMA and BMI1/2, so code holding one may call `#[target_feature]` functions compiled for
/// them.
#[derive(Clone, Copy, Debug)]
pub struct FmaIsa(());

impl FmaIsa {
    /// The token, if this CPU has the features.
    pub fn detect() -> Option<FmaIsa> {
        Isa::Fma.is_available().then_some(FmaIsa(()))
    }

    /// The token without asking the CPU.
    ///
    /// # Safety
    /// The CPU must have AVX2, FMA, BMI1 and BMI2: call it only in code reached through a
    /// dispatch on [`Isa::Fma`] (a checked or detected value), e.g. inside the
    /// `#[target_feature]` copy of a loop.
    #[inline(always)]
    pub unsafe fn new_unchecked() -> FmaIsa {
        FmaIsa(())
    }
}

impl IsaLevel for PortableIsa {
    const ISA: Isa = Isa::Portable;
}

impl IsaLevel for FmaIsa {
    const ISA: Isa = Isa::Fma;
}

mod sealed {
    pub trait Sealed {}
    impl Sealed for super::PortableIsa {}
    impl Sealed for super::FmaIsa {}
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detection_is_stable_and_tokens_follow_it() {
        let isa = Isa::detect();
        assert_eq!(Isa::detect(), isa);
        assert_eq!(isa, if has_fma() { Isa::Fma } else { Isa::Portable });
        assert!(Isa::Portable.checked().is_ok());
        assert_eq!(FmaIsa::detect().is_some(), isa == Isa::Fma);
        assert_eq!(Isa::Fma.checked().is_ok(), isa == Isa::Fma);
    }
}
