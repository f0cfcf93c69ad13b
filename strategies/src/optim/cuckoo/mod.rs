//! Cuckoo search with Lévy flights, the second stochastic baseline of the chaotic-splatting
//! paper (Quirce, Iglesias & Gálvez 2017 applied Yang & Deb's algorithm to IFS codes): n
//! nests; each generation every nest lays an egg a Lévy flight away (Mantegna's algorithm,
//! exponent β, steps scaled by the nest's distance to the best nest, as in Yang's reference
//! code) which replaces it if better, then a fraction `p_a` of every nest's coordinates is
//! abandoned and rebuilt from the difference of two random nests, again kept if better.
//!
//! Value-only (it needs [`Anneal`]'s cost): every comparison of a generation is made on the
//! generation's own random stream, the nests re-scored on it first, so a generation costs
//! 3n renders (the log's `evals`). The reported θ is the best nest.
//!
//! ## References
//! - X.-S. Yang, S. Deb, *Cuckoo search via Lévy flights*, NaBIC 2009.
//! - J. Quirce, A. Iglesias, A. Gálvez, *Cuckoo search algorithm approach for the IFS inverse
//!   problem of 2D binary fractal images*, ICSI 2017.
//! - R. N. Mantegna, *Fast, accurate algorithm for numerical simulation of Lévy stable
//!   stochastic processes*, Phys. Rev. E 49 (1994).

use argmin::core::{Error as ArgminError, KV, KvValue, Problem, Solver, State};
use rand::{Rng, SeedableRng};
use rand_distr::StandardNormal;
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};

use crate::driver::{Differentiable, GradState, Params, to_argmin};
use crate::error::{Error, Result};
use crate::optim::annealing::Anneal;

/// Hyper-parameters of cuckoo search (defaults: Yang & Deb's).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CuckooConfig {
    /// Nests n (each generation scores 3n codes).
    pub nests: usize,
    /// Discovery rate p_a: the share of coordinates abandoned per generation.
    pub discovery: f64,
    /// Lévy exponent β ∈ (0, 2].
    pub beta: f64,
    /// Scale of a Lévy step relative to the nest's distance to the best nest.
    pub step: f64,
    /// Spread of the first nests around the start (raw θ).
    pub sigma: f64,
}

impl Default for CuckooConfig {
    fn default() -> Self {
        CuckooConfig {
            nests: 15,
            discovery: 0.25,
            beta: 1.5,
            step: 0.01,
            sigma: 0.1,
        }
    }
}

impl Params for CuckooConfig {
    const KIND: &'static str = "cuckoo";
    const STATS: &'static [&'static str] = &["mse", "evals"];
    /// Checks every field; the error names the one to change.
    fn validate(&self) -> Result<()> {
        if self.nests < 3 {
            return Err(Error::param(
                "nests",
                format!("must be at least 3, got {}", self.nests),
            ));
        }
        if !(0.0..=1.0).contains(&self.discovery) {
            return Err(Error::param(
                "discovery",
                format!("must be in [0, 1], got {}", self.discovery),
            ));
        }
        if !(self.beta > 0.0 && self.beta <= 2.0) {
            return Err(Error::param(
                "beta",
                format!("must be in (0, 2], got {}", self.beta),
            ));
        }
        for (name, v) in [("step", self.step), ("sigma", self.sigma)] {
            if !(v.is_finite() && v > 0.0) {
                return Err(Error::param(name, format!("must be > 0, got {v}")));
            }
        }
        Ok(())
    }
}

/// Cuckoo search (see the module documentation).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Cuckoo {
    config: CuckooConfig,
    max_iters: u64,
    seed: u64,
    nests: Vec<Vec<f64>>,
    evals: u64,
}

/// Keeps the search's draws apart from the other uses of the run's seed.
const SALT: u64 = 0x4355_434b_4f4f_5f31;

/// Mantegna's σ_u for exponent β.
fn mantegna_sigma(beta: f64) -> f64 {
    let num = gamma(1.0 + beta) * (std::f64::consts::PI * beta / 2.0).sin();
    let den = gamma((1.0 + beta) / 2.0) * beta * 2f64.powf((beta - 1.0) / 2.0);
    (num / den).powf(1.0 / beta)
}

/// Γ(x) for x > 0 (Lanczos, g = 7, nine coefficients: ~15 digits).
fn gamma(x: f64) -> f64 {
    const G: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    if x < 0.5 {
        std::f64::consts::PI / ((std::f64::consts::PI * x).sin() * gamma(1.0 - x))
    } else {
        let x = x - 1.0;
        let t = x + 7.5;
        let a = G[1..]
            .iter()
            .enumerate()
            .fold(G[0], |a, (i, g)| a + g / (x + i as f64 + 1.0));
        (2.0 * std::f64::consts::PI).sqrt() * t.powf(x + 0.5) * (-t).exp() * a
    }
}

impl Cuckoo {
    /// A solver for a run of `max_iters` generations, seeded by `seed`.
    pub fn new(config: CuckooConfig, max_iters: u64, seed: u64) -> Result<Self> {
        config.validate()?;
        if max_iters == 0 {
            return Err(Error::param("iterations", "must be at least 1"));
        }
        Ok(Cuckoo {
            config,
            max_iters,
            seed,
            nests: Vec::new(),
            evals: 0,
        })
    }
}

impl<O: Anneal + Differentiable> Solver<O, GradState> for Cuckoo {
    fn name(&self) -> &str {
        "CuckooSearch"
    }

    // Nest i, its cost and its egg go together by index, as in the algorithm's statement.
    #[allow(clippy::needless_range_loop)]
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
        if self.nests.is_empty() {
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(ifslab::chaos::mix_seed(
                self.seed ^ SALT,
                u64::MAX,
            ));
            self.nests.push(start.clone());
            for _ in 1..self.config.nests {
                let mut x: Vec<f64> = start
                    .iter()
                    .map(|s| s + self.config.sigma * rng.sample::<f64, _>(StandardNormal))
                    .collect();
                project(problem, &mut x)?;
                self.nests.push(x);
            }
        }
        let frac = t as f64 / self.max_iters as f64;
        let mut rng =
            Xoshiro256PlusPlus::seed_from_u64(ifslab::chaos::mix_seed(self.seed ^ SALT, t));
        let mut evals = 0u64;
        let mut cost_of = |problem: &mut Problem<O>, x: &[f64]| {
            evals += 1;
            problem
                .problem("anneal_cost", |p| {
                    p.anneal_cost(x, t, frac).map_err(to_argmin)
                })
                .map(|c| if c.is_finite() { c } else { f64::INFINITY })
        };
        let n = self.nests.len();
        let mut costs = Vec::with_capacity(n);
        for x in &self.nests {
            costs.push(cost_of(problem, x)?);
        }
        let best_of = |costs: &[f64]| {
            (0..costs.len())
                .min_by(|&a, &b| costs[a].total_cmp(&costs[b]).then(a.cmp(&b)))
                .expect("at least three nests")
        };
        // Lévy flights, scaled by the distance to the best nest.
        let best = self.nests[best_of(&costs)].clone();
        let sigma_u = mantegna_sigma(self.config.beta);
        for i in 0..n {
            let mut egg: Vec<f64> = self.nests[i]
                .iter()
                .zip(&best)
                .map(|(x, b)| {
                    let u: f64 = rng.sample::<f64, _>(StandardNormal) * sigma_u;
                    let v: f64 = rng.sample(StandardNormal);
                    let levy = u / v.abs().powf(1.0 / self.config.beta);
                    let step = self.config.step * levy * (x - b);
                    x + step * rng.sample::<f64, _>(StandardNormal)
                })
                .collect();
            project(problem, &mut egg)?;
            let c = cost_of(problem, &egg)?;
            if c < costs[i] {
                self.nests[i] = egg;
                costs[i] = c;
            }
        }
        // Discovery: a share p_a of the coordinates rebuilt from two random nests.
        for i in 0..n {
            let (a, b) = (rng.random_range(0..n), rng.random_range(0..n));
            let r: f64 = rng.random();
            let mut egg: Vec<f64> = (0..self.nests[i].len())
                .map(|j| {
                    let x = self.nests[i][j];
                    if rng.random::<f64>() < self.config.discovery {
                        x + r * (self.nests[a][j] - self.nests[b][j])
                    } else {
                        x
                    }
                })
                .collect();
            project(problem, &mut egg)?;
            let c = cost_of(problem, &egg)?;
            if c < costs[i] {
                self.nests[i] = egg;
                costs[i] = c;
            }
        }
        let b = best_of(&costs);
        self.evals += evals;
        let mut kv = KV::new();
        kv.insert("mse", KvValue::Float(costs[b]));
        kv.insert("evals", KvValue::Float(self.evals as f64));
        Ok((state.param(self.nests[b].clone()).cost(costs[b]), Some(kv)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optim::testing::{NoisySphere, run as run_solver};

    const OPT: [f64; 4] = [1.0, -2.0, 0.5, 3.0];

    fn run(seed: u64, iters: u64) -> (Vec<f64>, f64, Cuckoo) {
        let cfg = CuckooConfig {
            sigma: 2.0,
            ..CuckooConfig::default()
        };
        let problem = NoisySphere {
            opt: OPT.to_vec(),
            noise: 1e-4,
        };
        run_solver(
            problem,
            Cuckoo::new(cfg, iters, seed).unwrap(),
            vec![0.0; 4],
            iters,
        )
    }

    #[test]
    fn gamma_and_mantegna_match_known_values() {
        assert!((gamma(5.0) - 24.0).abs() < 1e-10);
        assert!((gamma(0.5) - std::f64::consts::PI.sqrt()).abs() < 1e-12);
        // Yang's reference value for β = 1.5.
        assert!(
            (mantegna_sigma(1.5) - 0.696_574_4).abs() < 1e-6,
            "{}",
            mantegna_sigma(1.5)
        );
    }

    #[test]
    fn finds_the_minimum_of_a_noisy_sphere() {
        let start = NoisySphere::standard()
            .anneal_cost(&[0.0; 4], 0, 0.0)
            .unwrap();
        for seed in [1, 2] {
            let (theta, cost, solver) = run(seed, 300);
            assert!(cost < 1e-3 * start, "seed {seed}: {cost} from {start}");
            for (t, o) in theta.iter().zip(OPT) {
                assert!((t - o).abs() < 0.05, "seed {seed}: {theta:?}");
            }
            assert_eq!(solver.evals, 300 * 3 * 15);
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
                CuckooConfig {
                    nests: 2,
                    ..Default::default()
                },
                "nests",
            ),
            (
                CuckooConfig {
                    discovery: 1.5,
                    ..Default::default()
                },
                "discovery",
            ),
            (
                CuckooConfig {
                    beta: 0.0,
                    ..Default::default()
                },
                "beta",
            ),
            (
                CuckooConfig {
                    step: -1.0,
                    ..Default::default()
                },
                "step",
            ),
        ] {
            let e = cfg.validate().unwrap_err().to_string();
            assert!(e.contains(field), "{e}");
        }
    }
}
