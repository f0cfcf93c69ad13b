//! The EM loop: minibatch E-step, M-step, records; and [`fit`], which runs pre-selection
//! and then trains the chosen candidate at full depth.
//!
//! Each iteration draws N′ points without replacement from the training set (all of them
//! when N′ = 0 or N′ ≥ N), computes the per-code statistics, and applies the closed-form
//! M-step. Every random draw comes from a generator seeded by `(seed, stream, iteration)`,
//! so a run depends on its seed only, never on the thread count.
//!
//! The driver is written here rather than on argmin's `Executor`: EM's state is a model, not
//! a parameter vector with a cost and gradient, and the pool of pre-selection candidates
//! runs many short loops in parallel; an observer callback gives the caller progress bars
//! and logs.
//!
//! ## References
//! - P. Bloem and S. de Rooij, *An Expectation-Maximization Algorithm for the Fractal
//!   Inverse Problem*, arXiv:1706.03149, 2017.

use nalgebra::DMatrix;
use rand::Rng;
use serde::{Deserialize, Serialize};

use ifslab::chaos::{mix_seed, trajectory_rng};

use crate::em::data::PointSet;
use crate::em::estep::expectation;
use crate::em::init::{normalising_post, random_model};
use crate::em::model::{CodeTable, EmModel};
use crate::em::mstep::{ComponentUpdate, Degeneracy, MStepConfig, maximise, maximise_exact_blocks};
use crate::em::preselect::{Candidate, PreselectBy, preselect};
use crate::em::reorient::{ReorientConfig, Reorientation, reorient, rotation_set};
use crate::error::{Error, Result};

/// Stream tags that keep the run's random draws apart.
pub(crate) mod stream {
    pub const INIT: u64 = 0x1a17;
    pub const PRESELECT: u64 = 0x9e5e;
    pub const MAIN: u64 = 0x3a17;
    pub const EVAL: u64 = 0xe7a1;
    pub const ROTATIONS: u64 = 0x7047;
}

/// The largest number of codes a model may have (memory and time grow with it).
pub const MAX_CODES: usize = 4_000_000;

/// Everything a fit needs.
///
/// The defaults are the paper's Fig. 5a settings (K = 3, D = 6, 300 iterations, N′ = 500,
/// a pool of 10 trained for 100 iterations up to depth 3) with two changes that make a fit
/// converge far more often — the re-orientation search and the moment-matched base Gaussian
/// at the start of the main run (on an independent Sierpiński sample, 8/8 seeds against 3/8
/// and 1/8 with either one off) — and three that each alone changed nothing there: the
/// all-positions M-step, the depth curriculum and selection by likelihood in pre-selection.
/// The last two together make a random 4-map code converge (8/8 against 1/8 without), and
/// cost the Heighway dragon 0.24 nats/point (`paper_repro/ifs_em/README.md`).
/// [`EmConfig::paper`] gives the paper's algorithm.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EmConfig {
    /// Number of components K.
    pub components: usize,
    /// Maximum depth D of the codes.
    pub depth: usize,
    /// EM iterations of the chosen candidate at depth D.
    pub iterations: usize,
    /// Minibatch size N′ (0: full batch).
    pub batch_size: usize,
    /// Pre-selection pool size (1: a single random start, no pre-selection).
    pub pool: usize,
    /// Deepest depth at which pool candidates are trained (capped at `depth`).
    pub preselect_depth: usize,
    /// Iterations each pool candidate is trained (over all its curriculum stages).
    pub preselect_iterations: usize,
    /// Train candidates at depths 1, 2, …, `preselect_depth` in turn, the iterations spread
    /// evenly; false: all at `preselect_depth` (the paper).
    pub curriculum: bool,
    /// How the pre-selection winner is chosen.
    pub preselect_by: PreselectBy,
    /// The re-orientation search (see [`crate::em::reorient`]).
    pub reorient: ReorientConfig,
    /// Training points that score candidates and re-orientations, drawn once per fit
    /// (0: all of them).
    pub eval_points: usize,
    /// Move the model frame so that the base Gaussian has the invariant measure's mean and
    /// spread when the main run starts ([`EmModel::recentred`]).
    pub recentre: bool,
    /// A run has converged when this share of the depth weight is on depth D.
    pub convergence: f64,
    /// Scale of the initial maps.
    pub init_scale: f64,
    /// Evaluate the held-out log-likelihood every this many iterations (0: only at the end).
    pub eval_every: usize,
    /// M-step variant, bounds and repairs.
    pub mstep: MStepConfig,
    /// Seed of the run.
    pub seed: u64,
}

impl Default for EmConfig {
    fn default() -> Self {
        EmConfig {
            components: 3,
            depth: 6,
            iterations: 300,
            batch_size: 500,
            pool: 10,
            preselect_depth: 3,
            preselect_iterations: 100,
            curriculum: true,
            preselect_by: PreselectBy::LogLikelihood,
            reorient: ReorientConfig::default(),
            eval_points: 1000,
            recentre: true,
            convergence: 0.95,
            init_scale: 0.5,
            eval_every: 0,
            mstep: MStepConfig::default(),
            seed: 0,
        }
    }
}

impl EmConfig {
    /// The paper's algorithm at the paper's Fig. 5a settings: the outermost-map M-step,
    /// candidates trained at depth 3 only and chosen by mean depth, no re-orientation, the
    /// base Gaussian left where pre-selection put it.
    pub fn paper() -> Self {
        EmConfig {
            curriculum: false,
            preselect_by: PreselectBy::MeanDepth,
            reorient: ReorientConfig::off(),
            recentre: false,
            mstep: MStepConfig {
                update: ComponentUpdate::Outermost,
                ..MStepConfig::default()
            },
            ..EmConfig::default()
        }
    }
}

/// Number of codes of length 0 … `depth` over `k` symbols, saturating.
pub fn code_count(k: usize, depth: usize) -> usize {
    let mut n = 0usize;
    let mut level = 1usize;
    for _ in 0..=depth {
        n = n.saturating_add(level);
        level = level.saturating_mul(k);
    }
    n
}

impl EmConfig {
    /// Checks every field; the error names the one to change.
    pub fn validate(&self) -> Result<()> {
        if self.components == 0 {
            return Err(Error::param("k", "need at least one component"));
        }
        if self.depth == 0 {
            return Err(Error::param("depth", "must be at least 1"));
        }
        for (name, d) in [
            ("depth", self.depth),
            ("preselect_depth", self.preselect_depth),
        ] {
            let n = code_count(self.components, d);
            if n > MAX_CODES {
                return Err(Error::param(
                    if name == "depth" {
                        "depth"
                    } else {
                        "preselect_depth"
                    },
                    format!(
                        "K = {} at {name} {d} gives {n} codes (more than {MAX_CODES}); lower the depth",
                        self.components
                    ),
                ));
            }
        }
        if self.pool == 0 {
            return Err(Error::param("pool", "must be at least 1"));
        }
        if self.pool > 1 && self.preselect_depth == 0 {
            return Err(Error::param("preselect_depth", "must be at least 1"));
        }
        if !(self.convergence > 0.0 && self.convergence <= 1.0) {
            return Err(Error::param(
                "convergence",
                format!("must lie in (0, 1], got {}", self.convergence),
            ));
        }
        if !(self.init_scale > 0.0 && self.init_scale < 1.0) {
            return Err(Error::param(
                "init_scale",
                format!("must lie in (0, 1), got {}", self.init_scale),
            ));
        }
        self.reorient.validate()?;
        self.mstep.validate()
    }
}

/// What one EM step saw and did.
#[derive(Clone, Debug, PartialEq)]
pub struct StepInfo {
    /// Mean log-likelihood per point of the batch under the model *before* the step (nats).
    pub log_likelihood: f64,
    /// Degenerate cases the M-step repaired.
    pub degeneracies: Vec<Degeneracy>,
    /// False when the monotone safeguard rejected the component update (see
    /// [`MStepConfig::monotone`]).
    pub accepted: bool,
}

/// One EM iteration on `batch`: E-step under `model`, closed-form M-step.
pub fn em_step<R: Rng + ?Sized>(
    model: &EmModel,
    batch: &PointSet,
    mstep: &MStepConfig,
    rng: &mut R,
) -> Result<(EmModel, StepInfo)> {
    model.check_points(batch)?;
    if batch.is_empty() {
        return Err(Error::InvalidInput(
            "an EM step needs at least one point".into(),
        ));
    }
    let table = CodeTable::build(model, mstep.update == ComponentUpdate::AllPositions);
    let stats = expectation(model, &table, batch);
    if !stats.log_likelihood.is_finite() {
        return Err(Error::Numerical(format!(
            "the batch log-likelihood is {}; the data may lie extremely far from the model",
            stats.log_likelihood
        )));
    }
    let (mut next, mut degeneracies) = maximise(model, &table, &stats, mstep, rng)?;
    let mut accepted = true;
    if mstep.monotone {
        let after: f64 = next.log_densities(batch)?.iter().sum();
        let tol = 1e-12 * stats.log_likelihood.abs() + 1e-9;
        if after.is_nan() || after < stats.log_likelihood - tol {
            (next, degeneracies) = maximise_exact_blocks(model, &table, &stats)?;
            accepted = false;
        }
    }
    Ok((
        next,
        StepInfo {
            log_likelihood: stats.mean_log_likelihood(),
            degeneracies,
            accepted,
        },
    ))
}

/// One iteration of a training run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct IterationRecord {
    /// Iteration index (0-based).
    pub iteration: usize,
    /// Mean log-likelihood per point of the iteration's batch before the update (nats).
    pub batch_log_likelihood: f64,
    /// Mean held-out log-likelihood per point after the update, when evaluated (nats).
    pub heldout_log_likelihood: Option<f64>,
    /// v_D after the update.
    pub deepest_weight: f64,
    /// Σ d·v_d after the update.
    pub mean_depth: f64,
    /// Degenerate cases the M-step repaired.
    pub degeneracies: Vec<Degeneracy>,
    /// False when the monotone safeguard rejected the component update.
    #[serde(default = "yes")]
    pub accepted: bool,
    /// Components the re-orientation search turned after this iteration.
    #[serde(default)]
    pub reoriented: Vec<Reorientation>,
}

fn yes() -> bool {
    true
}

/// A training run's schedule: how many iterations, batch size, where its randomness comes from.
#[derive(Clone, Debug)]
pub struct Schedule<'a> {
    /// Iterations to run.
    pub iterations: usize,
    /// Minibatch size (0: full batch).
    pub batch_size: usize,
    /// Seed of the run's generator stream.
    pub stream: u64,
    /// Held-out points and how often to evaluate them (0: never).
    pub heldout: Option<(&'a PointSet, usize)>,
    /// A re-orientation search between iterations.
    pub reorient: Option<ReorientStep<'a>>,
}

/// A re-orientation search inside a training run: after every `every` iterations (not
/// after the last), scored on `points`.
#[derive(Clone, Debug)]
pub struct ReorientStep<'a> {
    /// Evaluation points.
    pub points: &'a PointSet,
    /// The rotations to try ([`rotation_set`]).
    pub rotations: &'a [DMatrix<f64>],
    /// Search after every this many iterations (0: never).
    pub every: usize,
}

/// Runs `schedule.iterations` EM iterations from `model` on `data`.
pub fn train(
    mut model: EmModel,
    data: &PointSet,
    mstep: &MStepConfig,
    schedule: &Schedule<'_>,
    observer: &mut dyn FnMut(&IterationRecord),
) -> Result<(EmModel, Vec<IterationRecord>)> {
    model.check_points(data)?;
    if data.is_empty() {
        return Err(Error::InvalidInput("no training points".into()));
    }
    let n = data.len();
    let full = schedule.batch_size == 0 || schedule.batch_size >= n;
    let mut history = Vec::with_capacity(schedule.iterations);
    for it in 0..schedule.iterations {
        let mut rng = trajectory_rng(schedule.stream, it as u64);
        let batch;
        let points = if full {
            data
        } else {
            let idx = rand::seq::index::sample(&mut rng, n, schedule.batch_size).into_vec();
            batch = data.select(&idx);
            &batch
        };
        let (next, info) = em_step(&model, points, mstep, &mut rng)?;
        model = next;
        let mut reoriented = Vec::new();
        if let Some(step) = &schedule.reorient
            && step.every > 0
            && (it + 1) % step.every == 0
            && it + 1 < schedule.iterations
        {
            (model, reoriented) = reorient(&model, step.points, step.rotations)?;
        }
        let heldout_log_likelihood = match schedule.heldout {
            Some((h, every))
                if every > 0 && ((it + 1) % every == 0 || it + 1 == schedule.iterations) =>
            {
                Some(model.mean_log_likelihood(h)?)
            }
            _ => None,
        };
        let rec = IterationRecord {
            iteration: it,
            batch_log_likelihood: info.log_likelihood,
            heldout_log_likelihood,
            deepest_weight: model.deepest_weight(),
            mean_depth: model.mean_depth(),
            degeneracies: info.degeneracies,
            accepted: info.accepted,
            reoriented,
        };
        observer(&rec);
        history.push(rec);
    }
    Ok((model, history))
}

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
/// [`crate::em::preselect`]), then `cfg.iterations` iterations at depth `cfg.depth` from the
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
    let eval = evaluation_points(data, cfg);
    let rotations = if cfg.reorient.enabled() {
        rotation_set(
            data.dim(),
            cfg.reorient.rotations,
            mix_seed(cfg.seed, stream::ROTATIONS),
        )
    } else {
        Vec::new()
    };
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
        reorient: (!rotations.is_empty()).then_some(ReorientStep {
            points: &eval,
            rotations: &rotations,
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
