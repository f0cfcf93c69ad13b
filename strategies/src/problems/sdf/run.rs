//! Running a fit: start, solver from the registry, argmin `Executor` with the shared
//! checkpoint and CSV log, resume.

use std::path::{Path, PathBuf};
use std::time::Instant;

use argmin::core::State;
use argmin::core::observers::Observe;
use ifslab::render::sdf::SdfView;

use crate::driver::{CsvLog, GradState, JsonCheckpoint, RunSpec, execute};
use crate::error::{Error, Result};
use crate::problems::image::run::{CHECKPOINT_FILE, LOG_FILE, START_FILE, ensure_new_run_dir};
use crate::problems::sdf::config::SdfConfig;
use crate::problems::sdf::init::initial_points;
use crate::problems::sdf::problem::{SDF_TERMS, SdfProblem};
use crate::registry;

/// What a fit produced.
#[derive(Clone, Debug)]
pub struct SdfOutcome {
    /// The control points returned: the last iterate, or the start when the start scores
    /// lower (a diverged run hands back what it was given).
    pub theta: Vec<f64>,
    /// Which of the two (`last`, `start`).
    pub returned: &'static str,
    /// The start.
    pub start: Vec<f64>,
    /// Iterations completed (including those before a resume).
    pub iterations: u64,
    /// Loss of the returned θ.
    pub loss: f64,
    /// Wall-clock seconds of this process's part of the run.
    pub seconds: f64,
    /// The CSV log.
    pub log: PathBuf,
}

/// The problem `cfg` describes for `target` (ink, `size × size`, seen as the unit square).
pub fn sdf_problem(cfg: &SdfConfig, target: Vec<f64>) -> Result<SdfProblem> {
    let p = SdfProblem::new(
        cfg.pattern()?,
        target,
        SdfView::unit_square(cfg.size),
        cfg.depth,
        cfg.sigma,
        cfg.loss.clone(),
    )?;
    let p = match &cfg.learned {
        Some(l) => p.with_learned_pattern(l.clone(), cfg.iterations)?,
        None => p,
    };
    match cfg.sigma_start {
        Some(s0) => p.with_sigma_schedule(s0, cfg.iterations),
        None => Ok(p),
    }
}

/// Runs the fit `cfg` describes against `target` (ink in [0, 1], `size × size`), writing
/// `start.json`, `checkpoint.json` and `log.csv` into `dir`. With `resume`, continues from
/// the checkpoint there; the render is deterministic, so the result is bit-identical to an
/// uninterrupted run.
pub fn run_sdf(
    cfg: &SdfConfig,
    target: Vec<f64>,
    dir: &Path,
    resume: bool,
    observers: Vec<Box<dyn Observe<GradState> + Send>>,
) -> Result<SdfOutcome> {
    cfg.validate()?;
    std::fs::create_dir_all(dir).map_err(|e| Error::file(dir, e))?;
    if !resume {
        ensure_new_run_dir(dir)?;
    }
    let ckpt_path = dir.join(CHECKPOINT_FILE);
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
    let problem = sdf_problem(cfg, target)?;
    let start_path = dir.join(START_FILE);
    let start = if resume_from.is_some() {
        let b = std::fs::read(&start_path).map_err(|e| Error::file(&start_path, e))?;
        serde_json::from_slice::<Vec<f64>>(&b).map_err(|e| Error::file(&start_path, e))?
    } else {
        let t = initial_points(
            problem.pattern(),
            problem.target(),
            problem.view(),
            cfg.init.kind,
            cfg.init.jitter,
            cfg.seed,
        )?;
        let t = match problem.learned() {
            Some(l) => l.start(&t, cfg.seed)?,
            None => t,
        };
        ifslab::io::write_atomic(
            &start_path,
            serde_json::to_string(&t)
                .map_err(|e| Error::Numerical(format!("start θ: {e}")))?
                .as_bytes(),
        )?;
        t
    };
    let stats = registry::stats(cfg.strategy.name())?;
    let columns: Vec<&str> = SDF_TERMS.iter().chain(stats).copied().collect();
    let log = CsvLog::open(dir.join(LOG_FILE), &columns, resume_from)?;
    let ckpt = JsonCheckpoint::new(&ckpt_path, cfg.checkpoint_every, resume, cfg.iterations);
    let clock = Instant::now();
    let entry = registry::find::<SdfProblem>(cfg.strategy.name())?;
    let solver = entry.build(
        cfg.strategy.params(),
        &RunSpec {
            iterations: cfg.iterations,
            seed: cfg.seed,
        },
    )?;
    let theta0 = if resume_from.is_some() {
        Vec::new()
    } else {
        start.clone()
    };
    let (problem, state) = execute(
        problem,
        solver,
        theta0,
        cfg.iterations,
        ckpt,
        log,
        observers,
    )?;
    let last = state
        .get_param()
        .cloned()
        .ok_or_else(|| Error::Numerical("the run ended without parameters".into()))?;
    let last_loss = problem
        .eval(&last, false)
        .map(|e| e.loss)
        .unwrap_or(f64::INFINITY);
    let start_loss = problem.eval(&start, false)?.loss;
    let (theta, returned, loss) = if last_loss <= start_loss {
        (last, "last", last_loss)
    } else {
        (start.clone(), "start", start_loss)
    };
    Ok(SdfOutcome {
        theta,
        returned,
        start,
        iterations: state.get_iter(),
        loss,
        seconds: clock.elapsed().as_secs_f64(),
        log: dir.join(LOG_FILE),
    })
}
