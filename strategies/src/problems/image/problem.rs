//! The image-inversion problem: θ → maps → fused splat op → composite loss, differentiated
//! through candle's autograd (the splat's reverse pass is the op's own) and the
//! parameterisation's chain rule — or, with the splat on the GPU and a loss the GPU computes,
//! in one fused GPU pass (`ifslab::render::splat::iteration`).

use std::borrow::Cow;

use candle_core::{Device, Tensor};
use ifslab::loss::{ImageLoss, LossBreakdown, LossConfig, MsMse, Objective};
use ifslab::render::splat::{SplatConfig, SplatDevice};

use crate::driver::{Differentiable, Evaluation};
use crate::error::{Error, Result};
use crate::optim::annealing::Anneal;
use crate::problems::image::config::InversionConfig;
use crate::problems::image::config::MapProbabilities;
use crate::problems::image::model::{AnyModel, DrawOptions};
use ifslab::model::ProbabilityRule;

/// Names of the logged loss terms, in column order.
pub const TERMS: [&str; 5] = ["msmse", "dssim", "lpips", "moments", "regulariser"];

/// Fit a `size × size` target with the maps of a model rendered by the fused splat op.
pub struct ImageProblem {
    model: Box<dyn AnyModel>,
    splat: SplatConfig,
    objective: Objective,
    target: Vec<f32>,
    anneal_mse: MsMse,
    seed: u64,
    /// `(σ at t = T, T)` when σ follows a schedule.
    sigma_schedule: Option<(f64, u64)>,
    /// How the chaos game picks maps.
    probabilities: MapProbabilities,
    /// Clamp renders to [0, 1].
    clamp: bool,
}

impl ImageProblem {
    /// The problem for `target` (row-major `splat.width × splat.height`, values in [0, 1]),
    /// fitting the maps of `model`.
    pub fn new(
        model: Box<dyn AnyModel>,
        splat: SplatConfig,
        loss: LossConfig,
        target: Vec<f32>,
        seed: u64,
    ) -> Result<Self> {
        splat.validate()?;
        loss.validate()?;
        if target.len() != splat.width * splat.height {
            return Err(Error::InvalidInput(format!(
                "target has {} pixels, the renderer {}×{}",
                target.len(),
                splat.width,
                splat.height
            )));
        }
        let t = Tensor::from_vec(target.clone(), (splat.height, splat.width), &Device::Cpu)
            .map_err(ifslab::Error::from)?;
        let anneal_mse = MsMse::new(loss.msmse_levels).with_reduction(loss.msmse_reduction);
        let objective = Objective::new(loss, &t)?;
        Ok(ImageProblem {
            model,
            splat,
            objective,
            target,
            anneal_mse,
            seed,
            sigma_schedule: None,
            probabilities: MapProbabilities::Uniform,
            clamp: false,
        })
    }

    /// The problem `cfg` describes (parameterisation, renderer with its σ schedule, loss,
    /// seed) for `target`.
    pub fn from_config(cfg: &InversionConfig, target: Vec<f32>) -> Result<Self> {
        let mut p = ImageProblem::new(
            cfg.model.build()?,
            cfg.splat_config(),
            cfg.loss.clone(),
            target,
            cfg.seed,
        )?;
        p.probabilities = cfg.model.probabilities;
        p.clamp = cfg.renderer.clamp;
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
        self.sigma_schedule = Some((sigma_final, iterations.max(1)));
        Ok(self)
    }

    /// The renderer at progress `frac = t/T` of the run.
    fn splat_at(&self, frac: f64) -> Cow<'_, SplatConfig> {
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

    fn progress(&self, iter: u64) -> f64 {
        self.sigma_schedule
            .map_or(0.0, |(_, t)| iter as f64 / t as f64)
    }

    /// The model θ is decoded with.
    pub fn model(&self) -> &dyn AnyModel {
        self.model.as_ref()
    }

    /// The renderer's configuration at the start of the run.
    pub fn splat_config(&self) -> &SplatConfig {
        &self.splat
    }

    /// The renderer's configuration at the end of the run (σ scheduled, if it is).
    pub fn final_splat_config(&self) -> SplatConfig {
        self.splat_at(1.0).into_owned()
    }

    /// The framed target.
    pub fn target(&self) -> &[f32] {
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
        self.model.render(
            theta,
            &self.splat_at(frac),
            self.seed,
            stream,
            &self.draw_options(theta)?,
        )
    }

    /// The map probabilities and clamping of a render of θ.
    fn draw_options(&self, theta: &[f64]) -> Result<DrawOptions> {
        let probs = match self.probabilities {
            MapProbabilities::Uniform => None,
            MapProbabilities::Determinant => {
                let dets: Vec<f64> = self
                    .model
                    .affine_maps(theta)?
                    .iter()
                    .map(|m| m.det().abs())
                    .collect();
                // ∝ |det| with no floor; all-degenerate maps fall back to uniform.
                (dets.iter().sum::<f64>() > 0.0)
                    .then(|| ProbabilityRule::Determinant { floor: 0.0 }.resolve(&dets))
                    .transpose()?
            }
        };
        Ok(DrawOptions {
            probs,
            clamp: self.clamp,
        })
    }

    /// The objective's terms at θ on random stream `stream`, without a gradient (for loss
    /// landscapes and evaluation), with the renderer the run ends with.
    pub fn loss_breakdown(&self, theta: &[f64], stream: u64) -> Result<LossBreakdown> {
        let img = self.render_at(theta, stream, 1.0)?;
        let pred = Tensor::from_vec(img, (self.splat.height, self.splat.width), &Device::Cpu)
            .map_err(tensor_err)?;
        self.model.breakdown(theta, &pred, &self.objective)
    }
}

fn tensor_err(e: candle_core::Error) -> Error {
    Error::Core(ifslab::Error::from(e))
}

impl Differentiable for ImageProblem {
    fn evaluate(&self, theta: &[f64], iter: u64) -> Result<Evaluation> {
        let (b, grad) = self.model.evaluate(
            theta,
            self.splat_at(self.progress(iter)).into_owned(),
            self.seed,
            iter,
            &self.draw_options(theta)?,
            &self.objective,
        )?;
        let terms = [b.msmse, b.dssim, b.lpips, b.moments, b.regulariser]
            .iter()
            .zip(TERMS)
            .map(|(v, n)| (n, v.unwrap_or(f64::NAN)))
            .collect();
        Ok(Evaluation {
            loss: b.total,
            grad,
            terms,
        })
    }

    fn project(&self, theta: &mut [f64]) {
        self.model.project(theta);
    }
}

impl Anneal for ImageProblem {
    fn anneal_cost(&self, theta: &[f64], stream: u64, frac: f64) -> Result<f64> {
        // With the splat on the GPU, the render is scored there and only the scalar comes
        // back; otherwise the render comes down and is scored here (the CPU's candidates do
        // not decode θ for the GPU's attempt first).
        if self.splat.device == SplatDevice::Cuda
            && let Some(v) = self.model.render_msmse(
                theta,
                &self.splat_at(frac),
                self.seed,
                stream,
                &self.draw_options(theta)?,
                &self.objective,
            )?
        {
            return Ok(v);
        }
        let pred = self.render_at(theta, stream, frac)?;
        Ok(self
            .anneal_mse
            .value(&pred, &self.target, self.splat.width, self.splat.height)? as f64)
    }
}
