//! Adding a new map type: a non-linear map defined outside the crate, rendered by the fused
//! splat op and differentiated end to end.
//!
//! The map is a flame-like transform `f(x) = y + w·sin(y)` (sine per coordinate) with
//! `y = A·x + b`: an affine step followed by a learnable amount of the *sinusoidal*
//! variation. Implementing [`Map<2>`](Map) (forward), [`DiffMap<2>`](DiffMap) (parameters and the two
//! vector–Jacobian products) and [`AffinePart`] (what the regulariser sees) is all it takes:
//! the chaos game, the framing, the splat, the candle op and the objective then work on it
//! unchanged, monomorphised for it.
//!
//! Checked here, in f64: the map's vjps against finite differences (with the core's
//! [`vjp_check`]), and the gradient of the whole objective (MS-MSE + D-SSIM + regulariser on
//! the affine steps) with respect to every parameter of every map, through
//! `SplatOp::uniform` and candle's autograd, against central differences of the same
//! objective on the same trajectories. LPIPS is left out: its network runs in f32, which
//! would drown f64 finite differences (the f32 end-to-end test in the strategies crate
//! includes it).

mod common;

use candle_core::{Device, Tensor, Var};
use ifslab::loss::{LossConfig, Objective};
use ifslab::model::diff_map::{flat_params, set_flat_params, vjp_check};
use ifslab::model::{Affine2, AffinePart, DiffMap, Map};
use ifslab::render::splat::{self, SplatConfig, SplatOp};
use proptest::prelude::*;

/// `x ↦ y + w·sin(y)`, `y = A·x + b`; parameters `[a, b, c, d, e, f, w]`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Sinusoidal {
    affine: Affine2,
    w: f64,
}

impl Map<2> for Sinusoidal {
    fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let y = self.affine.apply(p);
        [y[0] + self.w * y[0].sin(), y[1] + self.w * y[1].sin()]
    }
}

impl DiffMap<2> for Sinusoidal {
    // `PARAMS` is left at `None`, so the backward scan finds each map's gradient through the
    // offsets table: the path of map types whose parameter count varies from map to map.

    fn n_params(&self) -> usize {
        7
    }

    fn write_params(&self, out: &mut [f64]) {
        out[..6].copy_from_slice(&self.affine.coefficients());
        out[6] = self.w;
    }

    fn set_params(&mut self, p: &[f64]) {
        self.affine = Affine2::from_coefficients(&p[..6]);
        self.w = p[6];
    }

    /// `∂f/∂x = diag(1 + w·cos y)·A`, so `λᵀ∂f/∂x = Aᵀμ` with `μ = λ ⊙ (1 + w·cos y)`.
    fn vjp_point(&self, x: [f64; 2], lambda: [f64; 2]) -> [f64; 2] {
        let mut scratch = [0.0; 7];
        self.vjp(x, lambda, &mut scratch)
    }

    /// `∂f/∂(A, b)` is the affine step's with `μ` in place of `λ`; `∂f/∂w = sin y`.
    fn vjp_params(&self, x: [f64; 2], lambda: [f64; 2], grad: &mut [f64]) {
        self.vjp(x, lambda, grad);
    }

    /// Both at once: `y` and its sine and cosine are computed once per step.
    fn vjp(&self, x: [f64; 2], lambda: [f64; 2], grad: &mut [f64]) -> [f64; 2] {
        let y = self.affine.apply(x);
        let (s0, c0) = y[0].sin_cos();
        let (s1, c1) = y[1].sin_cos();
        let mu = [
            lambda[0] * (1.0 + self.w * c0),
            lambda[1] * (1.0 + self.w * c1),
        ];
        self.affine.vjp_params(x, mu, &mut grad[..6]);
        grad[6] += lambda[0] * s0 + lambda[1] * s1;
        self.affine.vjp_point(x, mu)
    }
}

impl AffinePart for Sinusoidal {
    /// The regulariser keeps the affine step contractive and well conditioned.
    fn affine_part(&self) -> Affine2 {
        self.affine
    }

    fn affine_part_backward(&self, g: &Affine2, grad: &mut [f64]) {
        self.affine.affine_part_backward(g, &mut grad[..6]);
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    /// `∂f/∂x = diag(1 + w·cos y)·A`, `∂f/∂w = sin y`, `∂f/∂(A, b)` through `μ`: against
    /// central differences at random maps, points and cotangents.
    #[test]
    fn sinusoidal_vjps_match_finite_differences(
        c in prop::collection::vec(-1.0f64..1.0, 6),
        w in -0.8f64..0.8,
        x in prop::array::uniform2(-2.0f64..2.0),
        lam in prop::array::uniform2(-2.0f64..2.0),
    ) {
        let map = Sinusoidal { affine: Affine2::from_coefficients(&c), w };
        let r = vjp_check(&map, x, lam, 1e-6);
        prop_assert!(r.point <= 1e-7 * (1.0 + r.scale), "point vjp off by {}", r.point);
        prop_assert!(r.params <= 1e-7 * (1.0 + r.scale), "parameter vjp off by {}", r.params);
        prop_assert!(r.fused == 0.0);
    }
}

/// A three-map Sierpiński-like code bent by the sinusoidal variation.
fn maps(w: [f64; 3]) -> Vec<Sinusoidal> {
    let a = [
        Affine2::new(0.45, 0.1, -0.05, 0.5, -0.4, -0.3),
        Affine2::new(0.5, -0.12, 0.08, 0.42, 0.45, -0.2),
        Affine2::new(0.38, 0.05, 0.1, 0.4, 0.05, 0.5),
    ];
    a.iter()
        .zip(w)
        .map(|(&affine, w)| Sinusoidal { affine, w })
        .collect()
}

/// The whole objective and its gradient for the maps' flat parameters `theta`, through the
/// candle op (one prototype, argument `(3, 7)`) and autograd, plus the regulariser's own
/// gradient.
fn objective_and_grad(
    objective: &Objective,
    cfg: &SplatConfig,
    theta: &[f64],
    seed: u64,
) -> (f64, Vec<f64>) {
    let mut m = maps([0.0; 3]);
    set_flat_params(&mut m, theta).unwrap();
    let dev = Device::Cpu;
    let var = Var::from_tensor(&Tensor::from_vec(theta.to_vec(), (3, 7), &dev).unwrap()).unwrap();
    let proto = m[0];
    common::objective_and_grad(
        objective,
        &m,
        &var,
        SplatOp::uniform(cfg.clone(), seed, proto),
    )
}

/// θ → non-linear maps → fused splat (chaos game, fitted framing, coverage, 2× pooling) →
/// MS-MSE + D-SSIM + regulariser: every one of the 21 partial derivatives against central
/// differences of the same objective on the same trajectories.
#[test]
fn whole_objective_gradient_through_a_nonlinear_map_matches_finite_differences() {
    let cfg = common::small_splat();
    let (target, _) = splat::forward::<f64>(&cfg, &maps([0.3, -0.2, 0.25]), 99).unwrap();
    let target = Tensor::from_vec(target, (cfg.height, cfg.width), &Device::Cpu).unwrap();
    let loss = LossConfig {
        lpips_weight: 0.0,
        ..LossConfig::default()
    };
    let objective = Objective::new(loss, &target).unwrap();
    let theta = flat_params(&maps([0.1, 0.05, -0.1]));
    let seed = 7;
    let (value, grad) = objective_and_grad(&objective, &cfg, &theta, seed);
    assert!(value.is_finite() && value > 0.0);
    let f = |t: &[f64]| objective_and_grad(&objective, &cfg, t, seed).0;
    // Small h: the splat's footprint vanishes continuously at its cut-off but with a kink.
    let (scale, worst) = common::check_against_central_differences(f, &theta, &grad, 1e-7, |k| {
        format!("map {} parameter {}", k / 7, k % 7)
    });
    assert!(
        scale > 1e-3,
        "gradients should not all vanish (max |fd| = {scale})"
    );
    // The variation's weights are part of what is learned.
    assert!(
        [6, 13, 20].iter().any(|&k| grad[k].abs() > 1e-3),
        "∂L/∂w should not vanish: {:?}",
        [grad[6], grad[13], grad[20]]
    );
    eprintln!("max |analytic − fd| = {worst:.2e} (max |fd| = {scale:.2e})");
}

/// The same seed gives the same image and gradient whatever the thread count, for this map
/// type as for affine maps.
#[test]
fn nonlinear_maps_are_deterministic_across_thread_counts() {
    let mut cfg = common::small_splat();
    cfg.game.trajectories = 300;
    let m = maps([0.1, 0.05, -0.1]);
    let w: Vec<f32> = (0..cfg.width * cfg.height)
        .map(|i| ((i * 37 % 101) as f32 / 50.0 - 1.0) * 0.3)
        .collect();
    let run = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| {
                let (img, tape) = splat::forward::<f32>(&cfg, &m, 3).unwrap();
                let g = splat::backward(&cfg, &m, &tape, &w).unwrap();
                (img, g)
            })
    };
    assert_eq!(run(1), run(2));
}
