//! Simulated annealing on raw θ, and the [`Anneal`] capability the hybrid strategy shares.
//!
//! Each iteration proposes `θ' = θ + N(0, s²)` with `s = noise·(1 − t/T)`, evaluates both
//! θ and θ' on the same fresh chaos-game trajectories (common random numbers, so the
//! comparison sees the codes' difference rather than sampling noise), and accepts if
//! `ΔMSE ≤ 0` or with probability `exp(−scale·ΔMSE/τ)`, `τ = τ₀·(1 − t/T)` (Metropolis; the
//! paper's τ₀ is 1). argmin's
//! own `SimulatedAnnealing` re-uses the previous cost, which a stochastic renderer makes
//! stale; hence this solver.
//!
//! ## References
//! - Kirkpatrick, Gelatt & Vecchi, *Optimization by Simulated Annealing*, Science 1983.
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point
//!   Splatting* (the annealing baseline and the hybrid's annealing phases).

use argmin::core::{Error as ArgminError, KV, KvValue, Problem, Solver, State};
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};

use crate::driver::{Differentiable, GradState, Params, to_argmin};
use crate::error::{Error, Result};

/// What annealing needs from a problem: a cheap cost on a chosen random stream, so several
/// candidates can be compared on identical trajectories.
pub trait Anneal {
    /// The annealing cost (the image MSE for image inversion) of θ on random stream `stream`
    /// at progress `frac = t/T` of the run (a problem whose cost changes over the run, such as
    /// the image problem with a σ schedule, evaluates it as at that point).
    fn anneal_cost(&self, theta: &[f64], stream: u64, frac: f64) -> Result<f64>;
}

/// Hyper-parameters of the Metropolis steps.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AnnealingConfig {
    /// Proposal scale at t = 0 (on raw θ), decaying linearly to 0: the standard deviation,
    /// or the variance with `proposal = "variance"`.
    pub noise: f64,
    /// How `noise` scales the Gaussian proposal (see [`ProposalScale`]).
    pub proposal: ProposalScale,
    /// Scale of ΔMSE in the acceptance probability `exp(−scale·ΔMSE/τ)`.
    pub accept_scale: f64,
    /// Proposals per iteration.
    pub candidates: usize,
    /// Initial temperature τ₀ (τ = τ₀·(1 − t/T)); the paper's schedule starts at 1. A small
    /// τ₀ explores near θ without giving up a good starting code (e.g. an EM fit).
    pub temperature: f64,
}

/// The paper writes the proposal as `Δθ ~ N(0, τ/s)`, which in the usual `N(μ, σ²)` notation
/// is a variance; the authors' reference code draws `noise·(1 − t/T)·N(0, 1)`, a standard
/// deviation. Both readings are here; the reference code's is the default
/// (`paper_repro/chaotic_splatting/README.md` compares them).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProposalScale {
    /// Standard deviation `noise·(1 − t/T)` (the reference code).
    #[default]
    Std,
    /// Variance `noise·(1 − t/T)`: standard deviation `√(noise·(1 − t/T))`.
    Variance,
}

impl ProposalScale {
    /// The proposal's standard deviation for a scale `v` (`noise·(1 − t/T)`).
    pub fn std(self, v: f64) -> f64 {
        match self {
            ProposalScale::Std => v,
            ProposalScale::Variance => v.max(0.0).sqrt(),
        }
    }
}

impl Default for AnnealingConfig {
    fn default() -> Self {
        AnnealingConfig {
            noise: 0.2,
            proposal: ProposalScale::Std,
            accept_scale: 10.0,
            candidates: 1,
            temperature: 1.0,
        }
    }
}

impl Params for AnnealingConfig {
    const KIND: &'static str = "annealing";
    const STATS: &'static [&'static str] = &["mse", "accepted"];
    /// Checks every field; the error names the one to change.
    fn validate(&self) -> Result<()> {
        if !(self.noise.is_finite() && self.noise >= 0.0) {
            return Err(Error::param(
                "noise",
                format!("must be ≥ 0, got {}", self.noise),
            ));
        }
        if !(self.accept_scale.is_finite() && self.accept_scale > 0.0) {
            return Err(Error::param(
                "accept_scale",
                format!("must be > 0, got {}", self.accept_scale),
            ));
        }
        if self.candidates == 0 {
            return Err(Error::param("candidates", "must be at least 1"));
        }
        if !(self.temperature.is_finite() && self.temperature > 0.0) {
            return Err(Error::param(
                "temperature",
                format!("must be > 0, got {}", self.temperature),
            ));
        }
        Ok(())
    }
}

/// Outcome of one Metropolis phase.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhaseStats {
    /// Candidates accepted.
    pub accepted: u32,
    /// Cost of the final θ on the phase's stream.
    pub cost: f64,
}

/// Runs `cfg.candidates` Metropolis proposals from θ (modified in place) at progress
/// `frac = t/T`, all on random stream `stream`; the proposal and acceptance draws come from
/// a generator seeded by `(seed, stream)`, so the phase is reproducible.
pub fn metropolis_phase<O: Anneal + Differentiable>(
    problem: &mut Problem<O>,
    theta: &mut Vec<f64>,
    cfg: &AnnealingConfig,
    frac: f64,
    seed: u64,
    stream: u64,
) -> Result<PhaseStats, ArgminError> {
    let progress = (1.0 - frac).max(0.0);
    let tau = cfg.temperature * progress;
    let std = cfg.proposal.std(cfg.noise * progress);
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(ifslab::chaos::mix_seed(seed, stream));
    let mut cost = problem.problem("anneal_cost", |p| {
        p.anneal_cost(theta, stream, frac).map_err(to_argmin)
    })?;
    let mut accepted = 0;
    for _ in 0..cfg.candidates {
        let (cand, c) = propose(problem, theta, std, &mut rng, stream, frac)?;
        let delta = c - cost;
        let u: f64 = rng.random();
        let accept = c.is_finite()
            && (delta <= 0.0 || (tau > 0.0 && u < (-cfg.accept_scale * delta / tau).exp()));
        if accept {
            *theta = cand;
            cost = c;
            accepted += 1;
        }
    }
    Ok(PhaseStats { accepted, cost })
}

/// One Gaussian proposal `θ + N(0, std²)` (projected back onto the parameterisation) and its
/// annealing cost on `stream` at progress `frac`.
pub(crate) fn propose<O: Anneal + Differentiable>(
    problem: &mut Problem<O>,
    theta: &[f64],
    std: f64,
    rng: &mut Xoshiro256PlusPlus,
    stream: u64,
    frac: f64,
) -> Result<(Vec<f64>, f64), ArgminError> {
    let mut cand: Vec<f64> = theta
        .iter()
        .map(|t| t + std * rng.sample::<f64, _>(StandardNormal))
        .collect();
    problem.problem("project", |p| {
        p.project(&mut cand);
        Ok(())
    })?;
    let c = problem.problem("anneal_cost", |p| {
        p.anneal_cost(&cand, stream, frac).map_err(to_argmin)
    })?;
    Ok((cand, c))
}

/// Pure simulated annealing.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimulatedAnnealing {
    config: AnnealingConfig,
    max_iters: u64,
    seed: u64,
    accepted: u64,
}

impl SimulatedAnnealing {
    /// A solver for a run of `max_iters` iterations (the schedule's T), seeded by `seed`.
    pub fn new(config: AnnealingConfig, max_iters: u64, seed: u64) -> Result<Self> {
        config.validate()?;
        if max_iters == 0 {
            return Err(Error::param("iterations", "must be at least 1"));
        }
        Ok(SimulatedAnnealing {
            config,
            max_iters,
            seed,
            accepted: 0,
        })
    }
}

impl<O: Anneal + Differentiable> Solver<O, GradState> for SimulatedAnnealing {
    fn name(&self) -> &str {
        "SimulatedAnnealing"
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        mut state: GradState,
    ) -> Result<(GradState, Option<KV>), ArgminError> {
        let t = state.get_iter();
        let mut theta = state
            .take_param()
            .ok_or_else(|| ArgminError::msg("no initial parameters"))?;
        let frac = t as f64 / self.max_iters as f64;
        let st = metropolis_phase(problem, &mut theta, &self.config, frac, self.seed, t)?;
        self.accepted += st.accepted as u64;
        let mut kv = KV::new();
        kv.insert("mse", KvValue::Float(st.cost));
        kv.insert("accepted", KvValue::Float(self.accepted as f64));
        Ok((state.param(theta).cost(st.cost), Some(kv)))
    }
}
