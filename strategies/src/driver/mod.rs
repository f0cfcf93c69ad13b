//! One driver for every iterative strategy: argmin's `Executor` runs the solver, this module
//! supplies what the strategies share — the problem interface, an atomic JSON checkpoint
//! that resumes bit-identically, and a CSV log that survives a crash.
//!
//! A strategy is an argmin [`Solver`](argmin::core::Solver) over [`GradState`] (θ as a flat
//! `Vec<f64>`); it talks to its problem through [`Differentiable`] (loss and gradient at
//! an iteration) and, for annealing-type steps, [`crate::optim::annealing::Anneal`].
//! Problems are stochastic: iteration `t` draws its own chaos-game trajectories from a seed
//! derived from `t`, so a resumed run sees exactly the randomness of an uninterrupted one.

mod checkpoint;
mod log;
pub mod plan;

pub use checkpoint::JsonCheckpoint;
pub use log::CsvLog;

use argmin::core::{IterState, KV, KvValue};

use std::fmt::Debug;

use serde::{Serialize, de::DeserializeOwned};

use crate::error::Result;

/// The solver state every gradient strategy runs on: θ, its gradient, the loss.
pub type GradState = IterState<Vec<f64>, Vec<f64>, (), (), (), f64>;

/// The loss at θ with its gradient and named terms (for logs).
#[derive(Clone, Debug, PartialEq)]
pub struct Evaluation {
    /// Total loss.
    pub loss: f64,
    /// ∂loss/∂θ.
    pub grad: Vec<f64>,
    /// Named terms of the loss (unweighted values, as logged).
    pub terms: Vec<(&'static str, f64)>,
}

/// A problem gradient strategies can minimise.
pub trait Differentiable {
    /// Loss and gradient at θ for iteration `iter` (which picks the iteration's randomness).
    fn evaluate(&self, theta: &[f64], iter: u64) -> Result<Evaluation>;

    /// Brings θ back onto the parameterisation's canonical set after an update.
    fn project(&self, _theta: &mut [f64]) {}

    /// Per-entry multipliers of a gradient strategy's learning rate at iteration `iter`
    /// (`None`: all 1), for problems whose parameters live on different scales — a flame's
    /// affine coefficients and its colour logits get one rate per group, as the
    /// learnable-flames authors set, and a group can be held still for the first iterations.
    fn rate_multipliers(&self, _iter: u64) -> Option<Vec<f64>> {
        None
    }
}

/// The key–value record of an evaluation, for argmin's observers.
pub fn kv_of(eval: &Evaluation) -> KV {
    let mut kv = KV::new();
    for (name, v) in &eval.terms {
        kv.insert(*name, KvValue::Float(*v));
    }
    kv
}

/// Converts the strategies' error into argmin's.
pub(crate) fn to_argmin(e: crate::Error) -> argmin::core::Error {
    argmin::core::Error::new(e)
}

/// What a run hands a strategy's constructor besides its hyper-parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RunSpec {
    /// The run's length T (schedules such as annealing's temperature depend on it).
    pub iterations: u64,
    /// The run's seed (a strategy's own random draws derive from it).
    pub seed: u64,
}

/// A strategy's hyper-parameters.
pub trait Params:
    Serialize + DeserializeOwned + Default + Clone + Debug + PartialEq + Send + Sync + 'static
{
    /// The name a config's `[strategy] kind` uses.
    const KIND: &'static str;
    /// The statistics its solver reports per iteration (argmin `KV` keys), logged as CSV
    /// columns after the loss terms; an iteration that does not report one logs NaN.
    const STATS: &'static [&'static str];
    /// Checks the values, naming the offending field.
    fn validate(&self) -> Result<()>;
}
