//! The differentiable multi-view splat: maps of space → one grey picture per camera, with a
//! hand-written reverse pass (issue 39's renderer, the 2-D splat taken through cameras).
//!
//! Forward, per call:
//! 1. **Chaos game** in 3-D with a tape ([`Tape3`]): `b` trajectories of `l` steps seeded
//!    per trajectory from the call's seed, the first `m` states dropped.
//! 2. **Projection**: every kept point through every [`Camera`] (pinhole or orthographic,
//!    [`camera`]) to that view's supersampled pixel coordinates. There is no fitted
//!    framing: the cameras fix the view of world space, and the maps' offsets (tanh for
//!    [`SvdMap3`](crate::model::map3::SvdMap3)) keep the attractor near the origin.
//! 3. **Splat**, per view, by the 2-D splat's own kernel ([`kernel::forward_with_isa`]): the
//!    same windowed Gaussian footprints on the `s×` supersampled grid, the same blending —
//!    coverage `I = 1 − Π(1 − α)` (the paper's; order-independent, so no depth sort: a
//!    view shows the attractor's silhouette, its density where α saturates less) or
//!    additive —, the same `s × s` pooling. The image is the views' planes, channel-major
//!    (one plane per camera, in the cameras' order), so a loss summed over views is a loss
//!    on the image.
//!
//! Reverse: per view, the kernel's reverse pass gives `∂L/∂(u, v)` per point
//! ([`kernel::backward`]); the projection's Jacobian ([`Camera::project_with_jacobian`])
//! takes it to `∂L/∂p` in world space, summed over views in the cameras' order; the tape's
//! backward scan ([`Tape3::backward`]) takes it to `∂L/∂θ` of every map, map after map
//! ([`param_offsets`](crate::model::map3::param_offsets)). Every sum has a fixed order, so
//! forward and reverse are the same bits on any thread count.
//!
//! [`MultiViewSplat`] is the op as a [`Renderer`]: the scene is the maps (`[M]` for any
//! [`DiffMap3`]); the cameras are the renderer's data, since they fix its image's shape
//! ([`Renderer::planes`]: one plane per view) and are not differentiated.
//!
//! ## References
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point
//!   Splatting* (the splat, coverage blending; 3-D named as future work).
//! - Mildenhall et al., *NeRF* (the camera convention and `transforms.json`).

pub mod camera;

use std::marker::PhantomData;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

pub use camera::{Camera, Frame, Lens, load_transforms, parse_transforms, turntable};

use crate::budget::MemoryEstimate;
use crate::chaos::{ChaosGame, Tape3, mix_seed};
use crate::error::{Error, Result};
use crate::isa::Isa;
use crate::model::map::check_finite_params;
use crate::model::map3::{DiffMap3, flat_params, param_offsets};
use crate::render::renderer::{Draws, Planes, Renderer};
use crate::render::splat::kernel::{self, Blend, SplatGrid, SplatReal, SplatState};
use crate::render::splat::{SplatConfig, SplatView};

/// The multi-view splat's settings besides the cameras (the footprint and the chaos game;
/// each view's size is its camera's).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MultiViewConfig {
    /// Supersampling factor per side.
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
}

impl Default for MultiViewConfig {
    /// Issue 39's setting: 4× supersampling, σ = 1 supersampled pixel, coverage blending,
    /// 400 trajectories of 260 steps (10 dropped): 100 000 points shared by all views.
    fn default() -> Self {
        MultiViewConfig {
            supersample: 4,
            sigma: 1.0,
            radius: 3.0,
            blend: Blend::Coverage,
            alpha_max: 0.99,
            game: ChaosGame {
                trajectories: 400,
                length: 260,
                warmup: 10,
                start_half_width: 1.0,
                seed: 0,
            },
        }
    }
}

impl MultiViewConfig {
    /// The one-view splat's config with these settings, for its checks.
    fn as_splat(&self, width: usize, height: usize) -> SplatConfig {
        SplatConfig {
            width,
            height,
            supersample: self.supersample,
            sigma: self.sigma,
            radius: self.radius,
            blend: self.blend,
            alpha_max: self.alpha_max,
            game: self.game.clone(),
            framing: SplatView::default(),
            device: Default::default(),
        }
    }

    /// Checks every field (the one-view splat's checks); the error names the one to change.
    pub fn validate(&self) -> Result<()> {
        self.as_splat(1, 1).validate()
    }

    /// What one call's buffers take for `views` views of `width × height` (f64): each
    /// view's splat buffers and projected points, and the tape.
    pub fn memory_estimate(&self, views: usize, width: usize, height: usize) -> MemoryEstimate {
        let one = self.as_splat(width, height).memory_estimate();
        let points = (self.game.trajectories as u64).saturating_mul(self.game.length as u64 + 1);
        MemoryEstimate::new()
            .with(
                "splat buffers of every view",
                one.total().saturating_mul(views as u64),
            )
            .with("3-D tape", points.saturating_mul(26))
    }
}

/// What the forward pass keeps for the reverse pass.
#[derive(Clone, Debug)]
pub struct MultiViewTape<T: SplatReal> {
    /// The 3-D chaos game's states and map indices.
    pub trajectories: Tape3,
    /// Each view's splat state (its points in supersampled pixels, bins, transmittance).
    pub views: Vec<SplatState<T>>,
}

/// The multi-view splat of maps of type `M` into one plane of `T` (f32 or f64) per camera,
/// map `i` drawn with probability `probs[i]` (uniform when `None`). See the module docs.
pub struct MultiViewSplat<M, T = f32> {
    cfg: MultiViewConfig,
    cameras: Vec<Camera>,
    probs: Option<Vec<f64>>,
    marker: PhantomData<fn(&[M]) -> T>,
}

impl<M, T> Clone for MultiViewSplat<M, T> {
    fn clone(&self) -> Self {
        MultiViewSplat {
            cfg: self.cfg.clone(),
            cameras: self.cameras.clone(),
            probs: self.probs.clone(),
            marker: PhantomData,
        }
    }
}

impl<M, T> std::fmt::Debug for MultiViewSplat<M, T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MultiViewSplat")
            .field("cfg", &self.cfg)
            .field("cameras", &self.cameras.len())
            .field("probs", &self.probs)
            .finish()
    }
}

impl<M: DiffMap3, T: SplatReal> MultiViewSplat<M, T> {
    /// The splat of `cfg` through `cameras`. Refuses an invalid config, no camera and
    /// cameras whose images differ in size (the views are planes of one image).
    pub fn new(cfg: MultiViewConfig, cameras: Vec<Camera>) -> Result<Self> {
        cfg.validate()?;
        let Some(first) = cameras.first() else {
            return Err(Error::Camera(
                "the multi-view splat needs at least one camera".into(),
            ));
        };
        let (w, h) = (first.width(), first.height());
        if let Some((i, c)) = cameras
            .iter()
            .enumerate()
            .find(|(_, c)| c.width() != w || c.height() != h)
        {
            return Err(Error::Camera(format!(
                "view {i} is {}×{} but view 0 is {w}×{h}: every view must have the same size",
                c.width(),
                c.height()
            )));
        }
        cfg.as_splat(w, h).validate()?;
        Ok(MultiViewSplat {
            cfg,
            cameras,
            probs: None,
            marker: PhantomData,
        })
    }

    /// The same splat drawing map `i` with probability `probs[i]` (uniform when `None`).
    pub fn with_probabilities(mut self, probs: Option<Vec<f64>>) -> Self {
        self.probs = probs;
        self
    }

    /// The settings.
    pub fn config(&self) -> &MultiViewConfig {
        &self.cfg
    }

    /// The cameras, one per plane.
    pub fn cameras(&self) -> &[Camera] {
        &self.cameras
    }

    fn grid(&self) -> SplatGrid {
        let c = &self.cameras[0];
        self.cfg.as_splat(c.width(), c.height()).grid()
    }

    /// The kept points of the tape projected by `camera` into supersampled pixels; points a
    /// pinhole cannot see become NaN, which the kernel skips (no footprint, zero gradient).
    fn project(&self, camera: &Camera, kept: &[[f64; 3]]) -> Vec<[T; 2]> {
        let s = self.cfg.supersample as f64;
        let nan = T::nan();
        kept.par_iter()
            .with_min_len(4096)
            .map(|&p| match camera.project(p) {
                Some([u, v]) => [T::from(u * s).unwrap_or(nan), T::from(v * s).unwrap_or(nan)],
                None => [nan, nan],
            })
            .collect()
    }
}

impl<M: DiffMap3, T: SplatReal> Renderer for MultiViewSplat<M, T> {
    type Scene = [M];
    type Pixel = T;
    /// The chaos game's seed.
    type Sampling = u64;
    type Tape = MultiViewTape<T>;

    const DRAWS: Draws = Draws::EveryCall;

    fn planes(&self) -> Planes {
        Planes {
            channels: self.cameras.len(),
            height: self.cameras[0].height(),
            width: self.cameras[0].width(),
        }
    }

    /// Stream `draw` of the run's seed.
    fn sampling(&self, _maps: &[M], seed: u64, draw: u64) -> u64 {
        mix_seed(seed, draw)
    }

    fn forward(&self, maps: &[M], seed: &u64) -> Result<(Vec<T>, MultiViewTape<T>)> {
        check_finite_params(&flat_params(maps), &param_offsets(maps))?;
        let tape = Tape3::run(&self.cfg.game, maps, self.probs.as_deref(), *seed)?;
        let kept = tape.kept_points();
        let grid = self.grid();
        let isa = Isa::detect();
        // The views in parallel as well as each view's tiles: an attractor that crowds a
        // few tiles of every view (a fern's frond) would otherwise leave a core idle while
        // one tile of one view is drawn. Each view's plane is its own, so the bits are
        // those of the views drawn one after another.
        let drawn: Vec<(Vec<T>, SplatState<T>)> = self
            .cameras
            .par_iter()
            .map(|camera| kernel::forward_with_isa(&grid, self.project(camera, &kept), isa))
            .collect();
        let mut image = Vec::with_capacity(self.planes().len());
        let mut views = Vec::with_capacity(self.cameras.len());
        for (plane, state) in drawn {
            image.extend_from_slice(&plane);
            views.push(state);
        }
        Ok((
            image,
            MultiViewTape {
                trajectories: tape,
                views,
            },
        ))
    }

    fn backward(
        &self,
        maps: &[M],
        _seed: &u64,
        tape: &MultiViewTape<T>,
        grad_image: &[T],
    ) -> Result<Vec<f64>> {
        let planes = self.planes();
        if grad_image.len() != planes.len() {
            return Err(Error::Shape(format!(
                "image gradient has {} values for {} views of {}×{}",
                grad_image.len(),
                planes.channels,
                planes.width,
                planes.height
            )));
        }
        if tape.views.len() != self.cameras.len() {
            return Err(Error::Shape(format!(
                "the tape holds {} views but the splat has {} cameras",
                tape.views.len(),
                self.cameras.len()
            )));
        }
        let grid = self.grid();
        let guv: Vec<Vec<[f64; 2]>> = tape
            .views
            .par_iter()
            .zip(grad_image.par_chunks_exact(planes.pixels()))
            .map(|(state, g)| kernel::backward(&grid, state, g))
            .collect();
        let kept = tape.trajectories.kept_points();
        let s = self.cfg.supersample as f64;
        // ∂L/∂p = Σ_views J_viewᵀ·s·∂L/∂(u_s, v_s), views in order.
        let grad_points: Vec<[f64; 3]> = kept
            .par_iter()
            .enumerate()
            .with_min_len(4096)
            .map(|(j, &p)| {
                let mut g = [0.0f64; 3];
                for (camera, gv) in self.cameras.iter().zip(&guv) {
                    let [gu, gw] = gv[j];
                    if gu == 0.0 && gw == 0.0 {
                        continue;
                    }
                    if let Some((_, jac)) = camera.project_with_jacobian(p) {
                        for (k, gk) in g.iter_mut().enumerate() {
                            *gk += s * (jac[0][k] * gu + jac[1][k] * gw);
                        }
                    }
                }
                g
            })
            .collect();
        tape.trajectories.backward(maps, &grad_points)
    }
}
