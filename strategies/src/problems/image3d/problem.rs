//! The multi-view fit: θ → SVD maps of space ([`SvdMap3`], 14 numbers a map) → the
//! multi-view splat ([`MultiViewSplat`], one plane per camera) → the 2-D image loss
//! ([`MsMse`]; 0 poolings is the plain MSE) on every view, averaged over the views → the
//! gradient through the splat's reverse pass; plus, optionally, `w·Σᵢ |det Mᵢ|`, the
//! volume the maps' images take of the attractor's (see [`Image3dProblem::with_volume`]);
//! plus, optionally, `w·mean over views of max(0, 1 − s − ink/ink of the view)²`, a guard
//! against fits that draw less ink than the views hold (see [`Image3dProblem::with_ink`]).
//! [`Differentiable`] and [`Anneal`], so every strategy of the registry runs it.

use ifslab::loss::{ImageLoss, MsMse};
use ifslab::model::map3::{DiffMap3, SVD3_PARAMS, SvdMap3};
use ifslab::render::splat::kernel::SplatReal;
use ifslab::render::splat3d::{Camera, MultiViewConfig, MultiViewSplat};
use ifslab::render::{Renderer, value_and_grad};

use crate::driver::{Differentiable, Evaluation};
use crate::error::{Error, Result};
use crate::optim::annealing::Anneal;
use crate::problems::image3d::config::MapChoice;
use crate::problems::image3d::views::Views;

/// Names of the logged loss terms (unweighted).
pub const IMAGE3D_TERMS: [&str; 3] = ["view_loss", "volume", "ink"];

/// Fit SVD maps of space to views (see the module docs), the views drawn and scored in
/// `T` (f32 for runs; f64 for checks against finite differences).
#[derive(Clone, Debug)]
pub struct Image3dProblem<T = f32> {
    /// Each map's reflection flag (fixed structure: θ cannot flip it).
    reflect: Vec<bool>,
    cameras: Vec<Camera>,
    targets: Vec<T>,
    render: MultiViewConfig,
    /// `(σ at the end, iterations)`: σ moves geometrically from `render.sigma` to it.
    sigma_schedule: Option<(f64, u64)>,
    loss: MsMse,
    /// Weight of `Σᵢ |det Mᵢ|`.
    volume: f64,
    /// Weight of the ink deficit.
    ink: f64,
    /// Fraction of a view's ink a render may lack before the ink term charges.
    ink_slack: f64,
    /// Each view's ink (the mean of its plane).
    target_ink: Vec<f64>,
    /// How the chaos game picks the maps (uniform unless [`Image3dProblem::with_map_choice`]).
    choice: MapChoice,
    seed: u64,
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
        let pixels = views.size().0 * views.size().1;
        let target_ink = views
            .planes
            .chunks_exact(pixels)
            .map(|p| p.iter().map(|&v| f64::from(v)).sum::<f64>() / pixels as f64)
            .collect();
        Ok(Image3dProblem {
            reflect: start.iter().map(SvdMap3::reflect).collect(),
            cameras: views.cameras.clone(),
            targets: views
                .planes
                .iter()
                .map(|&v| T::from(v).unwrap_or_else(T::zero))
                .collect(),
            render,
            sigma_schedule: None,
            loss,
            volume: 0.0,
            ink: 0.0,
            ink_slack: 0.0,
            target_ink,
            choice: MapChoice::Uniform,
            seed,
        })
    }

    /// Draws map `i` with the probability `choice` gives the maps at θ (recomputed at every
    /// θ; the map choices are not differentiated).
    pub fn with_map_choice(mut self, choice: MapChoice) -> Self {
        self.choice = choice;
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
        self.ink = weight;
        self.ink_slack = slack;
        Ok(self)
    }

    /// The ink term of `image` (all views, unweighted) and, when `grad` is given, its
    /// gradient times `weight` added into it.
    fn ink_term(&self, image: &[T], weight: f64, grad: Option<&mut [T]>) -> f64 {
        let pixels = self.cameras[0].width() * self.cameras[0].height();
        let n = self.cameras.len() as f64;
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

    /// Each view's ink (the mean of its picture).
    pub fn target_ink(&self) -> &[f64] {
        &self.target_ink
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
        self.volume = weight;
        Ok(self)
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

    /// σ moves geometrically from the render config's σ at iteration 0 to `sigma_final` at
    /// iteration `iterations` and stays there (coarse to fine, as the image problem's).
    pub fn with_sigma_schedule(mut self, sigma_final: f64, iterations: u64) -> Result<Self> {
        if !(sigma_final.is_finite() && sigma_final > 0.0) {
            return Err(Error::param(
                "sigma_final",
                format!("must be finite and > 0, got {sigma_final}"),
            ));
        }
        self.sigma_schedule = Some((sigma_final, iterations.max(1)));
        Ok(self)
    }

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

    /// The number of θ entries.
    pub fn n_params(&self) -> usize {
        self.reflect.len() * SVD3_PARAMS
    }

    /// The maps at θ.
    pub fn maps_at(&self, theta: &[f64]) -> Result<Vec<SvdMap3>> {
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

    /// The splat of `maps` at progress `frac` of the σ schedule.
    fn splat(&self, frac: f64, maps: &[SvdMap3]) -> Result<MultiViewSplat<SvdMap3, T>> {
        let cfg = MultiViewConfig {
            sigma: self.sigma_at(frac),
            ..self.render.clone()
        };
        Ok(MultiViewSplat::new(cfg, self.cameras.clone())?
            .with_probabilities(self.choice.for_svd(maps)))
    }

    /// The loss of `image` (all views) against the targets: the mean over views of the
    /// loss of each, and its gradient.
    fn objective(&self, image: &[T]) -> Result<(f64, Vec<T>)> {
        let (w, h) = (self.cameras[0].width(), self.cameras[0].height());
        let n = self.cameras.len();
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

    /// The views of θ drawn on random stream `stream` at progress `frac` of the σ schedule,
    /// and the loss (views and volume term).
    pub fn render(&self, theta: &[f64], stream: u64, frac: f64) -> Result<(f64, Vec<T>)> {
        let maps = self.maps_at(theta)?;
        let splat = self.splat(frac, &maps)?;
        let sampling = splat.sampling(&maps, self.seed, stream);
        let (image, _) = splat.forward(&maps, &sampling)?;
        let (loss, _) = self.objective(&image)?;
        let volume = Self::volume_term(&maps, 0.0, None);
        let ink = self.ink_term(&image, 0.0, None);
        Ok((loss + self.volume * volume + self.ink * ink, image))
    }

    /// The loss of θ (views and volume term) on random stream `stream` at progress `frac`
    /// of the σ schedule.
    pub fn cost(&self, theta: &[f64], stream: u64, frac: f64) -> Result<f64> {
        Ok(self.render(theta, stream, frac)?.0)
    }
}

impl<T: SplatReal> Differentiable for Image3dProblem<T> {
    fn evaluate(&self, theta: &[f64], iter: u64) -> Result<Evaluation> {
        let maps = self.maps_at(theta)?;
        let splat = self.splat(self.frac(iter), &maps)?;
        let sampling = splat.sampling(&maps, self.seed, iter);
        let mut ink = 0.0;
        let (view_loss, mut grad) = value_and_grad(&splat, &maps, &sampling, |image| {
            let (l, mut g) = self.objective(image)?;
            ink = self.ink_term(image, self.ink, Some(&mut g));
            Ok::<_, Error>((l, g))
        })?;
        let volume = Self::volume_term(&maps, self.volume, Some(&mut grad));
        Ok(Evaluation {
            loss: view_loss + self.volume * volume + self.ink * ink,
            grad,
            terms: vec![("view_loss", view_loss), ("volume", volume), ("ink", ink)],
        })
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

impl<T: SplatReal> Anneal for Image3dProblem<T> {
    fn anneal_cost(&self, theta: &[f64], stream: u64, frac: f64) -> Result<f64> {
        self.cost(theta, stream, frac)
    }
}
