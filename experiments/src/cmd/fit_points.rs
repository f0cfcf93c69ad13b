//! `ifslab fit-points DATA --k K --depth D --pool P -o DIR`: fit an IFS of similitudes to a
//! point cloud of any dimension with EM (Bloem & de Rooij), compare its held-out
//! log-likelihood with isotropic and full-covariance Gaussian mixtures, and write the code,
//! a log-likelihood curve and (2-D/3-D) a scatter of data against model samples.
//!
//! With `--sweep-pool 1,2,4,…` it instead measures the proportion of converged runs per
//! pre-selection pool size over `--repeats` seeded runs (the paper's Fig. 5b). With
//! `--truth CODE.json` (2-D) every fit is also compared with the code that made the data:
//! the agreement of the two attractors' coverage and the largest difference of their sorted
//! scales, since a run can meet the convergence criterion with a wrong code.
//!
//! The defaults are ifslab's (see `ifslab_strategies::problems::em::EmConfig`); `--paper` runs the
//! paper's algorithm instead.
//!
//! Every finished fit is checkpointed; `ifslab fit-points --resume DIR` continues a killed
//! run. Arguments only: the flags become a `PointsConfig` (the `problem = "points"` config
//! of `ifslab run`, one key per flag) and `ifslab_experiments::runs::points` does the work.

use std::path::PathBuf;

use anyhow::Context;
use ifslab_experiments::runs::RunConfig;
use ifslab_experiments::runs::inversion::CONFIG_FILE;
use ifslab_experiments::runs::points::{self, PointsConfig};
use ifslab_strategies::problems::em::{ComponentUpdate, PreselectBy};

use crate::bars::Bar;

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Update {
    /// Every occurrence of a map in a code informs its update (default).
    AllPositions,
    /// Only codes whose outermost map it is (the paper's rule).
    Outermost,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum SelectBy {
    /// Highest log-likelihood of the evaluation points (default).
    LogLikelihood,
    /// Highest mean depth (the paper's criterion).
    MeanDepth,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum Keep {
    /// The attractor closest to the cloud, both ways (default).
    Closeness,
    /// The best held-out log-likelihood (with --paper).
    Likelihood,
}

#[derive(clap::ValueEnum, Clone, Copy, Debug)]
pub enum PreselectSchedule {
    /// Depths 1, 2, …, --preselect-depth in turn (default).
    Curriculum,
    /// Every iteration at --preselect-depth (the paper).
    Fixed,
}

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Point cloud: CSV/text (one point per line) or NumPy .npy (N×H), any dimension H;
    /// or `ifs:NAME` / `ifs:CODE.json` to sample --points points from a code.
    #[arg(required_unless_present = "resume")]
    pub data: Option<String>,
    /// Number of similitudes K.
    #[arg(long, default_value_t = 3)]
    pub k: usize,
    /// Maximum code depth D.
    #[arg(long, default_value_t = 6)]
    pub depth: usize,
    /// Pre-selection pool size (1 = a single random start).
    #[arg(long, default_value_t = 10)]
    pub pool: usize,
    /// Output folder.
    #[arg(short, long, required_unless_present = "resume")]
    pub output: Option<PathBuf>,
    /// Continue the interrupted run in this folder (its config.toml says what it is): the
    /// fits it finished are read back, the others run.
    #[arg(long, conflicts_with = "data")]
    pub resume: Option<PathBuf>,
    /// EM iterations at depth D (300, 3e2, 1K).
    #[arg(long, visible_alias = "iters", default_value = "300", value_parser = count)]
    pub iterations: usize,
    /// Minibatch size N′ (0 = full batch).
    #[arg(long, default_value_t = 500)]
    pub batch: usize,
    /// Deepest depth of the pre-selection runs.
    #[arg(long, default_value_t = 3)]
    pub preselect_depth: usize,
    /// Iterations of each pre-selection run (the paper's 100).
    #[arg(long, default_value_t = 100)]
    pub preselect_iterations: usize,
    /// How pre-selection candidates are trained.
    #[arg(long, value_enum, default_value = "curriculum")]
    pub preselect_schedule: PreselectSchedule,
    /// How the pre-selection winner is chosen.
    #[arg(long, value_enum, default_value = "log-likelihood")]
    pub preselect_by: SelectBy,
    /// Orientations tried per component by the re-orientation search (0 = off) [default:
    /// 36; for one or two maps as many as cost what 36 cost four: 3,096 at depth 6].
    #[arg(long)]
    pub reorient: Option<usize>,
    /// Re-orientation search every this many main iterations (0 = only in pre-selection).
    #[arg(long, default_value_t = 100)]
    pub reorient_every: usize,
    /// Training points that score candidates and re-orientations (0 = all).
    #[arg(long, default_value_t = 1000)]
    pub eval_points: usize,
    /// Keep the base Gaussian where pre-selection left it (no moment matching).
    #[arg(long)]
    pub no_recentre: bool,
    /// Component update rule of the M-step.
    #[arg(long, value_enum, default_value = "all-positions")]
    pub update: Update,
    /// Maps rotate only (the paper's similitudes); by default they may also reflect.
    #[arg(long)]
    pub no_reflections: bool,
    /// No word search: a component that settled on a two-map word of the code (`S_a∘S_b`)
    /// is left there; by default it is replaced by the map it is made of.
    #[arg(long)]
    pub no_words: bool,
    /// Leave isolated points (stray outliers) out before fitting.
    #[arg(long)]
    pub trim_outliers: bool,
    /// The paper's algorithm: outermost update, fixed-depth pre-selection by mean depth,
    /// no re-orientation or word search, no recentring.
    #[arg(long, conflicts_with_all = ["preselect_schedule", "preselect_by", "reorient", "reorient_every", "no_recentre", "update", "no_reflections", "no_words", "trim_outliers"])]
    pub paper: bool,
    /// Independent runs, one kept (--keep) [default: 8 for up to three maps, 4 for four
    /// and five, else 1; with --paper 1].
    #[arg(long)]
    pub runs: Option<usize>,
    /// Which of the runs is kept: the one whose attractor lies closest to the cloud (the
    /// trimmed mean distances from the data to 20,000 attractor points and back), or the
    /// best held-out log-likelihood [default: closeness; with --paper likelihood].
    #[arg(long, value_enum)]
    pub keep: Option<Keep>,
    /// Fraction of the points held out for evaluation.
    #[arg(long, default_value_t = 0.1)]
    pub heldout: f64,
    /// Evaluate the held-out log-likelihood every this many iterations.
    #[arg(long, default_value_t = 10)]
    pub eval_every: usize,
    /// Seed (data sampling, split, initialisation, minibatches).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Points to sample when DATA is `ifs:…`.
    #[arg(long, default_value_t = 20_000)]
    pub points: usize,
    /// Also write the (sampled or loaded) points here (.csv or .npy).
    #[arg(long)]
    pub save_data: Option<PathBuf>,
    /// The code that made the data (2-D or 3-D): report each fit's coverage agreement with
    /// it (the share of covered pixels within one pixel of the other's, at 128², or voxels
    /// at 64³), their plain IoU, and the largest difference of the sorted scales.
    #[arg(long)]
    pub truth: Option<String>,
    /// Gaussian-mixture baselines: component counts (default: K, and the largest counts
    /// with no more parameters than the IFS model).
    #[arg(long, value_delimiter = ',')]
    pub gmm: Vec<usize>,
    /// Sweep mode: pre-selection pool sizes to compare (writes pool_sweep.csv/png only).
    #[arg(long, value_delimiter = ',')]
    pub sweep_pool: Vec<usize>,
    /// Sweep mode: seeded runs per pool size.
    #[arg(long, default_value_t = 16)]
    pub repeats: usize,
    /// Points in the render of a 2-D fit.
    #[arg(long, default_value_t = 2_000_000)]
    pub render_points: u64,
}

impl Args {
    /// The points config these flags describe.
    fn config(&self) -> PointsConfig {
        let chosen = |v| (!self.paper).then_some(v);
        PointsConfig {
            data: self.data.clone().unwrap_or_default(),
            points: self.points,
            k: self.k,
            depth: self.depth,
            pool: self.pool,
            iterations: self.iterations,
            batch: self.batch,
            preselect_depth: self.preselect_depth,
            preselect_iterations: self.preselect_iterations,
            preselect_schedule: (!self.paper).then_some(match self.preselect_schedule {
                PreselectSchedule::Curriculum => points::PreselectSchedule::Curriculum,
                PreselectSchedule::Fixed => points::PreselectSchedule::Fixed,
            }),
            preselect_by: (!self.paper).then_some(match self.preselect_by {
                SelectBy::LogLikelihood => PreselectBy::LogLikelihood,
                SelectBy::MeanDepth => PreselectBy::MeanDepth,
            }),
            reorient: self.reorient,
            reorient_every: chosen(self.reorient_every),
            recentre: (!self.paper).then_some(!self.no_recentre),
            update: (!self.paper).then_some(match self.update {
                Update::AllPositions => ComponentUpdate::AllPositions,
                Update::Outermost => ComponentUpdate::Outermost,
            }),
            reflections: (!self.paper).then_some(!self.no_reflections),
            words: (!self.paper).then_some(!self.no_words),
            trim_outliers: self.trim_outliers.then_some(true),
            paper: self.paper,
            eval_points: self.eval_points,
            runs: self.runs,
            keep: self.keep.map(|k| match k {
                Keep::Closeness => points::KeepBy::Closeness,
                Keep::Likelihood => points::KeepBy::Likelihood,
            }),
            heldout: self.heldout,
            eval_every: self.eval_every,
            seed: self.seed,
            save_data: self.save_data.clone(),
            truth: self.truth.clone(),
            gmm: self.gmm.clone(),
            sweep_pool: self.sweep_pool.clone(),
            repeats: self.repeats,
            render_points: self.render_points,
            output: self.output.clone(),
        }
    }
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let (cfg, dir, resume) = match &a.resume {
        Some(dir) => (
            RunConfig::load_resolved(&dir.join(CONFIG_FILE))
                .with_context(|| format!("{} holds no points run to resume", dir.display()))?,
            dir.clone(),
            true,
        ),
        None => {
            let cfg = a.config();
            cfg.validate().map_err(|e| flag_names(e.into()))?;
            let dir = cfg.output.clone().context("clap: -o or --resume")?;
            (RunConfig::Points(Box::new(cfg)), dir, false)
        }
    };
    anyhow::ensure!(
        cfg.problem() == "points",
        "{} holds a `{}` run, not a points run",
        dir.display(),
        cfg.problem()
    );
    cfg.run(&dir, resume, Box::new(Bar::logging()))?;
    Ok(())
}

/// A config error in the words of the command line: `` `sweep_pool` `` is `--sweep-pool`.
fn flag_names(e: anyhow::Error) -> anyhow::Error {
    let text = format!("{e:#}");
    let mut out = String::new();
    let mut parts = text.split('`');
    out.push_str(parts.next().unwrap_or(""));
    for (i, p) in parts.enumerate() {
        if i % 2 == 0 && !p.is_empty() && p.chars().all(|c| c.is_ascii_lowercase() || c == '_') {
            out.push_str(&format!("--{}", p.replace('_', "-")));
        } else if i % 2 == 0 {
            out.push('`');
            out.push_str(p);
            out.push('`');
        } else {
            out.push_str(p);
        }
    }
    anyhow::anyhow!(out)
}

/// A count as [`ifslab::budget::parse_count`] reads it (`300`, `3e2`, `1K`), as a `usize`.
fn count(text: &str) -> Result<usize, String> {
    let n = ifslab::budget::parse_count(text)?;
    usize::try_from(n).map_err(|_| format!("`{text}` is too large a count"))
}
