//! Flame transforms through the differentiable splatter: a deterministic flame transform
//! (`SmoothXform`: pre-affine, weighted variations with their parameters, post-affine) is a
//! `DiffMap2`, so the fused splat op renders it and differentiates it unchanged. Checked in
//! f64: every transform's vjps against finite differences, and the gradient of the whole
//! objective with respect to every parameter of every transform (affine coefficients,
//! variation weights, variation parameters) against central differences of the same
//! objective on the same trajectories.

mod common;

use candle_core::{Device, Tensor, Var};
use ifslab::loss::{LossConfig, Objective};
use ifslab::model::diff_map::{flat_params, param_offsets, set_flat_params, vjp_check};
use ifslab::model::flame::{SmoothXform, Variation, VariationKind, Xform};
use ifslab::render::splat::{self, SplatConfig, SplatOp, params_to_tensor};

/// Three transforms of a Sierpiński-like flame (flam3 coefficient order), each linear plus
/// one non-linear variation with `w` of it; the third has a parametric variation (curl).
fn flame(w: [f64; 3]) -> Vec<SmoothXform> {
    let coefs = [
        [0.45, -0.05, 0.1, 0.5, -0.4, -0.3],
        [0.5, 0.08, -0.12, 0.42, 0.45, -0.2],
        [0.38, 0.1, 0.05, 0.4, 0.05, 0.5],
    ];
    let kinds = [
        VariationKind::Spherical,
        VariationKind::Sinusoidal,
        VariationKind::Curl,
    ];
    coefs
        .iter()
        .zip(kinds)
        .zip(w)
        .map(|((c, k), w)| {
            SmoothXform::new(Xform::new(
                *c,
                vec![
                    Variation::new(VariationKind::Linear, 1.0),
                    Variation::new(k, w),
                ],
            ))
            .unwrap()
        })
        .collect()
}

#[test]
fn flame_transform_vjps_match_finite_differences() {
    for x in flame([0.2, -0.3, 0.25]) {
        for p in [[0.3, -0.2], [-0.7, 0.4], [1.1, 0.9]] {
            let c = vjp_check(&x, p, [0.6, -1.3], 1e-6);
            assert!(c.point <= 1e-6 * (1.0 + c.scale), "{c:?}");
            assert!(c.params <= 1e-6 * (1.0 + c.scale), "{c:?}");
        }
    }
}

fn objective_and_grad(
    objective: &Objective,
    cfg: &SplatConfig,
    theta: &[f64],
    seed: u64,
) -> (f64, Vec<f64>) {
    let mut maps = flame([0.0; 3]);
    set_flat_params(&mut maps, theta).unwrap();
    let dev = Device::Cpu;
    let var =
        Var::from_tensor(&params_to_tensor(&maps, candle_core::DType::F64, &dev).unwrap()).unwrap();
    let op = SplatOp::with_maps(cfg.clone(), seed, maps.clone());
    common::objective_and_grad(objective, &maps, &var, op)
}

#[test]
fn whole_objective_gradient_through_flame_transforms_matches_finite_differences() {
    let cfg = common::small_splat();
    let (target, _) = splat::forward::<f64>(&cfg, &flame([0.3, -0.2, 0.25]), 99).unwrap();
    assert!(target.iter().any(|&v| v > 0.1), "the flame draws something");
    let target = Tensor::from_vec(target, (cfg.height, cfg.width), &Device::Cpu).unwrap();
    let loss = LossConfig {
        lpips_weight: 0.0,
        ..LossConfig::default()
    };
    let objective = Objective::new(loss, &target).unwrap();
    let maps = flame([0.1, 0.05, -0.1]);
    let offsets = param_offsets(&maps);
    let theta = flat_params(&maps);
    let seed = 7;
    let (value, grad) = objective_and_grad(&objective, &cfg, &theta, seed);
    assert!(value.is_finite() && value > 0.0);
    let f = |t: &[f64]| objective_and_grad(&objective, &cfg, t, seed).0;
    let (scale, _) = common::check_against_central_differences(f, &theta, &grad, 1e-7, |k| {
        let map = offsets.iter().rposition(|&o| o <= k).unwrap();
        format!("transform {map} parameter {}", k - offsets[map])
    });
    assert!(
        scale > 1e-3,
        "gradients should not all vanish (max |fd| = {scale})"
    );
}
