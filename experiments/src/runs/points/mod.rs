//! Point cloud → IFS of similitudes by EM (Bloem & de Rooij), as a run: a [`PointsConfig`]
//! in, a run folder out.
//!
//! A run loads a point cloud (CSV/text or `.npy`, any dimension) or samples one from a code
//! (`ifs:NAME`), holds out a share of it, and then either
//! - fits `runs` seeded EM runs and keeps the one whose attractor lies closest to the
//!   cloud ([`closeness`]; or the best held-out log-likelihood, `keep = "likelihood"`),
//!   writing `code.json`, `history.csv`, `loglik.png`, `scatter.png` (2-D/3-D), `render.png`
//!   (2-D) and `report.json` with Gaussian-mixture baselines in the same units; or
//! - with `sweep_pool`, measures the proportion of converged runs per pre-selection pool size
//!   over `repeats` seeded runs (the paper's Fig. 5b): `pool_sweep.csv/json/png`.
//!
//! Both write the resolved `config.toml` and `summary.json`. Every finished fit is
//! checkpointed under `fits/` ([`fits`]); `resume` continues a killed run with the fits that
//! are missing and merges exactly what an uninterrupted run would have. A single fit is a few
//! seconds, so nothing is saved inside EM.
//!
//! With a `truth` code (2-D) every fit is also compared with the code that made the data
//! ([`truth`]).
//!
//! ## References
//! - P. Bloem and S. de Rooij, *An Expectation-Maximization Algorithm for the Fractal
//!   Inverse Problem*, arXiv:1706.03149, 2017.

pub mod closeness;
mod config;
pub mod fits;
mod outputs;
mod sweep;
pub mod truth;

use std::path::Path;
use std::time::Instant;

use crate::error::{Context, IoContext, bail};
use ifslab::chaos::{ChaosGame, generate_nd, mix_seed};
use ifslab_strategies::problems::em::{EmFit, Event, PointSet, fit};
use serde::{Deserialize, Serialize};
use serde_json::json;

use crate::codes::resolve_code;
use crate::progress::Progress;
use crate::runs::inversion::CONFIG_FILE;
pub use config::{KeepBy, PointsConfig, PreselectSchedule};
use truth::Truth;
mod data;
pub use data::{Data, load_data};

/// The best fit of a fitting run (not a sweep).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct BestFit {
    /// Which run it was.
    pub run: usize,
    /// Mean held-out log-likelihood per point (nats; on the training points when nothing
    /// is held out).
    pub heldout_log_likelihood: f64,
    /// Mean training log-likelihood per point (nats).
    pub train_log_likelihood: f64,
    /// Whether v_D reached the convergence threshold.
    pub converged: bool,
    /// Σ d·v_d.
    pub mean_depth: f64,
    /// Free parameters of the IFS model.
    pub parameters: usize,
    /// v_D, the weight of the deepest level (the paper's convergence criterion compares it
    /// with a threshold).
    #[serde(default)]
    pub deepest_weight: Option<f64>,
    /// Coverage agreement with `truth`, when one was given.
    pub truth_agreement: Option<f64>,
    /// Plain IoU of the coverage masks compared with `truth` (no tolerance).
    #[serde(default)]
    pub truth_iou: Option<f64>,
    /// How close its attractor lies to the data, both ways (older summaries have none).
    #[serde(default)]
    pub closeness: Option<closeness::Closeness>,
    /// The rule that kept it among the runs (older summaries: the likelihood).
    #[serde(default)]
    pub kept_by: Option<KeepBy>,
    /// The best Gaussian mixture's held-out log-likelihood among the baselines.
    pub best_gmm_heldout_log_likelihood: Option<f64>,
    /// Each Gaussian-mixture baseline's held-out log-likelihood, by covariance and
    /// component count (`isotropic_8`, `full_16`).
    #[serde(default)]
    pub gmm: std::collections::BTreeMap<String, f64>,
}

/// One pool size of a sweep.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PoolResult {
    /// Pre-selection pool size.
    pub pool: usize,
    /// Runs that converged.
    pub converged: usize,
    /// Runs of this pool size.
    pub repeats: usize,
    /// `converged / repeats`.
    pub proportion: f64,
    /// Median held-out log-likelihood of the runs (nats per point).
    pub median_heldout_log_likelihood: f64,
    /// Runs whose coverage agreement with `truth` reached the threshold (with a truth).
    pub right: Option<usize>,
    /// Runs both converged and right (with a truth).
    pub converged_and_right: Option<usize>,
}

/// What `summary.json` of a points run holds.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PointsSummary {
    /// Where the points came from.
    pub source: String,
    /// Dimension of the points.
    pub dim: usize,
    /// Points, training points, held-out points.
    pub points: [usize; 3],
    /// Fits the run is made of.
    pub fits: usize,
    /// Of them, fits read from checkpoints of an interrupted run rather than fitted now.
    pub resumed_fits: usize,
    /// Fits that failed (a sweep records them and goes on).
    pub failed_fits: usize,
    /// Fits whose v_D reached the convergence threshold (of all the run's fits).
    pub converged_fits: usize,
    /// Wall-clock seconds of this process.
    pub seconds: f64,
    /// The kept fit (a fitting run).
    pub best: Option<BestFit>,
    /// Proportion converged per pool size (a sweep).
    pub sweep: Vec<PoolResult>,
}

impl PointsSummary {
    /// A line for the terminal.
    pub fn headline(&self) -> String {
        let resumed = if self.resumed_fits > 0 {
            format!(" ({} from checkpoints)", self.resumed_fits)
        } else {
            String::new()
        };
        match &self.best {
            Some(b) => format!(
                "{} fit(s){resumed} in {:.1} s, best run {}: held-out {:.4} nats/point, {}converged",
                self.fits,
                self.seconds,
                b.run,
                b.heldout_log_likelihood,
                if b.converged { "" } else { "not " }
            ),
            None => format!(
                "pool sweep, {} fit(s){resumed} in {:.1} s: {}",
                self.fits,
                self.seconds,
                self.sweep
                    .iter()
                    .map(|p| format!("pool {} {}/{}", p.pool, p.converged, p.repeats))
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        }
    }
}

/// Runs (or with `resume` continues) the points run `cfg` into `dir`, reporting to
/// `progress`: each fit's iterations (a fitting run) or the finished fits (a sweep) as
/// counts, and what a person reads as messages, one line each.
pub fn run(
    cfg: &PointsConfig,
    dir: &Path,
    resume: bool,
    progress: Box<dyn Progress>,
) -> crate::Result<PointsSummary> {
    let start = Instant::now();
    cfg.validate()?;
    let _lock = crate::runs::lock::lock_run_dir(dir)?;
    let resolved = cfg.resolved()?;
    let config_path = dir.join(CONFIG_FILE);
    if resume {
        crate::error::ensure!(
            config_path.is_file(),
            "{} holds no points run to resume (no {CONFIG_FILE})",
            dir.display()
        );
        // Read as a resolved config: keys it leaves out when off read as off.
        let mut table = crate::runs::table::read_resolved(&config_path)?;
        if crate::runs::table::problem_of(&table) != "points" {
            bail!(
                "{} is not the config of a points run",
                config_path.display()
            );
        }
        table.remove(crate::runs::table::PROBLEM_KEY);
        let stored = PointsConfig::from_table(table, &config_path)?;
        let same = PointsConfig {
            output: None,
            ..stored
        } == PointsConfig {
            output: None,
            ..resolved.clone()
        };
        crate::error::ensure!(
            same,
            "{} describes another run than this config; resume with that config, or start \
             this one in a new folder",
            config_path.display()
        );
    } else if fits::any(dir) {
        bail!(
            "{} holds an unfinished points run ({}/); continue it with --resume or choose another output folder",
            dir.display(),
            fits::FITS_DIR
        );
    }
    let data = load_data(cfg)?;
    // The fits' work, before anything is written (a refused start leaves no folder).
    if cfg.sweep_pool.is_empty() {
        cfg.em_config(cfg.seed, cfg.pool)
            .check_work(data.train.len(), cfg.runs())?;
    }
    std::fs::create_dir_all(dir).doing("creating", dir)?;
    if !resume {
        ifslab::io::write_atomic(&config_path, resolved.to_toml()?.as_bytes())?;
    }
    if let Some(p) = &cfg.save_data {
        data.all.save(p)?;
    }
    progress.message(&format!(
        "{}: {} points in {} dimensions ({} training, {} held out)",
        data.source,
        data.all.len(),
        data.all.dim(),
        data.train.len(),
        data.test.len()
    ));
    let truth = cfg
        .truth
        .as_deref()
        .map(|t| Truth::load(t, data.all.dim()))
        .transpose()?;
    let mut summary = if cfg.sweep_pool.is_empty() {
        fit_runs(cfg, dir, &data, truth.as_ref(), start, &*progress)?
    } else {
        sweep::sweep(cfg, dir, &data, truth.as_ref(), start, &*progress)?
    };
    summary.seconds = start.elapsed().as_secs_f64();
    ifslab::io::write_atomic(
        &dir.join("summary.json"),
        serde_json::to_string_pretty(&summary)?.as_bytes(),
    )?;
    fits::clear(dir)?;
    Ok(summary)
}

/// The label of fitting run `r` under `fits/`.
fn run_label(r: usize) -> String {
    format!("run-{r:03}")
}

/// `runs` seeded EM fits, one after the other; the one `cfg.keep()` ranks first is kept and
/// written out with the GMM baselines.
fn fit_runs(
    cfg: &PointsConfig,
    dir: &Path,
    data: &Data,
    truth: Option<&Truth>,
    started: Instant,
    progress: &dyn Progress,
) -> crate::Result<PointsSummary> {
    let (train, heldout) = (&data.train, data.heldout());
    let mut runs = Vec::new();
    // The kept run: its held-out score, its rank under `cfg.keep()` (lower is better), its
    // closeness, index, fit.
    let mut best: Option<(f64, f64, Option<closeness::Closeness>, usize, EmFit)> = None;
    let mut resumed = 0;
    // The closeness needs data of at most three dimensions; the likelihood ranks the rest.
    let kept_by = match cfg.keep() {
        KeepBy::Closeness if data.all.dim() <= 3 => KeepBy::Closeness,
        _ => KeepBy::Likelihood,
    };
    for r in 0..cfg.runs() {
        let em = cfg.em_config(mix_seed(cfg.seed, r as u64), cfg.pool);
        let label = run_label(r);
        let (result, secs) = match fits::load(dir, &label, &em)? {
            Some((fit, secs)) => {
                resumed += 1;
                (fit.map_err(crate::Error::InvalidInput)?, secs)
            }
            None => {
                let t0 = Instant::now();
                progress.start(
                    &format!("EM run {}/{}", r + 1, cfg.runs()),
                    em.iterations as u64,
                );
                let result = fit(train, heldout, &em, &mut |e| {
                    if let Event::Iteration(_) = e {
                        progress.inc(1);
                    }
                })
                .with_context(|| format!("EM run {r}"))?;
                progress.finish();
                let secs = t0.elapsed().as_secs_f64();
                fits::save(dir, &label, &em, &Ok(result.clone()), secs)?;
                (result, secs)
            }
        };
        let score = result.model.mean_log_likelihood(heldout.unwrap_or(train))?;
        let train_ll = result.model.mean_log_likelihood(train)?;
        let against = truth.map(|t| t.compare(&result.model)).transpose()?;
        let close = closeness::closeness(&result.model, &data.all, 0)?;
        progress.message(&format!(
            "run {r}: held-out {score:.4} nats/point, train {train_ll:.4}, {}v_D {:.3}, mean depth {:.2}, {}converged{}, {secs:.1} s",
            close.map_or(String::new(), |c| format!("closeness {:.4}, ", c.chamfer())),
            result.model.deepest_weight(),
            result.model.mean_depth(),
            if result.converged { "" } else { "not " },
            against.map_or(String::new(), |a| format!(
                ", agreement with the truth {:.3}, scales within {:.4}",
                a.agreement, a.scale_error
            ))
        ));
        let repairs = result.degeneracy_counts();
        runs.push(json!({
            "truth_agreement": against.map(|a| a.agreement), "truth_iou": against.map(|a| a.iou),
            "truth_scale_error": against.map(|a| a.scale_error),
            "run": r, "seed": em.seed, "heldout_log_likelihood": score, "closeness": close,
            "train_log_likelihood": train_ll, "converged": result.converged,
            "deepest_weight": result.model.deepest_weight(), "mean_depth": result.model.mean_depth(),
            "chosen_candidate": result.chosen, "seconds": secs,
            "repairs": {"dead_components": repairs[0], "undetermined_rotations": repairs[1],
                        "clamped_scales": repairs[2], "non_finite": repairs[3]},
        }));
        let rank = match (kept_by, close) {
            (KeepBy::Closeness, Some(c)) => c.chamfer(),
            _ => -score,
        };
        if best.as_ref().is_none_or(|b| rank < b.1) {
            best = Some((score, rank, close, r, result));
        }
    }
    let converged_fits = runs
        .iter()
        .filter(|r| r["converged"] == json!(true))
        .count();
    let (best_score, _, best_close, best_run, result) = best.expect("at least one run");
    let out = outputs::write_fit(
        cfg, dir, data, &result, best_score, best_run, runs, started, progress,
    )?;
    let against = truth.map(|t| t.compare(&result.model)).transpose()?;
    Ok(PointsSummary {
        source: data.source.clone(),
        dim: data.all.dim(),
        points: [data.all.len(), data.train.len(), data.test.len()],
        fits: cfg.runs(),
        resumed_fits: resumed,
        failed_fits: 0,
        converged_fits,
        seconds: 0.0,
        best: Some(BestFit {
            run: best_run,
            heldout_log_likelihood: best_score,
            train_log_likelihood: result.model.mean_log_likelihood(train)?,
            converged: result.converged,
            mean_depth: result.model.mean_depth(),
            parameters: result.model.parameter_count(),
            deepest_weight: Some(result.model.deepest_weight()),
            truth_agreement: against.map(|a| a.agreement),
            truth_iou: against.map(|a| a.iou),
            closeness: best_close,
            kept_by: Some(kept_by),
            best_gmm_heldout_log_likelihood: out.best_gmm,
            gmm: out.gmm,
        }),
        sweep: Vec::new(),
    })
}
