//! Running a flame fit: the target, the start, solver from the registry, argmin `Executor`
//! with the shared checkpoint and CSV log, resume.

use std::path::{Path, PathBuf};
use std::time::Instant;

use argmin::core::State;
use argmin::core::observers::Observe;
use ifslab::model::flame::learnable::{FlameStack, LearnableFlame};

use crate::driver::{GradState, RunPlan, START_FILE};
use crate::error::{Error, Result};
use crate::problems::flame::config::FlameLearnConfig;
use crate::problems::flame::problem::{FLAME_TERMS, FlameProblem};

/// What a fit produced.
#[derive(Clone, Debug)]
pub struct FlameOutcome {
    /// θ returned: the last iterate, or the start when the start scores lower on the
    /// configured loss.
    pub theta: Vec<f64>,
    /// Which of the two (`last`, `start`).
    pub returned: &'static str,
    /// The start.
    pub start: Vec<f64>,
    /// MSE of the start.
    pub start_loss: f64,
    /// Iterations completed (including those before a resume).
    pub iterations: u64,
    /// The authors' MSE of the returned θ (generator order of the last iteration).
    pub loss: f64,
    /// The returned θ as a flame stack.
    pub stack: FlameStack,
    /// Its render at the training size (three planes, generator order of the last
    /// iteration).
    pub image: Vec<f64>,
    /// Wall-clock seconds of this process's part of the run.
    pub seconds: f64,
    /// The CSV log.
    pub log: PathBuf,
}

/// An RGB target of `size × size` pixels (three planes, row 0 at the top), resized from any
/// image the `image` crate reads (stretched to a square, as the authors' code does), and a
/// note on what was done to it: a grey image is used as RGB with equal channels; an image
/// with transparency is composited over `background` (the fit's background colour).
pub fn load_rgb_target(
    path: &Path,
    size: usize,
    background: [f64; 3],
) -> Result<(Vec<f32>, Option<String>)> {
    let bytes = std::fs::read(path).map_err(|e| Error::file(path, e))?;
    let img = image::load_from_memory(&bytes)
        .map_err(|e| Error::file(path, format!("not a readable image ({e})")))?;
    let colour = img.color();
    let mut notes = Vec::new();
    if !colour.has_color() {
        notes.push("the target is greyscale: learned as RGB with three equal channels");
    }
    if colour.has_alpha() {
        notes.push("the target has an alpha channel: composited over the background colour");
    }
    let rgba = img.to_rgba32f();
    let (w, h) = rgba.dimensions();
    if w == 0 || h == 0 {
        return Err(Error::file(path, "image has no pixels"));
    }
    let resized = image::imageops::resize(
        &rgba,
        size as u32,
        size as u32,
        image::imageops::FilterType::Triangle,
    );
    let n = size * size;
    let mut out = vec![0.0f32; 3 * n];
    for (i, p) in resized.pixels().enumerate() {
        let a = p.0[3].clamp(0.0, 1.0);
        for ch in 0..3 {
            let v = p.0[ch] * a + background[ch] as f32 * (1.0 - a);
            out[ch * n + i] = v.clamp(0.0, 1.0);
        }
    }
    let note = if notes.is_empty() {
        None
    } else {
        Some(notes.join("; "))
    };
    Ok((out, note))
}

/// The start `cfg` describes: each layer drawn in the authors' style from the run's seed.
pub fn initial_stack(cfg: &FlameLearnConfig, target: &[f32]) -> Result<FlameStack> {
    let layers = cfg
        .flames
        .iter()
        .enumerate()
        .map(|(i, spec)| {
            LearnableFlame::random(
                &spec.generators()?,
                cfg.learn,
                &cfg.init,
                cfg.seed.wrapping_add(1 + i as u64),
            )
            .map_err(Error::from)
        })
        .collect::<Result<Vec<_>>>()?;
    let stack = FlameStack {
        layers,
        background: cfg.background(target)?,
    };
    stack.validate()?;
    Ok(stack)
}

/// The problem `cfg` describes for `target`.
pub fn flame_problem(cfg: &FlameLearnConfig, target: Vec<f32>) -> Result<FlameProblem> {
    FlameProblem::new(
        initial_stack(cfg, &target)?,
        cfg.sampler.clone(),
        target,
        cfg.seed,
        cfg.redraw_every,
        &cfg.rates,
        cfg.loss.clone(),
    )
}

/// Runs the fit `cfg` describes against `target` (three planes of `size²`), writing
/// `start.json`, `checkpoint.json` and `log.csv` into `dir`. With `resume`, continues from
/// the checkpoint there; every step is deterministic, so the result is bit-identical to an
/// uninterrupted run.
pub fn run_flame(
    cfg: &FlameLearnConfig,
    target: Vec<f32>,
    dir: &Path,
    resume: bool,
    observers: Vec<Box<dyn Observe<GradState> + Send>>,
) -> Result<FlameOutcome> {
    cfg.validate()?;
    let plan = RunPlan {
        dir,
        resume,
        strategy: (cfg.strategy.name(), cfg.strategy.params()),
        iterations: cfg.iterations,
        seed: cfg.seed,
        checkpoint_every: cfg.checkpoint_every,
        terms: &FLAME_TERMS,
    };
    let resume_from = plan.prepare()?;
    let problem = flame_problem(cfg, target)?;
    let start = plan
        .start(resume_from, || Ok(problem.initial_params()))?
        .ok_or_else(|| Error::file(dir.join(START_FILE), "cannot resume: the start is missing"))?;
    let clock = Instant::now();
    let (problem, state) = plan.execute(problem, &start, resume_from, observers)?;
    let seconds = clock.elapsed().as_secs_f64();
    let last = state
        .get_param()
        .cloned()
        .ok_or_else(|| Error::Numerical("the run ended without parameters".into()))?;
    let at = state.get_iter();
    // Judged by the objective the run minimised; the MSE is reported beside it.
    let (start_cost, start_loss, start_image) = problem.scores(&start, at)?;
    let last_scores = problem.scores(&last, at).ok();
    let (theta, returned, loss, image) = match last_scores {
        Some((cost, mse, image)) if cost <= start_cost => (last, "last", mse, image),
        _ => (start.clone(), "start", start_loss, start_image),
    };
    Ok(FlameOutcome {
        stack: problem.stack_at(&theta)?,
        theta,
        returned,
        start,
        start_loss,
        iterations: at,
        loss,
        image,
        seconds,
        log: plan.log_path(),
    })
}
