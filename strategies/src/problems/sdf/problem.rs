//! The fit: control points θ → segment maps → SDF raster → multi-scale MSE on pixels and on
//! distances → gradient, all in f64 with the renderer's hand-written reverse pass; an
//! instance of the one image problem ([`RenderProblem`]).
//!
//! The paper's two losses: multi-scale MSE (the image and its 2×2-pooled copies, summed)
//! between the rendered pixels `exp(−d²/σ²)` and the target's ink, and between the raw
//! distances and the target's distance transform. Here they are two weighted terms of one
//! loss; distances are measured in units of the image side, so the term does not grow with
//! the resolution. The target's distance transform is to the centres of its dark pixels,
//! while the render's is to the figure itself: on a target drawn with width σ the two differ
//! by about σ near the figure, which the pixel term does not.

use std::borrow::{Borrow, Cow};

use ifslab::image::Image;
use ifslab::loss::{ImageLoss, MsMse};
use ifslab::model::segment::Pattern;
use ifslab::render::Renderer;
use ifslab::render::sdf::{SdfRenderConfig, SdfRenderer, SdfView};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::problems::render_problem::{Moment, PlaneLoss, RenderProblem, SceneModel, Terms};
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

/// Fit a pattern's control points to a target image: the [`RenderProblem`] of an
/// [`SdfModel`] scored by an [`SdfLoss`].
pub type SdfProblem = RenderProblem<SdfModel, SdfLoss>;

/// θ → the pattern with those control points (or, with learned pairs, the soft pattern of
/// the points and logits) → the SDF raster at the run's σ; the self-crossing penalty and the
/// scale barrier as priors on the pattern.
#[derive(Clone, Debug)]
pub struct SdfModel {
    pattern: Pattern,
    view: SdfView,
    render: SdfRenderConfig,
    sigma: f64,
    /// `(σ at iteration 0, T)` when σ shrinks over the run.
    sigma_schedule: Option<(f64, u64)>,
    /// The loss's weights: the priors', and which planes the renderer draws.
    weights: SdfLossConfig,
    /// Learned pairs: θ holds softmax logits after the points.
    learned: Option<LearnedPattern>,
}

/// A pattern drawn by the SDF problem, with the temperature its learned pairs (if any) were
/// softened at: what the chain rule back to θ needs.
#[derive(Clone, Debug)]
pub struct SdfScene {
    /// The pattern the raster draws.
    pub pattern: Pattern,
    /// The learned pairs' temperature (1 without learned pairs).
    pub tau: f64,
}

impl Borrow<Pattern> for SdfScene {
    fn borrow(&self) -> &Pattern {
        &self.pattern
    }
}

/// The paper's two terms on the raster's planes: multi-scale MSE between the intensity plane
/// and the target's ink, and between the distance plane and the target's distance transform.
#[derive(Clone, Debug)]
pub struct SdfLoss {
    target: Vec<f64>,
    /// The target's distance transform in units of the image side (distance term only).
    target_dist: Option<Vec<f64>>,
    pixel: f64,
    distance: f64,
    mse: MsMse,
    width: usize,
    height: usize,
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

impl SdfModel {
    /// σ at progress `frac = t/T` of the run.
    fn sigma_at(&self, frac: f64) -> f64 {
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

    /// The renderer of an evaluation with lines of width `sigma` (see
    /// [`SdfProblem::renderer`]).
    fn renderer_with(&self, sigma: f64) -> SdfRenderer {
        SdfRenderer {
            view: self.view,
            cfg: SdfRenderConfig {
                cutoff: self.render.cutoff.map(|_| CUTOFF_SIGMAS * sigma),
                ..self.render
            },
            sigma,
            intensity: self.weights.pixel > 0.0,
            distance: self.weights.distance > 0.0,
        }
    }

    /// The pattern of θ with learned pairs (if any) softened at temperature `tau`.
    fn scene_at(&self, theta: &[f64], tau: f64) -> Result<SdfScene> {
        let pattern = match &self.learned {
            Some(l) => l.soft_pattern(theta, tau, self.weights.scale_barrier > 0.0)?,
            None => self.pattern.with_flat_points(theta)?,
        };
        Ok(SdfScene { pattern, tau })
    }
}

impl SceneModel for SdfModel {
    type Renderer = SdfRenderer;
    type Scene = SdfScene;

    /// The iteration sets the learned pairs' temperature; an annealing candidate's progress
    /// sets it at that fraction of the learned schedule.
    fn scene(&self, theta: &[f64], at: Moment) -> Result<SdfScene> {
        let tau = self.learned.as_ref().map_or(1.0, |l| match at {
            Moment::Iteration(iter) => l.temperature_at(iter),
            Moment::Progress { frac, .. } => {
                l.temperature_at((frac.clamp(0.0, 1.0) * l.iterations() as f64) as u64)
            }
        });
        self.scene_at(theta, tau)
    }

    /// Deterministic: the moment only sets σ when σ follows a schedule.
    fn renderer(&self, _scene: &SdfScene, at: Moment) -> Result<Cow<'_, SdfRenderer>> {
        let frac = match at {
            Moment::Iteration(iter) => self.frac(iter),
            Moment::Progress { frac, .. } => frac,
        };
        Ok(Cow::Owned(self.renderer_with(self.sigma_at(frac))))
    }

    fn draw(&self, _at: Moment) -> u64 {
        0
    }

    fn priors(&self, scene: &SdfScene, terms: &mut Terms, grad: Option<&mut [f64]>) -> Result<()> {
        let w = &self.weights;
        let mut grad = grad;
        if w.crossing > 0.0 {
            let (v, g) = crossing_penalty(&scene.pattern, w.crossing_depth, grad.is_some())?;
            terms.set(SDF_TERMS[2], v, w.crossing);
            if let Some(grad) = grad.as_deref_mut() {
                for (x, c) in grad.iter_mut().zip(g) {
                    *x += w.crossing * c;
                }
            }
        }
        if w.scale_barrier > 0.0 {
            let (v, g) = scale_barrier(&scene.pattern, w.max_scale)?;
            terms.set(SDF_TERMS[3], v, w.scale_barrier);
            if let Some(grad) = grad {
                for (x, b) in grad.iter_mut().zip(g) {
                    *x += w.scale_barrier * b;
                }
            }
        }
        Ok(())
    }

    fn pull_back(&self, theta: &[f64], scene: &SdfScene, grad: Vec<f64>) -> Result<Vec<f64>> {
        match &self.learned {
            Some(l) => l.backward(theta, scene.tau, &grad),
            None => Ok(grad),
        }
    }

    /// A non-finite loss is refused: control points that far off are not a fit.
    fn check_loss(&self, loss: f64) -> Result<()> {
        if loss.is_finite() {
            Ok(())
        } else {
            Err(Error::Numerical(format!(
                "the loss is {loss} at these control points"
            )))
        }
    }
}

impl PlaneLoss<f64> for SdfLoss {
    /// The planes are the intensity plane when the pixel term is on, then the distance
    /// plane when the distance term is on.
    fn value_and_grad(
        &self,
        planes: &[f64],
        grad: bool,
        terms: &mut Terms,
    ) -> Result<Option<Vec<f64>>> {
        let (w, h) = (self.width, self.height);
        let intensity = self.pixel > 0.0;
        // ∂L/∂planes: the intensity plane's, then the distance plane's.
        let mut g_planes = if grad {
            vec![0.0; planes.len()]
        } else {
            Vec::new()
        };
        let (img, d) = planes.split_at(if intensity { w * h } else { 0 });
        if intensity {
            let (v, g) = self.mse.value_and_grad::<f64>(img, &self.target, w, h)?;
            terms.set(SDF_TERMS[0], v, self.pixel);
            if grad {
                for (a, x) in g_planes.iter_mut().zip(&g) {
                    *a = x * self.pixel;
                }
            }
        }
        if let Some(td) = &self.target_dist {
            let (v, g) = self.mse.value_and_grad::<f64>(d, td, w, h)?;
            terms.set(SDF_TERMS[1], v, self.distance);
            if grad {
                let at = g_planes.len() - w * h;
                for (a, x) in g_planes[at..].iter_mut().zip(&g) {
                    *a = self.distance * x;
                }
            }
        }
        Ok(grad.then_some(g_planes))
    }
}

impl SdfProblem {
    /// The fit of `pattern`'s structure to `target` (grey, the view's size, ink in [0, 1];
    /// at the raster's f64, [`Image::widened`] from a picture), drawn to `depth` with width
    /// `sigma` pixels.
    pub fn new(
        pattern: Pattern,
        target: Image<f64>,
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
        target.expect_shape("the target", 1, view.width, view.height)?;
        let target = target.values;
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
        let plane_loss = SdfLoss {
            target,
            distance: loss.distance,
            pixel: loss.pixel,
            mse: MsMse::new(loss.levels),
            width: view.width,
            height: view.height,
            target_dist,
        };
        let model = SdfModel {
            pattern,
            view,
            render,
            sigma,
            sigma_schedule: None,
            weights: loss,
            learned: None,
        };
        // The raster is deterministic: the seed draws nothing.
        Ok(RenderProblem::from_parts(model, plane_loss, 0, &SDF_TERMS))
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
        self.model.sigma_schedule = Some((sigma_start, iterations.max(1)));
        Ok(self)
    }

    /// Learned pairs (see [`crate::problems::sdf::learned`]): θ becomes the control points
    /// followed by one logit per pair endpoint and control point; τ shrinks over
    /// `iterations`.
    pub fn with_learned_pattern(mut self, cfg: LearnedConfig, iterations: u64) -> Result<Self> {
        self.model.learned = Some(LearnedPattern::new(
            self.model.pattern.clone(),
            cfg,
            iterations,
        )?);
        Ok(self)
    }

    /// The learned pairs, when θ holds logits.
    pub fn learned(&self) -> Option<&LearnedPattern> {
        self.model.learned.as_ref()
    }

    /// σ at progress `frac = t/T` of the run.
    pub fn sigma_at(&self, frac: f64) -> f64 {
        self.model.sigma_at(frac)
    }

    /// The pattern whose structure is fitted (its points are the start of nothing: θ is
    /// passed to every call).
    pub fn pattern(&self) -> &Pattern {
        &self.model.pattern
    }

    /// The view.
    pub fn view(&self) -> &SdfView {
        &self.model.view
    }

    /// The target's ink.
    pub fn target(&self) -> &[f64] {
        &self.loss.target
    }

    /// The render settings.
    pub fn render_config(&self) -> &SdfRenderConfig {
        &self.model.render
    }

    /// σ in pixels at the end of the run (and throughout, without a schedule).
    pub fn sigma(&self) -> f64 {
        self.model.sigma
    }

    /// The pattern with control points θ (with learned pairs: their hard assignment).
    pub fn pattern_at(&self, theta: &[f64]) -> Result<Pattern> {
        match &self.model.learned {
            Some(l) => l.hard_pattern(theta),
            None => Ok(self.model.pattern.with_flat_points(theta)?),
        }
    }

    /// The final temperature of learned pairs (1 without: unused).
    fn final_temperature(&self) -> f64 {
        self.model
            .learned
            .as_ref()
            .map_or(1.0, |l| l.temperature_at(u64::MAX))
    }

    /// The rendered image at θ (with the final σ).
    pub fn image(&self, theta: &[f64]) -> Result<Vec<f64>> {
        let p = self.pattern_at(theta)?;
        let m = &self.model;
        let renderer = SdfRenderer::new(m.view, m.render, m.sigma);
        Ok(renderer
            .forward(&p, &self.sampler.sampling(&renderer, &p, 0))?
            .0)
    }

    /// The renderer of an evaluation with lines of width `sigma`: the intensity plane when
    /// the loss has a pixel term, the distance plane when it has a distance term, the
    /// cut-off (without a distance term) at [`CUTOFF_SIGMAS`]·σ.
    pub fn renderer(&self, sigma: f64) -> SdfRenderer {
        self.model.renderer_with(sigma)
    }

    /// Loss terms at θ with the final σ, and the gradient when `grad`.
    pub fn eval(&self, theta: &[f64], grad: bool) -> Result<SdfEval> {
        self.eval_with(theta, grad, self.model.sigma)
    }

    /// Loss terms at θ drawn with width `sigma`, and the gradient when `grad`.
    pub fn eval_with(&self, theta: &[f64], grad: bool, sigma: f64) -> Result<SdfEval> {
        self.eval_at(theta, grad, sigma, self.final_temperature())
    }

    /// Loss terms at θ drawn with width `sigma`, learned pairs (if any) at temperature
    /// `tau`, and the gradient when `grad`.
    pub fn eval_at(&self, theta: &[f64], grad: bool, sigma: f64, tau: f64) -> Result<SdfEval> {
        let scene = self.model.scene_at(theta, tau)?;
        let out = self.pass_with(theta, &scene, &self.model.renderer_with(sigma), 0, grad)?;
        let t = &out.terms;
        Ok(SdfEval {
            loss: t.total(),
            pixel: t.get(SDF_TERMS[0]),
            distance: t.get(SDF_TERMS[1]),
            crossing: t.get(SDF_TERMS[2]),
            scale_barrier: t.get(SDF_TERMS[3]),
            grad: out.grad,
        })
    }
}
