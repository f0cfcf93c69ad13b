//! What the three differentiable renderers share: a [`Renderer`] takes a scene (the maps, a
//! segment pattern, a flame stack) and its sampling state to an image, and pulls a gradient
//! with respect to that image back to the scene's flat parameters.
//!
//! The renderers differ in data, not in shape:
//!
//! | renderer | scene | pixel | sampling ([`Draws`]) | planes |
//! |---|---|---|---|---|
//! | [`Splat`](crate::render::splat::Splat) | `[M]`, any [`DiffMap2`](crate::model::DiffMap2) | f32 or f64 | a chaos-game seed, fresh every call | 1 (grey) |
//! | [`SdfRenderer`](crate::render::sdf::SdfRenderer) | a segment [`Pattern`](crate::model::segment::Pattern) | f64 | none: deterministic | intensity and/or distance |
//! | [`FlameRenderer`](crate::render::flame_diff::FlameRenderer) | a [`FlameStack`](crate::model::flame::learnable::FlameStack) | f64 | the generator order, drawn once per run | 3 (RGB) |
//!
//! Everything is monomorphised: a problem generic over `R: Renderer` runs each renderer's
//! own loops, with no trait object below the call. The image is channel-major planes of
//! [`Renderer::Pixel`] in the shape [`Renderer::planes`] gives — the layout of
//! [`crate::image::Image`] and of a candle `(C, H, W)` tensor, which every loss takes — so a
//! loss sees a renderer's image without a copy.
//!
//! [`value_and_grad`] is one differentiable step through any renderer: render, the loss on
//! the image, the reverse pass. A problem obtains its sampling state through a [`Sampler`]:
//! it holds the run's seed and, for a renderer drawing once per run, the last draw, so every
//! problem draws the way [`Renderer::DRAWS`] says without a cache of its own.
//!
//! **Adding a renderer**: a type holding its settings, implementing the four methods; check
//! its reverse pass with a finite-difference test through the trait (`tests/renderer.rs`
//! does it for all three, generically).

use std::sync::{Arc, Mutex};

use crate::error::Result;
use crate::math::Real;

/// The shape of a renderer's image: `channels` planes of `height × width` pixels, row-major,
/// channel after channel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Planes {
    /// Number of planes.
    pub channels: usize,
    /// Rows.
    pub height: usize,
    /// Columns.
    pub width: usize,
}

impl Planes {
    /// Pixels per plane.
    pub fn pixels(&self) -> usize {
        self.height * self.width
    }

    /// Values in the whole image.
    pub fn len(&self) -> usize {
        self.channels * self.pixels()
    }

    /// Whether the image holds no value.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// How often a renderer's sampling state is drawn afresh.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Draws {
    /// Every call (the splat: new chaos-game trajectories each iteration).
    EveryCall,
    /// Once per run (the flame pipeline's generator order; a problem may redraw it every
    /// so many iterations).
    PerRun,
    /// Never: the render is deterministic (the SDF raster).
    Never,
}

/// A differentiable renderer: scene → image, `∂L/∂image` → `∂L/∂θ`.
pub trait Renderer {
    /// What is drawn: maps, a pattern, a flame stack.
    type Scene: ?Sized;
    /// The image's scalar.
    type Pixel: Real;
    /// The random state one render depends on (`()` for a deterministic renderer).
    type Sampling;
    /// What the forward pass keeps for the reverse pass.
    type Tape;

    /// How often [`Renderer::sampling`] is drawn afresh.
    const DRAWS: Draws;

    /// The image's shape.
    fn planes(&self) -> Planes;

    /// The sampling state of draw `draw` of a run seeded with `seed` (the iteration for a
    /// renderer drawing every call, the redraw epoch for one drawing per run).
    fn sampling(&self, scene: &Self::Scene, seed: u64, draw: u64) -> Self::Sampling;

    /// The image of `scene` (channel-major, [`Renderer::planes`]) and its tape.
    fn forward(
        &self,
        scene: &Self::Scene,
        sampling: &Self::Sampling,
    ) -> Result<(Vec<Self::Pixel>, Self::Tape)>;

    /// The gradient with respect to `scene`'s flat parameters (the maps' parameters map
    /// after map, the pattern's control points, the stack's θ) of a loss whose gradient with
    /// respect to the image of [`Renderer::forward`] is `grad_image`.
    fn backward(
        &self,
        scene: &Self::Scene,
        sampling: &Self::Sampling,
        tape: &Self::Tape,
        grad_image: &[Self::Pixel],
    ) -> Result<Vec<f64>>;
}

/// One differentiable step through `renderer`: the image of `scene`, `loss` on it (its value
/// and its gradient with respect to the image), and the reverse pass to the scene's
/// parameters.
pub fn value_and_grad<R, V, E>(
    renderer: &R,
    scene: &R::Scene,
    sampling: &R::Sampling,
    loss: impl FnOnce(&[R::Pixel]) -> std::result::Result<(V, Vec<R::Pixel>), E>,
) -> std::result::Result<(V, Vec<f64>), E>
where
    R: Renderer,
    E: From<crate::Error>,
{
    let (image, tape) = renderer.forward(scene, sampling)?;
    let (value, grad_image) = loss(&image)?;
    drop(image);
    let grad = renderer.backward(scene, sampling, &tape, &grad_image)?;
    Ok((value, grad))
}

/// A run's sampling states for renderers of type `R`: [`Renderer::sampling`] of the run's
/// seed, drawn as [`Renderer::DRAWS`] says — afresh on every call for
/// [`Draws::EveryCall`]; for [`Draws::PerRun`], once per draw index and kept until another
/// index is asked for (a problem redrawing every so many iterations asks for its epoch);
/// for [`Draws::Never`], draw 0 every time, nothing kept.
///
/// What it gives is exactly what `renderer.sampling(scene, seed, draw)` gives; it only
/// saves the redraws. A kept draw was drawn for the renderer and scene of the call that drew
/// it: a problem asks with one renderer setting and one scene per run for the sampling
/// (the flame problem: its start's stack), as the flame pipeline's generator order depends
/// only on the stack's shape.
pub struct Sampler<R: Renderer> {
    seed: u64,
    kept: Mutex<Option<(u64, Arc<R::Sampling>)>>,
}

impl<R: Renderer> Sampler<R> {
    /// The sampler of a run seeded with `seed`.
    pub fn new(seed: u64) -> Self {
        Sampler {
            seed,
            kept: Mutex::new(None),
        }
    }

    /// The run's seed.
    pub fn seed(&self) -> u64 {
        self.seed
    }

    /// The sampling state of draw `draw` (the iteration or random stream for a renderer
    /// drawing every call, the redraw epoch for one drawing per run; ignored for a
    /// deterministic renderer).
    pub fn sampling(&self, renderer: &R, scene: &R::Scene, draw: u64) -> Arc<R::Sampling> {
        match R::DRAWS {
            Draws::EveryCall => Arc::new(renderer.sampling(scene, self.seed, draw)),
            Draws::Never => Arc::new(renderer.sampling(scene, self.seed, 0)),
            Draws::PerRun => {
                // A poisoned lock still holds a whole draw or none: the slot is written in
                // one assignment.
                let mut kept = self.kept.lock().unwrap_or_else(|e| e.into_inner());
                if let Some((d, s)) = kept.as_ref()
                    && *d == draw
                {
                    return s.clone();
                }
                let s = Arc::new(renderer.sampling(scene, self.seed, draw));
                *kept = Some((draw, s.clone()));
                s
            }
        }
    }
}

impl<R: Renderer> Clone for Sampler<R> {
    /// The same seed, sharing the kept draw.
    fn clone(&self) -> Self {
        let kept = self.kept.lock().unwrap_or_else(|e| e.into_inner()).clone();
        Sampler {
            seed: self.seed,
            kept: Mutex::new(kept),
        }
    }
}

impl<R: Renderer> std::fmt::Debug for Sampler<R> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let kept = self
            .kept
            .lock()
            .map(|k| k.as_ref().map(|(d, _)| *d))
            .unwrap_or(None);
        f.debug_struct("Sampler")
            .field("seed", &self.seed)
            .field("draws", &R::DRAWS)
            .field("kept_draw", &kept)
            .finish()
    }
}
