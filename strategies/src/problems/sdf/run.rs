//! Running a fit: start, solver from the registry, argmin `Executor` with the shared
//! checkpoint and CSV log, resume.

use std::path::{Path, PathBuf};
use std::time::Instant;

use argmin::core::State;
use argmin::core::observers::Observe;
use ifslab::render::sdf::SdfView;

use crate::driver::{GradState, RunPlan, START_FILE};
use crate::error::{Error, Result};
use crate::problems::sdf::config::SdfConfig;
use crate::problems::sdf::init::initial_points;
use crate::problems::sdf::problem::{SDF_TERMS, SdfProblem};

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
        Some(s0) => p.with_sigma_schedule(s0, cfg.sigma_iterations.unwrap_or(cfg.iterations)),
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
    let plan = RunPlan {
        dir,
        resume,
        strategy: (cfg.strategy.name(), cfg.strategy.params()),
        iterations: cfg.iterations,
        seed: cfg.seed,
        checkpoint_every: cfg.checkpoint_every,
        terms: &SDF_TERMS,
    };
    let resume_from = plan.prepare()?;
    let problem = sdf_problem(cfg, target)?;
    let start = plan
        .start(resume_from, || {
            let t = initial_points(
                problem.pattern(),
                problem.target(),
                problem.view(),
                cfg.init.kind,
                cfg.init.jitter,
                cfg.seed,
            )?;
            match problem.learned() {
                Some(l) => l.start(&t, cfg.seed),
                None => Ok(t),
            }
        })?
        .ok_or_else(|| Error::file(dir.join(START_FILE), "cannot resume: the start is missing"))?;
    let clock = Instant::now();
    let (problem, state) = plan.execute(problem, &start, resume_from, observers)?;
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
        log: plan.log_path(),
    })
}
