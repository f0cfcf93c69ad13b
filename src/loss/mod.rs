//! Image losses and map regularisers, each with its hand-written gradient.
//!
//! The image losses compare a predicted grey image with a target of the same size. Images
//! are row-major `&[T]` slices of `width × height` values in [0, 1], row 0 at the top. Every
//! loss is generic over the float type ([`Real`]: `f64` in the gradient tests, `f32` on the
//! hot path), runs its per-pixel work in parallel with rayon, accumulates its reductions in
//! `f64`, and returns `(value, ∂L/∂pred)`:
//!
//! - [`msmse::MsMse`]: mean squared error summed over a 2×2 average-pooling mip pyramid;
//! - [`ssim::DSsim`]: 1 − SSIM with an 11-pixel Gaussian window (σ = 1.5);
//! - [`moments::Moments`]: squared differences of the images' spatial moments (the paper's
//!   ablation);
//! - [`lpips::Lpips`]: the learned perceptual distance (AlexNet, v0.1 heads), through candle.
//!
//! [`regulariser::Regulariser`] acts on the maps, not on the image: the paper's penalty on
//! singular values, offsets and condition numbers.
//!
//! [`candle_ops`] wraps any [`ImageLoss`] as a candle `CustomOp2` so that losses compose
//! as tensors with the differentiable splatting op, and [`objective`] assembles the paper's
//! weighted sum from a validated [`objective::LossConfig`]. With the `cuda` feature, `cuda`
//! computes MS-MSE and D-SSIM (value and gradient) on an NVIDIA GPU, on the splat's image
//! where it lies (`render::splat::iteration`).
//!
//! ## References
//! - Djeacoumar, Mujkanovic, Seidel, Leimkühler, *Learning Image Fractals Using Chaotic
//!   Differentiable Point Splatting*, Computer Graphics Forum (Eurographics) 2025.
//! - Wang, Bovik, Sheikh, Simoncelli, *Image Quality Assessment: From Error Visibility to
//!   Structural Similarity*, IEEE TIP 2004.
//! - Zhang, Isola, Efros, Shechtman, Wang, *The Unreasonable Effectiveness of Deep Features
//!   as a Perceptual Metric*, CVPR 2018.

pub mod candle_ops;
#[cfg(feature = "cuda")]
pub mod cuda;
pub mod lpips;
pub mod moments;
pub mod msmse;
pub mod objective;
pub mod regulariser;
pub mod ssim;

pub use candle_ops::{LossOp, apply_loss};
pub use lpips::{
    LPIPS_WEIGHTS_ENV, LPIPS_WEIGHTS_FILE, Lpips, LpipsFeatures, cache_dir,
    default_lpips_weights_path,
};
pub use moments::Moments;
pub use msmse::{MsMse, MsMseReduction};
pub use objective::{Evaluation, LossBreakdown, LossConfig, Objective, ParamEvaluation};
pub use regulariser::{ConditionTerm, Regulariser};
pub use ssim::{DSsim, ssim, ssim_map};

use crate::error::{Error, Result};

/// The float types the losses run in (`f32` and `f64`): [`crate::math::Real`].
pub use crate::math::Real;

/// An image-space loss with its exact gradient with respect to the prediction.
///
/// The target is treated as a constant.
pub trait ImageLoss: Send + Sync {
    /// Short name, used for logs and as the candle op's name.
    fn name(&self) -> &'static str;

    /// `(L(pred, target), ∂L/∂pred)` for two row-major `width × height` grey images.
    fn value_and_grad<T: Real>(
        &self,
        pred: &[T],
        target: &[T],
        width: usize,
        height: usize,
    ) -> Result<(T, Vec<T>)>;

    /// `L(pred, target)` alone; losses override it where that is cheaper than the gradient.
    fn value<T: Real>(&self, pred: &[T], target: &[T], width: usize, height: usize) -> Result<T> {
        Ok(self.value_and_grad(pred, target, width, height)?.0)
    }
}

/// Checks that two images have `width × height` pixels each and that the size is not empty.
pub(crate) fn check_pair<T>(pred: &[T], target: &[T], width: usize, height: usize) -> Result<()> {
    if width == 0 || height == 0 {
        return Err(Error::Empty(format!(
            "a {width}×{height} image has no pixels; losses need at least one"
        )));
    }
    let n = width
        .checked_mul(height)
        .ok_or_else(|| Error::Shape(format!("{width}×{height} overflows the pixel count")))?;
    if pred.len() != n || target.len() != n {
        return Err(Error::Shape(format!(
            "prediction has {} and target {} values; a {width}×{height} image has {n}",
            pred.len(),
            target.len()
        )));
    }
    Ok(())
}

/// An `f64` constant in the loss's float type (infallible for `f32`/`f64`; NaN otherwise).
#[inline(always)]
pub(crate) fn cst<T: Real>(x: f64) -> T {
    T::from(x).unwrap_or_else(T::nan)
}

/// A value of the loss's float type as `f64`, for reductions.
#[inline(always)]
pub(crate) fn f64_of<T: Real>(x: T) -> f64 {
    x.to_f64().unwrap_or(f64::NAN)
}
