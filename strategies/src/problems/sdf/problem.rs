//! The fit: control points θ → segment maps → SDF raster → multi-scale MSE on pixels and on
//! distances → gradient, all in f64 with the renderer's hand-written reverse pass.
//!
//! The paper's two losses: multi-scale MSE (the image and its 2×2-pooled copies, summed)
//! between the rendered pixels `exp(−d²/σ²)` and the target's ink, and between the raw
//! distances and the target's distance transform. Here they are two weighted terms of one
//! loss; distances are measured in units of the image side, so the term does not grow with
//! the resolution. The target's distance transform is to the centres of its dark pixels,
//! while the render's is to the figure itself: on a target drawn with width σ the two differ
//! by about σ near the figure, which the pixel term does not.

use ifslab::loss::{ImageLoss, MsMse};
use ifslab::model::segment::Pattern;
use ifslab::render::sdf::{SdfRenderConfig, SdfRenderer, SdfView};
use ifslab::render::{Renderer, Sampler};
use serde::{Deserialize, Serialize};

use crate::driver::{Differentiable, Evaluation};
use crate::error::{Error, Result};
use crate::optim::annealing::Anneal;
use crate::problems::sdf::barrier::scale_barrier;
use crate::problems::sdf::crossing::{MAX_CROSSING_DEPTH, crossing_penalty};
use crate::problems::sdf::learned::{LearnedConfig, LearnedPattern};
use crate::problems::sdf::target::distance_transform;

/// Names of the logged loss terms, in column order.
pub const SDF_TERMS: [&str; 4] = ["pixel", "distance", "crossing", "scale_barrier"];

/// Pixels beyond this many σ contribute less than `e^{−36} ≈ 2.3e-16` and are not computed
/// when the loss has no distance term.
pub const CUTOFF_SIGMAS: f64 = 6.0;

/// The loss of a fit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SdfLossConfig {
    /// Weight of the multi-scale MSE on pixels.
    pub pixel: f64,
    /// Weight of the multi-scale MSE on distances (in units of the image side).
    pub distance: f64,
    /// 2×2 poolings after the full-resolution level.
    pub levels: usize,
    /// Weight of the self-crossing penalty (0: off): the sum over pairs of copies of the
    /// base figure of their squared crossing depth, in units of the pattern's plane (see
    /// [`crate::problems::sdf::crossing`]).
    pub crossing: f64,
    /// Length of the words whose copies of the base figure the crossing penalty compares
    /// (1: one copy per map).
    pub crossing_depth: usize,
    /// Weight of the barrier on the maps' scales above `max_scale` (0: off; see
    /// [`crate::problems::sdf::barrier`]). With learned pairs it also lets soft maps that
    /// expand be drawn instead of refused.
    #[serde(skip_serializing_if = "is_zero")]
    pub scale_barrier: f64,
    /// The scale above which the barrier acts, in (0, 1).
    #[serde(skip_serializing_if = "is_default_max_scale")]
    pub max_scale: f64,
}

/// The barrier's threshold unless configured.
const DEFAULT_MAX_SCALE: f64 = 0.9;

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

fn is_default_max_scale(v: &f64) -> bool {
    *v == DEFAULT_MAX_SCALE
}

impl Default for SdfLossConfig {
    fn default() -> Self {
        SdfLossConfig {
            pixel: 1.0,
            distance: 0.0,
            levels: 4,
            crossing: 0.0,
            crossing_depth: 1,
            scale_barrier: 0.0,
            max_scale: DEFAULT_MAX_SCALE,
        }
    }
}

impl SdfLossConfig {
    /// Checks the weights; errors name the field.
    pub fn validate(&self) -> Result<()> {
        for (name, w) in [
            ("loss.pixel", self.pixel),
            ("loss.distance", self.distance),
            ("loss.crossing", self.crossing),
            ("loss.scale_barrier", self.scale_barrier),
        ] {
            if !(w.is_finite() && w >= 0.0) {
                return Err(Error::param(
                    name,
                    format!("must be finite and ≥ 0, got {w}"),
                ));
            }
        }
        if self.pixel == 0.0 && self.distance == 0.0 {
            return Err(Error::param(
                "loss",
                "at least one of `pixel` and `distance` must be > 0",
            ));
        }
        if !(self.max_scale > 0.0 && self.max_scale < 1.0) {
            return Err(Error::param(
                "loss.max_scale",
                format!(
                    "must lie in (0, 1) (the scale below which the barrier is silent), got {}",
                    self.max_scale
                ),
            ));
        }
        if !(1..=MAX_CROSSING_DEPTH).contains(&self.crossing_depth) {
            return Err(Error::param(
                "loss.crossing_depth",
                format!(
                    "must be between 1 and {MAX_CROSSING_DEPTH}, got {}",
                    self.crossing_depth
                ),
            ));
        }
        Ok(())
    }
}

/// Fit a pattern's control points to a target image.
#[derive(Clone, Debug)]
pub struct SdfProblem {
    pattern: Pattern,
    view: SdfView,
    render: SdfRenderConfig,
    sigma: f64,
    /// `(σ at iteration 0, T)` when σ shrinks over the run.
    sigma_schedule: Option<(f64, u64)>,
    loss: SdfLossConfig,
    target: Vec<f64>,
    /// The target's distance transform in units of the image side (distance term only).
    target_dist: Option<Vec<f64>>,
    /// Learned pairs: θ holds softmax logits after the points.
    learned: Option<LearnedPattern>,
    /// The raster's sampling state: none, it is deterministic (no seed).
    sampler: Sampler<SdfRenderer>,
}

/// One evaluation's numbers.
#[derive(Clone, Debug, PartialEq)]
pub struct SdfEval {
    /// Weighted total.
    pub loss: f64,
    /// Unweighted pixel term.
    pub pixel: f64,
    /// Unweighted distance term.
    pub distance: f64,
    /// Unweighted self-crossing penalty (0 when its weight is 0: not computed).
    pub crossing: f64,
    /// Unweighted scale barrier (0 when its weight is 0: not computed).
    pub scale_barrier: f64,
    /// ∂loss/∂θ, when asked for.
    pub grad: Option<Vec<f64>>,
}

impl SdfProblem {
    /// The fit of `pattern`'s structure to `target` (ink in [0, 1], row-major, the view's
    /// size), drawn to `depth` with width `sigma` pixels.
    pub fn new(
        pattern: Pattern,
        target: Vec<f64>,
        view: SdfView,
        depth: usize,
        sigma: f64,
        loss: SdfLossConfig,
    ) -> Result<Self> {
        view.validate()?;
        loss.validate()?;
        if !(sigma.is_finite() && sigma > 0.0) {
            return Err(Error::param(
                "sigma",
                format!("must be > 0 pixels, got {sigma}"),
            ));
        }
        if target.len() != view.width * view.height {
            return Err(Error::InvalidInput(format!(
                "target has {} pixels, the view {}×{}",
                target.len(),
                view.width,
                view.height
            )));
        }
        let target_dist = if loss.distance > 0.0 {
            let side = view.width.max(view.height) as f64;
            Some(
                distance_transform(&target, view.width, view.height)?
                    .into_iter()
                    .map(|d| d / side)
                    .collect(),
            )
        } else {
            None
        };
        let render = SdfRenderConfig {
            depth,
            cutoff: (loss.distance == 0.0).then_some(CUTOFF_SIGMAS * sigma),
        };
        Ok(SdfProblem {
            pattern,
            view,
            render,
            sigma,
            sigma_schedule: None,
            loss,
            target,
            target_dist,
            learned: None,
            sampler: Sampler::new(0),
        })
    }

    /// Coarse to fine: σ starts at `sigma_start` and shrinks geometrically to the problem's
    /// σ at iteration `iterations` (thick lines first, so that a figure far from the target's
    /// still overlaps it; the paper names coarse-to-fine as future work).
    pub fn with_sigma_schedule(mut self, sigma_start: f64, iterations: u64) -> Result<Self> {
        if !(sigma_start.is_finite() && sigma_start > 0.0) {
            return Err(Error::param(
                "sigma_start",
                format!("must be > 0 pixels, got {sigma_start}"),
            ));
        }
        self.sigma_schedule = Some((sigma_start, iterations.max(1)));
        Ok(self)
    }

    /// Learned pairs (see [`crate::problems::sdf::learned`]): θ becomes the control points
    /// followed by one logit per pair endpoint and control point; τ shrinks over
    /// `iterations`.
    pub fn with_learned_pattern(mut self, cfg: LearnedConfig, iterations: u64) -> Result<Self> {
        self.learned = Some(LearnedPattern::new(self.pattern.clone(), cfg, iterations)?);
        Ok(self)
    }

    /// The learned pairs, when θ holds logits.
    pub fn learned(&self) -> Option<&LearnedPattern> {
        self.learned.as_ref()
    }

    /// σ at progress `frac = t/T` of the run.
    pub fn sigma_at(&self, frac: f64) -> f64 {
        match self.sigma_schedule {
            None => self.sigma,
            Some((s0, _)) => s0 * (self.sigma / s0).powf(frac.clamp(0.0, 1.0)),
        }
    }

    fn frac(&self, iter: u64) -> f64 {
        match self.sigma_schedule {
            None => 1.0,
            Some((_, t)) => iter as f64 / t as f64,
        }
    }

    /// The pattern whose structure is fitted (its points are the start of nothing: θ is
    /// passed to every call).
    pub fn pattern(&self) -> &Pattern {
        &self.pattern
    }

    /// The view.
    pub fn view(&self) -> &SdfView {
        &self.view
    }

    /// The target's ink.
    pub fn target(&self) -> &[f64] {
        &self.target
    }

    /// The render settings.
    pub fn render_config(&self) -> &SdfRenderConfig {
        &self.render
    }

    /// σ in pixels at the end of the run (and throughout, without a schedule).
    pub fn sigma(&self) -> f64 {
        self.sigma
    }

    /// The pattern with control points θ (with learned pairs: their hard assignment).
    pub fn pattern_at(&self, theta: &[f64]) -> Result<Pattern> {
        match &self.learned {
            Some(l) => l.hard_pattern(theta),
            None => Ok(self.pattern.with_flat_points(theta)?),
        }
    }

    /// The final temperature of learned pairs (1 without: unused).
    fn final_temperature(&self) -> f64 {
        self.learned
            .as_ref()
            .map_or(1.0, |l| l.temperature_at(u64::MAX))
    }

    /// The rendered image at θ (with the final σ).
    pub fn image(&self, theta: &[f64]) -> Result<Vec<f64>> {
        let p = self.pattern_at(theta)?;
        let renderer = SdfRenderer::new(self.view, self.render, self.sigma);
        Ok(renderer
            .forward(&p, &self.sampler.sampling(&renderer, &p, 0))?
            .0)
    }

    /// The renderer of an evaluation with lines of width `sigma`: the intensity plane when
    /// the loss has a pixel term, the distance plane when it has a distance term, the
    /// cut-off (without a distance term) at [`CUTOFF_SIGMAS`]·σ.
    pub fn renderer(&self, sigma: f64) -> SdfRenderer {
        SdfRenderer {
            view: self.view,
            cfg: SdfRenderConfig {
                cutoff: self.render.cutoff.map(|_| CUTOFF_SIGMAS * sigma),
                ..self.render
            },
            sigma,
            intensity: self.loss.pixel > 0.0,
            distance: self.target_dist.is_some(),
        }
    }

    /// Loss terms at θ with the final σ, and the gradient when `grad`.
    pub fn eval(&self, theta: &[f64], grad: bool) -> Result<SdfEval> {
        self.eval_with(theta, grad, self.sigma)
    }

    /// Loss terms at θ drawn with width `sigma`, and the gradient when `grad`.
    pub fn eval_with(&self, theta: &[f64], grad: bool, sigma: f64) -> Result<SdfEval> {
        self.eval_at(theta, grad, sigma, self.final_temperature())
    }

    /// Loss terms at θ drawn with width `sigma`, learned pairs (if any) at temperature
    /// `tau`, and the gradient when `grad`.
    pub fn eval_at(&self, theta: &[f64], grad: bool, sigma: f64, tau: f64) -> Result<SdfEval> {
        let p = match &self.learned {
            Some(l) => l.soft_pattern(theta, tau, self.loss.scale_barrier > 0.0)?,
            None => self.pattern.with_flat_points(theta)?,
        };
        let renderer = self.renderer(sigma);
        let sampling = self.sampler.sampling(&renderer, &p, 0);
        let (planes, raster) = renderer.forward(&p, &sampling)?;
        let (w, h) = (self.view.width, self.view.height);
        let mse = MsMse::new(self.loss.levels);
        // ∂L/∂planes: the intensity plane's, then the distance plane's.
        let mut g_planes = if grad {
            vec![0.0; planes.len()]
        } else {
            Vec::new()
        };
        let (img, d) = planes.split_at(if renderer.intensity { w * h } else { 0 });
        let mut out = SdfEval {
            loss: 0.0,
            pixel: 0.0,
            distance: 0.0,
            crossing: 0.0,
            scale_barrier: 0.0,
            grad: None,
        };
        if renderer.intensity {
            let (v, g) = mse.value_and_grad::<f64>(img, &self.target, w, h)?;
            out.pixel = v;
            out.loss += self.loss.pixel * v;
            if grad {
                for (a, x) in g_planes.iter_mut().zip(&g) {
                    *a = x * self.loss.pixel;
                }
            }
        }
        if let Some(td) = &self.target_dist {
            let (v, g) = mse.value_and_grad::<f64>(d, td, w, h)?;
            out.distance = v;
            out.loss += self.loss.distance * v;
            if grad {
                let at = g_planes.len() - w * h;
                for (a, x) in g_planes[at..].iter_mut().zip(&g) {
                    *a = self.loss.distance * x;
                }
            }
        }
        let mut g_barrier = None;
        if self.loss.scale_barrier > 0.0 {
            let (v, g) = scale_barrier(&p, self.loss.max_scale)?;
            out.scale_barrier = v;
            out.loss += self.loss.scale_barrier * v;
            g_barrier = Some(g);
        }
        let mut g_cross = None;
        if self.loss.crossing > 0.0 {
            let (v, g) = crossing_penalty(&p, self.loss.crossing_depth, grad)?;
            out.crossing = v;
            out.loss += self.loss.crossing * v;
            g_cross = Some(g);
        }
        if !out.loss.is_finite() {
            return Err(Error::Numerical(format!(
                "the loss is {} at these control points",
                out.loss
            )));
        }
        if grad {
            let mut g = renderer.backward(&p, &sampling, &raster, &g_planes)?;
            if let Some(gc) = g_cross {
                for (x, c) in g.iter_mut().zip(gc) {
                    *x += self.loss.crossing * c;
                }
            }
            if let Some(gb) = g_barrier {
                for (x, b) in g.iter_mut().zip(gb) {
                    *x += self.loss.scale_barrier * b;
                }
            }
            out.grad = Some(match &self.learned {
                Some(l) => l.backward(theta, tau, &g)?,
                None => g,
            });
        }
        Ok(out)
    }
}

impl Differentiable for SdfProblem {
    /// Deterministic: the iteration only sets σ when σ follows a schedule.
    fn evaluate(&self, theta: &[f64], iter: u64) -> Result<Evaluation> {
        let tau = self
            .learned
            .as_ref()
            .map_or(1.0, |l| l.temperature_at(iter));
        let e = self.eval_at(theta, true, self.sigma_at(self.frac(iter)), tau)?;
        Ok(Evaluation {
            loss: e.loss,
            grad: e.grad.unwrap_or_default(),
            terms: vec![
                (SDF_TERMS[0], e.pixel),
                (SDF_TERMS[1], e.distance),
                (SDF_TERMS[2], e.crossing),
                (SDF_TERMS[3], e.scale_barrier),
            ],
        })
    }
}

impl Anneal for SdfProblem {
    /// The loss itself at progress `frac` (the render is deterministic: the stream does
    /// not matter).
    fn anneal_cost(&self, theta: &[f64], _stream: u64, frac: f64) -> Result<f64> {
        let tau = self.learned.as_ref().map_or(1.0, |l| {
            l.temperature_at((frac.clamp(0.0, 1.0) * l.iterations() as f64) as u64)
        });
        Ok(self.eval_at(theta, false, self.sigma_at(frac), tau)?.loss)
    }
}
