//! Checkpoints as JSON (floats written so they read back bit-exactly), written atomically:
//! a temporary file in the same folder, flushed, then renamed over the last checkpoint.
//!
//! JSON has no infinities, and argmin's state starts with `best_cost = +∞` and
//! `target_cost = −∞`: the five cost fields travel as text beside the state.

use std::path::PathBuf;

use argmin::core::checkpointing::{Checkpoint, CheckpointingFrequency};
use argmin::core::{Error as ArgminError, TerminationStatus};
use serde::{Deserialize, Serialize, de::DeserializeOwned};

use super::GradState;

/// How an interrupted run's error begins.
pub const INTERRUPTED: &str = "interrupted";

/// What a checkpoint file holds.
#[derive(Serialize, Deserialize)]
struct Record<S> {
    solver: S,
    state: GradState,
    /// `cost, prev_cost, best_cost, prev_best_cost, target_cost` as text (`inf`, `NaN`, …).
    costs: [String; 5],
}

fn costs_mut(state: &mut GradState) -> [&mut f64; 5] {
    [
        &mut state.cost,
        &mut state.prev_cost,
        &mut state.best_cost,
        &mut state.prev_best_cost,
        &mut state.target_cost,
    ]
}

/// Saves `(solver, state)` every `every` iterations; loads it back when resuming.
#[derive(Clone, Debug)]
pub struct JsonCheckpoint {
    path: PathBuf,
    every: u64,
    resume: bool,
    max_iters: u64,
}

impl JsonCheckpoint {
    /// A checkpoint at `path` written every `every` iterations (0: never). With `resume`,
    /// `load` restores the saved run and extends it to `max_iters` iterations.
    pub fn new(path: impl Into<PathBuf>, every: u64, resume: bool, max_iters: u64) -> Self {
        JsonCheckpoint {
            path: path.into(),
            every,
            resume,
            max_iters,
        }
    }

    /// Where the checkpoint lives.
    pub fn path(&self) -> &std::path::Path {
        &self.path
    }
}

impl<S: Serialize + DeserializeOwned> Checkpoint<S, GradState> for JsonCheckpoint {
    fn save(&self, solver: &S, state: &GradState) -> Result<(), ArgminError> {
        let mut state = state.clone();
        let costs = costs_mut(&mut state).map(|c| {
            let text = format!("{c:?}");
            *c = 0.0;
            text
        });
        let bytes = serde_json::to_vec(&Record {
            solver,
            state,
            costs,
        })?;
        ifslab::io::write_atomic(&self.path, &bytes)?;
        Ok(())
    }

    /// Saves on the schedule, and after any iteration at which a stop was asked for
    /// ([`ifslab::interrupt`]); then the run ends with an error that says how to continue it.
    fn save_cond(&self, solver: &S, state: &GradState, iter: u64) -> Result<(), ArgminError> {
        let due = self.every > 0 && iter.is_multiple_of(self.every);
        let stop = ifslab::interrupt::requested();
        if due || stop {
            self.save(solver, state)?;
        }
        if stop {
            return Err(super::to_argmin(crate::Error::Interrupted(format!(
                "{INTERRUPTED} after iteration {iter}: the checkpoint is saved ({}); continue \
                 the run with --resume",
                self.path.display()
            ))));
        }
        Ok(())
    }

    fn load(&self) -> Result<Option<(S, GradState)>, ArgminError> {
        if !self.resume {
            return Ok(None);
        }
        let bytes = std::fs::read(&self.path).map_err(|e| {
            ArgminError::msg(format!(
                "cannot resume: no checkpoint at {} ({e})",
                self.path.display()
            ))
        })?;
        let corrupt = |what: String| {
            ArgminError::msg(format!(
                "checkpoint {} is corrupt: {what}",
                self.path.display()
            ))
        };
        let rec: Record<S> = serde_json::from_slice(&bytes).map_err(|e| corrupt(e.to_string()))?;
        let (solver, mut state) = (rec.solver, rec.state);
        for (c, text) in costs_mut(&mut state).into_iter().zip(&rec.costs) {
            *c = text
                .parse()
                .map_err(|_| corrupt(format!("cost `{text}` is not a number")))?;
        }
        // The saved state may have stopped at its own limit: continue to this run's.
        state.max_iters = self.max_iters;
        state.termination_status = TerminationStatus::NotTerminated;
        Ok(Some((solver, state)))
    }

    fn frequency(&self) -> CheckpointingFrequency {
        if self.every == 0 {
            CheckpointingFrequency::Never
        } else {
            CheckpointingFrequency::Every(self.every)
        }
    }
}
