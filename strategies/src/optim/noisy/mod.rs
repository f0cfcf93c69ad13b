//! Adam with annealed Gaussian gradient noise: `g ← g + N(0, η/(1 + t)^γ)`, a baseline of
//! the chaotic-splatting paper (noise helps leave poor basins early and fades out).
//!
//! ## References
//! - Neelakantan et al., *Adding Gradient Noise Improves Learning for Very Deep Networks*, 2015.
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point Splatting*.

use argmin::core::{Error as ArgminError, KV, KvValue, Problem, Solver, State};
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};

use crate::driver::{Differentiable, GradState, Params};
use crate::error::{Error, Result};
use crate::optim::adam::{Adam, AdamConfig, adam_iteration};

/// Hyper-parameters of the noisy-gradient strategy.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct NoisyConfig {
    /// The Adam part.
    pub adam: AdamConfig,
    /// Noise variance at t = 0.
    pub eta: f64,
    /// Decay exponent of the variance.
    pub gamma: f64,
}

impl Default for NoisyConfig {
    fn default() -> Self {
        NoisyConfig {
            adam: AdamConfig::default(),
            eta: 0.3,
            gamma: 0.55,
        }
    }
}

impl Params for NoisyConfig {
    const KIND: &'static str = "noisy";
    const STATS: &'static [&'static str] = &["noise_std"];
    /// Checks every field; the error names the one to change.
    fn validate(&self) -> Result<()> {
        self.adam.validate()?;
        if !(self.eta.is_finite() && self.eta >= 0.0) {
            return Err(Error::param(
                "eta",
                format!("must be ≥ 0, got {}", self.eta),
            ));
        }
        if !(self.gamma.is_finite() && self.gamma >= 0.0) {
            return Err(Error::param(
                "gamma",
                format!("must be ≥ 0, got {}", self.gamma),
            ));
        }
        Ok(())
    }
}

/// Adam on noisy gradients.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NoisyAdam {
    config: NoisyConfig,
    adam: Adam,
    seed: u64,
}

impl NoisyAdam {
    /// A solver seeded by `seed`.
    pub fn new(config: NoisyConfig, seed: u64) -> Result<Self> {
        config.validate()?;
        Ok(NoisyAdam {
            adam: Adam::new(config.adam.clone())?,
            config,
            seed,
        })
    }
}

impl<O: Differentiable> Solver<O, GradState> for NoisyAdam {
    fn name(&self) -> &str {
        "NoisyAdam"
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        state: GradState,
    ) -> Result<(GradState, Option<KV>), ArgminError> {
        let t = state.get_iter();
        let std = (self.config.eta / (1.0 + t as f64).powf(self.config.gamma)).sqrt();
        let mut rng =
            Xoshiro256PlusPlus::seed_from_u64(ifslab::chaos::mix_seed(self.seed, t | (1 << 61)));
        let (state, mut kv) = adam_iteration(&mut self.adam, problem, state, |g| {
            for x in g.iter_mut() {
                *x += std * rng.sample::<f64, _>(StandardNormal);
            }
        })?;
        kv.insert("noise_std", KvValue::Float(std));
        Ok((state, Some(kv)))
    }
}
