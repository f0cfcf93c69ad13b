//! [`fit`]: pre-selection, then the chosen candidate trained at full depth; [`fit_all`] for
//! many fits in parallel.
//!
//! ## References
//! - P. Bloem and S. de Rooij, *An Expectation-Maximization Algorithm for the Fractal
//!   Inverse Problem*, arXiv:1706.03149, 2017.

use ifslab::chaos::{mix_seed, trajectory_rng};

use crate::error::{Error, Result};
use crate::problems::em::config::{EmConfig, stream};
use crate::problems::em::data::PointSet;
use crate::problems::em::init::{normalising_post, random_model};
use crate::problems::em::model::EmModel;
use crate::problems::em::mstep::Degeneracy;
use crate::problems::em::preselect::{Candidate, preselect};
use crate::problems::em::reorient::orientation_set;
use crate::problems::em::train::{IterationRecord, ReorientStep, Schedule, train};

/// What [`fit`] reports while it works.
#[derive(Debug)]
pub enum Event<'a> {
    /// Pre-selection finished; the candidates with their scores.
    Preselected(&'a [Candidate]),
    /// One iteration of the main run finished.
    Iteration(&'a IterationRecord),
}

/// The result of [`fit`].
#[derive(Clone, Debug)]
pub struct EmFit {
    /// The trained model.
    pub model: EmModel,
    /// Per-iteration records of the main run.
    pub history: Vec<IterationRecord>,
    /// The pre-selection pool (empty when the pool size is 1).
    pub candidates: Vec<Candidate>,
    /// Index of the candidate that was trained.
    pub chosen: usize,
    /// Whether v_D ≥ the convergence threshold at the end.
    pub converged: bool,
}

impl EmFit {
    /// Number of M-step repairs of each kind over the main run: (dead components, undetermined
    /// rotations, clamped scales, non-finite fits).
    pub fn degeneracy_counts(&self) -> [usize; 4] {
        let mut c = [0; 4];
        for d in self.history.iter().flat_map(|r| &r.degeneracies) {
            c[match d {
                Degeneracy::DeadComponent { .. } => 0,
                Degeneracy::RotationUndetermined { .. } => 1,
                Degeneracy::ScaleClamped { .. } => 2,
                Degeneracy::NonFinite { .. } => 3,
            }] += 1;
        }
        c
    }
}

/// Checks a training set against a config: enough points, consistent dimensions.
pub fn check_data(data: &PointSet, heldout: Option<&PointSet>, cfg: &EmConfig) -> Result<()> {
    if data.len() < cfg.components {
        return Err(Error::InvalidInput(format!(
            "{} training points for {} components: give at least as many points as components \
             (or lower --k)",
            data.len(),
            cfg.components
        )));
    }
    if let Some(h) = heldout
        && h.dim() != data.dim()
    {
        return Err(Error::InvalidInput(format!(
            "held-out points are {}-dimensional, training points {}-dimensional",
            h.dim(),
            data.dim()
        )));
    }
    Ok(())
}

/// Fits a model to `data`: pre-selection over `cfg.pool` random starts (see
/// [`crate::problems::em::preselect`]), then `cfg.iterations` iterations at depth `cfg.depth` from the
/// winner with uniform depth weights (its frame recentred when `cfg.recentre`), with a
/// re-orientation search every `cfg.reorient.every` iterations.
pub fn fit(
    data: &PointSet,
    heldout: Option<&PointSet>,
    cfg: &EmConfig,
    observer: &mut dyn FnMut(Event<'_>),
) -> Result<EmFit> {
    cfg.validate()?;
    check_data(data, heldout, cfg)?;
    cfg.check_work(data.len(), 1)?;
    let eval = evaluation_points(data, cfg);
    let rotations = if cfg.reorient.enabled() {
        orientation_set(
            data.dim(),
            cfg.reorient.rotations,
            mix_seed(cfg.seed, stream::ROTATIONS),
            cfg.mstep.reflections,
        )
    } else {
        Vec::new()
    };
    let words = cfg.word_moves();
    let (start, candidates, chosen) = if cfg.pool > 1 {
        let (model, candidates, chosen) = preselect(data, &eval, &rotations, cfg)?;
        observer(Event::Preselected(&candidates));
        (model.with_depth(cfg.depth), candidates, chosen)
    } else {
        let mut rng = trajectory_rng(mix_seed(cfg.seed, stream::INIT), 0);
        let model = random_model(
            cfg.components,
            cfg.depth,
            cfg.init_scale,
            normalising_post(data),
            &mut rng,
        )?;
        (model, Vec::new(), 0)
    };
    let start = if cfg.recentre {
        start.recentred()
    } else {
        start
    };
    let schedule = Schedule {
        iterations: cfg.iterations,
        batch_size: cfg.batch_size,
        stream: mix_seed(cfg.seed, stream::MAIN),
        heldout: heldout.map(|h| (h, cfg.eval_every)),
        reorient: (!rotations.is_empty() || words.is_some()).then_some(ReorientStep {
            points: &eval,
            rotations: &rotations,
            words,
            every: cfg.reorient.every,
        }),
    };
    let (model, history) = train(start, data, &cfg.mstep, &schedule, &mut |r| {
        observer(Event::Iteration(r))
    })?;
    let converged = model.is_converged(cfg.convergence);
    Ok(EmFit {
        model,
        history,
        candidates,
        chosen,
        converged,
    })
}

/// The points that score pre-selection candidates and re-orientations: `cfg.eval_points`
/// training points drawn without replacement by the fit's seed (all when there are fewer).
fn evaluation_points(data: &PointSet, cfg: &EmConfig) -> PointSet {
    let n = data.len();
    if cfg.eval_points == 0 || cfg.eval_points >= n {
        return data.clone();
    }
    let mut rng = trajectory_rng(mix_seed(cfg.seed, stream::EVAL), 0);
    let mut idx = rand::seq::index::sample(&mut rng, n, cfg.eval_points).into_vec();
    idx.sort_unstable();
    data.select(&idx)
}

/// Runs several independent fits (e.g. repeats or a sweep) in parallel, one per config, in
/// config order; `done` is called as each finishes (from worker threads).
pub fn fit_all(
    data: &PointSet,
    heldout: Option<&PointSet>,
    cfgs: &[EmConfig],
    done: &(dyn Fn(usize) + Sync),
) -> Vec<Result<EmFit>> {
    use rayon::prelude::*;
    cfgs.par_iter()
        .enumerate()
        .map(|(i, cfg)| {
            let r = fit(data, heldout, cfg, &mut |_| {});
            done(i);
            r
        })
        .collect()
}
