//! The splat as a [`Renderer`]: maps of any [`DiffMap2`] type → grey image, a fresh
//! chaos-game seed every call.

use std::marker::PhantomData;

use super::{SplatConfig, SplatReal, SplatTape, backward, forward_with_probabilities};
use crate::chaos::mix_seed;
use crate::error::Result;
use crate::model::map::DiffMap2;
use crate::render::renderer::{Draws, Planes, Renderer};

/// The fused splat of maps of type `M` into an image of `T` (f32 or f64), with the chaos
/// game drawing map `i` with probability `probs[i]` (uniform when `None`).
pub struct Splat<M, T = f32> {
    /// The splat's settings.
    pub cfg: SplatConfig,
    /// Map probabilities of the chaos game.
    pub probs: Option<Vec<f64>>,
    marker: PhantomData<fn(&[M]) -> T>,
}

impl<M, T> Clone for Splat<M, T> {
    fn clone(&self) -> Self {
        Splat {
            cfg: self.cfg.clone(),
            probs: self.probs.clone(),
            marker: PhantomData,
        }
    }
}

impl<M, T> std::fmt::Debug for Splat<M, T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Splat")
            .field("cfg", &self.cfg)
            .field("probs", &self.probs)
            .finish()
    }
}

impl<M: DiffMap2, T: SplatReal> Splat<M, T> {
    /// The splat with `cfg`, maps drawn uniformly.
    pub fn new(cfg: SplatConfig) -> Self {
        Splat {
            cfg,
            probs: None,
            marker: PhantomData,
        }
    }

    /// The same splat drawing map `i` with probability `probs[i]` (uniform when `None`).
    pub fn with_probabilities(mut self, probs: Option<Vec<f64>>) -> Self {
        self.probs = probs;
        self
    }
}

impl<M: DiffMap2, T: SplatReal> Renderer for Splat<M, T> {
    type Scene = [M];
    type Pixel = T;
    /// The chaos game's seed.
    type Sampling = u64;
    type Tape = SplatTape<T>;

    const DRAWS: Draws = Draws::EveryCall;

    fn planes(&self) -> Planes {
        Planes {
            channels: 1,
            height: self.cfg.height,
            width: self.cfg.width,
        }
    }

    /// Stream `draw` of the run's seed.
    fn sampling(&self, _maps: &[M], seed: u64, draw: u64) -> u64 {
        mix_seed(seed, draw)
    }

    fn forward(&self, maps: &[M], seed: &u64) -> Result<(Vec<T>, SplatTape<T>)> {
        forward_with_probabilities(&self.cfg, maps, self.probs.as_deref(), *seed)
    }

    fn backward(
        &self,
        maps: &[M],
        _seed: &u64,
        tape: &SplatTape<T>,
        grad_image: &[T],
    ) -> Result<Vec<f64>> {
        backward(&self.cfg, maps, tape, grad_image)
    }
}
