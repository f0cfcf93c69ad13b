//! The config of a points run: one key per flag of `ifslab fit-points`, validated with
//! errors that name the key, resolved (files absolute, every choice written out) for the run
//! folder's `config.toml`, and turned into the EM config of each fit.

use std::path::{Path, PathBuf};

use crate::error::{Context, IoContext, bail};
use ifslab_strategies::problems::em::{
    ComponentUpdate, EmConfig, MStepConfig, PreselectBy, ReorientConfig, code_count,
};
use serde::{Deserialize, Serialize};

use crate::runs::table::PROBLEM_KEY;

mod defaults;
mod read;

use defaults::{Choices, choices, default_runs};

/// How pre-selection candidates are trained.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PreselectSchedule {
    /// Depths 1, 2, …, `preselect_depth` in turn (ifslab's default).
    Curriculum,
    /// Every iteration at `preselect_depth` (the paper).
    Fixed,
}

/// Which of a run's independent fits is kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum KeepBy {
    /// The best held-out log-likelihood (the mixture of Gaussians at depth D).
    Likelihood,
    /// The attractor closest to the data, both ways ([`super::closeness`]); fits of data
    /// of more than three dimensions are ranked by the likelihood.
    Closeness,
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
    /// [default: 36, or 3,096 for one or two maps at depth 6 ([`default_reorient`](defaults::default_reorient));
    /// paper: 0].
    pub reorient: Option<usize>,
    /// Re-orientation search every this many main iterations, 0 = only in pre-selection
    /// [default: 100; paper: 0].
    pub reorient_every: Option<usize>,
    /// Move the base Gaussian to the invariant measure's mean and spread before the main run
    /// [default: true; paper: false].
    pub recentre: Option<bool>,
    /// Component update rule of the M-step [default: all-positions; paper: outermost].
    pub update: Option<ComponentUpdate>,
    /// Maps may reflect as well as rotate (orthogonal parts of either determinant)
    /// [default: true; paper: false]. A resolved config writes it only when true, so a
    /// run folder written before it existed (it had none) reads as the run it was.
    #[serde(skip_serializing_if = "not_true")]
    pub reflections: Option<bool>,
    /// The word search: a component that fits a two-map word of the code (`S_a∘S_b`,
    /// `S_a∘S_a`) is replaced by the map it is made of, tried wherever the re-orientation
    /// search runs [default: true; paper: false]. Written only when true, so a run folder
    /// written before it existed reads as the run it was.
    #[serde(skip_serializing_if = "not_true")]
    pub words: Option<bool>,
    /// Leave out isolated points before fitting (their distance to their 8th nearest
    /// neighbour over 4 robust standard deviations above the median, log scale; at most
    /// 5 % of the points) [default: false: it did not help on the robustness suite]. Written
    /// only when true.
    #[serde(skip_serializing_if = "not_true")]
    pub trim_outliers: Option<bool>,
    /// The paper's algorithm: outermost update, fixed-depth pre-selection by mean depth, no
    /// re-orientation or word search, no recentring.
    pub paper: bool,
    /// Training points that score candidates and re-orientations (0 = all).
    pub eval_points: usize,
    /// Independent runs; one is kept, as `keep` says [default: 8
    /// for up to three maps, 4 for four and five, else 1 ([`default_runs`]); paper: 1].
    pub runs: Option<usize>,
    /// Which of the runs is kept [default: closeness; paper: likelihood]. Written only
    /// when it is closeness and there is more than one run, so a run folder written before
    /// it existed reads as the run it was.
    #[serde(skip_serializing_if = "keeps_by_likelihood")]
    pub keep: Option<KeepBy>,
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
            reflections: None,
            words: None,
            trim_outliers: None,
            paper: false,
            eval_points: 1000,
            runs: None,
            keep: None,
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

fn not_true(v: &Option<bool>) -> bool {
    *v != Some(true)
}

fn keeps_by_likelihood(v: &Option<KeepBy>) -> bool {
    *v != Some(KeepBy::Closeness)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn written(cfg: PointsConfig) -> String {
        toml::to_string(&cfg.resolved().unwrap()).unwrap()
    }

    #[test]
    fn the_kept_run_is_named_only_where_the_closeness_keeps_it() {
        let base = PointsConfig {
            data: "ifs:sierpinski".into(),
            ..PointsConfig::default()
        };
        // Eight runs of three maps: kept by closeness, and the config says so.
        assert_eq!(base.keep(), KeepBy::Closeness);
        assert!(written(base.clone()).contains("keep = \"closeness\""));
        // One run, the paper's recipe or the likelihood asked for: written as before the
        // key existed, so those runs keep their ids.
        for cfg in [
            PointsConfig {
                runs: Some(1),
                ..base.clone()
            },
            PointsConfig {
                paper: true,
                ..base.clone()
            },
            PointsConfig {
                keep: Some(KeepBy::Likelihood),
                ..base.clone()
            },
        ] {
            assert_eq!(cfg.keep(), KeepBy::Likelihood);
            assert!(!written(cfg).contains("keep"));
        }
        // A closeness asked for with one run is no choice at all.
        let one = PointsConfig {
            runs: Some(1),
            keep: Some(KeepBy::Closeness),
            ..base
        };
        assert_eq!(one.keep(), KeepBy::Likelihood);
    }
}
