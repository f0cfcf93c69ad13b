//! The fit: θ → flame stack → differentiable flame pipeline → the authors' MSE against the
//! RGB target → gradient, all in f64 with the pipeline's hand-written reverse pass.

use std::sync::Arc;

use ifslab::model::flame::learnable::{Background, FlameStack};
use ifslab::render::flame_diff::{DiffFlameConfig, FlameFrame, FlameRenderer, GeneratorOrder, mse};
use ifslab::render::{Renderer, Sampler, value_and_grad};

use crate::driver::{Differentiable, Evaluation};
use crate::error::{Error, Result};
use crate::optim::annealing::Anneal;
use crate::problems::flame::config::{FlameLoss, Rates};

/// Names of the logged loss terms, in column order (unweighted).
pub const FLAME_TERMS: [&str; 2] = ["mse", "dssim"];

/// Fit a flame stack to an RGB target.
#[derive(Debug)]
pub struct FlameProblem {
    stack: FlameStack,
    renderer: FlameRenderer,
    /// Three planes, `size × size`, row 0 at the top.
    target: Vec<f32>,
    /// The run's generator orders: one per redraw epoch, drawn for the start's stack.
    sampler: Sampler<FlameRenderer>,
    redraw_every: u64,
    loss: FlameLoss,
    rates: Vec<f64>,
    /// Which θ entries the authors' sampler and splatter hold (generators, final
    /// transform, κ).
    geometry: Vec<bool>,
    freeze_geometry: u64,
}

impl FlameProblem {
    /// The problem of fitting stacks shaped like `stack` to `target` (three planes of
    /// `cfg.size²` values in [0, 1]).
    pub fn new(
        stack: FlameStack,
        cfg: DiffFlameConfig,
        target: Vec<f32>,
        seed: u64,
        redraw_every: u64,
        rates: &Rates,
        loss: FlameLoss,
    ) -> Result<Self> {
        loss.validate()?;
        cfg.validate()?;
        stack.validate()?;
        if target.len() != 3 * cfg.size * cfg.size {
            return Err(Error::InvalidInput(format!(
                "an RGB target of {} values for a {}² image",
                target.len(),
                cfg.size
            )));
        }
        let mut r = Vec::with_capacity(stack.n_params());
        let mut geometry = Vec::with_capacity(stack.n_params());
        for l in &stack.layers {
            let lay = l.layout();
            r.extend(std::iter::repeat_n(rates.generators, lay.final_at));
            r.extend(std::iter::repeat_n(rates.final_transform, 6));
            r.push(rates.kappa);
            // The authors' splatter holds the final transform and κ: both wait with the
            // sampler.
            geometry.extend(std::iter::repeat_n(true, lay.final_at + 7));
            r.extend(std::iter::repeat_n(rates.color, 4 * l.len()));
            geometry.extend(std::iter::repeat_n(false, 4 * l.len()));
        }
        if let Background::Learned(_) = stack.background {
            r.extend([rates.background; 3]);
            geometry.extend([false; 3]);
        }
        Ok(FlameProblem {
            stack,
            renderer: FlameRenderer { cfg },
            target,
            sampler: Sampler::new(seed),
            redraw_every,
            loss,
            rates: r,
            geometry,
            freeze_geometry: rates.freeze_geometry,
        })
    }

    /// The stack at θ.
    pub fn stack_at(&self, theta: &[f64]) -> Result<FlameStack> {
        let mut s = self.stack.clone();
        s.set_params(theta)?;
        Ok(s)
    }

    /// The pipeline's settings.
    pub fn config(&self) -> &DiffFlameConfig {
        &self.renderer.cfg
    }

    /// The target.
    pub fn target(&self) -> &[f32] {
        &self.target
    }

    /// The generator order used at iteration `iter`: the renderer's draw for the redraw
    /// epoch `iter / redraw_every` (0 throughout when the order is never redrawn), drawn
    /// once per epoch.
    pub fn order_at(&self, iter: u64) -> Arc<GeneratorOrder> {
        let epoch = iter.checked_div(self.redraw_every).unwrap_or(0);
        self.sampler.sampling(&self.renderer, &self.stack, epoch)
    }

    /// The render at θ with the order of iteration `iter`.
    pub fn render(&self, theta: &[f64], iter: u64) -> Result<FlameFrame> {
        let stack = self.stack_at(theta)?;
        let (image, mut frame) = self.renderer.forward(&stack, &self.order_at(iter))?;
        frame.image = image;
        Ok(frame)
    }

    /// The MSE at θ with the order of iteration `iter`.
    pub fn loss(&self, theta: &[f64], iter: u64) -> Result<f64> {
        let f = self.render(theta, iter)?;
        Ok(mse(&f.image, &self.target)?.0)
    }

    /// The configured loss (the objective the run minimises) at θ with the order of
    /// iteration `iter`.
    pub fn cost(&self, theta: &[f64], iter: u64) -> Result<f64> {
        Ok(self.scores(theta, iter)?.0)
    }

    /// One render at θ with the order of iteration `iter`: the configured loss, the
    /// authors' MSE and the image.
    pub fn scores(&self, theta: &[f64], iter: u64) -> Result<(f64, f64, Vec<f64>)> {
        let f = self.render(theta, iter)?;
        let (cost, _, [m, _]) = self.objective(&f.image)?;
        Ok((cost, m, f.image))
    }

    /// θ of the stack the problem was made with (its start).
    pub fn initial_params(&self) -> Vec<f64> {
        self.stack.params()
    }

    /// The configured loss of `image`: total, its gradient, and the unweighted terms.
    fn objective(&self, image: &[f64]) -> Result<(f64, Vec<f64>, [f64; 2])> {
        let (m, mut grad) = mse(image, &self.target)?;
        let w = &self.loss;
        let mut total = w.mse * m;
        grad.iter_mut().for_each(|g| *g *= w.mse);
        let mut dssim = 0.0;
        if w.dssim > 0.0 {
            use ifslab::loss::{DSsim, ImageLoss};
            let size = self.renderer.cfg.size;
            let n = size * size;
            let t64: Vec<f64> = self.target.iter().map(|&v| v as f64).collect();
            for ch in 0..3 {
                let (v, g) = DSsim::default().value_and_grad::<f64>(
                    &image[ch * n..(ch + 1) * n],
                    &t64[ch * n..(ch + 1) * n],
                    size,
                    size,
                )?;
                dssim += v / 3.0;
                for (a, b) in grad[ch * n..(ch + 1) * n].iter_mut().zip(&g) {
                    *a += w.dssim * b / 3.0;
                }
            }
            total += w.dssim * dssim;
        }
        Ok((total, grad, [m, dssim]))
    }
}

impl Differentiable for FlameProblem {
    fn evaluate(&self, theta: &[f64], iter: u64) -> Result<Evaluation> {
        let stack = self.stack_at(theta)?;
        let ((loss, [m, d]), grad) =
            value_and_grad(&self.renderer, &stack, &self.order_at(iter), |image| {
                let (loss, g, terms) = self.objective(image)?;
                Ok::<_, Error>(((loss, terms), g))
            })?;
        Ok(Evaluation {
            loss,
            grad,
            terms: vec![("mse", m), ("dssim", d)],
        })
    }

    fn rate_multipliers(&self, iter: u64) -> Option<Vec<f64>> {
        if iter < self.freeze_geometry {
            Some(
                self.rates
                    .iter()
                    .zip(&self.geometry)
                    .map(|(&r, &g)| if g { 0.0 } else { r })
                    .collect(),
            )
        } else {
            Some(self.rates.clone())
        }
    }
}

impl Anneal for FlameProblem {
    /// The configured loss with the generator order of the run's start (a fixed random
    /// stream).
    fn anneal_cost(&self, theta: &[f64], _stream: u64, _frac: f64) -> Result<f64> {
        self.cost(theta, 0)
    }
}
