//! The composite objective of the chaotic-splatting paper, from a validated config.
//!
//! `L = w_mse·MS-MSE + w_ssim·(1 − SSIM) + w_lpips·LPIPS + w_mom·Moments + R(maps)`
//!
//! with the paper's defaults `w_mse = 10` (10 mip levels), `w_ssim = 1`, `w_lpips = 2`,
//! `w_mom = 0` and the regulariser `R` weighted 1e-2 / 1e-1 ([`Regulariser`]). The image
//! terms are candle tensors, so [`Objective::image_loss`] returns a scalar whose
//! `backward()` flows into whatever produced the prediction (the splatting op); the
//! regulariser acts on the maps and returns its gradient with respect to them, for the
//! caller to add to the splat's map gradient before [`Parameterisation::backward`].
//!
//! A term whose weight is 0 is not computed. When LPIPS has a positive weight but no weights
//! file is found, the objective drops the term, says so once on stderr, and reports the
//! reason in [`Objective::lpips_skip_reason`]; set `lpips_required = true` to make that an
//! error instead.
//!
//! [`Parameterisation::backward`]: crate::model::param::Parameterisation::backward
//!
//! ## References
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point
//!   Splatting*, Eurographics 2025 (loss and weights).

use std::path::PathBuf;
use std::sync::Once;

use candle_core::{DType, Tensor};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::loss::candle_ops::{Downsample2x, apply_loss, image_chw};
use crate::loss::lpips::{FETCH_HINT, Lpips, LpipsFeatures, default_lpips_weights_path};
use crate::loss::{DSsim, Moments, MsMse, MsMseReduction, Regulariser};
use crate::model::affine::Affine2;
use crate::model::diff_map::{AffinePart, param_offsets};

/// Weights and options of the composite loss. Defaults are the paper's.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LossConfig {
    /// Weight of the multi-scale MSE (paper: 10).
    pub msmse_weight: f64,
    /// Number of 2×2 poolings after full resolution in the MS-MSE pyramid (paper: 10).
    pub msmse_levels: usize,
    /// How the MS-MSE levels are combined (default: summed, as in the reference code).
    pub msmse_reduction: MsMseReduction,
    /// Weight of D-SSIM = 1 − SSIM (paper: 1).
    pub dssim_weight: f64,
    /// Weight of LPIPS (paper: 2).
    pub lpips_weight: f64,
    /// Evaluate LPIPS on this mip level (0: full resolution; k: after k 2×2 poolings), to
    /// make it affordable on a CPU at large sizes.
    pub lpips_downsample: usize,
    /// Refuse to run without LPIPS weights instead of dropping the term.
    pub lpips_required: bool,
    /// The LPIPS weights file; default: `$IFSLAB_LPIPS_WEIGHTS`, else
    /// `lpips_alexnet.safetensors` in the per-user cache folder (`ifslab weights` prints it).
    pub lpips_weights: Option<PathBuf>,
    /// Weight of the moments loss (paper's ablation; default 0 = off).
    pub moments_weight: f64,
    /// Highest moment order of the moments loss (1 to 6; default 4).
    pub moments_max_order: usize,
    /// The map regulariser's weights.
    pub regulariser: Regulariser,
}

impl Default for LossConfig {
    fn default() -> Self {
        LossConfig {
            msmse_weight: 10.0,
            msmse_levels: 10,
            msmse_reduction: MsMseReduction::Sum,
            dssim_weight: 1.0,
            lpips_weight: 2.0,
            lpips_downsample: 0,
            lpips_required: false,
            lpips_weights: None,
            moments_weight: 0.0,
            moments_max_order: 4,
            regulariser: Regulariser::default(),
        }
    }
}

impl LossConfig {
    /// The LPIPS weights file the loss loads: `lpips_weights`, else the default
    /// ([`default_lpips_weights_path`]).
    pub fn lpips_weights_path(&self) -> PathBuf {
        self.lpips_weights
            .clone()
            .unwrap_or_else(default_lpips_weights_path)
    }

    /// Checks every field; the error names the field and says what is allowed.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("msmse_weight", self.msmse_weight),
            ("dssim_weight", self.dssim_weight),
            ("lpips_weight", self.lpips_weight),
            ("moments_weight", self.moments_weight),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::param(name, format!("{name} must be ≥ 0, got {v}")));
            }
        }
        if self.msmse_levels > 30 {
            return Err(Error::param(
                "msmse_levels",
                format!(
                    "msmse_levels must be at most 30 (a 2^30-pixel side), got {}",
                    self.msmse_levels
                ),
            ));
        }
        if self.lpips_downsample > 8 {
            return Err(Error::param(
                "lpips_downsample",
                format!(
                    "lpips_downsample must be at most 8 (LPIPS needs ≥ 31×31 pixels), got {}",
                    self.lpips_downsample
                ),
            ));
        }
        if !(1..=6).contains(&self.moments_max_order) {
            return Err(Error::param(
                "moments_max_order",
                format!(
                    "moments_max_order must be between 1 and 6, got {}",
                    self.moments_max_order
                ),
            ));
        }
        self.regulariser.validate().map_err(|e| match e {
            Error::InvalidParameter { name, message } => Error::InvalidParameter {
                name,
                message: format!("regulariser.{name} {message}"),
            },
            e => e,
        })
    }

    fn msmse(&self) -> MsMse {
        MsMse::new(self.msmse_levels).with_reduction(self.msmse_reduction)
    }
}

/// Unweighted values of each term (None: not computed) and the weighted total.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LossBreakdown {
    /// Multi-scale MSE.
    pub msmse: Option<f64>,
    /// 1 − SSIM.
    pub dssim: Option<f64>,
    /// LPIPS.
    pub lpips: Option<f64>,
    /// Moments loss.
    pub moments: Option<f64>,
    /// Map regulariser (already weighted by its own λs).
    pub regulariser: Option<f64>,
    /// The weighted sum of the computed terms.
    pub total: f64,
}

/// What [`Objective::evaluate`] returns.
#[derive(Debug)]
pub struct Evaluation {
    /// The weighted image terms as a scalar tensor (call `backward()` on it).
    pub image_total: Tensor,
    /// `∂R/∂maps` of the regulariser, to add to the image terms' map gradient.
    pub map_grad: Vec<Affine2>,
    /// Per-term values; `total` includes the regulariser.
    pub breakdown: LossBreakdown,
}

/// What [`Objective::evaluate_params`] returns: [`Evaluation`] for any map type, the
/// regulariser's gradient in the maps' flat parameter layout.
#[derive(Debug)]
pub struct ParamEvaluation {
    /// The weighted image terms as a scalar tensor (call `backward()` on it).
    pub image_total: Tensor,
    /// `∂R/∂θ` of the regulariser, map after map
    /// ([`param_offsets`]).
    pub param_grad: Vec<f64>,
    /// Per-term values; `total` includes the regulariser.
    pub breakdown: LossBreakdown,
}

static LPIPS_SKIP_NOTICE: Once = Once::new();

/// The composite loss against one target image (see the module docs).
pub struct Objective {
    config: LossConfig,
    target: Tensor,
    lpips: Option<(Lpips, LpipsFeatures)>,
    lpips_skip_reason: Option<String>,
    /// The target in f32 on the GPU, uploaded on first use by the fused GPU route.
    #[cfg(feature = "cuda")]
    device_target: std::sync::OnceLock<
        std::result::Result<crate::render::splat::cuda::DeviceSlice<f32>, String>,
    >,
}

impl std::fmt::Debug for Objective {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Objective")
            .field("config", &self.config)
            .field("target", &self.target.dims())
            .field("lpips", &self.lpips.is_some())
            .field("lpips_skip_reason", &self.lpips_skip_reason)
            .finish()
    }
}

fn scalar(t: &Tensor) -> Result<f64> {
    Ok(t.to_dtype(DType::F64)?.to_scalar::<f64>()?)
}

fn downsample(t: &Tensor, times: usize) -> Result<Tensor> {
    let mut t = t.clone();
    for _ in 0..times {
        t = t.apply_op1(Downsample2x)?;
    }
    Ok(t)
}

impl Objective {
    /// Validates the config, checks the target (an `(H, W)` grey or `(C, H, W)` image tensor
    /// in [0, 1], `f32` or `f64`; LPIPS takes grey or RGB), and loads LPIPS when its weight
    /// is positive. Every term of a `C`-channel image is the mean over its channels, except
    /// LPIPS, which sees RGB as RGB.
    pub fn new(config: LossConfig, target: &Tensor) -> Result<Self> {
        config.validate()?;
        let (c, ..) = image_chw(target.dims()).map_err(Error::Shape)?;
        if config.lpips_weight > 0.0 && !matches!(c, 1 | 3) {
            return Err(Error::Shape(format!(
                "LPIPS takes grey or RGB images; the target has {c} channels (set lpips_weight = 0)"
            )));
        }
        if !matches!(target.dtype(), DType::F32 | DType::F64) {
            return Err(Error::Shape(format!(
                "the target must be an f32 or f64 tensor, got {:?}",
                target.dtype()
            )));
        }
        let target = target.detach().contiguous()?;
        let (mut lpips, mut lpips_skip_reason) = (None, None);
        if config.lpips_weight > 0.0 {
            let path = config.lpips_weights_path();
            if path.exists() || config.lpips_required {
                let net = Lpips::load(&path)?;
                let feats = net.features(&downsample(&target, config.lpips_downsample)?)?;
                lpips = Some((net, feats));
            } else {
                let reason = format!(
                    "LPIPS term skipped: no weights file at {}; to include it, {FETCH_HINT} \
                     (or lpips_weights in the config). The loss uses the other terms.",
                    path.display()
                );
                LPIPS_SKIP_NOTICE.call_once(|| eprintln!("warning: {reason}"));
                lpips_skip_reason = Some(reason);
            }
        }
        Ok(Objective {
            config,
            target,
            lpips,
            lpips_skip_reason,
            #[cfg(feature = "cuda")]
            device_target: std::sync::OnceLock::new(),
        })
    }

    /// The image terms as the GPU computes them ([`crate::loss::cuda`]), or why this
    /// objective needs the CPU: LPIPS (a network, on the CPU through candle) or the moments
    /// term in the loss, or a target that is not one grey plane.
    #[cfg(feature = "cuda")]
    pub fn gpu_loss(&self) -> std::result::Result<crate::loss::cuda::GpuLoss, String> {
        let c = &self.config;
        if self.lpips.is_some() {
            return Err("the loss has an LPIPS term, which runs on the CPU".into());
        }
        if c.moments_weight > 0.0 {
            return Err("the loss has a moments term, which runs on the CPU".into());
        }
        if self.target.dims().len() != 2 {
            return Err(format!(
                "the target {:?} is not one grey plane",
                self.target.dims()
            ));
        }
        let loss = crate::loss::cuda::GpuLoss {
            msmse: c.msmse(),
            msmse_weight: c.msmse_weight,
            dssim: DSsim::default(),
            dssim_weight: c.dssim_weight,
        };
        loss.check().map_err(|e| e.to_string())?;
        Ok(loss)
    }

    /// The target in f32 on the GPU (uploaded once, then kept).
    #[cfg(feature = "cuda")]
    pub(crate) fn device_target(&self) -> Result<&crate::render::splat::cuda::DeviceSlice<f32>> {
        self.device_target
            .get_or_init(|| {
                let v: Vec<f32> = self
                    .target
                    .to_dtype(DType::F32)
                    .and_then(|t| t.flatten_all())
                    .and_then(|t| t.to_vec1())
                    .map_err(|e| e.to_string())?;
                crate::render::splat::cuda::DeviceSlice::upload(&v).map_err(|e| e.to_string())
            })
            .as_ref()
            .map_err(|e| Error::Device(e.clone()))
    }

    /// The validated config.
    pub fn config(&self) -> &LossConfig {
        &self.config
    }

    /// The target image tensor.
    pub fn target(&self) -> &Tensor {
        &self.target
    }

    /// Whether the LPIPS term is part of the loss.
    pub fn lpips_active(&self) -> bool {
        self.lpips.is_some()
    }

    /// Why LPIPS was dropped, if it was.
    pub fn lpips_skip_reason(&self) -> Option<&str> {
        self.lpips_skip_reason.as_deref()
    }

    /// The weighted image terms for `pred` (same shape as the target, `f32` or `f64`) as a
    /// scalar tensor of `pred`'s dtype, and the per-term values (`total` without the
    /// regulariser).
    pub fn image_loss(&self, pred: &Tensor) -> Result<(Tensor, LossBreakdown)> {
        if pred.dims() != self.target.dims() {
            return Err(Error::Shape(format!(
                "prediction {:?} and target {:?} differ in shape",
                pred.dims(),
                self.target.dims()
            )));
        }
        let target = if pred.dtype() == self.target.dtype() {
            self.target.clone()
        } else {
            self.target.to_dtype(pred.dtype())?
        };
        let c = &self.config;
        let mut b = LossBreakdown::default();
        let mut terms: Vec<Tensor> = Vec::new();
        let mut add = |t: Tensor, w: f64, slot: &mut Option<f64>| -> Result<()> {
            let v = scalar(&t)?;
            *slot = Some(v);
            b.total += w * v;
            terms.push((t * w)?);
            Ok(())
        };
        let (mut msmse, mut dssim, mut lpips, mut moments) = (None, None, None, None);
        if c.msmse_weight > 0.0 {
            add(
                apply_loss(c.msmse(), pred, &target)?,
                c.msmse_weight,
                &mut msmse,
            )?;
        }
        if c.dssim_weight > 0.0 {
            add(
                apply_loss(DSsim::default(), pred, &target)?,
                c.dssim_weight,
                &mut dssim,
            )?;
        }
        // Summed in the order the terms are logged: MS-MSE, D-SSIM, LPIPS, moments.
        if let (true, Some((net, feats))) = (c.lpips_weight > 0.0, &self.lpips) {
            let d = net
                .distance_to(&downsample(pred, c.lpips_downsample)?, feats)?
                .to_dtype(pred.dtype())?;
            add(d, c.lpips_weight, &mut lpips)?;
        }
        if c.moments_weight > 0.0 {
            let m = Moments {
                max_order: c.moments_max_order,
            };
            add(
                apply_loss(m, pred, &target)?,
                c.moments_weight,
                &mut moments,
            )?;
        }
        let total = b.total;
        let image_total = match terms.split_first() {
            Some((first, rest)) => rest.iter().try_fold(first.clone(), |acc, t| acc + t)?,
            None => Tensor::zeros((), pred.dtype(), pred.device())?,
        };
        Ok((
            image_total,
            LossBreakdown {
                msmse,
                dssim,
                lpips,
                moments,
                regulariser: None,
                total,
            },
        ))
    }

    /// The map regulariser's value and its gradient with respect to the maps.
    pub fn regulariser(&self, maps: &[Affine2]) -> Result<(f64, Vec<Affine2>)> {
        self.config.regulariser.value_and_grad(maps)
    }

    /// The map regulariser on the affine parts of any maps: its value and its gradient with
    /// respect to their parameters, map after map.
    pub fn regulariser_params<M: AffinePart>(&self, maps: &[M]) -> Result<(f64, Vec<f64>)> {
        let parts: Vec<Affine2> = maps.iter().map(AffinePart::affine_part).collect();
        let (r, g) = self.regulariser(&parts)?;
        let off = param_offsets(maps);
        let mut grad = vec![0.0; off[maps.len()]];
        for (i, (m, gi)) in maps.iter().zip(&g).enumerate() {
            m.affine_part_backward(gi, &mut grad[off[i]..off[i + 1]]);
        }
        Ok((r, grad))
    }

    /// Image terms for `pred` plus the regulariser on `maps` of any type with an affine part.
    pub fn evaluate_params<M: AffinePart>(
        &self,
        pred: &Tensor,
        maps: &[M],
    ) -> Result<ParamEvaluation> {
        let (image_total, mut breakdown) = self.image_loss(pred)?;
        let (r, param_grad) = self.regulariser_params(maps)?;
        breakdown.regulariser = Some(r);
        breakdown.total += r;
        Ok(ParamEvaluation {
            image_total,
            param_grad,
            breakdown,
        })
    }

    /// Image terms for `pred` plus the regulariser on `maps`.
    pub fn evaluate(&self, pred: &Tensor, maps: &[Affine2]) -> Result<Evaluation> {
        let (image_total, mut breakdown) = self.image_loss(pred)?;
        let (r, map_grad) = self.regulariser(maps)?;
        breakdown.regulariser = Some(r);
        breakdown.total += r;
        Ok(Evaluation {
            image_total,
            map_grad,
            breakdown,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_papers_and_valid() {
        let c = LossConfig::default();
        assert_eq!(
            (
                c.msmse_weight,
                c.msmse_levels,
                c.dssim_weight,
                c.lpips_weight,
                c.moments_weight
            ),
            (10.0, 10, 1.0, 2.0, 0.0)
        );
        assert_eq!(
            (c.regulariser.scale_weight, c.regulariser.condition_weight),
            (1e-2, 1e-1)
        );
        c.validate().unwrap();
    }

    #[test]
    fn validation_names_the_field() {
        let c = LossConfig {
            lpips_weight: -1.0,
            ..Default::default()
        };
        let msg = c.validate().unwrap_err().to_string();
        assert!(msg.contains("lpips_weight must be ≥ 0, got -1"), "{msg}");
        let c = LossConfig {
            regulariser: Regulariser {
                condition_weight: f64::NAN,
                ..Default::default()
            },
            ..Default::default()
        };
        let msg = c.validate().unwrap_err().to_string();
        assert!(msg.contains("regulariser.condition_weight"), "{msg}");
        let c = LossConfig {
            moments_max_order: 0,
            ..Default::default()
        };
        assert!(
            c.validate()
                .unwrap_err()
                .to_string()
                .contains("moments_max_order")
        );
    }

    #[test]
    fn config_round_trips_and_rejects_unknown_fields() {
        let c = LossConfig {
            lpips_weight: 0.5,
            moments_weight: 1.0,
            ..Default::default()
        };
        let s = serde_json::to_string(&c).unwrap();
        assert_eq!(serde_json::from_str::<LossConfig>(&s).unwrap(), c);
        let partial: LossConfig = serde_json::from_str(r#"{"dssim_weight": 0.0}"#).unwrap();
        assert_eq!(partial.msmse_weight, 10.0);
        assert!(serde_json::from_str::<LossConfig>(r#"{"lpips_wieght": 1}"#).is_err());
    }
}
