//! The image-inversion problem: θ → maps → fused splat op → composite loss, differentiated
//! through candle's autograd (the splat's reverse pass is the op's own) and the
//! parameterisation's chain rule.

use candle_core::{DType, Device, Tensor, Var};
use ifslab::chaos::mix_seed;
use ifslab::loss::{ImageLoss, LossBreakdown, LossConfig, MsMse, Objective};
use ifslab::model::{Affine2, Parameterisation};
use ifslab::render::splat::{self, SplatConfig, SplatOp, maps_from_tensor, maps_to_tensor};

use crate::annealing::Anneal;
use crate::driver::{Differentiable, Evaluation};
use crate::error::{Error, Result};

/// Names of the logged loss terms, in column order.
pub const TERMS: [&str; 5] = ["msmse", "dssim", "lpips", "moments", "regulariser"];

/// Fit a `size × size` target with maps rendered by the fused splat op.
pub struct ImageProblem {
    param: Box<dyn Parameterisation>,
    splat: SplatConfig,
    objective: Objective,
    target: Vec<f32>,
    anneal_mse: MsMse,
    seed: u64,
}

impl ImageProblem {
    /// The problem for `target` (row-major `splat.width × splat.height`, values in [0, 1]).
    pub fn new(
        param: Box<dyn Parameterisation>,
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
            param,
            splat,
            objective,
            target,
            anneal_mse,
            seed,
        })
    }

    /// The parameterisation θ is decoded with.
    pub fn parameterisation(&self) -> &dyn Parameterisation {
        self.param.as_ref()
    }

    /// The renderer's configuration.
    pub fn splat_config(&self) -> &SplatConfig {
        &self.splat
    }

    /// The framed target.
    pub fn target(&self) -> &[f32] {
        &self.target
    }

    /// Why LPIPS is not part of the loss, if it is not.
    pub fn lpips_skip_reason(&self) -> Option<&str> {
        self.objective.lpips_skip_reason()
    }

    /// The splat render of θ on random stream `stream`.
    pub fn render(&self, theta: &[f64], stream: u64) -> Result<Vec<f32>> {
        let maps = self.param.decode(theta)?;
        Ok(splat::forward::<f32>(&self.splat, &maps, mix_seed(self.seed, stream))?.0)
    }

    /// The objective's terms at θ on random stream `stream`, without a gradient (for loss
    /// landscapes and evaluation).
    pub fn loss_breakdown(&self, theta: &[f64], stream: u64) -> Result<LossBreakdown> {
        let maps = self.param.decode(theta)?;
        let img = splat::forward::<f32>(&self.splat, &maps, mix_seed(self.seed, stream))?.0;
        let pred = Tensor::from_vec(img, (self.splat.height, self.splat.width), &Device::Cpu)
            .map_err(tensor_err)?;
        Ok(self.objective.evaluate(&pred, &maps)?.breakdown)
    }
}

fn tensor_err(e: candle_core::Error) -> Error {
    Error::Core(ifslab::Error::from(e))
}

impl Differentiable for ImageProblem {
    fn evaluate(&self, theta: &[f64], iter: u64) -> Result<Evaluation> {
        let maps = self.param.decode(theta)?;
        let var =
            Var::from_tensor(&maps_to_tensor(&maps, DType::F32, &Device::Cpu).map_err(tensor_err)?)
                .map_err(tensor_err)?;
        let op = SplatOp::new(self.splat.clone(), mix_seed(self.seed, iter));
        let pred = var.as_tensor().apply_op1(op).map_err(tensor_err)?;
        let ev = self.objective.evaluate(&pred, &maps)?;
        let grads = ev.image_total.backward().map_err(tensor_err)?;
        let mut gmaps: Vec<Affine2> = match grads.get(var.as_tensor()) {
            Some(g) => maps_from_tensor(g).map_err(tensor_err)?,
            None => vec![Affine2::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0); maps.len()],
        };
        for (g, r) in gmaps.iter_mut().zip(&ev.map_grad) {
            g.m += r.m;
            g.b += r.b;
        }
        let grad = self.param.backward(theta, &gmaps)?;
        let b = ev.breakdown;
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
        self.param.project(theta);
    }
}

impl Anneal for ImageProblem {
    fn anneal_cost(&self, theta: &[f64], stream: u64) -> Result<f64> {
        let pred = self.render(theta, stream)?;
        Ok(self
            .anneal_mse
            .value(&pred, &self.target, self.splat.width, self.splat.height)? as f64)
    }
}
