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
//! The paper's phase ([`PhaseAcceptance::Proposals`]) judges each jump by the *raw* cost of
//! the jumped-to code, before any refinement, against a code Adam has just refined: almost
//! every jump looks worse, the Metropolis rule then accepts on temperature alone (a random
//! walk), and the Adam iterations that follow start over from a worse code — the loss curve
//! rises at every phase. [`PhaseAcceptance::Refined`] is basin hopping instead: the jump is
//! judged *after* Adam has refined it, at the next phase, against the code it jumped from, on
//! fixed random streams; a refined jump that is worse is undone.
//!
//! ## References
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point Splatting*.

use argmin::core::{Error as ArgminError, KV, KvValue, Problem, Solver, State};
use serde::{Deserialize, Serialize};

use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;

use crate::driver::{Differentiable, GradState, Params, to_argmin};
use crate::error::{Error, Result};
use crate::optim::adam::{Adam, AdamConfig, adam_iteration};
use crate::optim::annealing::{Anneal, AnnealingConfig, PhaseStats, metropolis_phase, propose};

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
    /// What a phase's Metropolis test compares (paper: the raw proposals). Left out of a
    /// written config when it is the paper's, so configs (and the sweep run ids hashed from
    /// them) written before the field existed keep their text.
    #[serde(skip_serializing_if = "PhaseAcceptance::is_paper")]
    pub acceptance: PhaseAcceptance,
}

/// What an annealing phase's Metropolis test compares.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PhaseAcceptance {
    /// The paper: `candidates` chained proposals from the current θ, each accepted or not on
    /// its own raw cost (`exp(−scale·ΔMSE/τ)`), then Adam continues from where the chain
    /// ended.
    #[default]
    Proposals,
    /// Basin hopping (Wales & Doye 1997): a phase first compares the θ Adam has refined since
    /// the last phase with the *anchor* (the refined θ that phase jumped from) on the fixed
    /// [`ACCEPT_STREAMS`], accepting a worse one with probability `exp(−scale·r/τ)`, `r` its
    /// relative cost increase — a rejected one is replaced by the anchor —, then jumps from
    /// the anchor to the best of `candidates` independent proposals (raw cost, the phase's
    /// stream). The last phase of the run only accepts or undoes; the refinement after it
    /// starts from the anchor.
    Refined,
}

impl PhaseAcceptance {
    /// Whether this is the paper's rule (the default).
    pub fn is_paper(&self) -> bool {
        *self == PhaseAcceptance::Proposals
    }
}

/// The random streams on which [`PhaseAcceptance::Refined`] compares refined codes: fixed for
/// the whole run, so two phases' costs differ only by the codes (and apart from the streams
/// of gradient iterations, phases and the final selection).
pub const ACCEPT_STREAMS: [u64; 2] = [u64::MAX - 11, u64::MAX - 12];

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
            acceptance: PhaseAcceptance::Proposals,
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
    /// [`PhaseAcceptance::Refined`]: the θ the last jump started from.
    #[serde(default)]
    anchor: Option<Vec<f64>>,
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
            anchor: None,
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

    /// Whether `t` is the run's last phase.
    fn is_last_phase(&self, t: u64) -> bool {
        self.anneals_at(t) && (t + 1..self.max_iters).all(|u| !self.anneals_at(u))
    }

    /// A basin-hopping phase ([`PhaseAcceptance::Refined`]) at iteration `t`: accept or undo
    /// the refinement since the last phase, then (unless it is the last phase) jump.
    fn basin_hop<O: Anneal + Differentiable>(
        &mut self,
        problem: &mut Problem<O>,
        theta: &mut Vec<f64>,
        t: u64,
        frac: f64,
    ) -> Result<PhaseStats, ArgminError> {
        let cfg = &self.config.annealing;
        let mut rng =
            Xoshiro256PlusPlus::seed_from_u64(ifslab::chaos::mix_seed(self.seed, t | (1 << 61)));
        let cost_of = |problem: &mut Problem<O>, th: &[f64]| {
            problem.problem("anneal_cost", |p| {
                let mut sum = 0.0;
                for s in ACCEPT_STREAMS {
                    sum += p.anneal_cost(th, s, frac).map_err(to_argmin)?;
                }
                Ok(sum / ACCEPT_STREAMS.len() as f64)
            })
        };
        let mut accepted = 0;
        let mut cost = cost_of(problem, theta)?;
        if let Some(anchor) = self.anchor.take() {
            let anchor_cost = cost_of(problem, &anchor)?;
            let tau = cfg.temperature * (1.0 - frac).max(0.0);
            let rel = (cost - anchor_cost) / anchor_cost.abs().max(1e-12);
            let u: f64 = rng.random();
            let keep = cost.is_finite()
                && (rel <= 0.0 || (tau > 0.0 && u < (-cfg.accept_scale * rel / tau).exp()));
            if keep {
                accepted += 1;
            } else {
                *theta = anchor;
                cost = anchor_cost;
            }
        }
        if !self.is_last_phase(t) {
            self.anchor = Some(theta.clone());
            let std = cfg.proposal.std(cfg.noise * (1.0 - frac).max(0.0));
            let stream = t | (1 << 62);
            let mut best: Option<(f64, Vec<f64>)> = None;
            for _ in 0..cfg.candidates {
                let (cand, c) = propose(problem, theta, std, &mut rng, stream, frac)?;
                if c.is_finite() && best.as_ref().is_none_or(|(b, _)| c < *b) {
                    best = Some((c, cand));
                }
            }
            if let Some((_, cand)) = best {
                *theta = cand;
            }
        }
        Ok(PhaseStats { accepted, cost })
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
            let st = match self.config.acceptance {
                PhaseAcceptance::Proposals => metropolis_phase(
                    problem,
                    &mut theta,
                    &self.config.annealing,
                    frac,
                    self.seed,
                    stream,
                )?,
                PhaseAcceptance::Refined => self.basin_hop(problem, &mut theta, t, frac)?,
            };
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
    use crate::driver::Evaluation;

    /// Σ x²/16 − ½·cos(2πx): a well at every integer, the deepest at 0 (−½ per coordinate).
    struct Wells;

    fn wells(x: &[f64]) -> f64 {
        x.iter()
            .map(|v| v * v / 16.0 - 0.5 * (std::f64::consts::TAU * v).cos())
            .sum()
    }

    impl Differentiable for Wells {
        fn evaluate(&self, x: &[f64], _iter: u64) -> Result<Evaluation> {
            let grad = x
                .iter()
                .map(|v| v / 8.0 + std::f64::consts::PI * (std::f64::consts::TAU * v).sin())
                .collect();
            Ok(Evaluation {
                loss: wells(x),
                grad,
                terms: vec![],
            })
        }
    }

    impl Anneal for Wells {
        fn anneal_cost(&self, x: &[f64], _stream: u64, _frac: f64) -> Result<f64> {
            Ok(wells(x))
        }
    }

    /// Runs the hybrid on [`Wells`] from (3, −3) step by step: the final θ and the cost each
    /// phase reported.
    fn hop(acceptance: PhaseAcceptance, anneal: bool) -> (Vec<f64>, Vec<f64>) {
        let iters = 400;
        let cfg = HybridConfig {
            adam: AdamConfig {
                lr: 0.05,
                ..AdamConfig::default()
            },
            annealing: AnnealingConfig {
                noise: 1.0,
                candidates: 10,
                temperature: 1e-3,
                ..AnnealingConfig::default()
            },
            anneal_every: 40,
            anneal_fraction: if anneal { 0.8 } else { 0.0 },
            acceptance,
        };
        let mut solver = Hybrid::new(cfg, iters, 5).unwrap();
        let mut problem = Problem::new(Wells);
        let mut state = GradState::new().param(vec![3.0, -3.0]);
        let mut phase_costs = vec![];
        for _ in 0..iters {
            let (next, kv) = solver.next_iter(&mut problem, state).unwrap();
            if let Some(KvValue::Float(c)) = kv.and_then(|kv| kv.get("anneal_mse").cloned()) {
                phase_costs.push(c);
            }
            state = next;
            state.increment_iter();
        }
        (state.take_param().unwrap(), phase_costs)
    }

    #[test]
    fn basin_hopping_undoes_worse_jumps_and_finds_a_deeper_well() {
        let (adam, _) = hop(PhaseAcceptance::Refined, false);
        let (hopped, costs) = hop(PhaseAcceptance::Refined, true);
        // Adam alone stays in the start's wells (near ±3).
        assert!(
            (adam[0] - 3.0).abs() < 0.1 && (adam[1] + 3.0).abs() < 0.1,
            "{adam:?}"
        );
        // Each phase keeps the better of the refined jump and its anchor (τ ≈ 0): the costs
        // the phases report never rise, and the run ends in deeper wells.
        assert_eq!(costs.len(), 8);
        assert!(costs.windows(2).all(|w| w[1] <= w[0] + 1e-12), "{costs:?}");
        assert!(wells(&hopped) < -0.5, "{hopped:?} {costs:?}");
    }

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
