//! The run folder every problem under the shared driver keeps, and the steps every such
//! run takes: refuse a folder that holds a run unless resuming, find where a resume starts,
//! keep the start θ (`start.json`), open the CSV log and the checkpoint, build the
//! registered strategy and execute it.

use std::path::{Path, PathBuf};

use argmin::core::KV;
use argmin::core::observers::Observe;

use crate::driver::{CsvLog, GradState, JsonCheckpoint, RunSpec};
use crate::error::{Error, Result};
use crate::registry::{self, StrategyProblem};

/// The checkpoint inside a run folder.
pub const CHECKPOINT_FILE: &str = "checkpoint.json";
/// The per-iteration log.
pub const LOG_FILE: &str = "log.csv";
/// The θ a run started from (JSON array), kept so a resumed run can still return it.
pub const START_FILE: &str = "start.json";

/// Refuses `dir` for a fresh run if it already holds one (its checkpoint), so that nothing of
/// that run — its config, its target — is overwritten before the refusal.
pub fn ensure_new_run_dir(dir: &Path) -> Result<()> {
    if dir.join(CHECKPOINT_FILE).exists() {
        return Err(Error::InvalidInput(format!(
            "{} already holds a run (checkpoint.json); continue it with --resume {} or choose another output folder",
            dir.display(),
            dir.display()
        )));
    }
    Ok(())
}

/// The iteration the checkpoint in `dir` stopped at.
pub fn checkpoint_iteration(dir: &Path) -> Result<u64> {
    let path = dir.join(CHECKPOINT_FILE);
    let bytes =
        std::fs::read(&path).map_err(|e| Error::file(&path, format!("cannot resume: {e}")))?;
    let v: serde_json::Value = serde_json::from_slice(&bytes)
        .map_err(|e| Error::file(&path, format!("checkpoint is corrupt: {e}")))?;
    v["state"]["iter"]
        .as_u64()
        .ok_or_else(|| Error::file(&path, "checkpoint has no iteration count"))
}

/// One run of a problem under the shared driver, into a run folder.
#[derive(Clone, Copy, Debug)]
pub struct RunPlan<'a> {
    /// The run folder.
    pub dir: &'a Path,
    /// Continue the run in `dir` from its checkpoint.
    pub resume: bool,
    /// The registered strategy's name and parameters.
    pub strategy: (&'a str, &'a toml::Table),
    /// The run's length.
    pub iterations: u64,
    /// The run's seed.
    pub seed: u64,
    /// Checkpoint every this many iterations (0: never).
    pub checkpoint_every: u64,
    /// The problem's logged loss terms (the strategy's statistics follow them in `log.csv`).
    pub terms: &'a [&'static str],
}

impl RunPlan<'_> {
    /// Creates the folder, refuses one that holds a run unless resuming, and returns the
    /// iteration a resume starts from (`None` for a fresh run).
    pub fn prepare(&self) -> Result<Option<u64>> {
        std::fs::create_dir_all(self.dir).map_err(|e| Error::file(self.dir, e))?;
        if self.resume {
            checkpoint_iteration(self.dir).map(Some)
        } else {
            ensure_new_run_dir(self.dir)?;
            Ok(None)
        }
    }

    /// The start θ: `make()`, written to `start.json`, for a fresh run; read back from it
    /// when resuming (`None` when the folder has none: runs from before it was kept).
    pub fn start(
        &self,
        resume_from: Option<u64>,
        make: impl FnOnce() -> Result<Vec<f64>>,
    ) -> Result<Option<Vec<f64>>> {
        let path = self.dir.join(START_FILE);
        if resume_from.is_some() {
            return Ok(std::fs::read(&path)
                .ok()
                .and_then(|b| serde_json::from_slice::<Vec<f64>>(&b).ok()));
        }
        let t = make()?;
        ifslab::io::write_atomic(
            &path,
            serde_json::to_string(&t)
                .map_err(|e| Error::Numerical(format!("start θ: {e}")))?
                .as_bytes(),
        )?;
        Ok(Some(t))
    }

    /// The CSV log.
    pub fn log_path(&self) -> PathBuf {
        self.dir.join(LOG_FILE)
    }

    /// Runs the registered strategy on `problem` from `start` (the checkpoint's θ when
    /// resuming), with the folder's checkpoint and log: the problem back and the final state.
    pub fn execute<P: StrategyProblem>(
        &self,
        problem: P,
        start: &[f64],
        resume_from: Option<u64>,
        observers: Vec<Box<dyn Observe<GradState> + Send>>,
    ) -> Result<(P, GradState)> {
        let (name, params) = self.strategy;
        let stats = registry::stats(name)?;
        let columns: Vec<&str> = self.terms.iter().chain(stats).copied().collect();
        let log = CsvLog::open(self.log_path(), &columns, resume_from)?;
        let ckpt = JsonCheckpoint::new(
            self.dir.join(CHECKPOINT_FILE),
            self.checkpoint_every,
            self.resume,
            self.iterations,
        );
        let solver = registry::find::<P>(name)?.build(
            params,
            &RunSpec {
                iterations: self.iterations,
                seed: self.seed,
            },
        )?;
        // A signal now stops the run at the end of an iteration, checkpointed.
        let _watch = ifslab::interrupt::Watch::start();
        let theta0 = if resume_from.is_some() {
            Vec::new()
        } else {
            start.to_vec()
        };
        execute(
            problem,
            solver,
            theta0,
            self.iterations,
            ckpt,
            log,
            observers,
        )
    }
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
