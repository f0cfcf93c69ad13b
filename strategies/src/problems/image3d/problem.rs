//! The multi-view fit: θ → SVD maps of space ([`SvdMap3`], 14 numbers a map) → the
//! multi-view splat ([`MultiViewSplat`], one plane per camera) → the 2-D image loss
//! ([`MsMse`]; 0 poolings is the plain MSE) on every view, averaged over the views → the
//! gradient through the splat's reverse pass; plus, optionally, `w·Σᵢ |det Mᵢ|`, the
//! volume the maps' images take of the attractor's (see [`Image3dProblem::with_volume`]);
//! plus, optionally, `w·mean over views of max(0, 1 − s − ink/ink of the view)²`, a guard
//! against fits that draw less ink than the views hold (see [`Image3dProblem::with_ink`]).
//! An instance of the one image problem ([`RenderProblem`]), so it is [`Differentiable`]
//! and [`Anneal`] and every strategy of the registry runs it.
//!
//! [`Differentiable`]: crate::driver::Differentiable
//! [`Anneal`]: crate::optim::annealing::Anneal

use std::borrow::Cow;

use ifslab::loss::{ImageLoss, MsMse};
use ifslab::model::map3::{DiffMap, SVD3_PARAMS, SvdMap3};
use ifslab::render::splat::kernel::SplatReal;
use ifslab::render::splat3d::{Camera, MultiViewConfig, MultiViewSplat};

use crate::error::{Error, Result};
use crate::problems::image3d::config::MapChoice;
use crate::problems::image3d::views::Views;
use crate::problems::render_problem::{Moment, PlaneLoss, RenderProblem, SceneModel, Terms};

/// Names of the logged loss terms (unweighted).
pub const IMAGE3D_TERMS: [&str; 3] = ["view_loss", "volume", "ink"];

/// Fit SVD maps of space to views (see the module docs), the views drawn and scored in
/// `T` (f32 for runs; f64 for checks against finite differences): the [`RenderProblem`] of
/// an [`Image3dModel`] scored by an [`Image3dLoss`].
pub type Image3dProblem<T = f32> = RenderProblem<Image3dModel<T>, Image3dLoss<T>>;

/// θ → SVD maps of space → the multi-view splat through the views' cameras, σ coarse to
/// fine; `w·Σᵢ |det Mᵢ|` as a prior.
#[derive(Clone, Debug)]
pub struct Image3dModel<T = f32> {
    /// Each map's reflection flag (fixed structure: θ cannot flip it).
    reflect: Vec<bool>,
    cameras: Vec<Camera>,
    render: MultiViewConfig,
    /// `(σ at the end, iterations)`: σ moves geometrically from `render.sigma` to it.
    sigma_schedule: Option<(f64, u64)>,
    /// Weight of `Σᵢ |det Mᵢ|`.
    volume: f64,
    /// How the chaos game picks the maps (uniform unless [`Image3dProblem::with_map_choice`]).
    choice: MapChoice,
    marker: std::marker::PhantomData<fn() -> T>,
}

/// The image loss on every view, averaged over the views, and the ink guard.
#[derive(Clone, Debug)]
pub struct Image3dLoss<T = f32> {
    targets: Vec<T>,
    loss: MsMse,
    /// Weight of the ink deficit.
    ink: f64,
    /// Fraction of a view's ink a render may lack before the ink term charges.
    ink_slack: f64,
    /// Each view's ink (the mean of its plane).
    target_ink: Vec<f64>,
    width: usize,
    height: usize,
}

impl<T: SplatReal> Image3dModel<T> {
    /// σ at progress `frac` of the schedule.
    fn sigma_at(&self, frac: f64) -> f64 {
        let s0 = self.render.sigma;
        match self.sigma_schedule {
            Some((end, _)) => s0 * (end / s0).powf(frac.clamp(0.0, 1.0)),
            None => s0,
        }
    }

    fn frac(&self, iter: u64) -> f64 {
        match self.sigma_schedule {
            Some((_, n)) => iter as f64 / n as f64,
            None => 0.0,
        }
    }

    fn n_params(&self) -> usize {
        self.reflect.len() * SVD3_PARAMS
    }

    /// The splat of `maps` at progress `frac` of the σ schedule.
    fn splat(&self, frac: f64, maps: &[SvdMap3]) -> Result<MultiViewSplat<SvdMap3, T>> {
        let cfg = MultiViewConfig {
            sigma: self.sigma_at(frac),
            ..self.render.clone()
        };
        Ok(MultiViewSplat::new(cfg, self.cameras.clone())?
            .with_probabilities(self.choice.for_svd(maps)))
    }

    /// `Σᵢ |det Mᵢ|` of `maps` and, when `grad` is given, its gradient added into it
    /// times `weight`: `|det M| = Π_k c·sigmoid(σ_k)`, so `∂|det M|/∂σ_k =
    /// |det M|·(1 − sigmoid(σ_k))`.
    fn volume_term(maps: &[SvdMap3], weight: f64, grad: Option<&mut [f64]>) -> f64 {
        let dets: Vec<f64> = maps
            .iter()
            .map(|m| m.singular_values().iter().map(|s| s.abs()).product())
            .collect();
        if let Some(grad) = grad {
            for ((m, d), g) in maps
                .iter()
                .zip(&dets)
                .zip(grad.chunks_exact_mut(SVD3_PARAMS))
            {
                let theta = m.params();
                for k in 0..3 {
                    let sig = 1.0 / (1.0 + (-theta[8 + k]).exp());
                    g[8 + k] += weight * d * (1.0 - sig);
                }
            }
        }
        dets.iter().sum()
    }
}

impl<T: SplatReal> SceneModel for Image3dModel<T> {
    type Renderer = MultiViewSplat<SvdMap3, T>;
    type Scene = Vec<SvdMap3>;

    fn scene(&self, theta: &[f64], _at: Moment) -> Result<Vec<SvdMap3>> {
        if theta.len() != self.n_params() {
            return Err(Error::InvalidInput(format!(
                "θ has {} entries for {} maps of {SVD3_PARAMS}",
                theta.len(),
                self.reflect.len()
            )));
        }
        theta
            .chunks_exact(SVD3_PARAMS)
            .zip(&self.reflect)
            .map(|(t, &r)| Ok(SvdMap3::new(t, r)?))
            .collect()
    }

    /// σ at the moment's progress; the maps' probabilities from the maps themselves (not
    /// differentiated).
    fn renderer(
        &self,
        maps: &Vec<SvdMap3>,
        at: Moment,
    ) -> Result<Cow<'_, MultiViewSplat<SvdMap3, T>>> {
        let frac = match at {
            Moment::Iteration(iter) => self.frac(iter),
            Moment::Progress { frac, .. } => frac,
        };
        Ok(Cow::Owned(self.splat(frac, maps)?))
    }

    /// Iteration `t` draws stream `t`.
    fn draw(&self, at: Moment) -> u64 {
        at.stream()
    }

    fn priors(
        &self,
        maps: &Vec<SvdMap3>,
        terms: &mut Terms,
        grad: Option<&mut [f64]>,
    ) -> Result<()> {
        let volume = Self::volume_term(maps, self.volume, grad);
        terms.set(IMAGE3D_TERMS[1], volume, self.volume);
        Ok(())
    }

    /// Each quaternion back to unit length (the map is unchanged; steps keep their scale).
    fn project(&self, theta: &mut [f64]) {
        for map in theta.chunks_exact_mut(SVD3_PARAMS) {
            for q in [0..4, 4..8] {
                let n = map[q.clone()].iter().map(|v| v * v).sum::<f64>().sqrt();
                if n.is_finite() && n > 1e-12 {
                    map[q].iter_mut().for_each(|v| *v /= n);
                }
            }
        }
    }
}

impl<T: SplatReal> Image3dLoss<T> {
    /// The loss of `image` (all views) against the targets: the mean over views of the
    /// loss of each, and its gradient.
    fn objective(&self, image: &[T]) -> Result<(f64, Vec<T>)> {
        let (w, h) = (self.width, self.height);
        let n = self.target_ink.len();
        let mut total = 0.0;
        let mut grad = Vec::with_capacity(image.len());
        for (pred, target) in image
            .chunks_exact(w * h)
            .zip(self.targets.chunks_exact(w * h))
        {
            let (l, g) = self.loss.value_and_grad::<T>(pred, target, w, h)?;
            total += l.to_f64().unwrap_or(f64::NAN) / n as f64;
            let inv = T::from(1.0 / n as f64).unwrap_or_else(T::one);
            grad.extend(g.iter().map(|&v| v * inv));
        }
        Ok((total, grad))
    }

    /// The ink term of `image` (all views, unweighted) and, when `grad` is given, its
    /// gradient times `weight` added into it.
    fn ink_term(&self, image: &[T], weight: f64, grad: Option<&mut [T]>) -> f64 {
        let pixels = self.width * self.height;
        let n = self.target_ink.len() as f64;
        let mut total = 0.0;
        let mut slopes = Vec::with_capacity(self.target_ink.len());
        for (plane, &target) in image.chunks_exact(pixels).zip(&self.target_ink) {
            let ink = plane.iter().map(|v| v.to_f64().unwrap_or(0.0)).sum::<f64>() / pixels as f64;
            let deficit = if target > 1e-9 {
                (1.0 - self.ink_slack - ink / target).max(0.0)
            } else {
                0.0
            };
            total += deficit * deficit / n;
            // ∂/∂pixel of deficit²/n = −2·deficit/(target·pixels·n).
            slopes.push(if deficit > 0.0 {
                -2.0 * deficit / (target * pixels as f64 * n)
            } else {
                0.0
            });
        }
        if let Some(grad) = grad
            && weight > 0.0
        {
            for (g, &slope) in grad.chunks_exact_mut(pixels).zip(&slopes) {
                if slope != 0.0 {
                    let d = T::from(weight * slope).unwrap_or_else(T::zero);
                    g.iter_mut().for_each(|v| *v = *v + d);
                }
            }
        }
        total
    }
}

impl<T: SplatReal> PlaneLoss<T> for Image3dLoss<T> {
    fn value_and_grad(&self, image: &[T], grad: bool, terms: &mut Terms) -> Result<Option<Vec<T>>> {
        let (view_loss, mut g) = self.objective(image)?;
        terms.set(IMAGE3D_TERMS[0], view_loss, 1.0);
        let (weight, g_ink) = if grad {
            (self.ink, Some(g.as_mut_slice()))
        } else {
            (0.0, None)
        };
        let ink = self.ink_term(image, weight, g_ink);
        terms.set(IMAGE3D_TERMS[2], ink, self.ink);
        Ok(grad.then_some(g))
    }
}

impl<T: SplatReal> Image3dProblem<T> {
    /// The problem of fitting maps with the reflection flags of `start` to `views`, drawn
    /// with `render`, scored by `loss` on every view; `seed` seeds every iteration's
    /// trajectories (iteration `t` draws stream `t`).
    pub fn new(
        start: &[SvdMap3],
        views: &Views,
        render: MultiViewConfig,
        loss: MsMse,
        seed: u64,
    ) -> Result<Self> {
        if start.is_empty() {
            return Err(Error::param("maps", "at least one map is needed"));
        }
        // Checks the config and the cameras as the splat will.
        MultiViewSplat::<SvdMap3, T>::new(render.clone(), views.cameras.clone())?;
        let (width, height) = views.size();
        let pixels = width * height;
        let target_ink = views
            .image
            .values
            .chunks_exact(pixels)
            .map(|p| p.iter().map(|&v| f64::from(v)).sum::<f64>() / pixels as f64)
            .collect();
        let model = Image3dModel {
            reflect: start.iter().map(SvdMap3::reflect).collect(),
            cameras: views.cameras.clone(),
            render,
            sigma_schedule: None,
            volume: 0.0,
            choice: MapChoice::Uniform,
            marker: std::marker::PhantomData,
        };
        let view_loss = Image3dLoss {
            targets: views
                .image
                .values
                .iter()
                .map(|&v| T::from(v).unwrap_or_else(T::zero))
                .collect(),
            loss,
            ink: 0.0,
            ink_slack: 0.0,
            target_ink,
            width,
            height,
        };
        Ok(RenderProblem::from_parts(
            model,
            view_loss,
            seed,
            &IMAGE3D_TERMS,
        ))
    }

    /// Draws map `i` with the probability `choice` gives the maps at θ (recomputed at every
    /// θ; the map choices are not differentiated).
    pub fn with_map_choice(mut self, choice: MapChoice) -> Self {
        self.model.choice = choice;
        self
    }

    /// Adds `weight·(1/V)·Σ_views max(0, 1 − slack − inkᵥ/targetᵥ)²` to the loss, `inkᵥ`
    /// the mean of view `v`'s render and `targetᵥ` of its picture (views without ink are
    /// skipped); `slack` in [0, 1) is the fraction of the ink a render may lack for free.
    /// The image loss alone lets a fit that has not found where the thin parts of a shape
    /// go shrink to fewer, denser clumps: ink put in the wrong place costs twice what ink
    /// left out costs, so drawing less lowers it while the attractor moves away from the
    /// truth. The term costs nothing while a render holds the view's ink and grows with
    /// the missing fraction.
    pub fn with_ink(mut self, weight: f64, slack: f64) -> Result<Self> {
        if !(weight.is_finite() && weight >= 0.0) {
            return Err(Error::param(
                "ink",
                format!("must be finite and ≥ 0, got {weight}"),
            ));
        }
        if !(0.0..1.0).contains(&slack) {
            return Err(Error::param(
                "ink_slack",
                format!("must lie in [0, 1), got {slack}"),
            ));
        }
        self.loss.ink = weight;
        self.loss.ink_slack = slack;
        Ok(self)
    }

    /// Each view's ink (the mean of its picture).
    pub fn target_ink(&self) -> &[f64] {
        &self.loss.target_ink
    }

    /// Adds `weight·Σᵢ |det Mᵢ|` to the loss. Silhouettes do not tell a solid from a
    /// fractal with the same outline (the Sierpiński tetrahedron's views are nearly filled
    /// triangles); the maps of an attractor with volume cover it, so `Σᵢ |det Mᵢ| ≥ 1`,
    /// while a fractal's sum is below 1 (the tetrahedron's: 4 · ⅛). The term prefers the
    /// thinnest code the views allow.
    pub fn with_volume(mut self, weight: f64) -> Result<Self> {
        if !(weight.is_finite() && weight >= 0.0) {
            return Err(Error::param(
                "volume",
                format!("must be finite and ≥ 0, got {weight}"),
            ));
        }
        self.model.volume = weight;
        Ok(self)
    }

    /// σ moves geometrically from the render config's σ at iteration 0 to `sigma_final` at
    /// iteration `iterations` and stays there (coarse to fine, as the image problem's).
    pub fn with_sigma_schedule(mut self, sigma_final: f64, iterations: u64) -> Result<Self> {
        if !(sigma_final.is_finite() && sigma_final > 0.0) {
            return Err(Error::param(
                "sigma_final",
                format!("must be finite and > 0, got {sigma_final}"),
            ));
        }
        self.model.sigma_schedule = Some((sigma_final, iterations.max(1)));
        Ok(self)
    }

    /// The number of θ entries.
    pub fn n_params(&self) -> usize {
        self.model.n_params()
    }

    /// The maps at θ.
    pub fn maps_at(&self, theta: &[f64]) -> Result<Vec<SvdMap3>> {
        self.model.scene(theta, Moment::Iteration(0))
    }

    /// The views of θ drawn on random stream `stream` at progress `frac` of the σ schedule,
    /// and the loss (views and volume term).
    pub fn render(&self, theta: &[f64], stream: u64, frac: f64) -> Result<(f64, Vec<T>)> {
        let out = self.pass(theta, Moment::Progress { stream, frac }, false)?;
        Ok((out.terms.total(), out.planes.unwrap_or_default()))
    }

    /// The loss of θ (views and volume term) on random stream `stream` at progress `frac`
    /// of the σ schedule.
    pub fn cost(&self, theta: &[f64], stream: u64, frac: f64) -> Result<f64> {
        Ok(self.render(theta, stream, frac)?.0)
    }
}
