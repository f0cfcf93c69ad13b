//! The hybrid strategy of the chaotic-splatting paper: Adam, interrupted every
//! `anneal_every` iterations during the first `anneal_fraction` of the run by an annealing
//! phase — `candidates` Metropolis proposals on raw θ with noise std `noise·(1 − t/T)` and
//! acceptance `exp(−scale·ΔMSE/τ)`, `τ = 1 − t/T` — after which Adam starts fresh (its
//! moment estimates no longer describe the new θ).
//!
//! Gradient descent alone gets stuck where maps overlap or a map's image lies far from
//! where it should be; the annealing phases let θ jump between those basins early, and Adam
//! refines afterwards.
//!
//! ## References
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point Splatting*.

use argmin::core::{Error as ArgminError, KV, KvValue, Problem, Solver, State};
use serde::{Deserialize, Serialize};

use crate::driver::{Differentiable, GradState, Params};
use crate::error::{Error, Result};
use crate::optim::adam::{Adam, AdamConfig, adam_iteration};
use crate::optim::annealing::{Anneal, AnnealingConfig, metropolis_phase};

/// Hyper-parameters of the hybrid (defaults: the paper's).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HybridConfig {
    /// The Adam part.
    pub adam: AdamConfig,
    /// The annealing phases (paper: 10 candidates, noise 0.2, scale 10).
    pub annealing: AnnealingConfig,
    /// Iterations between annealing phases (paper: 250).
    pub anneal_every: u64,
    /// Fraction of the run during which phases happen (paper: the first half).
    pub anneal_fraction: f64,
}

impl Default for HybridConfig {
    fn default() -> Self {
        HybridConfig {
            adam: AdamConfig::default(),
            annealing: AnnealingConfig {
                candidates: 10,
                ..AnnealingConfig::default()
            },
            anneal_every: 250,
            anneal_fraction: 0.5,
        }
    }
}

impl Params for HybridConfig {
    const KIND: &'static str = "hybrid";
    const STATS: &'static [&'static str] = &["anneal_accepted", "anneal_mse"];
    /// Checks every field; the error names the one to change.
    fn validate(&self) -> Result<()> {
        self.adam.validate()?;
        self.annealing.validate()?;
        if self.anneal_every == 0 {
            return Err(Error::param("anneal_every", "must be at least 1"));
        }
        if !(0.0..=1.0).contains(&self.anneal_fraction) {
            return Err(Error::param(
                "anneal_fraction",
                format!("must lie in [0, 1], got {}", self.anneal_fraction),
            ));
        }
        Ok(())
    }
}

impl HybridConfig {
    /// The hybrid for a start that already lies in the right basin (an EM fit): *cold*
    /// annealing phases (τ₀ = 0.02, noise 0.05) explore near it instead of throwing it away,
    /// and Adam's learning rate decays to 0.1× for the final refinement. The paper's defaults
    /// (τ₀ = 1, noise 0.2) suit random starts, where large jumps are the point.
    pub fn from_good_start() -> Self {
        let paper = HybridConfig::default();
        HybridConfig {
            annealing: AnnealingConfig {
                temperature: 0.02,
                noise: 0.05,
                ..paper.annealing
            },
            adam: AdamConfig {
                final_lr_factor: 0.1,
                ..paper.adam
            },
            ..paper
        }
    }
}

/// The hybrid started from a good code (an EM fit): the same strategy with
/// [`HybridConfig::from_good_start`] as its defaults, under its own name (`kind =
/// "cold_hybrid"`) so configs and commands name the recipe instead of spelling it out.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct ColdHybridConfig(pub HybridConfig);

impl Default for ColdHybridConfig {
    fn default() -> Self {
        ColdHybridConfig(HybridConfig::from_good_start())
    }
}

impl Params for ColdHybridConfig {
    const KIND: &'static str = "cold_hybrid";
    const STATS: &'static [&'static str] = HybridConfig::STATS;
    fn validate(&self) -> Result<()> {
        self.0.validate()
    }
}

/// Adam with annealing phases.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Hybrid {
    config: HybridConfig,
    adam: Adam,
    max_iters: u64,
    seed: u64,
    phases: u64,
    accepted: u64,
}

impl Hybrid {
    /// A solver for a run of `max_iters` iterations, seeded by `seed`.
    pub fn new(config: HybridConfig, max_iters: u64, seed: u64) -> Result<Self> {
        config.validate()?;
        if max_iters == 0 {
            return Err(Error::param("iterations", "must be at least 1"));
        }
        Ok(Hybrid {
            adam: Adam::new(config.adam.clone())?,
            config,
            max_iters,
            seed,
            phases: 0,
            accepted: 0,
        })
    }

    /// Whether iteration `t` starts with an annealing phase: after every `anneal_every`
    /// gradient iterations, up to and including the end of the first `anneal_fraction` of the
    /// run — the paper's 15 000 iterations with phases every 250 during the first half give
    /// 30 phases (t = 250, 500, …, 7 500).
    pub fn anneals_at(&self, t: u64) -> bool {
        t > 0
            && t.is_multiple_of(self.config.anneal_every)
            && (t as f64) <= self.config.anneal_fraction * self.max_iters as f64
    }

    /// How many annealing phases a whole run has.
    pub fn phase_count(&self) -> u64 {
        (1..self.max_iters).filter(|&t| self.anneals_at(t)).count() as u64
    }
}

impl<O: Anneal + Differentiable> Solver<O, GradState> for Hybrid {
    fn name(&self) -> &str {
        "Hybrid"
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        mut state: GradState,
    ) -> Result<(GradState, Option<KV>), ArgminError> {
        let t = state.get_iter();
        let mut phase = None;
        if self.anneals_at(t) {
            let mut theta = state
                .take_param()
                .ok_or_else(|| ArgminError::msg("no initial parameters"))?;
            let frac = t as f64 / self.max_iters as f64;
            // Streams of annealing phases are kept apart from the gradient iterations'.
            let stream = t | (1 << 62);
            let st = metropolis_phase(
                problem,
                &mut theta,
                &self.config.annealing,
                frac,
                self.seed,
                stream,
            )?;
            self.phases += 1;
            self.accepted += st.accepted as u64;
            self.adam.reset();
            state = state.param(theta);
            phase = Some(st);
        }
        let (state, mut kv) = adam_iteration(&mut self.adam, problem, state, |_| {})?;
        if let Some(st) = phase {
            kv.insert("anneal_accepted", KvValue::Float(st.accepted as f64));
            kv.insert("anneal_mse", KvValue::Float(st.cost));
        }
        Ok((state, Some(kv)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hybrid(every: u64, iters: u64) -> Hybrid {
        let cfg = HybridConfig {
            anneal_every: every,
            ..HybridConfig::default()
        };
        Hybrid::new(cfg, iters, 0).unwrap()
    }

    #[test]
    fn phases_fall_every_interval_through_the_first_half() {
        // The paper: 15 000 iterations, every 250, first half → 30 phases, the last at 7 500.
        let paper = hybrid(250, 15_000);
        assert_eq!(paper.phase_count(), 30);
        assert!(paper.anneals_at(7_500) && !paper.anneals_at(7_750) && !paper.anneals_at(0));
        // The reproduction's 800 iterations every 100: t = 100, 200, 300, 400.
        let ours = hybrid(100, 800);
        assert_eq!(ours.phase_count(), 4);
        assert!(ours.anneals_at(400) && !ours.anneals_at(500));
    }
}
