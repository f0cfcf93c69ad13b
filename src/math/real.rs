//! The float types the crate's generic maths runs in.
//!
//! - [`Real`]: `f32` and `f64` as the CPU code is generic over them (the losses, the
//!   metrics, the splat kernel);
//! - [`GpuScalar`]: the precisions the CUDA kernels exist in (`f32` and `f64`). With the
//!   `cuda` feature it also carries what the driver needs to copy a value to the GPU; the
//!   trait exists without the feature too, so generic code names one bound either way.

use std::fmt::Debug;

use num_traits::Float;

/// The float types the CPU code is generic over (`f32` and `f64`).
pub trait Real: Float + Send + Sync + Debug + 'static {}

impl<T: Float + Send + Sync + Debug + 'static> Real for T {}

/// The precisions the GPU kernels exist in.
pub trait GpuScalar: DeviceCopy + Copy + Send + Sync + 'static {
    /// Suffix of this precision's kernels (`"f32"`, `"f64"`).
    #[doc(hidden)]
    const SUFFIX: &'static str;
}

impl GpuScalar for f32 {
    const SUFFIX: &'static str = "f32";
}

impl GpuScalar for f64 {
    const SUFFIX: &'static str = "f64";
}

/// What the CUDA driver needs of a value it copies (with the `cuda` feature).
#[doc(hidden)]
#[cfg(feature = "cuda")]
pub trait DeviceCopy: cudarc::driver::DeviceRepr + cudarc::driver::ValidAsZeroBits + Unpin {}

#[cfg(feature = "cuda")]
impl<T: cudarc::driver::DeviceRepr + cudarc::driver::ValidAsZeroBits + Unpin> DeviceCopy for T {}

/// What the CUDA driver needs of a value it copies (nothing without the `cuda` feature).
#[doc(hidden)]
#[cfg(not(feature = "cuda"))]
pub trait DeviceCopy {}

#[cfg(not(feature = "cuda"))]
impl<T> DeviceCopy for T {}
