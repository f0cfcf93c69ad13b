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
pub use plan::{
    CHECKPOINT_FILE, LOG_FILE, RunPlan, START_FILE, checkpoint_iteration, ensure_new_run_dir,
};

use argmin::core::observers::Observe;
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

/// Lets a boxed observer (a run's log, checkpoint and progress) be handed to argmin's
/// executor, which takes observers by value.
struct Boxed(pub Box<dyn Observe<GradState> + Send>);

impl Observe<GradState> for Boxed {
    fn observe_init(
        &mut self,
        name: &str,
        state: &GradState,
        kv: &KV,
    ) -> std::result::Result<(), argmin::core::Error> {
        self.0.observe_init(name, state, kv)
    }
    fn observe_iter(
        &mut self,
        state: &GradState,
        kv: &KV,
    ) -> std::result::Result<(), argmin::core::Error> {
        self.0.observe_iter(state, kv)
    }
    fn observe_final(&mut self, state: &GradState) -> std::result::Result<(), argmin::core::Error> {
        self.0.observe_final(state)
    }
}

/// Runs `solver` on `problem` from `theta0` (empty when resuming: the checkpoint holds θ) for
/// `iterations`, checkpointing through `ckpt`, logging to `log` and reporting to
/// `observers`: the problem back (argmin moves it into the executor) and the final state.
/// An error of ours raised inside an iteration comes back as itself.
pub fn execute<P: crate::registry::StrategyProblem>(
    problem: P,
    solver: crate::registry::AnySolver<P>,
    theta0: Vec<f64>,
    iterations: u64,
    ckpt: JsonCheckpoint,
    log: CsvLog,
    observers: Vec<Box<dyn Observe<GradState> + Send>>,
) -> Result<(P, GradState)> {
    use argmin::core::Executor;
    use argmin::core::observers::ObserverMode;
    let mut exec = Executor::new(problem, solver)
        .configure(|s| s.param(theta0).max_iters(iterations))
        .checkpointing(ckpt)
        .add_observer(log, ObserverMode::Always);
    for o in observers {
        exec = exec.add_observer(Boxed(o), ObserverMode::Always);
    }
    let res = exec.run().map_err(|e| match e.downcast::<crate::Error>() {
        Ok(ours) => ours,
        Err(other) => crate::Error::Numerical(format!("optimisation failed: {other}")),
    })?;
    let state = res.state().clone();
    let problem = res
        .problem
        .problem
        .ok_or_else(|| crate::Error::Numerical("the executor lost the problem".into()))?;
    Ok((problem, state))
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
