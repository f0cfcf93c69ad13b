//! The one image problem: θ → a model's scene → a [`Renderer`] → a loss on the rendered
//! planes against the target → the gradient back through the renderer's reverse pass and
//! the model's chain rule. [`RenderProblem`] is generic over the model ([`SceneModel`]: how
//! θ becomes a scene, which renderer draws it at each moment of the run — σ and τ
//! schedules —, the priors on the scene) and the loss ([`PlaneLoss`]: the target and the
//! terms measured on the planes); the renderer is the model's associated type. It is
//! [`Differentiable`] and [`Anneal`] once, for every instance, so every registered strategy
//! runs every instance.
//!
//! The instances:
//!
//! | problem | model | renderer | loss |
//! |---|---|---|---|
//! | [`SdfProblem`](crate::problems::sdf::SdfProblem) | control points (or learned pairs) → a segment pattern, σ coarse to fine; crossing and scale-barrier priors | `sdf::SdfRenderer` | multi-scale MSE on pixels and on distances |
//! | [`FlameProblem`](crate::problems::flame::FlameProblem) | θ → a flame stack; per-group learning rates | `flame_diff::FlameRenderer` | MSE (and D-SSIM) per RGB channel |
//! | [`Image3dProblem`](crate::problems::image3d::Image3dProblem) | θ → SVD maps of space, σ coarse to fine; the volume prior | `splat3d::MultiViewSplat` | MS-MSE per view, averaged, and the ink guard |
//!
//! | [`SplatProblem`](crate::problems::image::instance::SplatProblem) | θ → maps of any [`ImageModel`](crate::problems::image::ImageModel), σ coarse to fine, map probabilities by rule; the map regulariser | `splat::Splat` | the composite `Objective` (MS-MSE, D-SSIM, LPIPS, moments), a candle graph to the image |
//!
//! The 2-D image problem's map type is picked by a config at run time, so
//! [`ImageProblem`](crate::problems::image::ImageProblem) holds its model type-erased and
//! builds the instance of that map type per evaluation; with the splat on a GPU it takes the
//! fused pass that never brings the image to the CPU instead.
//!
//! **Adding a problem** is a model and, when none of the existing ones fits, a loss: the
//! model names its renderer and says what a θ draws; the loss scores planes. Their terms
//! land in one [`Terms`] record whose names, given once per problem, are the run log's
//! columns; the loss is the weighted sum of the terms in that order.

use std::borrow::{Borrow, Cow};

use ifslab::math::Real;
use ifslab::render::{Renderer, Sampler};

use crate::driver::{Differentiable, Evaluation};
use crate::error::{Error, Result};
use crate::optim::annealing::Anneal;

/// When in a run a render is asked for: what picks its random draw and its schedules' state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Moment {
    /// Iteration `t` of the run (a strategy's [`Differentiable::evaluate`]).
    Iteration(u64),
    /// Random stream `stream` at progress `frac` ∈ [0, 1] of the run (an annealing
    /// candidate's cost, [`Anneal::anneal_cost`]).
    Progress {
        /// The random stream.
        stream: u64,
        /// `t / T`.
        frac: f64,
    },
}

impl Moment {
    /// The random stream of this moment for a renderer drawing afresh every call: the
    /// iteration, or the annealing candidate's stream.
    pub fn stream(self) -> u64 {
        match self {
            Moment::Iteration(t) => t,
            Moment::Progress { stream, .. } => stream,
        }
    }
}

/// The renderer of a [`SceneModel`].
pub type RendererOf<M> = <M as SceneModel>::Renderer;
/// The pixel type of a [`SceneModel`]'s renderer.
pub type PixelOf<M> = <RendererOf<M> as Renderer>::Pixel;

/// θ ↔ a renderer's scene: the model half of a [`RenderProblem`].
pub trait SceneModel {
    /// What draws the scene.
    type Renderer: Renderer + Clone;
    /// The scene a θ gives: the renderer's scene, or a value holding it with what the
    /// chain rule back to θ needs (a learned pattern's temperature).
    type Scene: Borrow<<Self::Renderer as Renderer>::Scene>;

    /// The scene of `theta` at `at`.
    fn scene(&self, theta: &[f64], at: Moment) -> Result<Self::Scene>;

    /// The renderer that draws `scene` at `at` (its widths follow the run's schedule).
    fn renderer(&self, scene: &Self::Scene, at: Moment) -> Result<Cow<'_, Self::Renderer>>;

    /// Which draw of the renderer's sampling state `at` uses (the iteration or stream for a
    /// renderer drawing every call, the redraw epoch for one drawing per run).
    fn draw(&self, at: Moment) -> u64;

    /// The priors on `scene`: each term into `terms` and, when `grad` is given, its
    /// weighted gradient with respect to the scene's flat parameters added into it.
    fn priors(
        &self,
        _scene: &Self::Scene,
        _terms: &mut Terms,
        _grad: Option<&mut [f64]>,
    ) -> Result<()> {
        Ok(())
    }

    /// A gradient with respect to the scene's flat parameters as one with respect to θ.
    fn pull_back(&self, _theta: &[f64], _scene: &Self::Scene, grad: Vec<f64>) -> Result<Vec<f64>> {
        Ok(grad)
    }

    /// Refuses a loss the model cannot use (`Ok` by default: a non-finite loss is the
    /// strategy's to handle).
    fn check_loss(&self, _loss: f64) -> Result<()> {
        Ok(())
    }

    /// θ back onto the parameterisation's canonical set (see [`Differentiable::project`]).
    fn project(&self, _theta: &mut [f64]) {}

    /// Per-entry learning-rate factors (see [`Differentiable::rate_multipliers`]).
    fn rate_multipliers(&self, _iter: u64) -> Option<Vec<f64>> {
        None
    }
}

/// A loss on a renderer's planes: the loss half of a [`RenderProblem`], holding the target.
pub trait PlaneLoss<P: Real> {
    /// The terms of `planes` (channel-major, the renderer's shape) into `terms` and, when
    /// `grad`, the gradient of their weighted sum with respect to the planes.
    fn value_and_grad(&self, planes: &[P], grad: bool, terms: &mut Terms)
    -> Result<Option<Vec<P>>>;
}

/// One evaluation's loss terms: each term's unweighted value and its weight, in the order of
/// the problem's names (the run log's columns). A term not set counts 0.
#[derive(Clone, Debug, PartialEq)]
pub struct Terms {
    names: &'static [&'static str],
    values: Vec<(f64, f64)>,
}

impl Terms {
    /// No term set yet, for a problem whose terms are `names`.
    pub fn new(names: &'static [&'static str]) -> Self {
        Terms {
            names,
            values: vec![(0.0, 0.0); names.len()],
        }
    }

    /// Term `name`'s unweighted value and its weight in the loss.
    ///
    /// # Panics
    /// If `name` is not one of the problem's names (a model or a loss that names a term its
    /// problem does not log is a programming error).
    pub fn set(&mut self, name: &'static str, value: f64, weight: f64) {
        let i = self
            .names
            .iter()
            .position(|n| *n == name)
            .unwrap_or_else(|| panic!("`{name}` is not one of the terms {:?}", self.names));
        self.values[i] = (value, weight);
    }

    /// Term `name`'s unweighted value (0 when it was not set or is not a term).
    pub fn get(&self, name: &str) -> f64 {
        self.names
            .iter()
            .position(|n| *n == name)
            .map_or(0.0, |i| self.values[i].0)
    }

    /// The loss: `Σ weight·value` in the names' order, terms of weight 0 left out (a term
    /// not computed may be logged as NaN with weight 0).
    pub fn total(&self) -> f64 {
        self.values
            .iter()
            .fold(0.0, |s, &(v, w)| if w == 0.0 { s } else { s + w * v })
    }

    /// The unweighted terms, named, in order.
    pub fn named(&self) -> Vec<(&'static str, f64)> {
        self.names
            .iter()
            .zip(&self.values)
            .map(|(n, &(v, _))| (*n, v))
            .collect()
    }
}

/// What one pass through a [`RenderProblem`] gives.
#[derive(Debug)]
pub struct Outcome<P> {
    /// The loss terms (their weighted sum is the loss).
    pub terms: Terms,
    /// `∂loss/∂θ`, when asked for.
    pub grad: Option<Vec<f64>>,
    /// The rendered planes, when no gradient was asked for (a reverse pass frees them
    /// first).
    pub planes: Option<Vec<P>>,
}

impl<P> Outcome<P> {
    /// The loss.
    pub fn loss(&self) -> f64 {
        self.terms.total()
    }
}

/// The image problem of model `M` and loss `L` (see the module docs).
pub struct RenderProblem<M: SceneModel, L> {
    /// θ ↔ scene, the renderer, the priors.
    pub(crate) model: M,
    /// The target and the terms on the planes.
    pub(crate) loss: L,
    /// The run's sampling states.
    pub(crate) sampler: Sampler<M::Renderer>,
    /// The logged terms' names, in column order.
    pub(crate) terms: &'static [&'static str],
}

impl<M: SceneModel + Clone, L: Clone> Clone for RenderProblem<M, L> {
    fn clone(&self) -> Self {
        RenderProblem {
            model: self.model.clone(),
            loss: self.loss.clone(),
            sampler: self.sampler.clone(),
            terms: self.terms,
        }
    }
}

impl<M: SceneModel + std::fmt::Debug, L: std::fmt::Debug> std::fmt::Debug for RenderProblem<M, L> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RenderProblem")
            .field("model", &self.model)
            .field("loss", &self.loss)
            .field("sampler", &self.sampler)
            .field("terms", &self.terms)
            .finish()
    }
}

impl<M, L> RenderProblem<M, L>
where
    M: SceneModel,
    L: PlaneLoss<PixelOf<M>>,
{
    /// The problem of `model` scored by `loss`, its random draws from `seed`, its terms
    /// logged as `terms`.
    pub fn from_parts(model: M, loss: L, seed: u64, terms: &'static [&'static str]) -> Self {
        RenderProblem {
            model,
            loss,
            sampler: Sampler::new(seed),
            terms,
        }
    }

    /// The model.
    pub fn scene_model(&self) -> &M {
        &self.model
    }

    /// The loss.
    pub fn plane_loss(&self) -> &L {
        &self.loss
    }

    /// One pass at θ at moment `at`: the loss terms and, when `grad`, the gradient.
    pub fn pass(&self, theta: &[f64], at: Moment, grad: bool) -> Result<Outcome<PixelOf<M>>> {
        let scene = self.model.scene(theta, at)?;
        let renderer = self.model.renderer(&scene, at)?;
        self.pass_with(theta, &scene, &renderer, self.model.draw(at), grad)
    }

    /// One pass over a given scene (of θ) drawn by `renderer` with sampling draw `draw`.
    pub fn pass_with(
        &self,
        theta: &[f64],
        scene: &M::Scene,
        renderer: &M::Renderer,
        draw: u64,
        grad: bool,
    ) -> Result<Outcome<PixelOf<M>>> {
        let drawn: &<M::Renderer as Renderer>::Scene = scene.borrow();
        let sampling = self.sampler.sampling(renderer, drawn, draw);
        let (planes, tape) = renderer.forward(drawn, &sampling)?;
        let mut terms = Terms::new(self.terms);
        let g_planes = self.loss.value_and_grad(&planes, grad, &mut terms)?;
        self.model.check_loss(terms.total())?;
        let Some(g_planes) = g_planes.filter(|_| grad) else {
            self.model.priors(scene, &mut terms, None)?;
            self.model.check_loss(terms.total())?;
            return Ok(Outcome {
                terms,
                grad: None,
                planes: Some(planes),
            });
        };
        drop(planes);
        let mut g = renderer.backward(drawn, &sampling, &tape, &g_planes)?;
        drop(tape);
        self.model.priors(scene, &mut terms, Some(&mut g))?;
        self.model.check_loss(terms.total())?;
        let g = self.model.pull_back(theta, scene, g)?;
        Ok(Outcome {
            terms,
            grad: Some(g),
            planes: None,
        })
    }
}

impl<M, L> Differentiable for RenderProblem<M, L>
where
    M: SceneModel,
    L: PlaneLoss<PixelOf<M>>,
{
    fn evaluate(&self, theta: &[f64], iter: u64) -> Result<Evaluation> {
        let out = self.pass(theta, Moment::Iteration(iter), true)?;
        Ok(Evaluation {
            loss: out.terms.total(),
            grad: out
                .grad
                .ok_or_else(|| Error::Numerical("the pass returned no gradient".into()))?,
            terms: out.terms.named(),
        })
    }

    fn project(&self, theta: &mut [f64]) {
        self.model.project(theta);
    }

    fn rate_multipliers(&self, iter: u64) -> Option<Vec<f64>> {
        self.model.rate_multipliers(iter)
    }
}

impl<M, L> Anneal for RenderProblem<M, L>
where
    M: SceneModel,
    L: PlaneLoss<PixelOf<M>>,
{
    /// The loss on random stream `stream` at progress `frac` (no reverse pass).
    fn anneal_cost(&self, theta: &[f64], stream: u64, frac: f64) -> Result<f64> {
        Ok(self
            .pass(theta, Moment::Progress { stream, frac }, false)?
            .loss())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn terms_sum_in_their_order_and_unset_ones_count_zero() {
        let mut t = Terms::new(&["a", "b", "c"]);
        t.set("c", 2.0, 0.5);
        t.set("a", 1.0, 3.0);
        assert_eq!(t.total(), 3.0 + 1.0);
        assert_eq!(t.get("b"), 0.0);
        assert_eq!(t.named(), vec![("a", 1.0), ("b", 0.0), ("c", 2.0)]);
        // A term not computed, logged as NaN with weight 0, does not count.
        t.set("b", f64::NAN, 0.0);
        assert_eq!(t.total(), 4.0);
        assert!(t.get("b").is_nan());
    }

    #[test]
    #[should_panic(expected = "is not one of the terms")]
    fn an_unknown_term_is_a_programming_error() {
        Terms::new(&["a"]).set("b", 1.0, 1.0);
    }
}
