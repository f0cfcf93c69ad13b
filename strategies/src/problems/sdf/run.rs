//! Running a fit: start, solver from the registry, argmin `Executor` with the shared
//! checkpoint and CSV log, resume.

use std::path::{Path, PathBuf};
use std::time::Instant;

use argmin::core::State;
use argmin::core::observers::Observe;
use ifslab::image::Image;
use ifslab::render::sdf::SdfView;

use crate::driver::GradState;
use crate::driver::plan::{RunPlan, START_FILE};
use crate::error::{Error, Result};
use crate::problems::sdf::config::{RESCUE_DISTANCE, RESCUE_SIGMA_START, SdfConfig};
use crate::problems::sdf::init::{SdfInit, candidate_starts, initial_points};
use crate::problems::sdf::problem::{SDF_TERMS, SdfProblem};
use crate::problems::sdf::target::{STROKE_SIGMA_RANGE, sigma_for_stroke};
use ifslab::model::segment::PrimitiveKind;

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
    /// Which start it is, where it is one of the starts the config names: `line`,
    /// `pattern`, `given`, or for `best` the [`candidate_starts`] entry it equals (so a
    /// resumed run names it too); none for a learned pattern's or a jittered start.
    pub start_kind: Option<&'static str>,
    /// Iterations completed (including those before a resume).
    pub iterations: u64,
    /// Loss of the returned θ.
    pub loss: f64,
    /// Wall-clock seconds of this process's part of the run.
    pub seconds: f64,
    /// The CSV log.
    pub log: PathBuf,
}

/// The widths σ a fit of `cfg` runs at, one whole fit each, when it runs more than one: the
/// strokes' σ ([`sigma_for_stroke`] of the framed stroke width `stroke`) times each of
/// `sigma_factors`, at least the lower bound of [`STROKE_SIGMA_RANGE`], each width once, in
/// the factors' order. Empty when the fit runs once as `cfg` says: no factors, σ not from
/// the strokes, a base figure that is not a segment, or no stroke measured.
pub fn stroke_sigma_legs(cfg: &SdfConfig, stroke: Option<f64>) -> Result<Vec<f64>> {
    let Some(w) = stroke.filter(|_| cfg.stroke_sigma && !cfg.sigma_factors.is_empty()) else {
        return Ok(Vec::new());
    };
    if cfg.pattern()?.base().kind != PrimitiveKind::Segment {
        return Ok(Vec::new());
    }
    let base = sigma_for_stroke(w);
    let mut legs: Vec<f64> = Vec::new();
    for f in &cfg.sigma_factors {
        let s = (base * f).max(STROKE_SIGMA_RANGE.0);
        if !legs.iter().any(|&l| (l - s).abs() < 1e-9) {
            legs.push(s);
        }
    }
    Ok(legs)
}

/// The further fits of `cfg` where the fit kept at width `sigma` agrees with its target on
/// an IoU below `rescue_below`, each with its folder name: coarse to fine from
/// [`RESCUE_SIGMA_START`] (or twice `sigma`) down to `sigma`, and at `sigma` with the
/// distance term at [`RESCUE_DISTANCE`]. Empty when `rescue_below` is 0.
pub fn rescue_legs(cfg: &SdfConfig, sigma: f64) -> Vec<(String, SdfConfig)> {
    if cfg.rescue_below <= 0.0 {
        return Vec::new();
    }
    let at = SdfConfig {
        rescue_below: 0.0,
        ..at_sigma(cfg, sigma)
    };
    let coarse = SdfConfig {
        sigma_start: Some(RESCUE_SIGMA_START.max(2.0 * sigma)),
        sigma_iterations: None,
        ..at.clone()
    };
    let mut distance = at;
    distance.loss.distance = RESCUE_DISTANCE;
    vec![
        ("rescue-0".to_owned(), coarse),
        ("rescue-1".to_owned(), distance),
    ]
}

/// `cfg` with σ fixed at `sigma` (one leg of [`stroke_sigma_legs`]).
pub fn at_sigma(cfg: &SdfConfig, sigma: f64) -> SdfConfig {
    SdfConfig {
        stroke_sigma: false,
        sigma_factors: Vec::new(),
        sigma,
        ..cfg.clone()
    }
}

/// The problem `cfg` describes for `target` (ink, `size × size`, seen as the unit square)
/// whose strokes are `stroke` framed pixels wide, when that was measured (it sets σ with
/// `stroke_sigma`).
pub fn sdf_problem(cfg: &SdfConfig, target: Image<f64>, stroke: Option<f64>) -> Result<SdfProblem> {
    let pattern = cfg.pattern()?;
    let sigma = match (cfg.stroke_sigma, stroke) {
        (true, Some(w)) if pattern.base().kind == PrimitiveKind::Segment => sigma_for_stroke(w),
        _ => cfg.sigma,
    };
    let p = SdfProblem::new(
        pattern,
        target,
        SdfView::unit_square(cfg.size),
        cfg.depth,
        sigma,
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

/// The start [`SdfInit::Best`] picks for `problem`: every [`candidate_starts`] entry followed
/// for `init.probe_steps` Adam steps at the first σ of the run (the strategy's learning rate
/// when it is Adam, else 2e-3); the candidate whose loss is lowest after them, by name, with
/// its *starting* points (the fit then runs its whole schedule from there). Deterministic.
pub fn best_start(problem: &SdfProblem, cfg: &SdfConfig) -> Result<(&'static str, Vec<f64>)> {
    let lr = cfg
        .strategy
        .typed::<crate::optim::adam::AdamConfig>()
        .map_or(2e-3, |a| a.lr);
    let sigma = problem.sigma_at(0.0);
    let candidates = candidate_starts(
        problem.pattern(),
        problem.target(),
        problem.view(),
        cfg.init.stretched,
    )?;
    let mut best: Option<(f64, &'static str, Vec<f64>)> = None;
    for (name, start) in candidates {
        let Ok(loss) = probe(problem, &start, lr, sigma, cfg.init.probe_steps) else {
            continue;
        };
        if best.as_ref().is_none_or(|b| loss < b.0) {
            best = Some((loss, name, start));
        }
    }
    let (_, name, theta) = best.ok_or_else(|| {
        Error::InvalidInput(format!(
            "no start of pattern `{}` could be followed on this target",
            problem.pattern().name()
        ))
    })?;
    Ok((name, theta))
}

/// The loss at width `sigma` after `steps` Adam steps from `start`.
fn probe(problem: &SdfProblem, start: &[f64], lr: f64, sigma: f64, steps: u64) -> Result<f64> {
    let (b1, b2, eps) = (0.9f64, 0.999f64, 1e-8);
    let mut theta = start.to_vec();
    let (mut m, mut v) = (vec![0.0; theta.len()], vec![0.0; theta.len()]);
    for t in 1..=steps as i32 {
        let g = problem
            .eval_with(&theta, true, sigma)?
            .grad
            .expect("asked for the gradient");
        for i in 0..theta.len() {
            m[i] = b1 * m[i] + (1.0 - b1) * g[i];
            v[i] = b2 * v[i] + (1.0 - b2) * g[i] * g[i];
            let (mh, vh) = (m[i] / (1.0 - b1.powi(t)), v[i] / (1.0 - b2.powi(t)));
            theta[i] -= lr * mh / (vh.sqrt() + eps);
        }
    }
    Ok(problem.eval_with(&theta, false, sigma)?.loss)
}

/// The name of the start `start` of a fit of `cfg` (see [`SdfOutcome::start_kind`]).
fn start_kind(
    cfg: &SdfConfig,
    problem: &SdfProblem,
    start: &[f64],
) -> Result<Option<&'static str>> {
    if problem.learned().is_some() || cfg.init.jitter > 0.0 {
        return Ok(None);
    }
    Ok(match cfg.init.kind {
        SdfInit::Best => candidate_starts(
            problem.pattern(),
            problem.target(),
            problem.view(),
            cfg.init.stretched,
        )?
        .into_iter()
        .find(|(_, t)| t.as_slice() == start)
        .map(|(name, _)| name),
        kind => Some(kind.name()),
    })
}

/// Runs the fit `cfg` describes against `target` (ink in [0, 1], `size × size`), writing
/// `start.json`, `checkpoint.json` and `log.csv` into `dir`. With `resume`, continues from
/// the checkpoint there; the render is deterministic, so the result is bit-identical to an
/// uninterrupted run.
pub fn run_sdf(
    cfg: &SdfConfig,
    target: Image<f64>,
    stroke: Option<f64>,
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
    let problem = sdf_problem(cfg, target, stroke)?;
    let start = plan
        .start(resume_from, || {
            let t = match cfg.init.kind {
                SdfInit::Best => best_start(&problem, cfg)?.1,
                kind => initial_points(
                    problem.pattern(),
                    problem.target(),
                    problem.view(),
                    kind,
                    cfg.init.jitter,
                    cfg.seed,
                )?,
            };
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
    let start_kind = start_kind(cfg, &problem, &start)?;
    Ok(SdfOutcome {
        theta,
        returned,
        start_kind,
        start,
        iterations: state.get_iter(),
        loss,
        seconds: clock.elapsed().as_secs_f64(),
        log: plan.log_path(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_widths_are_the_strokes_sigma_times_each_factor_floored_and_once_each() {
        let cfg = SdfConfig::new("t.png", "koch");
        // A stroke whose σ is 4 px: 4, 3 and 2.
        let w = 4.0 * 2.0 * std::f64::consts::LN_2.sqrt();
        let legs = stroke_sigma_legs(&cfg, Some(w)).unwrap();
        assert_eq!(legs.len(), 3);
        for (l, e) in legs.iter().zip([4.0, 3.0, 2.0]) {
            assert!((l - e).abs() < 1e-9, "{legs:?}");
        }
        // A one-pixel line at the floor: one width, the floor.
        assert_eq!(
            stroke_sigma_legs(&cfg, Some(0.5)).unwrap(),
            vec![STROKE_SIGMA_RANGE.0]
        );
        // σ 1.2: 1.2, 0.9, and 0.6 raised to the floor 0.75.
        let legs =
            stroke_sigma_legs(&cfg, Some(1.2 * 2.0 * std::f64::consts::LN_2.sqrt())).unwrap();
        assert_eq!(legs.len(), 3);
        assert!((legs[2] - STROKE_SIGMA_RANGE.0).abs() < 1e-12, "{legs:?}");
        // One fit as configured: no stroke measured, σ given, no factors, a filled figure.
        assert!(stroke_sigma_legs(&cfg, None).unwrap().is_empty());
        assert!(
            stroke_sigma_legs(&at_sigma(&cfg, 2.0), Some(w))
                .unwrap()
                .is_empty()
        );
        let mut none = cfg.clone();
        none.sigma_factors.clear();
        assert!(stroke_sigma_legs(&none, Some(w)).unwrap().is_empty());
        let carpet = SdfConfig::new("t.png", "carpet-square");
        assert!(stroke_sigma_legs(&carpet, Some(w)).unwrap().is_empty());
        // A leg draws at its width.
        let leg = at_sigma(&cfg, 3.0);
        assert!(!leg.stroke_sigma && leg.sigma == 3.0 && leg.sigma_factors.is_empty());
    }

    #[test]
    fn a_poorly_agreeing_fit_is_followed_by_a_coarse_to_fine_fit_and_a_distance_fit() {
        let cfg = SdfConfig::new("t.png", "koch");
        assert_eq!(cfg.rescue_below, crate::problems::sdf::DEFAULT_RESCUE_BELOW);
        let legs = rescue_legs(&cfg, 0.75);
        let names: Vec<&str> = legs.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["rescue-0", "rescue-1"]);
        for (_, leg) in &legs {
            // At the kept width, one fit each, never rescued again.
            assert!(leg.sigma == 0.75 && !leg.stroke_sigma && leg.sigma_factors.is_empty());
            assert_eq!(leg.rescue_below, 0.0);
            leg.validate().unwrap();
        }
        assert_eq!(legs[0].1.sigma_start, Some(RESCUE_SIGMA_START));
        assert_eq!(legs[0].1.loss.distance, cfg.loss.distance);
        assert_eq!(legs[1].1.sigma_start, None);
        assert_eq!(legs[1].1.loss.distance, RESCUE_DISTANCE);
        // Coarse to fine starts at least twice the kept width.
        assert_eq!(rescue_legs(&cfg, 1.5)[0].1.sigma_start, Some(3.0));
        // The paper's recipe never fits again.
        assert!(rescue_legs(&SdfConfig::paper("t.png", "koch"), 0.75).is_empty());
        let mut bad = cfg.clone();
        bad.rescue_below = 1.5;
        assert!(
            bad.validate()
                .unwrap_err()
                .to_string()
                .contains("rescue_below")
        );
    }
}
