//! One step of image inversion in one call: a splat render of the maps, the objective
//! ([`Objective`]: the weighted image terms and the map regulariser) and its gradient with
//! respect to the maps' parameters. Two routes give the same result up to the kernels'
//! rounding:
//!
//! - **Fused on the GPU** when [`gpu_route`] allows it (`device = "cuda"`, a loss made of the
//!   terms the GPU computes — MS-MSE and D-SSIM, no LPIPS or moments term — and no clamping
//!   of the render): the splat's image stays on the GPU, the loss and its gradient are
//!   computed there ([`crate::loss::cuda`]), and that gradient feeds the splat's reverse pass
//!   where it lies ([`cuda::fused`]). The points go up and their gradients come down through
//!   page-locked buffers; besides them only the loss's sums cross the bus. The chaos game,
//!   the framing and the scan back through the trajectories stay on the CPU.
//! - **Through candle** otherwise ([`objective_and_grad_candle`]): the splat as a
//!   [`Renderer`] ([`Splat`]) renders (on the GPU when `device = "cuda"`, its image coming
//!   down and its gradient going up), the objective is a candle graph on the CPU whose
//!   autograd stops at the image, and the renderer's reverse pass takes its gradient from
//!   there — the same numbers as the [`SplatOp`](super::SplatOp) inside the graph.
//!   This is the route with LPIPS.
//!
//! Both routes render the maps with their parameters rounded to f32 (the candle op's argument
//! is an f32 tensor) and return the image terms' gradient rounded to f32; the regulariser
//! sees the maps as given.
//!
//! [`render_msmse`] scores a render by its MS-MSE alone (an annealing candidate), on the GPU
//! with only the scalar coming back.
//!
//! [`cuda::fused`]: super::cuda::fused

use candle_core::{Device, Tensor, Var};

#[cfg(feature = "cuda")]
use super::cuda;
use super::{Splat, SplatConfig, SplatDevice};
use crate::error::Result;
use crate::loss::{LossBreakdown, Objective};
use crate::model::{AffinePart, DiffMap2};
use crate::render::renderer::Renderer;

/// Whether [`objective_and_grad`] takes the fused GPU route for this renderer, objective and
/// clamping: `Ok(())`, or why not (the candle route is taken instead).
pub fn gpu_route(
    cfg: &SplatConfig,
    objective: &Objective,
    clamp: bool,
) -> std::result::Result<(), String> {
    if cfg.device != SplatDevice::Cuda {
        return Err("the splat runs on the CPU (device = \"cpu\")".into());
    }
    if clamp {
        return Err("the render is clamped to [0, 1], which the GPU route does not do".into());
    }
    #[cfg(feature = "cuda")]
    {
        objective.gpu_loss().map(|_| ())
    }
    #[cfg(not(feature = "cuda"))]
    {
        let _ = objective;
        Err("this build has no GPU backend (the cuda feature)".into())
    }
}

/// The objective's terms for a splat render of `maps` (chaos game seeded by `seed`, map `i`
/// drawn with probability `probs[i]`, uniform when `None`; the image clamped to [0, 1] when
/// `clamp`) and the gradient of their total with respect to the maps' parameters, map after
/// map. Fused on the GPU when [`gpu_route`] allows, else through candle (see the module
/// docs).
pub fn objective_and_grad<M: AffinePart + 'static>(
    cfg: &SplatConfig,
    maps: &[M],
    probs: Option<&[f64]>,
    clamp: bool,
    seed: u64,
    objective: &Objective,
) -> Result<(LossBreakdown, Vec<f64>)> {
    #[cfg(feature = "cuda")]
    if gpu_route(cfg, objective, clamp).is_ok() {
        return fused_objective(cfg, maps, probs, seed, objective, &mut None);
    }
    objective_and_grad_candle(cfg, maps, probs, clamp, seed, objective)
}

/// [`objective_and_grad`] through candle whatever the device: the splat as a [`Renderer`]
/// (on `cfg.device`) of the maps rounded to f32, the objective as a candle graph on its
/// image, autograd to the image, the renderer's reverse pass, its gradient rounded to f32 —
/// what the [`SplatOp`](super::SplatOp) on an f32 tensor of the parameters computes, bit
/// for bit.
pub fn objective_and_grad_candle<M: AffinePart + 'static>(
    cfg: &SplatConfig,
    maps: &[M],
    probs: Option<&[f64]>,
    clamp: bool,
    seed: u64,
    objective: &Objective,
) -> Result<(LossBreakdown, Vec<f64>)> {
    let splat = Splat::<M, f32>::new(cfg.clone()).with_probabilities(probs.map(<[f64]>::to_vec));
    objective_through::<M>(&splat, &through_f32(maps), maps, &seed, clamp, objective)
}

/// The objective's terms for `renderer`'s image of `rounded` and their gradient with
/// respect to the maps' parameters: the image terms through `rounded` (rounded to f32 on
/// the way, as a candle op's f32 argument would be), the regulariser's on `maps`.
fn objective_through<M: AffinePart>(
    renderer: &Splat<M, f32>,
    rounded: &[M],
    maps: &[M],
    sampling: &u64,
    clamp: bool,
    objective: &Objective,
) -> Result<(LossBreakdown, Vec<f64>)> {
    let (image, tape) = renderer.forward(rounded, sampling)?;
    let planes = renderer.planes();
    let var = Var::from_tensor(&Tensor::from_vec(
        image,
        (planes.height, planes.width),
        &Device::Cpu,
    )?)?;
    let mut pred = var.as_tensor().clone();
    if clamp {
        pred = pred.clamp(0f32, 1f32)?;
    }
    let ev = objective.evaluate_params(&pred, maps)?;
    let grads = ev.image_total.backward()?;
    let mut g: Vec<f64> = match grads.get(var.as_tensor()) {
        Some(gi) => {
            let gi: Vec<f32> = gi.flatten_all()?.to_vec1()?;
            // Rounded to f32 and added to a zero gradient, as candle accumulates an f32
            // argument's gradient (−0 becomes +0).
            renderer
                .backward(rounded, sampling, &tape, &gi)?
                .into_iter()
                .map(|v| (0.0f32 + v as f32) as f64)
                .collect()
        }
        None => vec![0.0; ev.param_grad.len()],
    };
    for (a, r) in g.iter_mut().zip(&ev.param_grad) {
        *a += r;
    }
    Ok((ev.breakdown, g))
}

/// The objective's MS-MSE (its levels and reduction, unweighted) of a splat render of `maps`
/// against its target, computed on the GPU with only the scalar coming back: `None` when
/// that route does not apply (the splat on the CPU, a clamped render, a colour target, a
/// build without the `cuda` feature), for the caller to score on the CPU.
pub fn render_msmse<M: DiffMap2>(
    cfg: &SplatConfig,
    maps: &[M],
    probs: Option<&[f64]>,
    clamp: bool,
    seed: u64,
    objective: &Objective,
) -> Result<Option<f64>> {
    if cfg.device != SplatDevice::Cuda || clamp || objective.target().dims().len() != 2 {
        return Ok(None);
    }
    #[cfg(feature = "cuda")]
    {
        let c = objective.config();
        let loss = crate::loss::cuda::GpuLoss::msmse_only(
            crate::loss::MsMse::new(c.msmse_levels).with_reduction(c.msmse_reduction),
        );
        let (value, _) = gpu_pass(cfg, maps, probs, seed, objective, &loss, false, &mut None)?;
        Ok(value.msmse)
    }
    #[cfg(not(feature = "cuda"))]
    {
        let _ = (maps, probs, seed);
        Ok(None)
    }
}

/// The maps with their parameters rounded to f32, as the candle op sees them (what both
/// routes render).
pub fn through_f32<M: DiffMap2>(maps: &[M]) -> Vec<M> {
    maps.iter()
        .map(|m| {
            let mut p = vec![0.0; m.n_params()];
            m.write_params(&mut p);
            p.iter_mut().for_each(|v| *v = *v as f32 as f64);
            let mut r = m.clone();
            r.set_params(&p);
            r
        })
        .collect()
}

/// The fused GPU route of [`objective_and_grad`].
#[cfg(feature = "cuda")]
fn fused_objective<M: AffinePart>(
    cfg: &SplatConfig,
    maps: &[M],
    probs: Option<&[f64]>,
    seed: u64,
    objective: &Objective,
    marks: &mut cuda::Marks,
) -> Result<(LossBreakdown, Vec<f64>)> {
    let loss = objective.gpu_loss().map_err(crate::Error::Device)?;
    let rounded = through_f32(maps);
    let (value, grad) = gpu_pass(cfg, &rounded, probs, seed, objective, &loss, true, marks)?;
    // The candle route's gradient is an f32 tensor: rounded the same way.
    let mut g: Vec<f64> = grad
        .unwrap_or_default()
        .iter()
        .map(|&v| v as f32 as f64)
        .collect();
    let (r, rg) = objective.regulariser_params(maps)?;
    for (a, r) in g.iter_mut().zip(&rg) {
        *a += r;
    }
    Ok((
        LossBreakdown {
            msmse: value.msmse,
            dssim: value.dssim,
            lpips: None,
            moments: None,
            regulariser: Some(r),
            total: value.total + r,
        },
        g,
    ))
}

/// Chaos game and framing on the CPU, then forward, `loss` and (when `grad`) the reverse pass
/// on the GPU, then the scan back through the trajectories: the loss's value and the
/// gradient with respect to the maps' parameters.
#[cfg(feature = "cuda")]
#[allow(clippy::too_many_arguments)]
fn gpu_pass<M: DiffMap2>(
    cfg: &SplatConfig,
    maps: &[M],
    probs: Option<&[f64]>,
    seed: u64,
    objective: &Objective,
    loss: &crate::loss::cuda::GpuLoss,
    grad: bool,
    marks: &mut cuda::Marks,
) -> Result<(crate::loss::cuda::GpuLossValue, Option<Vec<f64>>)> {
    let (tape, kept, frame) = super::trace(cfg, maps, probs, seed)?;
    let target = objective.device_target()?;
    let (w, h) = (cfg.width, cfg.height);
    if target.len() != w * h {
        return Err(crate::Error::Shape(format!(
            "the target has {} pixels, the renderer {w}×{h}",
            target.len()
        )));
    }
    let (value, guv) = cuda::fused_marked::<f32, _>(
        &cfg.grid(),
        kept.len(),
        |dst| super::project_into(&frame, &kept, dst),
        |st, image, marks| loss.on_device(st, image, target.slice(), w, h, grad, marks),
        marks,
    )?;
    let param_grad = guv.map(|guv| {
        let gx = frame.backward(&kept, &guv);
        tape.backward(maps, &gx)
    });
    Ok((value, param_grad))
}

/// GPU time of each stage of one fused iteration (`(stage, ms)`, in order, each ending at
/// its label), measured with CUDA events; `Err` when [`gpu_route`] does not allow it.
#[cfg(feature = "cuda")]
pub fn profile_fused<M: AffinePart>(
    cfg: &SplatConfig,
    maps: &[M],
    seed: u64,
    objective: &Objective,
) -> Result<Vec<(&'static str, f64)>> {
    gpu_route(cfg, objective, false).map_err(crate::Error::Device)?;
    let mut marks: cuda::Marks = Some(Vec::new());
    fused_objective(cfg, maps, None, seed, objective, &mut marks)?;
    cuda::stage_times(marks)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::chaos::ChaosGame;
    use crate::loss::LossConfig;
    use crate::model::Affine2;
    use crate::model::diff_map::flat_params;
    use crate::render::splat::SplatOp;
    use candle_core::DType;

    fn setup() -> (SplatConfig, Vec<Affine2>, Objective) {
        let cfg = SplatConfig {
            width: 32,
            height: 24,
            supersample: 2,
            sigma: 1.2,
            game: ChaosGame {
                trajectories: 60,
                length: 40,
                warmup: 5,
                ..ChaosGame::default()
            },
            ..SplatConfig::default()
        };
        let maps = vec![
            Affine2::new(0.45, 0.1, -0.05, 0.5, -0.4, -0.3),
            Affine2::new(0.5, -0.12, 0.08, 0.42, 0.45, -0.2),
            Affine2::new(0.38, 0.05, 0.1, 0.4, 0.05, 0.5),
        ];
        let (target, _) = super::super::forward::<f32>(&cfg, &maps, 99).unwrap();
        let t = Tensor::from_vec(target, (cfg.height, cfg.width), &Device::Cpu).unwrap();
        let loss = LossConfig {
            lpips_weight: 0.0,
            ..LossConfig::default()
        };
        let shifted: Vec<Affine2> = maps
            .iter()
            .map(|m| Affine2 {
                m: m.m,
                b: m.b * 0.9,
            })
            .collect();
        (cfg, shifted, Objective::new(loss, &t).unwrap())
    }

    /// On the CPU the one call is the composition callers wrote before it: the op on an f32
    /// tensor of the parameters, the objective, autograd, the regulariser's gradient added —
    /// bit for bit, with and without clamping and map probabilities.
    #[test]
    fn the_candle_route_is_the_op_and_the_objective_composed() {
        let (cfg, maps, objective) = setup();
        for (clamp, probs) in [
            (false, None),
            (true, None),
            (false, Some(vec![0.5, 0.3, 0.2])),
        ] {
            composed_as_the_op(&cfg, &maps, &objective, clamp, probs);
        }
    }

    fn composed_as_the_op(
        cfg: &SplatConfig,
        maps: &[Affine2],
        objective: &Objective,
        clamp: bool,
        probs: Option<Vec<f64>>,
    ) {
        let (b, g) = objective_and_grad(cfg, maps, probs.as_deref(), clamp, 5, objective).unwrap();
        let var = Var::from_tensor(
            &Tensor::new(flat_params(maps), &Device::Cpu)
                .unwrap()
                .to_dtype(DType::F32)
                .unwrap(),
        )
        .unwrap();
        let mut op = SplatOp::with_maps(cfg.clone(), 5, maps.to_vec());
        if let Some(p) = probs {
            op = op.with_probabilities(p);
        }
        let mut pred = var.as_tensor().apply_op1(op).unwrap();
        if clamp {
            pred = pred.clamp(0f32, 1f32).unwrap();
        }
        let ev = objective.evaluate_params(&pred, maps).unwrap();
        let grads = ev.image_total.backward().unwrap();
        let mut want: Vec<f64> = grads
            .get(var.as_tensor())
            .unwrap()
            .to_dtype(DType::F64)
            .unwrap()
            .to_vec1()
            .unwrap();
        for (a, r) in want.iter_mut().zip(&ev.param_grad) {
            *a += r;
        }
        assert_eq!(b, ev.breakdown);
        // Bit for bit, the sign of zero included.
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&g), bits(&want), "clamp {clamp}");
        assert!(g.iter().any(|v| *v != 0.0));
    }

    #[test]
    fn the_gpu_route_says_why_not() {
        let (cfg, _, objective) = setup();
        let why = gpu_route(&cfg, &objective, false).unwrap_err();
        assert!(why.contains("CPU"), "{why}");
        let cuda = SplatConfig {
            device: SplatDevice::Cuda,
            ..cfg
        };
        let why = gpu_route(&cuda, &objective, true).unwrap_err();
        assert!(why.contains("clamped"), "{why}");
        assert_eq!(
            render_msmse(
                &cuda,
                &[Affine2::new(0.5, 0.0, 0.0, 0.5, 0.0, 0.0)],
                None,
                true,
                0,
                &objective
            )
            .unwrap(),
            None
        );
    }

    #[test]
    fn rounding_through_f32_is_what_the_op_sees() {
        let m = [Affine2::new(0.1, 0.2, 0.3, 0.4, 0.5, 1.0 / 3.0)];
        let r = through_f32(&m);
        assert_eq!(r[0].coefficients()[5], (1.0f64 / 3.0) as f32 as f64);
        assert_eq!(r[0].coefficients()[0], 0.1f32 as f64);
    }
}
