//! The image-inversion problem: θ → maps → splat → composite loss and its gradient. Each
//! evaluation is a pass of the one image problem's instance for the model's map type
//! ([`instance::SplatProblem`](super::instance::SplatProblem)) — or, with the splat on the
//! GPU and a loss the GPU computes, one fused GPU pass (`ifslab::render::splat::iteration`).

use candle_core::{DType, Device, Tensor};
use ifslab::image::Image;
use ifslab::loss::{ImageLoss, LossBreakdown, LossConfig, MsMse, Objective};
use ifslab::render::splat::{SplatConfig, SplatDevice};

use crate::driver::{Differentiable, Evaluation};
use crate::error::{Error, Result};
use crate::optim::annealing::Anneal;
use crate::problems::image::config::InversionConfig;
use crate::problems::image::config::MapProbabilities;
use crate::problems::image::instance::ImageRendering;
use crate::problems::image::model::AnyModel;
use crate::problems::render_problem::Moment;

pub use crate::problems::image::instance::TERMS;

/// Fit a `size × size` target with the maps of a model rendered by the splat.
pub struct ImageProblem {
    model: Box<dyn AnyModel>,
    rendering: ImageRendering,
    objective: Objective,
    target: Image,
    anneal_mse: MsMse,
}

impl ImageProblem {
    /// The problem for `target` (grey, `splat.width × splat.height`, values in [0, 1]),
    /// fitting the maps of `model`.
    pub fn new(
        model: Box<dyn AnyModel>,
        splat: SplatConfig,
        loss: LossConfig,
        target: Image,
        seed: u64,
    ) -> Result<Self> {
        splat.validate()?;
        loss.validate()?;
        target.expect_shape("the target", 1, splat.width, splat.height)?;
        let t = target.to_tensor(DType::F32, &Device::Cpu)?;
        let anneal_mse = MsMse::new(loss.msmse_levels).with_reduction(loss.msmse_reduction);
        let objective = Objective::new(loss, &t)?;
        Ok(ImageProblem {
            model,
            rendering: ImageRendering {
                splat,
                sigma_schedule: None,
                probabilities: MapProbabilities::Uniform,
                clamp: false,
                seed,
            },
            objective,
            target,
            anneal_mse,
        })
    }

    /// The problem `cfg` describes (parameterisation, renderer with its σ schedule, loss,
    /// seed) for `target`.
    pub fn from_config(cfg: &InversionConfig, target: Image) -> Result<Self> {
        let mut p = ImageProblem::new(
            cfg.model.build()?,
            cfg.splat_config(),
            cfg.loss.clone(),
            target,
            cfg.seed,
        )?;
        p.rendering.probabilities = cfg.model.probabilities;
        p.rendering.clamp = cfg.renderer.clamp;
        match cfg.renderer.sigma_final {
            Some(end) => p.with_sigma_schedule(end, cfg.iterations),
            None => Ok(p),
        }
    }

    /// Moves σ geometrically from the splat config's σ at iteration 0 to `sigma_final` at
    /// iteration `iterations` (coarse-to-fine; see `RendererConfig::sigma_final`).
    pub fn with_sigma_schedule(mut self, sigma_final: f64, iterations: u64) -> Result<Self> {
        if !(sigma_final.is_finite() && sigma_final > 0.0) {
            return Err(Error::param(
                "sigma_final",
                format!("must be > 0, got {sigma_final}"),
            ));
        }
        self.rendering.sigma_schedule = Some((sigma_final, iterations.max(1)));
        Ok(self)
    }

    /// The model θ is decoded with.
    pub fn model(&self) -> &dyn AnyModel {
        self.model.as_ref()
    }

    /// The renderer's configuration at the start of the run.
    pub fn splat_config(&self) -> &SplatConfig {
        &self.rendering.splat
    }

    /// How θ is drawn: the splat, its σ schedule, the map probabilities, clamping, the seed.
    pub fn rendering(&self) -> &ImageRendering {
        &self.rendering
    }

    /// The renderer's configuration at the end of the run (σ scheduled, if it is).
    pub fn final_splat_config(&self) -> SplatConfig {
        self.rendering.splat_at(1.0).into_owned()
    }

    /// The framed target.
    pub fn target(&self) -> &Image {
        &self.target
    }

    /// Why LPIPS is not part of the loss, if it is not.
    pub fn lpips_skip_reason(&self) -> Option<&str> {
        self.objective.lpips_skip_reason()
    }

    /// The splat render of θ on random stream `stream`, with the renderer the run ends with.
    pub fn render(&self, theta: &[f64], stream: u64) -> Result<Vec<f32>> {
        self.render_at(theta, stream, 1.0)
    }

    fn render_at(&self, theta: &[f64], stream: u64, frac: f64) -> Result<Vec<f32>> {
        self.model
            .render(theta, &self.rendering, Moment::Progress { stream, frac })
    }

    /// The objective's terms at θ on random stream `stream`, without a gradient (for loss
    /// landscapes and evaluation), with the renderer the run ends with.
    pub fn loss_breakdown(&self, theta: &[f64], stream: u64) -> Result<LossBreakdown> {
        let img = self.render_at(theta, stream, 1.0)?;
        let shape = (self.rendering.splat.height, self.rendering.splat.width);
        let pred = Tensor::from_vec(img, shape, &Device::Cpu).map_err(tensor_err)?;
        self.model.breakdown(theta, &pred, &self.objective)
    }
}

fn tensor_err(e: candle_core::Error) -> Error {
    Error::Core(ifslab::Error::from(e))
}

impl Differentiable for ImageProblem {
    fn evaluate(&self, theta: &[f64], iter: u64) -> Result<Evaluation> {
        self.model
            .evaluate(theta, &self.rendering, &self.objective, iter)
    }

    fn project(&self, theta: &mut [f64]) {
        self.model.project(theta);
    }
}

impl Anneal for ImageProblem {
    /// The MS-MSE alone of a render of θ (the maps as decoded) on stream `stream` at
    /// progress `frac`.
    fn anneal_cost(&self, theta: &[f64], stream: u64, frac: f64) -> Result<f64> {
        // With the splat on the GPU, the render is scored there and only the scalar comes
        // back; otherwise the render comes down and is scored here (the CPU's candidates do
        // not decode θ for the GPU's attempt first).
        let r = &self.rendering;
        if r.splat.device == SplatDevice::Cuda
            && let Some(v) = self.model.render_msmse(
                theta,
                r,
                &self.objective,
                Moment::Progress { stream, frac },
            )?
        {
            return Ok(v);
        }
        let pred = self.render_at(theta, stream, frac)?;
        Ok(self
            .anneal_mse
            .value(&pred, &self.target.values, r.splat.width, r.splat.height)? as f64)
    }
}
