//! The differentiable point splatter: one fused op from concrete maps to an image, with a
//! hand-written reverse pass.
//!
//! Forward, per call (one optimisation iteration):
//! 1. **Chaos game** ([`trajectories`]): `b` trajectories of `l` steps from start points
//!    uniform in a box, map sequence drawn per step with uniform probabilities, seeded per
//!    trajectory from the call's seed (fresh points every iteration); the first `m` states
//!    are dropped. Every state and map index is kept on the tape.
//! 2. **Framing** ([`frame`]): the kept points are centred on their bounding box and scaled
//!    so the longest side spans 75% of the frame — differentiably (the bounding box's
//!    extreme points receive the framing's gradient) — or mapped through a fixed window.
//! 3. **Splat** ([`kernel`]): an isotropic Gaussian per point on an `s×` supersampled grid,
//!    blended as *coverage* (`α = min(α_max, g)`, image = `1 − Π(1 − α)`, order-independent)
//!    or *additive* density (`Σ g`), then `s×s` average pooling. `g` is the Gaussian
//!    windowed to vanish continuously at `radius·σ`: `g = (e^{−d²/2σ²} − ε)/(1 − ε)`,
//!    `ε = e^{−radius²/2}` (within 1.1% of the plain Gaussian at the default radius 3, and
//!    without the jump a hard cut-off would put into the loss).
//!
//! Reverse: per-pixel gradients are pulled back to per-point gradients tile by tile, through
//! the framing, then through each trajectory by a backward scan over its maps
//! (`λ_k = J_x(f_{i_k}, x_k)ᵀ λ_{k+1} + ∂L/∂x_k`, `∂L/∂θ_i += J_θ(f_i, x_k)ᵀ λ_{k+1}`; for an
//! affine map `J_x = A_i`, `∂L/∂A_i += λ_{k+1} x_kᵀ`, `∂L/∂b_i += λ_{k+1}`).
//!
//! Everything is generic over the map type ([`DiffMap2`]: affine maps, similitudes, and
//! any map that provides its two vector–Jacobian products) and monomorphised per type, so
//! the affine path runs the same inlined loops as a hand-written affine splatter. Map
//! gradients come back flat, map after map ([`param_offsets`]).
//!
//! The grid is processed in tiles of about 64×64 supersampled pixels (at least 16×16 output
//! pixels): points are binned to the tiles
//! their footprint touches by a stable counting sort, and each tile is splatted by one
//! thread in point order. Every floating-point sum has a fixed order, so forward and reverse
//! are bit-identical for any thread count.
//!
//! The splat (step 3 and its reverse) runs on the CPU or, with the `cuda` feature and
//! `device = "cuda"`, on an NVIDIA GPU ([`cuda`]); steps 1–2 and the reverse scan stay on
//! the CPU either way.
//!
//! [`SplatOp`] wraps the fused op as a candle `CustomOp1` (affine maps `(n, 6)`, or the
//! parameters of any [`DiffMap2`] maps, → image `(H, W)`) so image losses compose as candle
//! tensors; with `device = "cuda"` in its config the op's splat runs on the GPU while its
//! tensors stay on the CPU. [`iteration`] is one step of image inversion in one call —
//! render, the objective, `∂/∂θ` — through that op, or, on the GPU with a loss the GPU
//! computes (MS-MSE, D-SSIM), with the image and its gradient never leaving the GPU.
//! [`Splat`] is the fused op as a [`Renderer`](crate::render::Renderer): maps to a grey
//! plane, a fresh chaos-game seed every call.
//!
//! ## References
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point Splatting*.

mod candle_op;
#[cfg(feature = "cuda")]
pub mod cuda;
pub mod frame;
pub mod iteration;
pub mod kernel;
mod renderer;
pub mod trajectories;

use serde::{Deserialize, Serialize};

pub use candle_op::{SplatOp, maps_from_tensor, maps_to_tensor, params_to_tensor};
#[allow(deprecated)] // the former name, kept for code written against it
pub use frame::{FrameState, SplatFraming, SplatView};
pub use iteration::{
    gpu_route, objective_and_grad, objective_and_grad_candle, render_msmse, through_f32,
};
pub use kernel::{Blend, SplatGrid, SplatReal, SplatState, release_buffers};
pub use renderer::Splat;
pub use trajectories::TrajectoryTape;

use crate::budget::MemoryEstimate;
use crate::chaos::ChaosGame;
use crate::error::{Error, Result};
use crate::isa::Isa;
use crate::model::map::{DiffMap2, check_finite_params, flat_params, param_offsets};

/// Where the splat kernel runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SplatDevice {
    /// The CPU kernel (tiled, all cores).
    #[default]
    Cpu,
    /// An NVIDIA GPU (needs the `cuda` feature, the driver and NVRTC at run time).
    Cuda,
}

impl SplatDevice {
    /// `true` for the CPU (the default, left out of serialised configs).
    pub fn is_cpu(&self) -> bool {
        *self == SplatDevice::Cpu
    }

    /// Refuses a device this build or machine cannot use, saying why.
    pub fn check(&self) -> Result<()> {
        match self {
            SplatDevice::Cpu => Ok(()),
            #[cfg(feature = "cuda")]
            SplatDevice::Cuda => cuda::available(),
            #[cfg(not(feature = "cuda"))]
            SplatDevice::Cuda => Err(Error::Device(
                "device = \"cuda\" needs a build with the GPU backend: \
                 cargo build --release --features cuda (the binary: -p ifslab-experiments \
                 --features cuda)"
                    .into(),
            )),
        }
    }
}

impl std::str::FromStr for SplatDevice {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "cpu" => Ok(SplatDevice::Cpu),
            "cuda" => Ok(SplatDevice::Cuda),
            other => Err(Error::param(
                "device",
                format!("must be \"cpu\" or \"cuda\", got \"{other}\""),
            )),
        }
    }
}

/// Everything the fused op needs besides the maps and the seed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SplatConfig {
    /// Output width in pixels.
    pub width: usize,
    /// Output height in pixels.
    pub height: usize,
    /// Supersampling factor per side (the grid is `s·width × s·height`, average-pooled).
    pub supersample: usize,
    /// Gaussian standard deviation in supersampled pixels.
    pub sigma: f64,
    /// Footprint radius in units of σ.
    pub radius: f64,
    /// How splats combine.
    pub blend: Blend,
    /// Upper bound of a single splat's α in coverage blending.
    pub alpha_max: f64,
    /// Trajectory layout (its `seed` is ignored: each call passes its own).
    pub game: ChaosGame,
    /// Fit the points (differentiably) or use a fixed window.
    pub framing: SplatView,
    /// Where the splat runs.
    #[serde(skip_serializing_if = "SplatDevice::is_cpu")]
    pub device: SplatDevice,
}

impl Default for SplatConfig {
    /// The paper's setting: 2000 × 250 trajectories (10 dropped), 5× supersampling, σ = 2.5
    /// supersampled pixels, coverage blending, fitted framing; 256² output.
    fn default() -> Self {
        SplatConfig {
            width: 256,
            height: 256,
            supersample: 5,
            sigma: 2.5,
            radius: 3.0,
            blend: Blend::Coverage,
            alpha_max: 0.99,
            game: ChaosGame::default(),
            framing: SplatView::default(),
            device: SplatDevice::Cpu,
        }
    }
}

impl SplatConfig {
    /// Checks every field; the error names the one to change.
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(Error::param("size", "width and height must be at least 1"));
        }
        if self.supersample == 0 || self.supersample > 16 {
            return Err(Error::param(
                "supersample",
                format!("must lie in 1..=16, got {}", self.supersample),
            ));
        }
        if !(self.sigma.is_finite() && self.sigma > 0.0) {
            return Err(Error::param(
                "sigma",
                format!("must be > 0, got {}", self.sigma),
            ));
        }
        if !(self.radius.is_finite() && self.radius >= 1.0 && self.radius <= 8.0) {
            return Err(Error::param(
                "radius",
                format!("must lie in [1, 8] (units of σ), got {}", self.radius),
            ));
        }
        if !(self.alpha_max > 0.0 && self.alpha_max < 1.0) {
            return Err(Error::param(
                "alpha_max",
                format!("must lie in (0, 1), got {}", self.alpha_max),
            ));
        }
        self.game.validate()?;
        if self.game.trajectories.saturating_mul(self.game.length + 1) > u32::MAX as usize {
            return Err(Error::param("trajectories", "too many points for one call"));
        }
        self.framing.validate()?;
        self.device.check()
    }

    /// What one call's buffers take (f64, the larger precision): the transmittance of
    /// every supersampled pixel in the worst case that points reach every tile, the image,
    /// its gradient and the target, the trajectory tape and the binned points.
    pub fn memory_estimate(&self) -> MemoryEstimate {
        let (w, h, s) = (
            self.width as u64,
            self.height as u64,
            self.supersample as u64,
        );
        let points = (self.game.trajectories as u64).saturating_mul(self.game.length as u64 + 1);
        MemoryEstimate::new()
            .with(
                "supersampled grid",
                (w * s).saturating_mul(h * s).saturating_mul(8),
            )
            .with("image, gradient and target", w * h * 8 * 3)
            .with(
                "trajectories and binned points",
                points.saturating_mul(18 + 64),
            )
    }

    /// The supersampled grid.
    pub fn grid(&self) -> SplatGrid {
        SplatGrid {
            width: self.width,
            height: self.height,
            supersample: self.supersample,
            sigma: self.sigma,
            radius: self.radius,
            alpha_max: self.alpha_max,
            blend: self.blend,
        }
    }
}

/// What the forward pass keeps for the reverse pass.
#[derive(Clone, Debug)]
pub struct SplatTape<T: SplatReal> {
    /// Trajectory states and map indices.
    pub trajectories: TrajectoryTape,
    /// The framing and what its reverse pass needs.
    pub frame: FrameState,
    /// The splat's own state (points in pixel space, bins, transmittance).
    pub splat: SplatStateOn<T>,
}

/// The splat's tape on the device it ran on.
#[derive(Clone, Debug)]
pub enum SplatStateOn<T: SplatReal> {
    /// The CPU kernel's state.
    Cpu(kernel::SplatState<T>),
    /// The GPU kernel's state (kept on the GPU).
    #[cfg(feature = "cuda")]
    Cuda(cuda::CudaSplatState<T>),
}

/// Forward pass: the image (row-major `height × width`, values ≥ 0) and its tape.
///
/// Generic over the map type and monomorphised: the chaos game calls the map's `apply`
/// inline.
pub fn forward<T: SplatReal>(
    cfg: &SplatConfig,
    maps: &[impl DiffMap2],
    seed: u64,
) -> Result<(Vec<T>, SplatTape<T>)> {
    forward_with_probabilities(cfg, maps, None, seed)
}

/// [`forward`] with the chaos game drawing map `i` with probability `probs[i]` (uniform when
/// `None`, as the paper's generator does; Learning Fractals draws ∝ |det|).
pub fn forward_with_probabilities<T: SplatReal>(
    cfg: &SplatConfig,
    maps: &[impl DiffMap2],
    probs: Option<&[f64]>,
    seed: u64,
) -> Result<(Vec<T>, SplatTape<T>)> {
    let (tape, kept, frame) = trace(cfg, maps, probs, seed)?;
    let grid = cfg.grid();
    let (image, splat) = match cfg.device {
        SplatDevice::Cpu => {
            let uv: Vec<[T; 2]> = kept.iter().map(|p| frame.project(p)).collect();
            let (image, state) = kernel::forward_with_isa(&grid, uv, tape.isa);
            (image, SplatStateOn::Cpu(state))
        }
        #[cfg(feature = "cuda")]
        SplatDevice::Cuda => {
            let (image, state) =
                cuda::forward_with(&grid, kept.len(), |dst| project_into(&frame, &kept, dst))?;
            (image, SplatStateOn::Cuda(state))
        }
        #[cfg(not(feature = "cuda"))]
        SplatDevice::Cuda => unreachable!("validate() refuses cuda without the feature"),
    };
    Ok((
        image,
        SplatTape {
            trajectories: tape,
            frame,
            splat,
        },
    ))
}

/// Steps 1–2 of the forward pass (checks, chaos game, framing): the tape, the kept points
/// and the frame they are projected through. The instruction set of the whole call (chaos
/// game, splat kernel, and the reverse pass, which reads it from the tapes) is decided
/// here, once ([`Isa::detect`]).
fn trace(
    cfg: &SplatConfig,
    maps: &[impl DiffMap2],
    probs: Option<&[f64]>,
    seed: u64,
) -> Result<(TrajectoryTape, Vec<[f64; 2]>, FrameState)> {
    cfg.validate()?;
    if maps.is_empty() {
        return Err(Error::Empty("the code has no maps".into()));
    }
    if maps.len() > u16::MAX as usize {
        return Err(Error::param("maps", "at most 65535 maps"));
    }
    check_finite_params(&flat_params(maps), &param_offsets(maps))?;
    let tape = trajectories::run_with_isa(&cfg.game, maps, probs, seed, Isa::detect())?;
    let kept = tape.kept_points();
    let frame = frame::fit(
        &cfg.framing,
        &kept,
        cfg.width * cfg.supersample,
        cfg.height * cfg.supersample,
    )?;
    Ok((tape, kept, frame))
}

/// The kept points in supersampled pixel coordinates, written into `dst` (the GPU's
/// page-locked upload buffer) in parallel.
#[cfg(feature = "cuda")]
fn project_into<T: SplatReal>(frame: &FrameState, kept: &[[f64; 2]], dst: &mut [[T; 2]]) {
    use rayon::prelude::*;
    dst.par_iter_mut()
        .zip(kept.par_iter())
        .with_min_len(4096)
        .for_each(|(d, p)| *d = frame.project(p));
}

/// Reverse pass: `∂L/∂θ` of every map, map after map in the layout of
/// [`param_offsets`] (for [`Affine2`] maps: `[a, b, c, d, e, f]` per map, i.e. `∂L/∂M`
/// row-major then `∂L/∂b`), from `∂L/∂image` (row-major, same shape as the forward image).
///
/// [`Affine2`]: crate::model::Affine2
pub fn backward<T: SplatReal>(
    cfg: &SplatConfig,
    maps: &[impl DiffMap2],
    tape: &SplatTape<T>,
    grad_image: &[T],
) -> Result<Vec<f64>> {
    if grad_image.len() != cfg.width * cfg.height {
        return Err(Error::Shape(format!(
            "image gradient has {} values for a {}×{} image",
            grad_image.len(),
            cfg.width,
            cfg.height
        )));
    }
    if maps.len() != tape.trajectories.maps {
        return Err(Error::Shape(format!(
            "the tape was recorded with {} maps but {} were given",
            tape.trajectories.maps,
            maps.len()
        )));
    }
    let grid = cfg.grid();
    let guv = match &tape.splat {
        SplatStateOn::Cpu(state) => kernel::backward(&grid, state, grad_image),
        #[cfg(feature = "cuda")]
        SplatStateOn::Cuda(state) => cuda::backward(&grid, state, grad_image)?,
    };
    let kept = tape.trajectories.kept_points();
    let gx = tape.frame.backward(&kept, &guv);
    Ok(tape.trajectories.backward(maps, &gx))
}
