//! Running an inversion: initial code, solver, argmin `Executor` with the shared checkpoint
//! and CSV log, resume.

use std::path::{Path, PathBuf};
use std::time::Instant;

use argmin::core::observers::{Observe, ObserverMode};
use argmin::core::{Error as ArgminError, Executor, KV, State};
use ifslab::model::Affine2;

use crate::driver::{CsvLog, GradState, JsonCheckpoint, RunSpec};
use crate::error::{Error, Result};
use crate::problems::image::config::InversionConfig;
use crate::problems::image::init::initial_theta;
use crate::problems::image::problem::{ImageProblem, TERMS};
use crate::registry::{self, AnySolver};

/// File names inside a run folder.
pub const CHECKPOINT_FILE: &str = "checkpoint.json";
/// The per-iteration log.
pub const LOG_FILE: &str = "log.csv";

/// What an inversion produced.
#[derive(Clone, Debug)]
pub struct InversionOutcome {
    /// Final θ.
    pub theta: Vec<f64>,
    /// Final maps (θ decoded).
    pub maps: Vec<Affine2>,
    /// Iterations completed (including those before a resume).
    pub iterations: u64,
    /// Loss of the last iteration.
    pub final_loss: f64,
    /// Wall-clock seconds of this process's part of the run.
    pub seconds: f64,
    /// Why LPIPS was left out of the loss, if it was.
    pub lpips_note: Option<String>,
    /// The CSV log.
    pub log: PathBuf,
}

/// Lets a boxed observer be handed to argmin's executor.
struct Boxed(Box<dyn Observe<GradState> + Send>);

impl Observe<GradState> for Boxed {
    fn observe_init(
        &mut self,
        name: &str,
        state: &GradState,
        kv: &KV,
    ) -> std::result::Result<(), ArgminError> {
        self.0.observe_init(name, state, kv)
    }
    fn observe_iter(&mut self, state: &GradState, kv: &KV) -> std::result::Result<(), ArgminError> {
        self.0.observe_iter(state, kv)
    }
    fn observe_final(&mut self, state: &GradState) -> std::result::Result<(), ArgminError> {
        self.0.observe_final(state)
    }
}

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

/// Runs the inversion described by `cfg` against `target` (framed, `size × size`), writing
/// `checkpoint.json` and `log.csv` into `dir`. With `resume`, continues from the checkpoint
/// there; the result is bit-identical to an uninterrupted run. `observers` see every
/// iteration (a progress bar, say).
pub fn run_inversion(
    cfg: &InversionConfig,
    target: Vec<f32>,
    dir: &Path,
    resume: bool,
    observers: Vec<Box<dyn Observe<GradState> + Send>>,
) -> Result<InversionOutcome> {
    cfg.validate()?;
    std::fs::create_dir_all(dir).map_err(|e| Error::file(dir, e))?;
    let ckpt_path = dir.join(CHECKPOINT_FILE);
    if !resume {
        ensure_new_run_dir(dir)?;
    }
    let resume_from = if resume {
        let bytes = std::fs::read(&ckpt_path)
            .map_err(|e| Error::file(&ckpt_path, format!("cannot resume: {e}")))?;
        let v: serde_json::Value = serde_json::from_slice(&bytes)
            .map_err(|e| Error::file(&ckpt_path, format!("checkpoint is corrupt: {e}")))?;
        Some(
            v["state"]["iter"]
                .as_u64()
                .ok_or_else(|| Error::file(&ckpt_path, "checkpoint has no iteration count"))?,
        )
    } else {
        None
    };
    // A resumed run takes θ from its checkpoint; the start (an EM fit, say) is not redone.
    let problem = ImageProblem::from_config(cfg, target)?;
    let theta0 = if resume_from.is_some() {
        Vec::new()
    } else {
        initial_theta(cfg, problem.model(), problem.target())?
    };
    let lpips_note = problem.lpips_skip_reason().map(str::to_owned);
    let stats = registry::stats(cfg.strategy.name())?;
    let columns: Vec<&str> = TERMS.iter().chain(stats).copied().collect();
    let log = CsvLog::open(dir.join(LOG_FILE), &columns, resume_from)?;
    let ckpt = JsonCheckpoint::new(&ckpt_path, cfg.checkpoint_every, resume, cfg.iterations);
    let t = cfg.iterations;
    let start = Instant::now();
    let entry = registry::find::<ImageProblem>(cfg.strategy.name())?;
    let solver = entry.build(
        cfg.strategy.params(),
        &RunSpec {
            iterations: t,
            seed: cfg.seed,
        },
    )?;
    let res = execute(problem, solver, theta0, t, ckpt, log, observers)?;
    let (problem, state) = res;
    let theta = state
        .get_param()
        .cloned()
        .ok_or_else(|| Error::Numerical("the run ended without parameters".into()))?;
    let maps = problem.model().affine_maps(&theta)?;
    Ok(InversionOutcome {
        theta,
        maps,
        iterations: state.get_iter(),
        final_loss: state.get_cost(),
        seconds: start.elapsed().as_secs_f64(),
        lpips_note,
        log: dir.join(LOG_FILE),
    })
}

fn execute(
    problem: ImageProblem,
    solver: AnySolver<ImageProblem>,
    theta0: Vec<f64>,
    iterations: u64,
    ckpt: JsonCheckpoint,
    log: CsvLog,
    observers: Vec<Box<dyn Observe<GradState> + Send>>,
) -> Result<(ImageProblem, GradState)> {
    let mut exec = Executor::new(problem, solver)
        .configure(|s| s.param(theta0).max_iters(iterations))
        .checkpointing(ckpt)
        .add_observer(log, ObserverMode::Always);
    for o in observers {
        exec = exec.add_observer(Boxed(o), ObserverMode::Always);
    }
    let res = exec.run().map_err(|e| match e.downcast::<Error>() {
        Ok(ours) => ours,
        Err(other) => Error::Numerical(format!("optimisation failed: {other}")),
    })?;
    let state = res.state().clone();
    let problem = res
        .problem
        .problem
        .ok_or_else(|| Error::Numerical("the executor lost the problem".into()))?;
    Ok((problem, state))
}
