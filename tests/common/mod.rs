//! What the end-to-end gradient tests of new map types share: a small splat setting and the
//! whole-objective finite-difference check.

use ifslab::chaos::ChaosGame;
use ifslab::render::splat::{Blend, SplatConfig, SplatView};

/// A 32 × 28 coverage splat at 2× supersampling, 24 trajectories of 100 kept points.
pub fn small_splat() -> SplatConfig {
    SplatConfig {
        width: 32,
        height: 28,
        supersample: 2,
        sigma: 1.3,
        radius: 3.0,
        blend: Blend::Coverage,
        alpha_max: 0.99,
        game: ChaosGame {
            trajectories: 24,
            length: 110,
            warmup: 10,
            start_half_width: 2.0,
            seed: 0,
        },
        framing: SplatView::default(),
        device: Default::default(),
    }
}

/// Checks `grad` (the analytic gradient of `f` at `theta`) against central differences of
/// `f` with step `h`, entry by entry (relative tolerance `2e-4`); `name(k)` names entry `k`
/// in a failure. Returns the largest |finite difference| and the largest error.
pub fn check_against_central_differences(
    f: impl Fn(&[f64]) -> f64,
    theta: &[f64],
    grad: &[f64],
    h: f64,
    name: impl Fn(usize) -> String,
) -> (f64, f64) {
    let (mut scale, mut worst) = (0.0f64, 0.0f64);
    for k in 0..theta.len() {
        let mut t = theta.to_vec();
        t[k] += h;
        let up = f(&t);
        t[k] -= 2.0 * h;
        let fd = (up - f(&t)) / (2.0 * h);
        scale = scale.max(fd.abs());
        worst = worst.max((fd - grad[k]).abs());
        assert!(
            (fd - grad[k]).abs() <= 2e-4 * (1.0 + fd.abs()),
            "{}: analytic {} vs finite difference {fd}",
            name(k),
            grad[k]
        );
    }
    (scale, worst)
}

/// The whole objective at `maps` and its gradient with respect to their flat parameters:
/// `params` (a candle variable holding them in the layout `op` expects) rendered by `op`,
/// the objective's image terms differentiated by autograd, plus the regulariser's own
/// gradient.
pub fn objective_and_grad<M: ifslab::model::AffinePart + Send + Sync + 'static>(
    objective: &ifslab::loss::Objective,
    maps: &[M],
    params: &candle_core::Var,
    op: ifslab::render::splat::SplatOp<M>,
) -> (f64, Vec<f64>) {
    let pred = params.as_tensor().apply_op1(op).unwrap();
    let ev = objective.evaluate_params(&pred, maps).unwrap();
    let grads = ev.image_total.backward().unwrap();
    let g: Vec<f64> = grads
        .get(params.as_tensor())
        .unwrap()
        .flatten_all()
        .unwrap()
        .to_vec1()
        .unwrap();
    let total = g.iter().zip(&ev.param_grad).map(|(a, b)| a + b).collect();
    (ev.breakdown.total, total)
}
