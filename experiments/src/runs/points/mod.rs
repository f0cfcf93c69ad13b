//! Point cloud → IFS of similitudes by EM (Bloem & de Rooij), as a run: a [`PointsConfig`]
//! in, a run folder out.
//!
//! A run loads a point cloud (CSV/text or `.npy`, any dimension) or samples one from a code
//! (`ifs:NAME`), holds out a share of it, and then either
//! - fits `runs` seeded EM runs and keeps the one with the best held-out log-likelihood,
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

pub mod fits;
mod outputs;
mod sweep;
pub mod truth;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, bail};
use ifslab::chaos::{ChaosGame, generate_nd, mix_seed};
use ifslab_strategies::problems::em::{
    ComponentUpdate, EmConfig, EmFit, Event, MStepConfig, PointSet, PreselectBy, ReorientConfig,
    fit,
};
use serde::{Deserialize, Serialize};
use serde_json::json;

use crate::codes::resolve_code;
use crate::progress::Progress;
use crate::runs::config::{PROBLEM_KEY, RunConfig};
use crate::runs::inversion::CONFIG_FILE;
use truth::Truth;

/// How pre-selection candidates are trained.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PreselectSchedule {
    /// Depths 1, 2, …, `preselect_depth` in turn (ifslab's default).
    Curriculum,
    /// Every iteration at `preselect_depth` (the paper).
    Fixed,
}

/// A points run: what `ifslab fit-points` takes as flags, one key per flag (`--sweep-pool`
/// is `sweep_pool`, `--no-recentre` is `recentre = false`). Every default is ifslab's;
/// `paper = true` runs the paper's algorithm, and then the six choices it fixes
/// (`preselect_schedule`, `preselect_by`, `reorient`, `reorient_every`, `recentre`,
/// `update`) may only be left out or given the paper's values.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct PointsConfig {
    /// Point cloud: CSV/text (one point per line) or NumPy `.npy` (N×H), any dimension H;
    /// or `ifs:NAME` / `ifs:CODE.json` to sample `points` points from a code.
    pub data: String,
    /// Points to sample when `data` is `ifs:…`.
    pub points: usize,
    /// Number of similitudes K.
    pub k: usize,
    /// Maximum code depth D.
    pub depth: usize,
    /// Pre-selection pool size (1 = a single random start).
    pub pool: usize,
    /// EM iterations at depth D.
    pub iterations: usize,
    /// Minibatch size N′ (0 = full batch).
    pub batch: usize,
    /// Deepest depth of the pre-selection runs.
    pub preselect_depth: usize,
    /// Iterations of each pre-selection run (the paper's 100).
    pub preselect_iterations: usize,
    /// How pre-selection candidates are trained [default: curriculum; paper: fixed].
    pub preselect_schedule: Option<PreselectSchedule>,
    /// How the pre-selection winner is chosen [default: log-likelihood; paper: mean-depth].
    pub preselect_by: Option<PreselectBy>,
    /// Orientations tried per component by the re-orientation search, 0 = off
    /// [default: 12; paper: 0].
    pub reorient: Option<usize>,
    /// Re-orientation search every this many main iterations, 0 = only in pre-selection
    /// [default: 100; paper: 0].
    pub reorient_every: Option<usize>,
    /// Move the base Gaussian to the invariant measure's mean and spread before the main run
    /// [default: true; paper: false].
    pub recentre: Option<bool>,
    /// Component update rule of the M-step [default: all-positions; paper: outermost].
    pub update: Option<ComponentUpdate>,
    /// The paper's algorithm: outermost update, fixed-depth pre-selection by mean depth, no
    /// re-orientation, no recentring.
    pub paper: bool,
    /// Training points that score candidates and re-orientations (0 = all).
    pub eval_points: usize,
    /// Independent runs; the one with the best held-out log-likelihood is kept.
    pub runs: usize,
    /// Fraction of the points held out for evaluation.
    pub heldout: f64,
    /// Evaluate the held-out log-likelihood every this many iterations.
    pub eval_every: usize,
    /// Seed (data sampling, split, initialisation, minibatches).
    pub seed: u64,
    /// Also write the (sampled or loaded) points here (.csv or .npy).
    pub save_data: Option<PathBuf>,
    /// The code that made the data (2-D): each fit's coverage agreement with it and the
    /// largest difference of the sorted scales are reported.
    pub truth: Option<String>,
    /// Gaussian-mixture baselines: component counts (empty: K, and the largest counts with
    /// no more parameters than the IFS model).
    pub gmm: Vec<usize>,
    /// Pool sweep: pre-selection pool sizes to compare (writes `pool_sweep.*` instead of a
    /// fit); empty: no sweep.
    pub sweep_pool: Vec<usize>,
    /// Pool sweep: seeded runs per pool size.
    pub repeats: usize,
    /// Points in the render of a 2-D fit.
    pub render_points: u64,
    /// The run folder (the command line's `-o` wins).
    pub output: Option<PathBuf>,
}

impl Default for PointsConfig {
    fn default() -> Self {
        PointsConfig {
            data: String::new(),
            points: 20_000,
            k: 3,
            depth: 6,
            pool: 10,
            iterations: 300,
            batch: 500,
            preselect_depth: 3,
            preselect_iterations: 100,
            preselect_schedule: None,
            preselect_by: None,
            reorient: None,
            reorient_every: None,
            recentre: None,
            update: None,
            paper: false,
            eval_points: 1000,
            runs: 1,
            heldout: 0.1,
            eval_every: 10,
            seed: 0,
            save_data: None,
            truth: None,
            gmm: Vec::new(),
            sweep_pool: Vec::new(),
            repeats: 16,
            render_points: 2_000_000,
            output: None,
        }
    }
}

/// The six choices `paper = true` fixes, as (schedule, by, reorient, every, recentre, update).
type Choices = (
    PreselectSchedule,
    PreselectBy,
    usize,
    usize,
    bool,
    ComponentUpdate,
);

fn choices(paper: bool) -> Choices {
    let e = if paper {
        EmConfig::paper()
    } else {
        EmConfig::default()
    };
    (
        if e.curriculum {
            PreselectSchedule::Curriculum
        } else {
            PreselectSchedule::Fixed
        },
        e.preselect_by,
        e.reorient.rotations,
        e.reorient.every,
        e.recentre,
        e.mstep.update,
    )
}

impl PointsConfig {
    /// Parses TOML text (without the `problem` key) and validates it; `origin` names the
    /// text in errors.
    pub fn from_toml(text: &str, origin: &Path) -> anyhow::Result<Self> {
        let cfg: PointsConfig = toml::from_str(text)
            .with_context(|| format!("{} is not a valid points config", origin.display()))?;
        cfg.validate()
            .with_context(|| format!("{} is not a valid points config", origin.display()))?;
        Ok(cfg)
    }

    /// The same config with its relative file names (point file, `ifs:` code file, truth
    /// code file, `save_data`) read as relative to `dir`, the folder of its config file.
    pub fn relative_to(mut self, dir: &Path) -> Self {
        let file_spec = |spec: &str| -> Option<String> {
            let p = Path::new(spec);
            (p.is_relative() && dir.join(p).is_file())
                .then(|| dir.join(p).to_string_lossy().into_owned())
        };
        if let Some(code) = self.data.strip_prefix("ifs:") {
            if let Some(s) = file_spec(code) {
                self.data = format!("ifs:{s}");
            }
        } else if Path::new(&self.data).is_relative() && !self.data.is_empty() {
            self.data = dir.join(&self.data).to_string_lossy().into_owned();
        }
        if let Some(t) = &self.truth
            && let Some(s) = file_spec(t)
        {
            self.truth = Some(s);
        }
        for p in [&mut self.save_data, &mut self.output]
            .into_iter()
            .flatten()
        {
            if p.is_relative() {
                *p = dir.join(&*p);
            }
        }
        self
    }

    /// Every file it names made absolute (against the working directory) and every choice
    /// written out: what a run folder's `config.toml` holds.
    pub fn resolved(&self) -> anyhow::Result<Self> {
        let abs =
            |p: &Path| std::path::absolute(p).with_context(|| format!("resolving {}", p.display()));
        let file_spec = |spec: &str| -> anyhow::Result<String> {
            let p = Path::new(spec);
            Ok(if p.is_file() {
                abs(p)?.to_string_lossy().into_owned()
            } else {
                spec.to_string()
            })
        };
        let mut c = self.clone();
        c.data = match self.data.strip_prefix("ifs:") {
            Some(code) => format!("ifs:{}", file_spec(code)?),
            None => abs(Path::new(&self.data))?.to_string_lossy().into_owned(),
        };
        c.truth = self.truth.as_deref().map(file_spec).transpose()?;
        c.save_data = self.save_data.as_deref().map(abs).transpose()?;
        c.output = self.output.as_deref().map(abs).transpose()?;
        let (s, b, r, e, rc, u) = self.choices();
        c.preselect_schedule = Some(s);
        c.preselect_by = Some(b);
        c.reorient = Some(r);
        c.reorient_every = Some(e);
        c.recentre = Some(rc);
        c.update = Some(u);
        Ok(c)
    }

    /// The six choices `paper` fixes, as given or by default.
    fn choices(&self) -> Choices {
        let d = choices(self.paper);
        (
            self.preselect_schedule.unwrap_or(d.0),
            self.preselect_by.unwrap_or(d.1),
            self.reorient.unwrap_or(d.2),
            self.reorient_every.unwrap_or(d.3),
            self.recentre.unwrap_or(d.4),
            self.update.unwrap_or(d.5),
        )
    }

    /// Checks every field before anything runs; errors name the field and say what to change.
    pub fn validate(&self) -> anyhow::Result<()> {
        if self.data.is_empty() {
            bail!(
                "`data` is missing: name a point cloud (.csv, .txt or .npy) or `ifs:NAME` to sample one from a code"
            );
        }
        if self.data.starts_with("ifs:") && self.points == 0 {
            bail!("`points` must be at least 1 to sample `{}`", self.data);
        }
        if self.runs == 0 {
            bail!("`runs` must be at least 1");
        }
        if !(0.0..1.0).contains(&self.heldout) {
            bail!(
                "`heldout` is the share of points held out: give a number in [0, 1), got {}",
                self.heldout
            );
        }
        if !self.sweep_pool.is_empty() {
            if self.repeats == 0 {
                bail!("`repeats` must be at least 1");
            }
            if let Some(p) = self.sweep_pool.iter().find(|&&p| p == 0) {
                bail!("`sweep_pool` sizes must be at least 1, got {p}");
            }
        }
        if self.paper {
            let paper = choices(true);
            let given = [
                (
                    "preselect_schedule",
                    self.preselect_schedule.map(|v| v != paper.0),
                ),
                ("preselect_by", self.preselect_by.map(|v| v != paper.1)),
                ("reorient", self.reorient.map(|v| v != paper.2)),
                ("reorient_every", self.reorient_every.map(|v| v != paper.3)),
                ("recentre", self.recentre.map(|v| v != paper.4)),
                ("update", self.update.map(|v| v != paper.5)),
            ];
            if let Some((name, _)) = given.iter().find(|(_, differs)| *differs == Some(true)) {
                bail!(
                    "`{name}` conflicts with `paper = true`, which fixes it to the paper's choice; \
                     leave `{name}` out or set `paper = false`"
                );
            }
        }
        for pool in self.sweep_pool.iter().copied().chain([self.pool]) {
            self.em_config(self.seed, pool).validate()?;
        }
        Ok(())
    }

    /// The EM config of one fit.
    pub fn em_config(&self, seed: u64, pool: usize) -> EmConfig {
        let (schedule, by, rotations, every, recentre, update) = self.choices();
        let base = if self.paper {
            EmConfig::paper()
        } else {
            EmConfig::default()
        };
        EmConfig {
            components: self.k,
            depth: self.depth,
            iterations: self.iterations,
            batch_size: self.batch,
            pool,
            preselect_depth: self.preselect_depth,
            preselect_iterations: self.preselect_iterations,
            curriculum: schedule == PreselectSchedule::Curriculum,
            preselect_by: by,
            reorient: ReorientConfig { rotations, every },
            recentre,
            mstep: MStepConfig {
                update,
                ..base.mstep.clone()
            },
            eval_points: self.eval_points,
            eval_every: self.eval_every,
            seed,
            ..base
        }
    }

    /// TOML text of the resolved config, `problem = "points"` first: a run folder's
    /// `config.toml`, which `ifslab run` reads back as the same run.
    pub fn to_toml(&self) -> anyhow::Result<String> {
        Ok(format!(
            "{PROBLEM_KEY} = \"points\"\n{}",
            toml::to_string_pretty(&self.resolved()?)?
        ))
    }
}

/// The data of a run: all points, the training and held-out parts, and where they came from.
pub struct Data {
    /// Every point.
    pub all: PointSet,
    /// The training points.
    pub train: PointSet,
    /// The held-out points (may be empty).
    pub test: PointSet,
    /// Where the points came from, in words.
    pub source: String,
}

impl Data {
    /// The held-out points, if any.
    pub fn heldout(&self) -> Option<&PointSet> {
        (!self.test.is_empty()).then_some(&self.test)
    }
}

/// Loads the config's point cloud or samples it from a code, and splits it.
pub fn load_data(cfg: &PointsConfig) -> anyhow::Result<Data> {
    let (all, source) = if let Some(spec) = cfg.data.strip_prefix("ifs:") {
        let code = resolve_code(spec).with_context(|| format!("`data` {}", cfg.data))?;
        let probs = code.evaluation_probabilities()?;
        // Many short trajectories: points close to independent draws from the measure.
        let per = 50usize;
        let game = ChaosGame {
            trajectories: cfg.points.div_ceil(per),
            length: per + 30,
            warmup: 30,
            start_half_width: 1.0,
            seed: mix_seed(cfg.seed, 0xda7a),
        };
        let pts = generate_nd(&game, &code.maps, &probs)?;
        let all = PointSet::new(code.dim(), pts)?;
        let src = format!(
            "{} points sampled from `{spec}` by the chaos game (seed {})",
            cfg.points, cfg.seed
        );
        (all.head(cfg.points), src)
    } else {
        let p =
            PointSet::load(&cfg.data).with_context(|| format!("`data`: reading {}", cfg.data))?;
        (p, cfg.data.clone())
    };
    let (train, test) = all.split(cfg.heldout, cfg.seed)?;
    if train.len() < cfg.k {
        bail!(
            "{} training points (after holding out {}) for k = {}: give at least as many \
             points as components, or lower `k` / `heldout`",
            train.len(),
            test.len(),
            cfg.k
        );
    }
    Ok(Data {
        all,
        train,
        test,
        source,
    })
}

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
    /// Coverage agreement with `truth`, when one was given.
    pub truth_agreement: Option<f64>,
    /// The best Gaussian mixture's held-out log-likelihood among the baselines.
    pub best_gmm_heldout_log_likelihood: Option<f64>,
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
) -> anyhow::Result<PointsSummary> {
    let start = Instant::now();
    cfg.validate()?;
    let resolved = cfg.resolved()?;
    let config_path = dir.join(CONFIG_FILE);
    if resume {
        let stored = std::fs::read_to_string(&config_path).with_context(|| {
            format!(
                "{} holds no points run to resume (no {CONFIG_FILE})",
                dir.display()
            )
        })?;
        let RunConfig::Points(stored) = RunConfig::from_toml(&stored, &config_path)? else {
            bail!(
                "{} is not the config of a points run",
                config_path.display()
            );
        };
        let same = PointsConfig {
            output: None,
            ..*stored
        } == PointsConfig {
            output: None,
            ..resolved.clone()
        };
        anyhow::ensure!(
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
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
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

/// `runs` seeded EM fits, one after the other; the best held-out likelihood is kept and
/// written out with the GMM baselines.
fn fit_runs(
    cfg: &PointsConfig,
    dir: &Path,
    data: &Data,
    truth: Option<&Truth>,
    started: Instant,
    progress: &dyn Progress,
) -> anyhow::Result<PointsSummary> {
    let (train, heldout) = (&data.train, data.heldout());
    let mut runs = Vec::new();
    let mut best: Option<(f64, usize, EmFit)> = None;
    let mut resumed = 0;
    for r in 0..cfg.runs {
        let em = cfg.em_config(mix_seed(cfg.seed, r as u64), cfg.pool);
        let label = run_label(r);
        let (result, secs) = match fits::load(dir, &label, &em)? {
            Some((fit, secs)) => {
                resumed += 1;
                (fit.map_err(anyhow::Error::msg)?, secs)
            }
            None => {
                let t0 = Instant::now();
                progress.start(
                    &format!("EM run {}/{}", r + 1, cfg.runs),
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
        progress.message(&format!(
            "run {r}: held-out {score:.4} nats/point, train {train_ll:.4}, v_D {:.3}, mean depth {:.2}, {}converged{}, {secs:.1} s",
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
            "truth_agreement": against.map(|a| a.agreement), "truth_scale_error": against.map(|a| a.scale_error),
            "run": r, "seed": em.seed, "heldout_log_likelihood": score,
            "train_log_likelihood": train_ll, "converged": result.converged,
            "deepest_weight": result.model.deepest_weight(), "mean_depth": result.model.mean_depth(),
            "chosen_candidate": result.chosen, "seconds": secs,
            "repairs": {"dead_components": repairs[0], "undetermined_rotations": repairs[1],
                        "clamped_scales": repairs[2], "non_finite": repairs[3]},
        }));
        if best.as_ref().is_none_or(|b| score > b.0) {
            best = Some((score, r, result));
        }
    }
    let (best_score, best_run, result) = best.expect("at least one run");
    let out = outputs::write_fit(
        cfg, dir, data, &result, best_score, best_run, runs, started, progress,
    )?;
    let against = truth.map(|t| t.compare(&result.model)).transpose()?;
    Ok(PointsSummary {
        source: data.source.clone(),
        dim: data.all.dim(),
        points: [data.all.len(), data.train.len(), data.test.len()],
        fits: cfg.runs,
        resumed_fits: resumed,
        failed_fits: 0,
        seconds: 0.0,
        best: Some(BestFit {
            run: best_run,
            heldout_log_likelihood: best_score,
            train_log_likelihood: result.model.mean_log_likelihood(train)?,
            converged: result.converged,
            mean_depth: result.model.mean_depth(),
            parameters: result.model.parameter_count(),
            truth_agreement: against.map(|a| a.agreement),
            best_gmm_heldout_log_likelihood: out.best_gmm,
        }),
        sweep: Vec::new(),
    })
}
