//! Evolutionary programming, the stochastic baseline of the chaotic-splatting paper
//! (Nettleton & Garigliano 1994 applied it to IFS codes): a population of μ codes, each of
//! which makes one offspring by Gaussian perturbation with its own self-adapted step sizes,
//! and competitive survival — the 2μ parents and offspring meet q random opponents each,
//! score a win against every one they are not worse than, and the μ with the most wins live
//! on (Fogel's EP).
//!
//! Value-only: it needs [`Anneal`]'s cost and no gradient. One argmin iteration is one
//! generation; every member of it, parents included, is scored on the generation's own
//! random stream (common random numbers, as the annealing steps compare candidates), so a
//! parent that was lucky on an earlier stream has no lasting advantage. A generation costs
//! 2μ renders: the log's `evals` column counts them for budget comparisons with gradient
//! strategies (one forward + backward pass per iteration).
//!
//! The reported θ is the generation's best survivor.
//!
//! ## References
//! - D. J. Nettleton, R. Garigliano, *Evolutionary algorithms and a fractal inverse problem*,
//!   Biosystems 33 (1994).
//! - D. B. Fogel, *An introduction to simulated evolutionary optimization*, IEEE TNN 5 (1994):
//!   the lognormal self-adaptation and the q-tournament.

use argmin::core::{Error as ArgminError, KV, KvValue, Problem, Solver, State};
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};

use crate::driver::{Differentiable, GradState, Params, to_argmin};
use crate::error::{Error, Result};
use crate::optim::annealing::Anneal;

/// Hyper-parameters of evolutionary programming.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EvolutionaryConfig {
    /// Parents μ (each generation scores 2μ codes).
    pub population: usize,
    /// Initial step size of every coordinate (raw θ), and the spread of the first
    /// population around the start.
    pub sigma: f64,
    /// Smallest step size the self-adaptation may reach.
    pub min_sigma: f64,
    /// Opponents q each code meets in the competition.
    pub tournament: usize,
}

impl Default for EvolutionaryConfig {
    fn default() -> Self {
        EvolutionaryConfig {
            population: 16,
            sigma: 0.1,
            min_sigma: 1e-4,
            tournament: 10,
        }
    }
}

impl Params for EvolutionaryConfig {
    const KIND: &'static str = "evolutionary";
    const STATS: &'static [&'static str] = &["mse", "evals", "sigma"];
    /// Checks every field; the error names the one to change.
    fn validate(&self) -> Result<()> {
        if self.population < 2 {
            return Err(Error::param(
                "population",
                format!("must be at least 2, got {}", self.population),
            ));
        }
        if !(self.sigma.is_finite() && self.sigma > 0.0) {
            return Err(Error::param(
                "sigma",
                format!("must be > 0, got {}", self.sigma),
            ));
        }
        if !(self.min_sigma.is_finite() && self.min_sigma > 0.0 && self.min_sigma <= self.sigma) {
            return Err(Error::param(
                "min_sigma",
                format!("must be in (0, sigma], got {}", self.min_sigma),
            ));
        }
        if self.tournament == 0 {
            return Err(Error::param("tournament", "must be at least 1"));
        }
        Ok(())
    }
}

/// One member of the population: a code and its step sizes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Individual {
    /// θ.
    pub theta: Vec<f64>,
    /// Per-coordinate step sizes.
    pub sigma: Vec<f64>,
}

/// Evolutionary programming (see the module documentation).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Evolutionary {
    config: EvolutionaryConfig,
    max_iters: u64,
    seed: u64,
    /// The parents of the next generation (empty before the first).
    population: Vec<Individual>,
    /// Renders so far.
    evals: u64,
}

/// Keeps the mutation draws apart from the other uses of the run's seed.
const MUTATION_SALT: u64 = 0x4550_5f6d_7574_6174;

impl Evolutionary {
    /// A solver for a run of `max_iters` generations, seeded by `seed`.
    pub fn new(config: EvolutionaryConfig, max_iters: u64, seed: u64) -> Result<Self> {
        config.validate()?;
        if max_iters == 0 {
            return Err(Error::param("iterations", "must be at least 1"));
        }
        Ok(Evolutionary {
            config,
            max_iters,
            seed,
            population: Vec::new(),
            evals: 0,
        })
    }

    /// The first population: the start itself and μ − 1 codes spread around it.
    fn seed_population<O: Differentiable>(
        &mut self,
        problem: &mut Problem<O>,
        start: &[f64],
    ) -> std::result::Result<(), ArgminError> {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(ifslab::chaos::mix_seed(
            self.seed ^ MUTATION_SALT,
            u64::MAX,
        ));
        let sigma = vec![self.config.sigma; start.len()];
        let mut pop = vec![Individual {
            theta: start.to_vec(),
            sigma: sigma.clone(),
        }];
        for _ in 1..self.config.population {
            let mut theta: Vec<f64> = start
                .iter()
                .map(|t| t + self.config.sigma * rng.sample::<f64, _>(StandardNormal))
                .collect();
            problem.problem("project", |p| {
                p.project(&mut theta);
                Ok(())
            })?;
            pop.push(Individual {
                theta,
                sigma: sigma.clone(),
            });
        }
        self.population = pop;
        Ok(())
    }
}

/// Each parent's offspring: lognormal self-adaptation of the step sizes (τ′ shared by
/// all coordinates, τ per coordinate, Fogel's/Schwefel's settings), then a Gaussian step.
fn offspring(parent: &Individual, rng: &mut Xoshiro256PlusPlus, min_sigma: f64) -> Individual {
    let n = parent.theta.len().max(1) as f64;
    let tau_shared = 1.0 / (2.0 * n).sqrt();
    let tau = 1.0 / (2.0 * n.sqrt()).sqrt();
    let shared: f64 = rng.sample(StandardNormal);
    let sigma: Vec<f64> = parent
        .sigma
        .iter()
        .map(|s| {
            let z: f64 = rng.sample(StandardNormal);
            (s * (tau_shared * shared + tau * z).exp()).max(min_sigma)
        })
        .collect();
    let theta = parent
        .theta
        .iter()
        .zip(&sigma)
        .map(|(t, s)| t + s * rng.sample::<f64, _>(StandardNormal))
        .collect();
    Individual { theta, sigma }
}

impl<O: Anneal + Differentiable> Solver<O, GradState> for Evolutionary {
    fn name(&self) -> &str {
        "EvolutionaryProgramming"
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        mut state: GradState,
    ) -> std::result::Result<(GradState, Option<KV>), ArgminError> {
        let t = state.get_iter();
        let start = state
            .take_param()
            .ok_or_else(|| ArgminError::msg("no initial parameters"))?;
        if self.population.is_empty() {
            self.seed_population(problem, &start)?;
        }
        let frac = t as f64 / self.max_iters as f64;
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(ifslab::chaos::mix_seed(
            self.seed ^ MUTATION_SALT,
            t,
        ));
        let mut members = self.population.clone();
        for parent in &self.population {
            let mut child = offspring(parent, &mut rng, self.config.min_sigma);
            problem.problem("project", |p| {
                p.project(&mut child.theta);
                Ok(())
            })?;
            members.push(child);
        }
        // Every member on this generation's stream; a code that does not render loses.
        let mut costs = Vec::with_capacity(members.len());
        for m in &members {
            let c = problem.problem("anneal_cost", |p| {
                p.anneal_cost(&m.theta, t, frac).map_err(to_argmin)
            })?;
            costs.push(if c.is_finite() { c } else { f64::INFINITY });
        }
        self.evals += members.len() as u64;
        // q-tournament: a win for every random opponent not better than the member.
        let k = members.len();
        let wins: Vec<usize> = (0..k)
            .map(|i| {
                (0..self.config.tournament)
                    .filter(|_| costs[i] <= costs[rng.random_range(0..k)])
                    .count()
            })
            .collect();
        let mut order: Vec<usize> = (0..k).collect();
        order.sort_by(|&a, &b| {
            wins[b]
                .cmp(&wins[a])
                .then(costs[a].total_cmp(&costs[b]))
                .then(a.cmp(&b))
        });
        order.truncate(self.config.population);
        let best = *order
            .iter()
            .min_by(|&&a, &&b| costs[a].total_cmp(&costs[b]).then(a.cmp(&b)))
            .expect("a population of at least 2");
        let best_cost = costs[best];
        let best_theta = members[best].theta.clone();
        let mean_sigma =
            members[best].sigma.iter().sum::<f64>() / members[best].sigma.len().max(1) as f64;
        self.population = order.into_iter().map(|i| members[i].clone()).collect();
        let mut kv = KV::new();
        kv.insert("mse", KvValue::Float(best_cost));
        kv.insert("evals", KvValue::Float(self.evals as f64));
        kv.insert("sigma", KvValue::Float(mean_sigma));
        Ok((state.param(best_theta).cost(best_cost), Some(kv)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optim::testing::{NoisySphere, run as run_solver};

    const OPT: [f64; 4] = [1.0, -2.0, 0.5, 3.0];

    fn run(seed: u64, iters: u64) -> (Vec<f64>, f64, Evolutionary) {
        let cfg = EvolutionaryConfig {
            sigma: 0.5,
            ..EvolutionaryConfig::default()
        };
        let problem = NoisySphere {
            opt: OPT.to_vec(),
            noise: 1e-3,
        };
        run_solver(
            problem,
            Evolutionary::new(cfg, iters, seed).unwrap(),
            vec![0.0; 4],
            iters,
        )
    }

    #[test]
    fn finds_the_minimum_of_a_noisy_sphere() {
        let start = NoisySphere::standard()
            .anneal_cost(&[0.0; 4], 0, 0.0)
            .unwrap();
        for seed in [1, 2] {
            let (theta, cost, solver) = run(seed, 150);
            assert!(cost < 1e-3 * start, "seed {seed}: {cost} from {start}");
            for (t, o) in theta.iter().zip(OPT) {
                assert!((t - o).abs() < 0.05, "seed {seed}: {theta:?}");
            }
            assert_eq!(solver.evals, 150 * 2 * 16);
        }
    }

    #[test]
    fn the_same_seed_gives_the_same_run_and_another_seed_another() {
        assert_eq!(run(3, 20).0, run(3, 20).0);
        assert_ne!(run(3, 20).0, run(4, 20).0);
    }

    #[test]
    fn bad_parameters_are_named() {
        for (cfg, field) in [
            (
                EvolutionaryConfig {
                    population: 1,
                    ..Default::default()
                },
                "population",
            ),
            (
                EvolutionaryConfig {
                    sigma: f64::NAN,
                    ..Default::default()
                },
                "sigma",
            ),
            (
                EvolutionaryConfig {
                    min_sigma: 1.0,
                    ..Default::default()
                },
                "min_sigma",
            ),
            (
                EvolutionaryConfig {
                    tournament: 0,
                    ..Default::default()
                },
                "tournament",
            ),
        ] {
            let e = cfg.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
    }
}
