//! Particle swarm optimisation (the standard inertia-weight PSO with Clerc & Kennedy's
//! constriction constants): n particles move through θ-space, each pulled towards its own
//! best position and the swarm's best.
//!
//! argmin ships a particle swarm, but it runs on its own population state type and cannot
//! go through this crate's driver (one `GradState` for every strategy, checkpointed as
//! JSON, resumed bit-identically); this is the same algorithm on that state. Value-only (it
//! needs [`Anneal`]'s cost): each generation scores every particle and every personal best
//! on the generation's own random stream (common random numbers), 2n renders (the log's
//! `evals`). The reported θ is the swarm's best.
//!
//! ## References
//! - J. Kennedy, R. Eberhart, *Particle swarm optimization*, ICNN 1995.
//! - M. Clerc, J. Kennedy, *The particle swarm — explosion, stability, and convergence in a
//!   multidimensional complex space*, IEEE TEC 6 (2002).

use argmin::core::{Error as ArgminError, KV, KvValue, Problem, Solver, State};
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};

use crate::driver::{Differentiable, GradState, Params, to_argmin};
use crate::error::{Error, Result};
use crate::optim::annealing::Anneal;

/// Hyper-parameters of the particle swarm (defaults: Clerc & Kennedy's constriction).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SwarmConfig {
    /// Particles n (each generation scores 2n codes).
    pub particles: usize,
    /// Inertia weight w.
    pub inertia: f64,
    /// Pull towards the particle's own best, c₁.
    pub cognitive: f64,
    /// Pull towards the swarm's best, c₂.
    pub social: f64,
    /// Spread of the first particles (and of their first velocities) around the start.
    pub sigma: f64,
}

impl Default for SwarmConfig {
    fn default() -> Self {
        SwarmConfig {
            particles: 20,
            inertia: 0.729_8,
            cognitive: 1.496_18,
            social: 1.496_18,
            sigma: 0.1,
        }
    }
}

impl Params for SwarmConfig {
    const KIND: &'static str = "swarm";
    const STATS: &'static [&'static str] = &["mse", "evals"];
    /// Checks every field; the error names the one to change.
    fn validate(&self) -> Result<()> {
        if self.particles < 2 {
            return Err(Error::param(
                "particles",
                format!("must be at least 2, got {}", self.particles),
            ));
        }
        if !(self.inertia.is_finite() && (0.0..1.0).contains(&self.inertia)) {
            return Err(Error::param(
                "inertia",
                format!("must be in [0, 1), got {}", self.inertia),
            ));
        }
        for (name, v) in [
            ("cognitive", self.cognitive),
            ("social", self.social),
            ("sigma", self.sigma),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::param(name, format!("must be > 0, got {v}")));
            }
        }
        Ok(())
    }
}

/// One particle.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Particle {
    x: Vec<f64>,
    v: Vec<f64>,
    best: Vec<f64>,
}

/// Particle swarm optimisation (see the module documentation).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Swarm {
    config: SwarmConfig,
    max_iters: u64,
    seed: u64,
    particles: Vec<Particle>,
    evals: u64,
}

/// Keeps the swarm's draws apart from the other uses of the run's seed.
const SALT: u64 = 0x5053_4f5f_5357_524d;

impl Swarm {
    /// A solver for a run of `max_iters` generations, seeded by `seed`.
    pub fn new(config: SwarmConfig, max_iters: u64, seed: u64) -> Result<Self> {
        config.validate()?;
        if max_iters == 0 {
            return Err(Error::param("iterations", "must be at least 1"));
        }
        Ok(Swarm {
            config,
            max_iters,
            seed,
            particles: Vec::new(),
            evals: 0,
        })
    }
}

impl<O: Anneal + Differentiable> Solver<O, GradState> for Swarm {
    fn name(&self) -> &str {
        "ParticleSwarm"
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
        let project = |problem: &mut Problem<O>, x: &mut Vec<f64>| {
            problem.problem("project", |p| {
                p.project(x);
                Ok(())
            })
        };
        let sigma = self.config.sigma;
        if self.particles.is_empty() {
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(ifslab::chaos::mix_seed(
                self.seed ^ SALT,
                u64::MAX,
            ));
            for i in 0..self.config.particles {
                let mut x: Vec<f64> = if i == 0 {
                    start.clone()
                } else {
                    start
                        .iter()
                        .map(|s| s + sigma * rng.sample::<f64, _>(StandardNormal))
                        .collect()
                };
                project(problem, &mut x)?;
                let v = (0..x.len())
                    .map(|_| sigma * rng.sample::<f64, _>(StandardNormal))
                    .collect();
                self.particles.push(Particle {
                    best: x.clone(),
                    x,
                    v,
                });
            }
        }
        let frac = t as f64 / self.max_iters as f64;
        let mut evals = 0u64;
        let mut cost_of = |problem: &mut Problem<O>, x: &[f64]| {
            evals += 1;
            problem
                .problem("anneal_cost", |p| {
                    p.anneal_cost(x, t, frac).map_err(to_argmin)
                })
                .map(|c| if c.is_finite() { c } else { f64::INFINITY })
        };
        // Personal bests and positions on this generation's stream.
        let mut best_costs = Vec::with_capacity(self.particles.len());
        for p in &mut self.particles {
            let b = cost_of(problem, &p.best)?;
            let c = cost_of(problem, &p.x)?;
            if c < b {
                p.best = p.x.clone();
                best_costs.push(c);
            } else {
                best_costs.push(b);
            }
        }
        let g = (0..best_costs.len())
            .min_by(|&a, &b| best_costs[a].total_cmp(&best_costs[b]).then(a.cmp(&b)))
            .expect("at least two particles");
        let global = self.particles[g].best.clone();
        let global_cost = best_costs[g];
        self.evals += evals;
        // Move.
        let mut rng =
            Xoshiro256PlusPlus::seed_from_u64(ifslab::chaos::mix_seed(self.seed ^ SALT, t));
        let c = &self.config;
        for p in &mut self.particles {
            for ((x, v), (b, g)) in p.x.iter_mut().zip(&mut p.v).zip(p.best.iter().zip(&global)) {
                let (r1, r2): (f64, f64) = (rng.random(), rng.random());
                *v = c.inertia * *v + c.cognitive * r1 * (b - *x) + c.social * r2 * (g - *x);
                *x += *v;
            }
            project(problem, &mut p.x)?;
        }
        let mut kv = KV::new();
        kv.insert("mse", KvValue::Float(global_cost));
        kv.insert("evals", KvValue::Float(self.evals as f64));
        Ok((state.param(global).cost(global_cost), Some(kv)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optim::testing::{NoisySphere, run as run_solver};

    const OPT: [f64; 4] = [1.0, -2.0, 0.5, 3.0];

    fn run(seed: u64, iters: u64) -> (Vec<f64>, f64, Swarm) {
        let cfg = SwarmConfig {
            sigma: 2.0,
            ..SwarmConfig::default()
        };
        let problem = NoisySphere {
            opt: OPT.to_vec(),
            noise: 1e-4,
        };
        run_solver(
            problem,
            Swarm::new(cfg, iters, seed).unwrap(),
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
            assert_eq!(solver.evals, 150 * 2 * 20);
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
                SwarmConfig {
                    particles: 1,
                    ..Default::default()
                },
                "particles",
            ),
            (
                SwarmConfig {
                    inertia: 1.0,
                    ..Default::default()
                },
                "inertia",
            ),
            (
                SwarmConfig {
                    social: 0.0,
                    ..Default::default()
                },
                "social",
            ),
        ] {
            let e = cfg.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
    }
}
