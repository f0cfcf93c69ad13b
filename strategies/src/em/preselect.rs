//! Pre-selection: a pool of random starts, each trained briefly at a shallow depth; the one
//! with the highest mean depth Σ d·v_d goes on to the full run.
//!
//! EM from a random start often settles where most responsibility stays on shallow codes
//! (the maps do not reproduce the data's self-similarity, so deep Gaussians explain it
//! badly). The mean depth after a few cheap iterations at depth 3 (40 codes for K = 3) is a
//! good predictor of which start will reach the paper's convergence criterion. Candidates
//! are trained in parallel, each from its own seeded generators.
//!
//! ## References
//! - P. Bloem and S. de Rooij, *An Expectation-Maximization Algorithm for the Fractal
//!   Inverse Problem*, arXiv:1706.03149, 2017 (pre-selection by mean depth, Fig. 5b).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use ifslab::chaos::{mix_seed, trajectory_rng};

use crate::em::data::PointSet;
use crate::em::driver::{EmConfig, Schedule, stream, train};
use crate::em::init::{normalising_post, random_model};
use crate::em::model::EmModel;
use crate::error::{Error, Result};

/// One pre-selection candidate's outcome.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// Index in the pool.
    pub index: usize,
    /// Mean depth after the brief training (−∞ when the candidate failed).
    pub mean_depth: f64,
    /// Mean batch log-likelihood of its last iteration (nats per point).
    pub log_likelihood: f64,
    /// Why it failed, if it did.
    pub failure: Option<String>,
}

/// Trains `cfg.pool` random starts for `cfg.preselect_iterations` at `cfg.preselect_depth`
/// and returns the one with the highest mean depth (ties: the lowest index), all candidates'
/// scores, and the winner's index.
pub fn preselect(data: &PointSet, cfg: &EmConfig) -> Result<(EmModel, Vec<Candidate>, usize)> {
    let post = normalising_post(data);
    let results: Vec<(Option<EmModel>, Candidate)> = (0..cfg.pool)
        .into_par_iter()
        .map(|p| {
            let run = || -> Result<(EmModel, f64)> {
                let mut rng = trajectory_rng(mix_seed(cfg.seed, stream::INIT), p as u64);
                let model = random_model(
                    cfg.components,
                    cfg.preselect_depth,
                    cfg.init_scale,
                    post.clone(),
                    &mut rng,
                )?;
                let schedule = Schedule {
                    iterations: cfg.preselect_iterations,
                    batch_size: cfg.batch_size,
                    stream: mix_seed(mix_seed(cfg.seed, stream::PRESELECT), p as u64),
                    heldout: None,
                };
                let (model, hist) = train(model, data, &cfg.mstep, &schedule, &mut |_| {})?;
                let ll = hist.last().map_or(f64::NAN, |r| r.batch_log_likelihood);
                Ok((model, ll))
            };
            match run() {
                Ok((m, ll)) => {
                    let c = Candidate {
                        index: p,
                        mean_depth: m.mean_depth(),
                        log_likelihood: ll,
                        failure: None,
                    };
                    (Some(m), c)
                }
                Err(e) => (
                    None,
                    Candidate {
                        index: p,
                        mean_depth: f64::NEG_INFINITY,
                        log_likelihood: f64::NAN,
                        failure: Some(e.to_string()),
                    },
                ),
            }
        })
        .collect();
    let best = results
        .iter()
        .filter(|(m, _)| m.is_some())
        .max_by(|a, b| {
            a.1.mean_depth
                .total_cmp(&b.1.mean_depth)
                .then(b.1.index.cmp(&a.1.index))
        })
        .map(|(_, c)| c.index);
    let Some(best) = best else {
        let why = results
            .first()
            .and_then(|r| r.1.failure.clone())
            .unwrap_or_default();
        return Err(Error::Numerical(format!(
            "every pre-selection candidate failed (first: {why})"
        )));
    };
    let mut candidates = Vec::with_capacity(results.len());
    let mut winner = None;
    for (m, c) in results {
        if c.index == best {
            winner = m;
        }
        candidates.push(c);
    }
    let winner = winner.expect("the best candidate has a model");
    Ok((winner, candidates, best))
}
