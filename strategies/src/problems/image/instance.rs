//! The 2-D image problem as an instance of the one image problem: [`SplatProblem`] is a
//! [`RenderProblem`] whose model ([`SplatModel`]) decodes θ into maps of an [`ImageModel`]'s
//! type, draws them with the splat ([`Splat`], σ on its schedule, the map probabilities of
//! the run's rule) and adds the map regulariser as its prior, and whose loss
//! ([`ObjectiveLoss`]) is the composite [`Objective`] — a candle graph (LPIPS and moments
//! included) whose autograd stops at the image.
//!
//! The map type is chosen by a config at run time, so the [`ImageProblem`] holds its model
//! type-erased ([`AnyModel`]) and builds the instance of the model's map type for each
//! evaluation, from borrowed parts (no copy of the target or the network). With the splat on
//! a GPU and a loss the GPU computes, the evaluation takes the same scene and renderer
//! through the fused GPU pass instead ([`splat::objective_and_grad`]), which never brings
//! the image to the CPU.
//!
//! The trait the instance is generic over, [`ImageModel`] (θ ↔ maps of one type), and the
//! probability rule [`MapProbabilities`] are defined here, so this file imports nothing of
//! the models or the config that use it.
//!
//! [`ImageProblem`]: super::ImageProblem
//! [`AnyModel`]: super::AnyModel

use std::borrow::{Borrow, Cow};

use candle_core::{Device, Tensor, Var};
use ifslab::loss::{LossBreakdown, Objective};
use ifslab::model::{Affine2, AffinePart, ProbabilityRule};
use ifslab::render::Renderer;
use ifslab::render::splat::{self, Splat, SplatConfig};
use serde::{Deserialize, Serialize};

use crate::driver::{Differentiable, Evaluation};
use crate::error::{Error, Result};
use crate::problems::render_problem::{Moment, PlaneLoss, RenderProblem, SceneModel, Terms};

/// θ ↔ maps of type [`ImageModel::Map`]: what the image problem fits.
pub trait ImageModel: Send + Sync + 'static {
    /// The maps θ describes.
    type Map: AffinePart + Send + Sync + 'static;

    /// The maps θ describes (an error when θ has the wrong length or a bad value).
    fn decode(&self, theta: &[f64]) -> Result<Vec<Self::Map>>;

    /// The chain rule: the gradient with respect to θ from the gradient with respect to the
    /// maps' parameters (flat, map after map, in [`DiffMap::write_params`](ifslab::model::DiffMap::write_params) order).
    fn backward(&self, theta: &[f64], grad_params: &[f64]) -> Result<Vec<f64>>;

    /// Brings θ back into the model's domain after a step (default: nothing to do).
    fn project(&self, _theta: &mut [f64]) {}

    /// θ for a start given as affine maps (the closest maps of the model).
    fn encode(&self, start: &[Affine2]) -> Result<Vec<f64>>;
}

/// How the differentiable renderer's chaos game picks maps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MapProbabilities {
    /// Every map equally likely.
    #[default]
    Uniform,
    /// Proportional to |det M| (uniform if every determinant is 0).
    Determinant,
}

impl MapProbabilities {
    pub(crate) fn is_uniform(&self) -> bool {
        *self == MapProbabilities::Uniform
    }
}

/// Names of the logged loss terms, in column order.
pub const TERMS: [&str; 5] = ["msmse", "dssim", "lpips", "moments", "regulariser"];

/// How the image problem renders θ: the splat at the start of the run, its σ schedule, the
/// chaos game's map-probability rule, clamping, and the run's seed.
#[derive(Clone, Debug, PartialEq)]
pub struct ImageRendering {
    /// The splat at iteration 0.
    pub splat: SplatConfig,
    /// `(σ at t = T, T)` when σ follows a schedule (geometric from `splat.sigma`).
    pub sigma_schedule: Option<(f64, u64)>,
    /// How the chaos game picks maps.
    pub probabilities: MapProbabilities,
    /// Clamp renders to [0, 1] (Learning Fractals sums Gaussians, then clamps).
    pub clamp: bool,
    /// The run's seed; draw `t` of it seeds iteration `t`'s chaos game.
    pub seed: u64,
}

impl ImageRendering {
    /// The splat at progress `frac = t/T` of the run.
    pub fn splat_at(&self, frac: f64) -> Cow<'_, SplatConfig> {
        match self.sigma_schedule {
            None => Cow::Borrowed(&self.splat),
            Some((end, _)) => {
                let s0 = self.splat.sigma;
                Cow::Owned(SplatConfig {
                    sigma: s0 * (end / s0).powf(frac.clamp(0.0, 1.0)),
                    ..self.splat.clone()
                })
            }
        }
    }

    /// The progress of moment `at` (iteration `t` is `t/T` on a schedule, 0 without one).
    pub fn progress(&self, at: Moment) -> f64 {
        match at {
            Moment::Iteration(t) => self
                .sigma_schedule
                .map_or(0.0, |(_, n)| t as f64 / n as f64),
            Moment::Progress { frac, .. } => frac,
        }
    }

    /// The splat that draws `maps` at `at`: σ of the schedule, the rule's map
    /// probabilities.
    pub fn splat<M: AffinePart>(&self, maps: &[M], at: Moment) -> Result<Splat<M, f32>> {
        let probs = match self.probabilities {
            MapProbabilities::Uniform => None,
            MapProbabilities::Determinant => {
                let dets: Vec<f64> = maps.iter().map(|m| m.affine_part().det().abs()).collect();
                // ∝ |det| with no floor; all-degenerate maps fall back to uniform.
                (dets.iter().sum::<f64>() > 0.0)
                    .then(|| ProbabilityRule::Determinant { floor: 0.0 }.resolve(&dets))
                    .transpose()?
            }
        };
        Ok(Splat::new(self.splat_at(self.progress(at)).into_owned()).with_probabilities(probs))
    }

    /// [`ImageRendering::splat`] and its chaos game's seed at `at`: stream `at.stream()` of
    /// the run's seed, as the run's [`Sampler`](ifslab::render::Sampler) gives it to the
    /// instance.
    pub fn drawn<M: AffinePart>(&self, maps: &[M], at: Moment) -> Result<(Splat<M, f32>, u64)> {
        let renderer = self.splat(maps, at)?;
        let seed = renderer.sampling(maps, self.seed, at.stream());
        Ok((renderer, seed))
    }
}

/// θ ↔ the maps of an [`ImageModel`], drawn by the splat: the model half of a
/// [`SplatProblem`].
pub struct SplatModel<'a, IM> {
    /// θ ↔ maps.
    pub model: &'a IM,
    /// How the maps are drawn.
    pub rendering: &'a ImageRendering,
    /// The objective whose map regulariser is the prior.
    pub objective: &'a Objective,
}

/// The scene of a θ: its maps, and the same maps with their parameters rounded to f32 — what
/// the splat draws (the candle op's argument is an f32 tensor; every committed run was
/// computed so).
#[derive(Clone, Debug)]
pub struct SplatScene<M> {
    /// The maps θ decodes to (the regulariser sees these).
    pub maps: Vec<M>,
    /// The maps rounded to f32 (the splat draws these).
    pub rounded: Vec<M>,
}

impl<M> Borrow<[M]> for SplatScene<M> {
    fn borrow(&self) -> &[M] {
        &self.rounded
    }
}

impl<IM: ImageModel> SceneModel for SplatModel<'_, IM> {
    type Renderer = Splat<IM::Map, f32>;
    type Scene = SplatScene<IM::Map>;

    fn scene(&self, theta: &[f64], _at: Moment) -> Result<Self::Scene> {
        let maps = self.model.decode(theta)?;
        let rounded = splat::through_f32(&maps);
        Ok(SplatScene { maps, rounded })
    }

    fn renderer(&self, scene: &Self::Scene, at: Moment) -> Result<Cow<'_, Self::Renderer>> {
        Ok(Cow::Owned(self.rendering.splat(&scene.maps, at)?))
    }

    /// A fresh chaos game every call: the iteration, or the annealing candidate's stream.
    fn draw(&self, at: Moment) -> u64 {
        at.stream()
    }

    /// The map regulariser on the maps as decoded. The image terms' gradient arrives from
    /// the splat's reverse pass and is first rounded to f32 — the candle op's f32 argument
    /// accumulates its gradient so (−0 becoming +0) —, then the regulariser's is added.
    fn priors(
        &self,
        scene: &Self::Scene,
        terms: &mut Terms,
        grad: Option<&mut [f64]>,
    ) -> Result<()> {
        let (r, rg) = self.objective.regulariser_params(&scene.maps)?;
        terms.set("regulariser", r, 1.0);
        if let Some(g) = grad {
            for (a, r) in g.iter_mut().zip(&rg) {
                *a = (0.0f32 + *a as f32) as f64 + r;
            }
        }
        Ok(())
    }

    fn pull_back(&self, theta: &[f64], _scene: &Self::Scene, grad: Vec<f64>) -> Result<Vec<f64>> {
        self.model.backward(theta, &grad)
    }

    fn project(&self, theta: &mut [f64]) {
        ImageModel::project(self.model, theta)
    }
}

/// The composite [`Objective`] on the splat's grey plane: the loss half of a
/// [`SplatProblem`]. Its terms are logged under [`TERMS`]; a term the config leaves out is
/// not computed and logs NaN.
pub struct ObjectiveLoss<'a> {
    /// The objective, holding the target.
    pub objective: &'a Objective,
    /// Clamp the render to [0, 1] before scoring it.
    pub clamp: bool,
    /// The plane's `(height, width)`.
    pub shape: (usize, usize),
}

impl PlaneLoss<f32> for ObjectiveLoss<'_> {
    fn value_and_grad(
        &self,
        planes: &[f32],
        grad: bool,
        terms: &mut Terms,
    ) -> Result<Option<Vec<f32>>> {
        let image = Tensor::from_vec(planes.to_vec(), self.shape, &Device::Cpu);
        let var = image
            .and_then(|t| Var::from_tensor(&t))
            .map_err(tensor_err)?;
        let mut pred = var.as_tensor().clone();
        if self.clamp {
            pred = pred.clamp(0f32, 1f32).map_err(tensor_err)?;
        }
        let (image_total, b) = self.objective.image_loss(&pred)?;
        set_image_terms(terms, &b, self.objective);
        if !grad {
            return Ok(None);
        }
        let grads = image_total.backward().map_err(tensor_err)?;
        Ok(Some(match grads.get(var.as_tensor()) {
            Some(gi) => gi
                .flatten_all()
                .and_then(|g| g.to_vec1())
                .map_err(tensor_err)?,
            // No image term depends on the render (every image weight 0).
            None => vec![0.0; planes.len()],
        }))
    }
}

/// The image terms of `b` with their weights (NaN with weight 0 for the ones not computed).
fn set_image_terms(terms: &mut Terms, b: &LossBreakdown, objective: &Objective) {
    let c = objective.config();
    for (name, value, weight) in [
        ("msmse", b.msmse, c.msmse_weight),
        ("dssim", b.dssim, c.dssim_weight),
        ("lpips", b.lpips, c.lpips_weight),
        ("moments", b.moments, c.moments_weight),
    ] {
        match value {
            Some(v) => terms.set(name, v, weight),
            None => terms.set(name, f64::NAN, 0.0),
        }
    }
}

/// The 2-D image problem of model `IM`: the splat of its maps scored by the objective.
pub type SplatProblem<'a, IM> = RenderProblem<SplatModel<'a, IM>, ObjectiveLoss<'a>>;

/// The instance for `model` rendered as `rendering` says and scored by `objective`.
pub fn splat_problem<'a, IM: ImageModel>(
    model: &'a IM,
    rendering: &'a ImageRendering,
    objective: &'a Objective,
) -> SplatProblem<'a, IM> {
    let shape = (rendering.splat.height, rendering.splat.width);
    RenderProblem::from_parts(
        SplatModel {
            model,
            rendering,
            objective,
        },
        ObjectiveLoss {
            objective,
            clamp: rendering.clamp,
            shape,
        },
        rendering.seed,
        &TERMS,
    )
}

/// One evaluation of the instance at iteration `iter`: through the fused GPU pass where
/// [`splat::gpu_route`] allows, else a [`RenderProblem`] pass (render, objective, reverse
/// pass, priors, chain rule).
pub fn evaluate<IM: ImageModel>(
    problem: &SplatProblem<'_, IM>,
    theta: &[f64],
    iter: u64,
) -> Result<Evaluation> {
    let model = problem.scene_model();
    let at = Moment::Iteration(iter);
    let (rendering, objective) = (model.rendering, model.objective);
    if splat::gpu_route(&rendering.splat, objective, rendering.clamp).is_ok() {
        let maps = model.model.decode(theta)?;
        let (renderer, seed) = rendering.drawn(&maps, at)?;
        let (b, g) = splat::objective_and_grad(
            &renderer.cfg,
            &maps,
            renderer.probs.as_deref(),
            rendering.clamp,
            seed,
            objective,
        )?;
        let mut terms = Terms::new(&TERMS);
        set_image_terms(&mut terms, &b, objective);
        terms.set("regulariser", b.regulariser.unwrap_or(f64::NAN), 1.0);
        return Ok(Evaluation {
            loss: b.total,
            grad: model.model.backward(theta, &g)?,
            terms: terms.named(),
        });
    }
    Differentiable::evaluate(problem, theta, iter)
}

fn tensor_err(e: candle_core::Error) -> Error {
    Error::Core(ifslab::Error::from(e))
}
