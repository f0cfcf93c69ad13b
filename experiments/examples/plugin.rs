//! Extending ifslab from outside its crates: a strategy and a map family defined here, made
//! known with `ifslab_strategies::plugins`, then named in a config and run through
//! [`RunConfig::run`] — the call behind `ifslab run` and sweeps — with checkpoints, the log
//! and the summary like any built-in one.
//!
//! - `random_search`: a value-only strategy — each iteration tries a few random steps of θ
//!   and keeps the best if it lowers the cost (the problem's `anneal_cost`, no gradient);
//! - `diagonal`: maps `x ↦ diag(a, d)·x + b` (axis-aligned scalings), θ = (a, d, bx, by) per
//!   map, drawn and differentiated by the splat as affine maps.
//!
//! `cargo run --release -p ifslab-experiments --example plugin [OUT]` inverts Sierpiński's
//! triangle (which diagonal maps can express) with both; `experiments/tests/plugin.rs` runs
//! it in the test command.

use std::path::{Path, PathBuf};

use argmin::core::{Error as ArgminError, KV, KvValue, Problem, Solver, State};
use ifslab::model::Affine2;
use ifslab_experiments::progress::Silent;
use ifslab_experiments::runs::{RunConfig, RunReport};
use ifslab_strategies::driver::{Differentiable, GradState, Params, RunSpec};
use ifslab_strategies::error::{Error, Result};
use ifslab_strategies::optim::annealing::Anneal;
use ifslab_strategies::plugins::{
    ModelEntry, StrategyEntry, StrategyPlugin, StrategyProblem, register_model, register_strategy,
};
use ifslab_strategies::problems::image::ImageModel;
use rand::Rng;
use serde::{Deserialize, Serialize};

// ---- A strategy -------------------------------------------------------------------------

/// `random_search`'s hyper-parameters: `[strategy] kind = "random_search"`, `step`,
/// `candidates`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RandomSearchConfig {
    /// Largest change of one θ entry in a step (uniform in ±`step`).
    pub step: f64,
    /// Steps tried per iteration.
    pub candidates: usize,
}

impl Default for RandomSearchConfig {
    fn default() -> Self {
        RandomSearchConfig {
            step: 0.05,
            candidates: 4,
        }
    }
}

impl Params for RandomSearchConfig {
    const KIND: &'static str = "random_search";
    const STATS: &'static [&'static str] = &["accepted"];
    fn validate(&self) -> Result<()> {
        if !(self.step.is_finite() && self.step > 0.0) {
            return Err(Error::param(
                "step",
                format!("must be > 0, got {}", self.step),
            ));
        }
        if self.candidates == 0 {
            return Err(Error::param("candidates", "must be at least 1"));
        }
        Ok(())
    }
}

/// The solver: its whole state serialises, so runs checkpoint and resume.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RandomSearch {
    config: RandomSearchConfig,
    iterations: u64,
    seed: u64,
    accepted: u64,
}

impl<P: Differentiable + Anneal> Solver<P, GradState> for RandomSearch {
    fn name(&self) -> &str {
        "RandomSearch"
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<P>,
        mut state: GradState,
    ) -> std::result::Result<(GradState, Option<KV>), ArgminError> {
        let t = state.get_iter();
        let frac = t as f64 / self.iterations.max(1) as f64;
        let mut theta = state
            .take_param()
            .ok_or_else(|| ArgminError::msg("no initial parameters"))?;
        // Every candidate on the same random stream: a fair comparison.
        let cost = |p: &mut Problem<P>, th: &[f64]| {
            p.problem("anneal_cost", |q| {
                q.anneal_cost(th, t, frac)
                    .map_err(|e| ArgminError::msg(e.to_string()))
            })
        };
        let mut best = cost(problem, &theta)?;
        let mut rng = ifslab::chaos::trajectory_rng(self.seed, t);
        for _ in 0..self.config.candidates {
            let mut cand: Vec<f64> = theta
                .iter()
                .map(|v| v + self.config.step * (2.0 * rng.random::<f64>() - 1.0))
                .collect();
            problem.problem("project", |q| {
                q.project(&mut cand);
                Ok(())
            })?;
            let c = cost(problem, &cand)?;
            if c < best {
                (theta, best) = (cand, c);
                self.accepted += 1;
            }
        }
        let mut kv = KV::new();
        kv.insert("accepted", KvValue::Float(self.accepted as f64));
        Ok((state.param(theta).cost(best), Some(kv)))
    }
}

/// The registration: one entry per problem type, built by the registry.
struct RandomSearchPlugin;

impl StrategyPlugin for RandomSearchPlugin {
    fn entry<P: StrategyProblem>() -> StrategyEntry<P> {
        StrategyEntry::new(|c: RandomSearchConfig, run: &RunSpec| {
            Ok(RandomSearch {
                config: c,
                iterations: run.iterations,
                seed: run.seed,
                accepted: 0,
            })
        })
    }
}

// ---- A map family -----------------------------------------------------------------------

/// Axis-aligned scalings: θ = (a, d, bx, by) per map, |a|, |d| ≤ [`DiagonalModel::MAX`].
pub struct DiagonalModel;

impl DiagonalModel {
    /// The largest scale a map may take (a contraction).
    pub const MAX: f64 = 0.95;
}

impl ImageModel for DiagonalModel {
    type Map = Affine2;

    fn decode(&self, theta: &[f64]) -> Result<Vec<Affine2>> {
        if theta.is_empty() || !theta.len().is_multiple_of(4) {
            return Err(Error::InvalidInput(format!(
                "a diagonal code has 4 numbers per map, got {}",
                theta.len()
            )));
        }
        Ok(theta
            .chunks_exact(4)
            .map(|p| Affine2::new(p[0], 0.0, 0.0, p[1], p[2], p[3]))
            .collect())
    }

    /// The affine gradient is in the order a b c d e f; θ keeps a, d, e, f.
    fn backward(&self, _theta: &[f64], grad_params: &[f64]) -> Result<Vec<f64>> {
        Ok(grad_params
            .chunks_exact(6)
            .flat_map(|g| [g[0], g[3], g[4], g[5]])
            .collect())
    }

    fn project(&self, theta: &mut [f64]) {
        for p in theta.chunks_exact_mut(4) {
            p[0] = p[0].clamp(-Self::MAX, Self::MAX);
            p[1] = p[1].clamp(-Self::MAX, Self::MAX);
        }
    }

    fn encode(&self, start: &[Affine2]) -> Result<Vec<f64>> {
        let mut theta: Vec<f64> = start
            .iter()
            .flat_map(|m| [m.m[(0, 0)], m.m[(1, 1)], m.b[0], m.b[1]])
            .collect();
        ImageModel::project(self, &mut theta);
        Ok(theta)
    }
}

// ---- Using them -------------------------------------------------------------------------

/// Registers both (once per process; a second call is refused by the registries).
pub fn register() -> Result<()> {
    register_strategy::<RandomSearchPlugin>()?;
    register_model(ModelEntry {
        name: "diagonal",
        about: "axis-aligned scalings diag(a, d)·x + b, θ = (a, d, bx, by) per map",
        build: |_| Box::new(DiagonalModel),
    })
}

/// The config that names them: Sierpiński's triangle, 32², three diagonal maps from a
/// random start, 60 iterations of `random_search`.
pub const CONFIG: &str = r#"
seed = 3
iterations = 60
checkpoint_every = 20

[target]
code = "sierpinski"
size = 32

[model]
family = "diagonal"
maps = 3
init = "random"

[generator]
trajectories = 200
length = 60

[loss]
lpips_weight = 0.0

[strategy]
kind = "random_search"
step = 0.05
candidates = 4
"#;

/// Registers the plugins and runs [`CONFIG`] into `dir` through the library's run call.
pub fn run(dir: &Path) -> anyhow::Result<RunReport> {
    register()?;
    let cfg = RunConfig::from_toml(CONFIG, &dir.join("plugin.toml"))?;
    Ok(cfg.run(dir, false, Box::new(Silent))?)
}

#[allow(dead_code)] // `experiments/tests/plugin.rs` includes this file for `run`.
fn main() -> anyhow::Result<()> {
    let dir = std::env::args()
        .nth(1)
        .map_or_else(|| PathBuf::from("out/plugin"), PathBuf::from);
    let report = run(&dir)?;
    println!("{}: {}", dir.display(), report.headline);
    Ok(())
}
