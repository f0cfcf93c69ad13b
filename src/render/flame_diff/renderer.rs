//! The differentiable flame pipeline as a [`Renderer`]: a flame stack → RGB image, with the
//! generator order drawn once per run (or per redraw epoch) as its sampling state.

use super::{DiffFlameConfig, FlameFrame, GeneratorOrder, backward, forward};
use crate::error::Result;
use crate::model::flame::learnable::FlameStack;
use crate::render::renderer::{Draws, Planes, Renderer};

/// The pipeline with these sampling and image settings.
#[derive(Clone, Debug, PartialEq)]
pub struct FlameRenderer {
    /// Image side, trajectories, steps, warm-up, work split.
    pub cfg: DiffFlameConfig,
}

impl Renderer for FlameRenderer {
    type Scene = FlameStack;
    type Pixel = f64;
    /// Every layer's generator order.
    type Sampling = GeneratorOrder;
    /// Each layer's splat buffer and painted RGBA (the frame without its image).
    type Tape = FlameFrame;

    const DRAWS: Draws = Draws::PerRun;

    fn planes(&self) -> Planes {
        Planes {
            channels: 3,
            height: self.cfg.size,
            width: self.cfg.size,
        }
    }

    /// Uniform orders for `stack`'s generator counts, seeded by the run's seed and the
    /// redraw epoch `draw`.
    fn sampling(&self, stack: &FlameStack, seed: u64, draw: u64) -> GeneratorOrder {
        GeneratorOrder::draw(
            stack,
            &self.cfg,
            seed.wrapping_add(draw.wrapping_mul(0x2545_f491_4f6c_dd1d)),
        )
    }

    fn forward(
        &self,
        stack: &FlameStack,
        order: &GeneratorOrder,
    ) -> Result<(Vec<f64>, FlameFrame)> {
        let mut frame = forward(stack, &self.cfg, order)?;
        let image = std::mem::take(&mut frame.image);
        Ok((image, frame))
    }

    fn backward(
        &self,
        stack: &FlameStack,
        order: &GeneratorOrder,
        frame: &FlameFrame,
        grad_image: &[f64],
    ) -> Result<Vec<f64>> {
        backward(stack, &self.cfg, order, frame, grad_image)
    }
}
