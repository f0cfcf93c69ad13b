//! CMA-ES, the modern evolution strategy the chaotic-splatting paper did not try: a
//! (μ/μ_w, λ) strategy with rank-one and rank-μ covariance updates and cumulative step-size
//! adaptation, with the default constants of Hansen's tutorial.
//!
//! Value-only (it needs [`Anneal`]'s cost): one argmin iteration is one generation of λ
//! candidates, all scored on the generation's own random stream (common random numbers),
//! plus the new mean on the same stream, which is the reported θ. The log's `evals` column
//! counts the λ + 1 renders per generation. A candidate the problem projects (onto its
//! parameterisation's canonical set) is scored where it lands, while the distribution is
//! updated with the step that was drawn.
//!
//! Written on nalgebra rather than with the `cmaes` crate: a run must checkpoint the
//! whole strategy state (mean, covariance, paths, step size) and resume bit-identically
//! one generation at a time under argmin's executor, which that crate's state does not
//! offer (it is not serialisable and owns its loop).
//!
//! ## References
//! - N. Hansen, *The CMA Evolution Strategy: A Tutorial*, arXiv:1604.00772 (2016).

use argmin::core::{Error as ArgminError, KV, KvValue, Problem, Solver, State};
use nalgebra::{DMatrix, DVector, SymmetricEigen};
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};

use crate::driver::{Differentiable, GradState, Params, to_argmin};
use crate::error::{Error, Result};
use crate::optim::annealing::Anneal;

/// Hyper-parameters of CMA-ES (the rest are the tutorial's functions of the dimension).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CmaesConfig {
    /// Initial step size σ₀ on raw θ.
    pub sigma: f64,
    /// Candidates per generation λ; 0: the default 4 + ⌊3 ln n⌋.
    pub population: usize,
}

impl Default for CmaesConfig {
    fn default() -> Self {
        CmaesConfig {
            sigma: 0.1,
            population: 0,
        }
    }
}

impl Params for CmaesConfig {
    const KIND: &'static str = "cmaes";
    const STATS: &'static [&'static str] = &["mse", "evals", "sigma"];
    /// Checks every field; the error names the one to change.
    fn validate(&self) -> Result<()> {
        if !(self.sigma.is_finite() && self.sigma > 0.0) {
            return Err(Error::param(
                "sigma",
                format!("must be > 0, got {}", self.sigma),
            ));
        }
        if self.population == 1 {
            return Err(Error::param(
                "population",
                "must be at least 2 (or 0 for the default)",
            ));
        }
        Ok(())
    }
}

/// The strategy's state between generations (plain vectors, so it checkpoints as JSON).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Distribution_ {
    mean: Vec<f64>,
    sigma: f64,
    /// Covariance C, n × n column by column (symmetric).
    cov: Vec<f64>,
    path_sigma: Vec<f64>,
    path_c: Vec<f64>,
    generation: u64,
}

/// CMA-ES (see the module documentation).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Cmaes {
    config: CmaesConfig,
    max_iters: u64,
    seed: u64,
    state: Option<Distribution_>,
    evals: u64,
}

/// Keeps the sampling draws apart from the other uses of the run's seed.
const SAMPLING_SALT: u64 = 0x434d_415f_4553_5f31;

/// The tutorial's constants for dimension `n` and λ candidates.
struct Constants {
    lambda: usize,
    weights: Vec<f64>,
    mu_eff: f64,
    c_sigma: f64,
    d_sigma: f64,
    c_c: f64,
    c_1: f64,
    c_mu: f64,
    chi_n: f64,
}

impl Constants {
    fn new(n: usize, population: usize) -> Self {
        let nf = n as f64;
        let lambda = if population == 0 {
            4 + (3.0 * nf.ln()).floor() as usize
        } else {
            population
        };
        let mu = lambda / 2;
        let raw: Vec<f64> = (1..=mu)
            .map(|i| ((lambda as f64 + 1.0) / 2.0).ln() - (i as f64).ln())
            .collect();
        let sum: f64 = raw.iter().sum();
        let weights: Vec<f64> = raw.iter().map(|w| w / sum).collect();
        let mu_eff = 1.0 / weights.iter().map(|w| w * w).sum::<f64>();
        let c_sigma = (mu_eff + 2.0) / (nf + mu_eff + 5.0);
        let d_sigma = 1.0 + 2.0 * (((mu_eff - 1.0) / (nf + 1.0)).sqrt() - 1.0).max(0.0) + c_sigma;
        let c_c = (4.0 + mu_eff / nf) / (nf + 4.0 + 2.0 * mu_eff / nf);
        let c_1 = 2.0 / ((nf + 1.3).powi(2) + mu_eff);
        let c_mu =
            (1.0 - c_1).min(2.0 * (mu_eff - 2.0 + 1.0 / mu_eff) / ((nf + 2.0).powi(2) + mu_eff));
        let chi_n = nf.sqrt() * (1.0 - 1.0 / (4.0 * nf) + 1.0 / (21.0 * nf * nf));
        Constants {
            lambda,
            weights,
            mu_eff,
            c_sigma,
            d_sigma,
            c_c,
            c_1,
            c_mu,
            chi_n,
        }
    }
}

impl Cmaes {
    /// A solver for a run of `max_iters` generations, seeded by `seed`.
    pub fn new(config: CmaesConfig, max_iters: u64, seed: u64) -> Result<Self> {
        config.validate()?;
        if max_iters == 0 {
            return Err(Error::param("iterations", "must be at least 1"));
        }
        Ok(Cmaes {
            config,
            max_iters,
            seed,
            state: None,
            evals: 0,
        })
    }
}

impl<O: Anneal + Differentiable> Solver<O, GradState> for Cmaes {
    fn name(&self) -> &str {
        "CMA-ES"
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
        let n = start.len();
        if n == 0 {
            return Err(ArgminError::msg("CMA-ES needs at least one parameter"));
        }
        let sigma0 = self.config.sigma;
        let d = self.state.get_or_insert_with(|| Distribution_ {
            mean: start.clone(),
            sigma: sigma0,
            cov: DMatrix::<f64>::identity(n, n).as_slice().to_vec(),
            path_sigma: vec![0.0; n],
            path_c: vec![0.0; n],
            generation: 0,
        });
        let k = Constants::new(n, self.config.population);
        let frac = t as f64 / self.max_iters as f64;
        let mean = DVector::from_column_slice(&d.mean);
        let cov = DMatrix::from_column_slice(n, n, &d.cov);
        // C = B·diag(λ)·Bᵀ; clamp tiny or negative eigenvalues from round-off.
        let eig = SymmetricEigen::new(cov.clone());
        let sqrt_vals = eig.eigenvalues.map(|v| v.max(1e-20).sqrt());
        let b = &eig.eigenvectors;
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(ifslab::chaos::mix_seed(
            self.seed ^ SAMPLING_SALT,
            t,
        ));
        let mut steps = Vec::with_capacity(k.lambda);
        let mut costs = Vec::with_capacity(k.lambda);
        for _ in 0..k.lambda {
            let z = DVector::<f64>::from_fn(n, |_, _| StandardNormal.sample(&mut rng));
            let y = b * z.component_mul(&sqrt_vals);
            let mut x: Vec<f64> = (&mean + d.sigma * &y).iter().copied().collect();
            problem.problem("project", |p| {
                p.project(&mut x);
                Ok(())
            })?;
            let c = problem.problem("anneal_cost", |p| {
                p.anneal_cost(&x, t, frac).map_err(to_argmin)
            })?;
            costs.push(if c.is_finite() { c } else { f64::INFINITY });
            steps.push(y);
        }
        let mut order: Vec<usize> = (0..k.lambda).collect();
        order.sort_by(|&a, &b| costs[a].total_cmp(&costs[b]).then(a.cmp(&b)));
        // Recombination: the weighted mean of the μ best steps.
        let mut y_w = DVector::<f64>::zeros(n);
        for (w, &i) in k.weights.iter().zip(&order) {
            y_w += *w * &steps[i];
        }
        let new_mean = &mean + d.sigma * &y_w;
        // Step-size path (through C^{-1/2} = B·diag(1/√λ)·Bᵀ) and covariance path.
        let c_inv_sqrt_y = b * (b.transpose() * &y_w).component_div(&sqrt_vals);
        let mut p_sigma = DVector::from_column_slice(&d.path_sigma);
        p_sigma = (1.0 - k.c_sigma) * p_sigma
            + (k.c_sigma * (2.0 - k.c_sigma) * k.mu_eff).sqrt() * c_inv_sqrt_y;
        let g = (d.generation + 1) as f64;
        let h_sigma = p_sigma.norm() / (1.0 - (1.0 - k.c_sigma).powf(2.0 * g)).sqrt()
            < (1.4 + 2.0 / (n as f64 + 1.0)) * k.chi_n;
        let h = if h_sigma { 1.0 } else { 0.0 };
        let mut p_c = DVector::from_column_slice(&d.path_c);
        p_c = (1.0 - k.c_c) * p_c + h * (k.c_c * (2.0 - k.c_c) * k.mu_eff).sqrt() * &y_w;
        let mut rank_mu = DMatrix::<f64>::zeros(n, n);
        for (w, &i) in k.weights.iter().zip(&order) {
            rank_mu += *w * &steps[i] * steps[i].transpose();
        }
        let new_cov = (1.0 - k.c_1 - k.c_mu) * &cov
            + k.c_1 * (&p_c * p_c.transpose() + (1.0 - h) * k.c_c * (2.0 - k.c_c) * &cov)
            + k.c_mu * rank_mu;
        // Keep C exactly symmetric against round-off.
        let new_cov = (&new_cov + new_cov.transpose()) * 0.5;
        let new_sigma =
            d.sigma * ((k.c_sigma / k.d_sigma) * (p_sigma.norm() / k.chi_n - 1.0)).exp();
        if !(new_sigma.is_finite() && new_sigma > 0.0 && new_cov.iter().all(|v| v.is_finite())) {
            return Err(ArgminError::msg(format!(
                "CMA-ES diverged at generation {t} (step size {new_sigma})"
            )));
        }
        let mut theta: Vec<f64> = new_mean.iter().copied().collect();
        problem.problem("project", |p| {
            p.project(&mut theta);
            Ok(())
        })?;
        let cost = problem.problem("anneal_cost", |p| {
            p.anneal_cost(&theta, t, frac).map_err(to_argmin)
        })?;
        self.evals += k.lambda as u64 + 1;
        *d = Distribution_ {
            mean: new_mean.iter().copied().collect(),
            sigma: new_sigma,
            cov: new_cov.as_slice().to_vec(),
            path_sigma: p_sigma.iter().copied().collect(),
            path_c: p_c.iter().copied().collect(),
            generation: d.generation + 1,
        };
        let mut kv = KV::new();
        kv.insert("mse", KvValue::Float(cost));
        kv.insert("evals", KvValue::Float(self.evals as f64));
        kv.insert("sigma", KvValue::Float(new_sigma));
        Ok((state.param(theta).cost(cost), Some(kv)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::driver::Evaluation;
    use crate::optim::testing::run as run_solver;

    /// An ill-conditioned, rotated ellipsoid with stream-dependent noise; minimum at `OPT`.
    struct NoisyEllipsoid;
    const OPT: [f64; 5] = [1.0, -2.0, 0.5, 3.0, -1.0];

    impl Differentiable for NoisyEllipsoid {
        fn evaluate(&self, _theta: &[f64], _iter: u64) -> Result<Evaluation> {
            Err(Error::InvalidInput("value-only test problem".into()))
        }
    }
    impl Anneal for NoisyEllipsoid {
        fn anneal_cost(&self, theta: &[f64], stream: u64, _frac: f64) -> Result<f64> {
            let noise = (ifslab::chaos::mix_seed(stream, 7) % 1000) as f64 * 1e-9;
            let d: Vec<f64> = theta.iter().zip(OPT).map(|(t, o)| t - o).collect();
            // Coupled coordinates (a rotation of the axes) with condition number 10⁴.
            let u: Vec<f64> = (0..d.len())
                .map(|i| d[i] + 0.5 * d[(i + 1) % d.len()])
                .collect();
            Ok(u.iter()
                .enumerate()
                .map(|(i, v)| 10f64.powf(i as f64) * v * v)
                .sum::<f64>()
                + noise)
        }
    }

    fn run(seed: u64, iters: u64) -> (Vec<f64>, f64, Cmaes) {
        let cfg = CmaesConfig {
            sigma: 1.0,
            ..CmaesConfig::default()
        };
        run_solver(
            NoisyEllipsoid,
            Cmaes::new(cfg, iters, seed).unwrap(),
            vec![0.0; 5],
            iters,
        )
    }

    #[test]
    fn finds_the_minimum_of_a_rotated_ill_conditioned_ellipsoid() {
        let start = NoisyEllipsoid.anneal_cost(&[0.0; 5], 0, 0.0).unwrap();
        for seed in [1, 2] {
            let (theta, cost, solver) = run(seed, 400);
            assert!(cost < 1e-6 * start, "seed {seed}: {cost} from {start}");
            for (t, o) in theta.iter().zip(OPT) {
                assert!((t - o).abs() < 1e-2, "seed {seed}: {theta:?}");
            }
            // λ = 4 + ⌊3 ln 5⌋ = 8 candidates and the mean per generation.
            assert_eq!(solver.evals, 400 * 9);
        }
    }

    #[test]
    fn the_same_seed_gives_the_same_run_and_another_seed_another() {
        assert_eq!(run(3, 30).0, run(3, 30).0);
        assert_ne!(run(3, 30).0, run(4, 30).0);
    }

    #[test]
    fn bad_parameters_are_named() {
        let e = CmaesConfig {
            sigma: -1.0,
            ..Default::default()
        }
        .validate()
        .unwrap_err()
        .to_string();
        assert!(e.contains("sigma"), "{e}");
        let e = CmaesConfig {
            population: 1,
            ..Default::default()
        }
        .validate()
        .unwrap_err()
        .to_string();
        assert!(e.contains("population"), "{e}");
    }
}
