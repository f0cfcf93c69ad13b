//! Running an inversion: initial code, solver, argmin `Executor` with the shared checkpoint
//! and CSV log, resume.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use argmin::core::State;
use argmin::core::observers::Observe;
use ifslab::image::Image;
use ifslab::model::Affine2;

use crate::driver::GradState;
use crate::driver::plan::RunPlan;
use crate::error::{Error, Result};
use crate::problems::image::config::{InversionConfig, polish_needs_affine};
use crate::problems::image::init::{fit_offsets, initial_theta};
use crate::problems::image::polish::{Polish, Polished, polish};
use crate::problems::image::problem::{ImageProblem, TERMS};
use crate::problems::image::result::Recovered;
use crate::problems::image::target::load_framed_picture;

pub use crate::driver::plan::{CHECKPOINT_FILE, LOG_FILE, START_FILE, ensure_new_run_dir};

/// What an inversion produced.
#[derive(Clone, Debug)]
pub struct InversionOutcome {
    /// The θ the run returns: of the last iterate, the best one the run recorded and the
    /// start, whichever scores lowest on fixed random streams ([`Selection`]).
    pub theta: Vec<f64>,
    /// What θ describes, as the model draws and stores it (any family).
    pub result: Arc<dyn Recovered>,
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
    /// How `theta` was chosen.
    pub selection: Selection,
    /// What the IoU polish did (`model.polish`), if it ran.
    pub polished: Option<Polished>,
}

/// The side at which the IoU polish reads a picture target.
pub const POLISH_SIZE: usize = 256;

/// The IoU polish of the fitted `maps` (`model.polish` rounds) against the picture read at
/// [`POLISH_SIZE`], or against the framed `target` where the target is no picture.
fn polish_fit(
    cfg: &InversionConfig,
    target: &[f32],
    maps: &[Affine2],
    rounds: usize,
) -> Result<Option<Polished>> {
    let reread = match &cfg.target.image {
        Some(path) if cfg.target.size != POLISH_SIZE => Some(
            load_framed_picture(path, POLISH_SIZE, cfg.target.polarity)?
                .image
                .values,
        ),
        _ => None,
    };
    let (image, side) = reread
        .as_ref()
        .map_or((target, cfg.target.size), |v| (v.as_slice(), POLISH_SIZE));
    let settings = Polish {
        rounds,
        ..Polish::default()
    };
    let Some(mut p) = polish(image, side, maps, cfg.seed, &settings)? else {
        return Ok(None);
    };
    fit_offsets(&mut p.maps, 0.9);
    Ok(Some(p))
}

/// The random streams the returned θ is chosen on: far from any iteration's own stream, the
/// same for every candidate, so the comparison is not decided by one lucky draw of points.
pub const SELECTION_STREAMS: [u64; 3] = [u64::MAX - 1, u64::MAX - 2, u64::MAX - 3];

/// The choice of the θ a run returns, among the last iterate, the best one argmin recorded
/// (the lowest cost any iteration reported) and the start. Each iteration's cost is measured
/// on its own random stream — and for Adam at the θ *before* the step it then takes, so the
/// recorded best is one step away from the θ that was measured — so none is trusted: each is
/// scored on [`SELECTION_STREAMS`] with the renderer the run ends with, and the lowest mean
/// wins (ties go to the later one: last, then best, then start).
///
/// A candidate whose maps are not all contractive is no IFS (it has no attractor, and the
/// run's code file would be refused) and is passed over, whatever its score: an
/// unconstrained parameterisation (`naive`) can end a run with an expanding map. The start
/// is contractive by construction, so a run always returns an IFS.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Selection {
    /// `last`, `best` or `start`.
    pub returned: &'static str,
    /// Mean objective of the last iterate on the selection streams.
    pub last: f64,
    /// Mean objective of the recorded best, when it differs from the last iterate.
    pub best: Option<f64>,
    /// Iteration at which the recorded best was reported.
    pub best_iter: Option<u64>,
    /// Mean objective of the start, when it differs from both.
    pub start: Option<f64>,
    /// Candidates passed over because a map is not contractive (`last`, `best`, `start`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub not_contractive: Vec<&'static str>,
}

/// Whether θ decodes to maps that are all contractive ([`Recovered::contractive`]).
fn is_ifs(problem: &ImageProblem, theta: &[f64]) -> bool {
    problem
        .model()
        .recovered(theta)
        .is_ok_and(|r| r.contractive())
}

fn mean_objective(problem: &ImageProblem, theta: &[f64]) -> Result<f64> {
    let mut sum = 0.0;
    for s in SELECTION_STREAMS {
        sum += problem.loss_breakdown(theta, s)?.total;
    }
    Ok(sum / SELECTION_STREAMS.len() as f64)
}

/// Picks the θ a run returns (see [`Selection`]).
fn select(
    problem: &ImageProblem,
    state: &GradState,
    start: &[f64],
) -> Result<(Vec<f64>, Selection)> {
    let last = state
        .get_param()
        .cloned()
        .ok_or_else(|| Error::Numerical("the run ended without parameters".into()))?;
    let last_score = mean_objective(problem, &last)?;
    let usable = |t: &&Vec<f64>| **t != last && t.iter().all(|v| v.is_finite());
    let best = state.get_best_param().filter(usable);
    let start = Some(start.to_vec())
        .filter(|s| s.len() == last.len() && Some(s) != best)
        .filter(|s| usable(&s));
    // A candidate the model cannot decode (a code the image problem refuses) loses.
    let score = |t: &[f64]| mean_objective(problem, t).unwrap_or(f64::INFINITY);
    let best_score = best.map(|b| score(b));
    let start_score = start.as_deref().map(score);
    let not_contractive: Vec<&'static str> = [
        ("last", Some(last.as_slice())),
        ("best", best.map(Vec::as_slice)),
        ("start", start.as_deref()),
    ]
    .into_iter()
    .filter_map(|(name, t)| t.filter(|t| !is_ifs(problem, t)).map(|_| name))
    .collect();
    let mut choice: Option<(&'static str, f64)> = None;
    for (name, v) in [
        ("last", Some(last_score)),
        ("best", best_score),
        ("start", start_score),
    ] {
        if let Some(v) = v
            && !not_contractive.contains(&name)
            && choice.is_none_or(|(_, c)| v < c)
        {
            choice = Some((name, v));
        }
    }
    // None eligible: the last iterate (the caller's validation of the code then says which
    // map is not contractive).
    let choice = choice.unwrap_or(("last", last_score));
    let theta = match choice.0 {
        "best" => best.cloned().expect("scored"),
        "start" => start.clone().expect("scored"),
        _ => last,
    };
    Ok((
        theta,
        Selection {
            returned: choice.0,
            last: last_score,
            best: best_score,
            best_iter: best.map(|_| state.get_last_best_iter()),
            start: start_score,
            not_contractive,
        },
    ))
}

/// Runs the inversion described by `cfg` against `target` (framed, grey, `size × size`), writing
/// `checkpoint.json` and `log.csv` into `dir`. With `resume`, continues from the checkpoint
/// there; the result is bit-identical to an uninterrupted run. `observers` see every
/// iteration (a progress bar, say).
pub fn run_inversion(
    cfg: &InversionConfig,
    target: Image,
    dir: &Path,
    resume: bool,
    observers: Vec<Box<dyn Observe<GradState> + Send>>,
) -> Result<InversionOutcome> {
    cfg.validate()?;
    let plan = RunPlan {
        dir,
        resume,
        strategy: (cfg.strategy.name(), cfg.strategy.params()),
        iterations: cfg.iterations,
        seed: cfg.seed,
        checkpoint_every: cfg.checkpoint_every,
        terms: &TERMS,
    };
    let resume_from = plan.prepare()?;
    // A resumed run takes θ from its checkpoint; the start (an EM fit, say) is not redone.
    let problem = ImageProblem::from_config(cfg, target)?;
    // Run folders from before the start was kept have none: the start is then no candidate.
    let start_theta = plan
        .start(resume_from, || {
            initial_theta(cfg, problem.model(), &problem.target().values)
        })?
        .unwrap_or_default();
    let lpips_note = problem.lpips_skip_reason().map(str::to_owned);
    let start = Instant::now();
    let (problem, state) = plan.execute(problem, &start_theta, resume_from, observers)?;
    let (mut theta, selection) = select(&problem, &state, &start_theta)?;
    let mut result: Arc<dyn Recovered> = problem.model().recovered(&theta)?.into();
    let polished = match cfg.model.polish {
        0 => None,
        rounds => {
            // `validate` refused a family without affine maps.
            let maps = result
                .affine()
                .ok_or_else(|| polish_needs_affine(&cfg.model.family))?;
            polish_fit(cfg, &problem.target().values, maps, rounds)?
        }
    };
    if let Some(p) = polished.as_ref().filter(|p| p.kept) {
        theta = problem.model().encode(&p.maps)?;
        result = problem.model().recovered(&theta)?.into();
    }
    Ok(InversionOutcome {
        theta,
        result,
        polished,
        iterations: state.get_iter(),
        final_loss: state.get_cost(),
        seconds: start.elapsed().as_secs_f64(),
        lpips_note,
        log: dir.join(LOG_FILE),
        selection,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::image::config::{
        GeneratorConfig, ModelConfig, RendererConfig, StrategyConfig, TargetConfig,
    };
    use ifslab::model::{ParamKind, library};
    use ifslab::render::{RenderConfig, render};

    /// A run whose last iterate has an expanding map — closer to the target than the
    /// start, so it would win on score — returns the start instead: it is an IFS.
    #[test]
    fn an_expanding_last_iterate_is_passed_over() {
        let size = 48;
        let sierpinski = library::builtin("sierpinski").unwrap();
        let maps = sierpinski.affine2().unwrap();
        let target = render(
            &maps,
            &sierpinski.evaluation_probabilities().unwrap(),
            &RenderConfig {
                width: size as u32,
                height: size as u32,
                points: 200_000,
                supersample: 2,
                ..RenderConfig::default()
            },
            None,
        )
        .unwrap()
        .image;
        let cfg = InversionConfig {
            paper: true,
            seed: 1,
            iterations: 1,
            best_of: 1,
            best_of_starts: Default::default(),
            checkpoint_every: 0,
            output: None,
            target: TargetConfig {
                image: None,
                code: Some("sierpinski".into()),
                suite: None,
                index: None,
                truth: None,
                size,
                polarity: Default::default(),
                cells: None,
            },
            generator: GeneratorConfig {
                trajectories: 300,
                length: 110,
                warmup: 10,
                start_half_width: 2.0,
            },
            renderer: RendererConfig::default(),
            model: ModelConfig {
                maps: 3,
                parameterisation: ParamKind::Naive,
                ..ModelConfig::default()
            },
            loss: ifslab::loss::LossConfig {
                lpips_weight: 0.0,
                ..Default::default()
            },
            strategy: StrategyConfig::default(),
        };
        let problem = ImageProblem::from_config(&cfg, target.clone()).unwrap();
        // Sierpiński with its first map stretched 3 % along x: not contractive.
        let mut stretched = maps.clone();
        stretched[0].m[(0, 0)] *= 2.0 * 1.03;
        let last = problem.model().encode(&stretched).unwrap();
        let start = initial_theta(&cfg, problem.model(), &problem.target().values).unwrap();
        assert!(!is_ifs(&problem, &last) && is_ifs(&problem, &start));
        let state = GradState::new().param(last.clone());
        let (theta, s) = select(&problem, &state, &start).unwrap();
        assert!(
            s.last < s.start.unwrap(),
            "the expanding code scores better: {s:?}"
        );
        assert_eq!(s.returned, "start", "{s:?}");
        assert_eq!(s.not_contractive, ["last"]);
        assert_eq!(theta, start);
    }
}
