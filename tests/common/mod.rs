//! What the end-to-end gradient tests of new map types share: a small splat setting and the
//! whole-objective finite-difference check.

use ifslab::chaos::ChaosGame;
use ifslab::render::splat::{Blend, SplatConfig, SplatFraming};

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
        framing: SplatFraming::default(),
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
