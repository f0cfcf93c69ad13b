//! The EM loop: minibatch E-step, M-step, records.
//!
//! Each iteration draws N′ points without replacement from the training set (all of them
//! when N′ = 0 or N′ ≥ N), computes the per-code statistics, and applies the closed-form
//! M-step. Every random draw comes from a generator seeded by `(seed, stream, iteration)`,
//! so a run depends on its seed only, never on the thread count.
//!
//! The loop is written here rather than on argmin's `Executor`: EM's state is a model, not
//! a parameter vector with a cost and gradient, and the pool of pre-selection candidates
//! runs many short loops in parallel; an observer callback gives the caller progress bars
//! and logs.
//!
//! ## References
//! - P. Bloem and S. de Rooij, *An Expectation-Maximization Algorithm for the Fractal
//!   Inverse Problem*, arXiv:1706.03149, 2017.

use nalgebra::DMatrix;
use rand::Rng;
use serde::{Deserialize, Serialize};

use ifslab::chaos::trajectory_rng;

use crate::error::{Error, Result};
use crate::problems::em::data::PointSet;
use crate::problems::em::estep::expectation;
use crate::problems::em::model::{CodeTable, EmModel};
use crate::problems::em::mstep::{
    ComponentUpdate, Degeneracy, MStepConfig, maximise, maximise_exact_blocks,
};
use crate::problems::em::reorient::{Reorientation, reorient};
use crate::problems::em::words::{Unwinding, WordMoves, unwind};

/// What one EM step saw and did.
#[derive(Clone, Debug, PartialEq)]
pub struct StepInfo {
    /// Mean log-likelihood per point of the batch under the model *before* the step (nats).
    pub log_likelihood: f64,
    /// Degenerate cases the M-step repaired.
    pub degeneracies: Vec<Degeneracy>,
    /// False when the monotone safeguard rejected the component update (see
    /// [`MStepConfig::monotone`]).
    pub accepted: bool,
}

/// One EM iteration on `batch`: E-step under `model`, closed-form M-step.
pub fn em_step<R: Rng + ?Sized>(
    model: &EmModel,
    batch: &PointSet,
    mstep: &MStepConfig,
    rng: &mut R,
) -> Result<(EmModel, StepInfo)> {
    model.check_points(batch)?;
    if batch.is_empty() {
        return Err(Error::InvalidInput(
            "an EM step needs at least one point".into(),
        ));
    }
    let table = CodeTable::build(model, mstep.update == ComponentUpdate::AllPositions);
    let stats = expectation(model, &table, batch);
    if !stats.log_likelihood.is_finite() {
        return Err(Error::Numerical(format!(
            "the batch log-likelihood is {}; the data may lie extremely far from the model",
            stats.log_likelihood
        )));
    }
    let (mut next, mut degeneracies) = maximise(model, &table, &stats, mstep, rng)?;
    let mut accepted = true;
    if mstep.monotone {
        let after: f64 = next.log_densities(batch)?.iter().sum();
        let tol = 1e-12 * stats.log_likelihood.abs() + 1e-9;
        if after.is_nan() || after < stats.log_likelihood - tol {
            (next, degeneracies) = maximise_exact_blocks(model, &table, &stats)?;
            accepted = false;
        }
    }
    Ok((
        next,
        StepInfo {
            log_likelihood: stats.mean_log_likelihood(),
            degeneracies,
            accepted,
        },
    ))
}

/// One iteration of a training run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IterationRecord {
    /// Iteration index (0-based).
    pub iteration: usize,
    /// Mean log-likelihood per point of the iteration's batch before the update (nats).
    pub batch_log_likelihood: f64,
    /// Mean held-out log-likelihood per point after the update, when evaluated (nats).
    pub heldout_log_likelihood: Option<f64>,
    /// v_D after the update.
    pub deepest_weight: f64,
    /// Σ d·v_d after the update.
    pub mean_depth: f64,
    /// Degenerate cases the M-step repaired.
    pub degeneracies: Vec<Degeneracy>,
    /// False when the monotone safeguard rejected the component update.
    #[serde(default = "yes")]
    pub accepted: bool,
    /// Components the re-orientation search turned after this iteration.
    #[serde(default)]
    pub reoriented: Vec<Reorientation>,
    /// Components the word search replaced after this iteration.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub unwound: Vec<Unwinding>,
}

fn yes() -> bool {
    true
}

/// A training run's schedule: how many iterations, batch size, where its randomness comes from.
#[derive(Clone, Debug)]
pub struct Schedule<'a> {
    /// Iterations to run.
    pub iterations: usize,
    /// Minibatch size (0: full batch).
    pub batch_size: usize,
    /// Seed of the run's generator stream.
    pub stream: u64,
    /// Held-out points and how often to evaluate them (0: never).
    pub heldout: Option<(&'a PointSet, usize)>,
    /// A re-orientation search between iterations.
    pub reorient: Option<ReorientStep<'a>>,
}

/// A re-orientation search inside a training run: after every `every` iterations (not
/// after the last), scored on `points`.
#[derive(Clone, Debug)]
pub struct ReorientStep<'a> {
    /// Evaluation points.
    pub points: &'a PointSet,
    /// The rotations to try ([`crate::problems::em::reorient::rotation_set`]).
    pub rotations: &'a [DMatrix<f64>],
    /// The word search's bounds, when it runs ([`crate::problems::em::words`]).
    pub words: Option<WordMoves>,
    /// Search after every this many iterations (0: never).
    pub every: usize,
}

/// Runs `schedule.iterations` EM iterations from `model` on `data`.
pub fn train(
    mut model: EmModel,
    data: &PointSet,
    mstep: &MStepConfig,
    schedule: &Schedule<'_>,
    observer: &mut dyn FnMut(&IterationRecord),
) -> Result<(EmModel, Vec<IterationRecord>)> {
    model.check_points(data)?;
    if data.is_empty() {
        return Err(Error::InvalidInput("no training points".into()));
    }
    let n = data.len();
    let full = schedule.batch_size == 0 || schedule.batch_size >= n;
    let mut history = Vec::with_capacity(schedule.iterations);
    for it in 0..schedule.iterations {
        let mut rng = trajectory_rng(schedule.stream, it as u64);
        let batch;
        let points = if full {
            data
        } else {
            let idx = rand::seq::index::sample(&mut rng, n, schedule.batch_size).into_vec();
            batch = data.select(&idx);
            &batch
        };
        let (next, info) = em_step(&model, points, mstep, &mut rng)?;
        model = next;
        let mut reoriented = Vec::new();
        let mut unwound = Vec::new();
        if let Some(step) = &schedule.reorient
            && step.every > 0
            && (it + 1) % step.every == 0
            && it + 1 < schedule.iterations
        {
            if let Some(moves) = &step.words {
                (model, unwound) = unwind(&model, step.points, moves)?;
            }
            (model, reoriented) = reorient(&model, step.points, step.rotations)?;
        }
        let heldout_log_likelihood = match schedule.heldout {
            Some((h, every))
                if every > 0 && ((it + 1) % every == 0 || it + 1 == schedule.iterations) =>
            {
                Some(model.mean_log_likelihood(h)?)
            }
            _ => None,
        };
        let rec = IterationRecord {
            iteration: it,
            batch_log_likelihood: info.log_likelihood,
            heldout_log_likelihood,
            deepest_weight: model.deepest_weight(),
            mean_depth: model.mean_depth(),
            degeneracies: info.degeneracies,
            accepted: info.accepted,
            reoriented,
            unwound,
        };
        observer(&rec);
        history.push(rec);
    }
    Ok((model, history))
}
