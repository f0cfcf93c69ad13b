//! The optimiser of *Learning Fractals by Gradient Descent* (Tu et al., AAAI 2023), the
//! gradient baseline of the chaotic-splatting paper's Table 3: Adam with the gradient of each
//! parameter group clipped to norm 1, the learning rate halved at every quarter of the run,
//! and Gaussian noise added to the map weights every 10 iterations through the first 60% of
//! the run (facts read from the authors' `train_deep_fractal.py`: `lr = 0.05`,
//! `clip_grad_norm_(·, 1.0)` on the weights and on the offsets separately, `lr *= 0.5` every
//! `num_iters // 4`, `noise = 0.1` in their reconstruction script).
//!
//! The groups follow the rotation–scale–rotation layout (`model.parameterisation = "rsr"`,
//! 8 numbers a map: 6 weights, then the 2 offsets); `block = 0` makes θ one group and puts
//! the noise on all of it (for other parameterisations).
//!
//! The rest of their recipe is the problem's, not the optimiser's: their splat (Gaussians
//! `exp(−d²)` summed and clamped: `renderer.blend = "additive"`, `sigma = 0.7071`,
//! `clamp = true`), their fixed frame ([−5, 5]²: `renderer.window`), map probabilities ∝
//! |det| (`model.probabilities = "determinant"`) and plain MSE. `ifslab invert --strategy
//! learning-fractals` sets all of it.

use argmin::core::{Error as ArgminError, KV, KvValue, Problem, Solver, State};
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};

use crate::driver::{Differentiable, GradState, Params, kv_of, to_argmin};
use crate::error::{Error, Result};
use crate::optim::adam::{Adam, AdamConfig};

/// Hyper-parameters of the Learning Fractals optimiser.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LearningFractalsConfig {
    /// The Adam part (their learning rate 0.05).
    pub adam: AdamConfig,
    /// Largest gradient norm of each group (their 1.0); 0 turns clipping off.
    pub clip_norm: f64,
    /// Parameters per map (their 8); 0: θ is one group.
    pub block: usize,
    /// Leading parameters of each block that are weights (their 6); the rest are offsets.
    pub weights: usize,
    /// Standard deviation of the weight noise (their 0.1).
    pub noise: f64,
    /// Noise every this many iterations (their 10).
    pub noise_every: u64,
    /// Noise only before this fraction of the run (their 600 of 1000).
    pub noise_until: f64,
    /// Halvings of the learning rate over the run (their 4, at every quarter).
    pub halvings: u64,
}

impl Default for LearningFractalsConfig {
    fn default() -> Self {
        LearningFractalsConfig {
            adam: AdamConfig {
                lr: 0.05,
                ..AdamConfig::default()
            },
            clip_norm: 1.0,
            block: 8,
            weights: 6,
            noise: 0.1,
            noise_every: 10,
            noise_until: 0.6,
            halvings: 4,
        }
    }
}

impl Params for LearningFractalsConfig {
    const KIND: &'static str = "learning_fractals";
    const STATS: &'static [&'static str] = &["lr", "grad_norm"];
    /// Checks every field; the error names the one to change.
    fn validate(&self) -> Result<()> {
        self.adam.validate()?;
        if !(self.clip_norm.is_finite() && self.clip_norm >= 0.0) {
            return Err(Error::param(
                "clip_norm",
                format!("must be ≥ 0, got {}", self.clip_norm),
            ));
        }
        if self.block > 0 && self.weights > self.block {
            return Err(Error::param(
                "weights",
                format!(
                    "the {} weights of a block cannot exceed its {} parameters",
                    self.weights, self.block
                ),
            ));
        }
        if !(self.noise.is_finite() && self.noise >= 0.0) {
            return Err(Error::param(
                "noise",
                format!("must be ≥ 0, got {}", self.noise),
            ));
        }
        if self.noise_every == 0 {
            return Err(Error::param("noise_every", "must be at least 1"));
        }
        if !(0.0..=1.0).contains(&self.noise_until) {
            return Err(Error::param(
                "noise_until",
                format!("must lie in [0, 1], got {}", self.noise_until),
            ));
        }
        Ok(())
    }
}

/// The Learning Fractals optimiser.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LearningFractals {
    config: LearningFractalsConfig,
    adam: Adam,
    iterations: u64,
    seed: u64,
}

impl LearningFractals {
    /// A solver for a run of `iterations`, its noise seeded by `seed`.
    pub fn new(config: LearningFractalsConfig, iterations: u64, seed: u64) -> Result<Self> {
        config.validate()?;
        Ok(LearningFractals {
            adam: Adam::new(config.adam.clone())?,
            config,
            iterations: iterations.max(1),
            seed,
        })
    }

    /// Whether parameter `i` is a map weight (noised; first clipping group).
    fn is_weight(&self, i: usize) -> bool {
        let c = &self.config;
        c.block == 0 || i % c.block < c.weights
    }

    /// Clips the weights' and the offsets' gradients to norm `clip_norm` each; returns the
    /// norm before clipping.
    fn clip(&self, g: &mut [f64]) -> f64 {
        let mut sq = [0.0f64; 2];
        for (i, v) in g.iter().enumerate() {
            sq[usize::from(!self.is_weight(i))] += v * v;
        }
        let norms = [sq[0].sqrt(), sq[1].sqrt()];
        let c = self.config.clip_norm;
        if c > 0.0 {
            for (i, v) in g.iter_mut().enumerate() {
                let n = norms[usize::from(!self.is_weight(i))];
                if n > c {
                    *v *= c / n;
                }
            }
        }
        (sq[0] + sq[1]).sqrt()
    }
}

impl<O: Differentiable> Solver<O, GradState> for LearningFractals {
    fn name(&self) -> &str {
        "LearningFractals"
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        mut state: GradState,
    ) -> Result<(GradState, Option<KV>), ArgminError> {
        let t = state.get_iter();
        let big_t = self.iterations;
        let mut theta = state.take_param().ok_or_else(|| {
            ArgminError::msg("no initial parameters: configure the state with param(θ)")
        })?;
        // Their loop counts from 1 and adds the noise before the forward pass.
        let step = t + 1;
        let c = &self.config;
        if c.noise > 0.0
            && step.is_multiple_of(c.noise_every)
            && (step as f64) < c.noise_until * big_t as f64
        {
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(ifslab::chaos::mix_seed(
                self.seed,
                t | (1 << 60),
            ));
            for (i, v) in theta.iter_mut().enumerate() {
                if self.is_weight(i) {
                    *v += c.noise * rng.sample::<f64, _>(StandardNormal);
                }
            }
        }
        let mut eval = problem.problem("loss_and_gradient", |p| {
            p.evaluate(&theta, t).map_err(to_argmin)
        })?;
        if !eval.loss.is_finite() {
            return Err(to_argmin(Error::Numerical(format!(
                "loss became {} at iteration {t}",
                eval.loss
            ))));
        }
        let grad_norm = self.clip(&mut eval.grad);
        // Halved after every `T / halvings` steps: iterations 1..=T/4 at lr, and so on.
        let period = big_t.checked_div(c.halvings).map_or(u64::MAX, |p| p.max(1));
        let scale = 0.5f64.powi((t / period).min(1000) as i32);
        self.adam
            .step_scaled(&mut theta, &eval.grad, scale)
            .map_err(to_argmin)?;
        problem.problem("project", |p| {
            p.project(&mut theta);
            Ok(())
        })?;
        let mut kv = kv_of(&eval);
        kv.insert("lr", KvValue::Float(scale * c.adam.lr));
        kv.insert("grad_norm", KvValue::Float(grad_norm));
        Ok((
            state.param(theta).gradient(eval.grad).cost(eval.loss),
            Some(kv),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::driver::Evaluation;
    use crate::optim::testing::run;

    /// ‖θ − (1, −2, 0.5, 3)‖².
    struct Bowl;

    impl Differentiable for Bowl {
        fn evaluate(&self, theta: &[f64], _iter: u64) -> Result<Evaluation> {
            let opt = [1.0, -2.0, 0.5, 3.0];
            Ok(Evaluation {
                loss: theta.iter().zip(opt).map(|(t, o)| (t - o).powi(2)).sum(),
                grad: theta.iter().zip(opt).map(|(t, o)| 2.0 * (t - o)).collect(),
                terms: vec![],
            })
        }
    }

    #[test]
    fn it_minimises_a_bowl_with_its_schedule_and_noise() {
        let cfg = LearningFractalsConfig {
            block: 0,
            ..LearningFractalsConfig::default()
        };
        let solver = LearningFractals::new(cfg, 400, 3).unwrap();
        let (theta, cost, _) = run(Bowl, solver, vec![0.0; 4], 400);
        assert!(cost < 1e-3, "{cost} at {theta:?}");
    }

    #[test]
    fn clipping_is_per_group() {
        let s = LearningFractals::new(LearningFractalsConfig::default(), 10, 0).unwrap();
        // One map: 6 weights with gradient norm 3, offsets with norm 0.5.
        let mut g = vec![3.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.3, 0.4];
        let n = s.clip(&mut g);
        assert!((n - (9.0f64 + 0.25).sqrt()).abs() < 1e-12);
        assert!((g[0] - 1.0).abs() < 1e-12, "weights scaled to norm 1");
        assert_eq!(&g[6..], &[0.3, 0.4], "offsets under the bound untouched");
        assert!(s.is_weight(5) && !s.is_weight(6) && s.is_weight(8));
    }

    #[test]
    fn bad_settings_are_named() {
        let bad = LearningFractalsConfig {
            weights: 9,
            ..LearningFractalsConfig::default()
        };
        assert!(bad.validate().unwrap_err().to_string().contains("weights"));
    }
}
