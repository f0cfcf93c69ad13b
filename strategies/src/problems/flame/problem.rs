//! The fit: θ → flame stack → differentiable flame pipeline → the authors' MSE against the
//! RGB target → gradient, all in f64 with the pipeline's hand-written reverse pass; an
//! instance of the one image problem ([`RenderProblem`]).

use std::borrow::Cow;
use std::sync::Arc;

use ifslab::image::Image;
use ifslab::loss::{DSsim, ImageLoss};
use ifslab::model::flame::learnable::{Background, FlameStack};
use ifslab::render::Renderer;
use ifslab::render::flame_diff::{DiffFlameConfig, FlameFrame, FlameRenderer, GeneratorOrder, mse};

use crate::error::Result;
use crate::problems::flame::config::{FlameLoss, Rates};
use crate::problems::render_problem::{Moment, PlaneLoss, RenderProblem, SceneModel, Terms};

/// Names of the logged loss terms, in column order (unweighted).
pub const FLAME_TERMS: [&str; 2] = ["mse", "dssim"];

/// Fit a flame stack to an RGB target: the [`RenderProblem`] of a [`FlameModel`] scored by
/// a [`FlameImageLoss`].
pub type FlameProblem = RenderProblem<FlameModel, FlameImageLoss>;

/// θ → a flame stack shaped like the start's → the differentiable flame pipeline, its
/// generator order redrawn every `redraw_every` iterations; per-group learning rates, the
/// geometry held still for the first iterations.
#[derive(Clone, Debug)]
pub struct FlameModel {
    stack: FlameStack,
    renderer: FlameRenderer,
    redraw_every: u64,
    rates: Vec<f64>,
    /// Which θ entries the authors' sampler and splatter hold (generators, final
    /// transform, κ).
    geometry: Vec<bool>,
    freeze_geometry: u64,
}

/// The authors' MSE against the RGB target, and optionally D-SSIM per channel.
#[derive(Clone, Debug)]
pub struct FlameImageLoss {
    /// Three planes, `size × size`, row 0 at the top.
    target: Vec<f32>,
    /// The target in f64, for D-SSIM.
    target64: Vec<f64>,
    weights: FlameLoss,
    size: usize,
}

impl FlameModel {
    /// The stack at θ.
    fn stack_at(&self, theta: &[f64]) -> Result<FlameStack> {
        let mut s = self.stack.clone();
        s.set_params(theta)?;
        Ok(s)
    }

    /// The redraw epoch of iteration `iter` (0 throughout when the order is never redrawn).
    fn epoch(&self, iter: u64) -> u64 {
        iter.checked_div(self.redraw_every).unwrap_or(0)
    }
}

impl SceneModel for FlameModel {
    type Renderer = FlameRenderer;
    type Scene = FlameStack;

    fn scene(&self, theta: &[f64], _at: Moment) -> Result<FlameStack> {
        self.stack_at(theta)
    }

    fn renderer(&self, _scene: &FlameStack, _at: Moment) -> Result<Cow<'_, FlameRenderer>> {
        Ok(Cow::Borrowed(&self.renderer))
    }

    /// The redraw epoch of an iteration; an annealing candidate is scored with the order of
    /// the run's start (a fixed random stream).
    fn draw(&self, at: Moment) -> u64 {
        match at {
            Moment::Iteration(iter) => self.epoch(iter),
            Moment::Progress { .. } => 0,
        }
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

impl PlaneLoss<f64> for FlameImageLoss {
    fn value_and_grad(
        &self,
        image: &[f64],
        grad: bool,
        terms: &mut Terms,
    ) -> Result<Option<Vec<f64>>> {
        let (m, mut g) = mse(image, &self.target)?;
        let w = &self.weights;
        terms.set(FLAME_TERMS[0], m, w.mse);
        g.iter_mut().for_each(|v| *v *= w.mse);
        if w.dssim > 0.0 {
            let n = self.size * self.size;
            let mut dssim = 0.0;
            for ch in 0..3 {
                let (v, gd) = DSsim::default().value_and_grad::<f64>(
                    &image[ch * n..(ch + 1) * n],
                    &self.target64[ch * n..(ch + 1) * n],
                    self.size,
                    self.size,
                )?;
                dssim += v / 3.0;
                for (a, b) in g[ch * n..(ch + 1) * n].iter_mut().zip(&gd) {
                    *a += w.dssim * b / 3.0;
                }
            }
            terms.set(FLAME_TERMS[1], dssim, w.dssim);
        }
        Ok(grad.then_some(g))
    }
}

impl FlameProblem {
    /// The problem of fitting stacks shaped like `stack` to `target` (RGB, `cfg.size ×
    /// cfg.size`, values in [0, 1]).
    pub fn new(
        stack: FlameStack,
        cfg: DiffFlameConfig,
        target: Image,
        seed: u64,
        redraw_every: u64,
        rates: &Rates,
        loss: FlameLoss,
    ) -> Result<Self> {
        loss.validate()?;
        cfg.validate()?;
        stack.validate()?;
        target.expect_shape("the target", 3, cfg.size, cfg.size)?;
        let target = target.values;
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
        let size = cfg.size;
        let model = FlameModel {
            stack,
            renderer: FlameRenderer { cfg },
            redraw_every,
            rates: r,
            geometry,
            freeze_geometry: rates.freeze_geometry,
        };
        let image_loss = FlameImageLoss {
            target64: target.iter().map(|&v| v as f64).collect(),
            target,
            weights: loss,
            size,
        };
        Ok(RenderProblem::from_parts(
            model,
            image_loss,
            seed,
            &FLAME_TERMS,
        ))
    }

    /// The stack at θ.
    pub fn stack_at(&self, theta: &[f64]) -> Result<FlameStack> {
        self.model.stack_at(theta)
    }

    /// The pipeline's settings.
    pub fn config(&self) -> &DiffFlameConfig {
        &self.model.renderer.cfg
    }

    /// The target.
    pub fn target(&self) -> &[f32] {
        &self.loss.target
    }

    /// The generator order used at iteration `iter`: the renderer's draw for the redraw
    /// epoch `iter / redraw_every` (0 throughout when the order is never redrawn), drawn
    /// once per epoch.
    pub fn order_at(&self, iter: u64) -> Arc<GeneratorOrder> {
        let m = &self.model;
        self.sampler.sampling(&m.renderer, &m.stack, m.epoch(iter))
    }

    /// The render at θ with the order of iteration `iter`.
    pub fn render(&self, theta: &[f64], iter: u64) -> Result<FlameFrame> {
        let stack = self.stack_at(theta)?;
        let (image, mut frame) = self.model.renderer.forward(&stack, &self.order_at(iter))?;
        frame.image = image;
        Ok(frame)
    }

    /// The MSE at θ with the order of iteration `iter`.
    pub fn loss(&self, theta: &[f64], iter: u64) -> Result<f64> {
        let f = self.render(theta, iter)?;
        Ok(mse(&f.image, &self.loss.target)?.0)
    }

    /// The configured loss (the objective the run minimises) at θ with the order of
    /// iteration `iter`.
    pub fn cost(&self, theta: &[f64], iter: u64) -> Result<f64> {
        Ok(self.scores(theta, iter)?.0)
    }

    /// One render at θ with the order of iteration `iter`: the configured loss, the
    /// authors' MSE and the image.
    pub fn scores(&self, theta: &[f64], iter: u64) -> Result<(f64, f64, Vec<f64>)> {
        let out = self.pass(theta, Moment::Iteration(iter), false)?;
        let image = out.planes.unwrap_or_default();
        Ok((out.terms.total(), out.terms.get(FLAME_TERMS[0]), image))
    }

    /// θ of the stack the problem was made with (its start).
    pub fn initial_params(&self) -> Vec<f64> {
        self.model.stack.params()
    }
}
