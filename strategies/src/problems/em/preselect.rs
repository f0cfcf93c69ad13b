//! Pre-selection: a pool of random starts, each trained briefly at shallow depth; the best
//! goes on to the full run.
//!
//! EM from a random start often settles where the maps do not reproduce the data's
//! self-similarity. The paper trains each candidate for 100 iterations at depth 3 and keeps
//! the one with the highest mean depth Σ d·v_d. ifslab's default differs in three ways,
//! each switchable back to the paper's choice (`paper_repro/ifs_em/README.md`): the
//! re-orientation is what makes the Sierpiński triangle converge, the curriculum and the
//! selection by likelihood together what makes a random 4-map code converge (8/8 seeds
//! against 1/8), at a cost on the Heighway dragon:
//!
//! - **Curriculum** ([`EmConfig::curriculum`]): the iterations are spread over depths
//!   1, 2, …, `preselect_depth` in turn. At depth 1 the model is a constrained Gaussian
//!   mixture that places the K pieces; each deeper stage then only has to orient and refine
//!   them, instead of seeking the pieces' places and orientations at once.
//! - **Re-orientation** ([`crate::problems::em::reorient`]) at the start of every stage from depth 2 on
//!   (half-way through the single stage when the curriculum is off).
//! - **Selection by likelihood** ([`PreselectBy::LogLikelihood`]): the mean log-likelihood of
//!   a fixed set of evaluation points: at depth 3 most candidates reach a mean depth near
//!   3, right or wrong (the paper suspects mean depth is a poor criterion for Koch, K = 4).
//!
//! Candidates are trained in parallel, each from its own seeded generators.
//!
//! ## References
//! - P. Bloem and S. de Rooij, *An Expectation-Maximization Algorithm for the Fractal
//!   Inverse Problem*, arXiv:1706.03149, 2017 (pre-selection by mean depth, Fig. 5b).

use nalgebra::DMatrix;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use ifslab::chaos::{mix_seed, trajectory_rng};

use crate::error::{Error, Result};
use crate::problems::em::config::{EmConfig, PreselectBy, stream};
use crate::problems::em::data::PointSet;
use crate::problems::em::init::{normalising_post, random_model};
use crate::problems::em::model::EmModel;
use crate::problems::em::reorient::reorient;
use crate::problems::em::train::{Schedule, train};

/// One pre-selection candidate's outcome.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Candidate {
    /// Index in the pool.
    pub index: usize,
    /// Mean depth after the brief training (−∞ when the candidate failed).
    pub mean_depth: f64,
    /// Mean log-likelihood of the evaluation points after the brief training (nats per
    /// point; NaN when the candidate failed).
    pub log_likelihood: f64,
    /// Components the re-orientation search turned over the candidate's training.
    #[serde(default)]
    pub reoriented: usize,
    /// Why it failed, if it did.
    pub failure: Option<String>,
}

impl Candidate {
    fn score(&self, by: PreselectBy) -> f64 {
        let s = match by {
            PreselectBy::LogLikelihood => self.log_likelihood,
            PreselectBy::MeanDepth => self.mean_depth,
        };
        if s.is_nan() { f64::NEG_INFINITY } else { s }
    }
}

/// Iterations of curriculum stage `stage` (1-based) of `stages`: the total spread evenly,
/// summing to exactly `total`.
fn stage_iterations(total: usize, stage: usize, stages: usize) -> usize {
    total * stage / stages - total * (stage - 1) / stages
}

/// Trains one candidate (see the module docs).
fn train_candidate(
    data: &PointSet,
    eval: &PointSet,
    rotations: &[DMatrix<f64>],
    cfg: &EmConfig,
    p: usize,
) -> Result<(EmModel, usize)> {
    let depth = cfg.preselect_depth.min(cfg.depth);
    let mut rng = trajectory_rng(mix_seed(cfg.seed, stream::INIT), p as u64);
    let first = if cfg.curriculum { 1 } else { depth };
    let mut model = random_model(
        cfg.components,
        first,
        cfg.init_scale,
        normalising_post(data),
        &mut rng,
    )?;
    let stages = depth - first + 1;
    let mut reoriented = 0;
    let mut search = |model: EmModel| -> Result<EmModel> {
        let (m, turned) = reorient(&model, eval, rotations)?;
        reoriented += turned.len();
        Ok(m)
    };
    let run = |model: EmModel, iterations: usize, part: u64| -> Result<EmModel> {
        let schedule = Schedule {
            iterations,
            batch_size: cfg.batch_size,
            stream: mix_seed(
                mix_seed(mix_seed(cfg.seed, stream::PRESELECT), p as u64),
                part,
            ),
            heldout: None,
            reorient: None,
        };
        Ok(train(model, data, &cfg.mstep, &schedule, &mut |_| {})?.0)
    };
    for (i, d) in (first..=depth).enumerate() {
        if d != model.depth() {
            model = model.with_depth(d);
        }
        let n = stage_iterations(cfg.preselect_iterations, i + 1, stages);
        let searching = d >= 2 && !rotations.is_empty();
        if searching && stages == 1 {
            // One stage (the paper's schedule): search half-way, once the start has settled.
            model = run(model, n / 2, 2 * d as u64)?;
            model = search(model)?;
            model = run(model, n - n / 2, 2 * d as u64 + 1)?;
        } else {
            if searching {
                model = search(model)?;
            }
            model = run(model, n, 2 * d as u64)?;
        }
    }
    Ok((model, reoriented))
}

/// Trains `cfg.pool` random starts (see the module docs) and returns the winner by
/// `cfg.preselect_by` (ties: the lowest index), all candidates' scores, and the winner's
/// index. `eval` holds the points that score candidates and re-orientations; `rotations`
/// is the re-orientation set (empty: no search).
pub fn preselect(
    data: &PointSet,
    eval: &PointSet,
    rotations: &[DMatrix<f64>],
    cfg: &EmConfig,
) -> Result<(EmModel, Vec<Candidate>, usize)> {
    let results: Vec<(Option<EmModel>, Candidate)> = (0..cfg.pool)
        .into_par_iter()
        .map(|p| {
            let run = || -> Result<(EmModel, usize, f64)> {
                let (model, reoriented) = train_candidate(data, eval, rotations, cfg, p)?;
                let ll = model.mean_log_likelihood(eval)?;
                Ok((model, reoriented, ll))
            };
            match run() {
                Ok((m, reoriented, ll)) => {
                    let c = Candidate {
                        index: p,
                        mean_depth: m.mean_depth(),
                        log_likelihood: ll,
                        reoriented,
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
                        reoriented: 0,
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
            a.1.score(cfg.preselect_by)
                .total_cmp(&b.1.score(cfg.preselect_by))
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stages_share_the_iterations_exactly() {
        for total in [0, 1, 7, 100] {
            for stages in 1..5 {
                let sum: usize = (1..=stages)
                    .map(|s| stage_iterations(total, s, stages))
                    .sum();
                assert_eq!(sum, total);
            }
        }
        assert_eq!(
            (1..=3)
                .map(|s| stage_iterations(100, s, 3))
                .collect::<Vec<_>>(),
            vec![33, 33, 34]
        );
    }
}
