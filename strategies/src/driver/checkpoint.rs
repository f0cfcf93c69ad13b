//! Checkpoints as JSON (floats written so they read back bit-exactly), written atomically:
//! a temporary file in the same folder, flushed, then renamed over the last checkpoint.

use std::path::PathBuf;

use argmin::core::checkpointing::{Checkpoint, CheckpointingFrequency};
use argmin::core::{Error as ArgminError, TerminationStatus};
use serde::{Serialize, de::DeserializeOwned};

use super::GradState;

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
        let bytes = serde_json::to_vec(&(solver, state))?;
        ifslab::io::write_atomic(&self.path, &bytes)?;
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
        let (solver, mut state): (S, GradState) = serde_json::from_slice(&bytes).map_err(|e| {
            ArgminError::msg(format!(
                "checkpoint {} is corrupt: {e}",
                self.path.display()
            ))
        })?;
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
