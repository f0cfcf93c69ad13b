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
    /// [default: 36, or 3,096 for one or two maps at depth 6 ([`default_reorient`]);
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

/// The six choices `paper = true` fixes, as (schedule, by, reorient, every, recentre, update).
type Choices = (
    PreselectSchedule,
    PreselectBy,
    usize,
    usize,
    bool,
    ComponentUpdate,
);

/// ifslab's orientations per component of the re-orientation search for point clouds of
/// three or more maps: turns by 10° in 2-D, 35 Haar-random rotations in 3-D (12, the EM
/// module's own default, left a third of the robustness suite's 3-D clouds unrecovered;
/// robustness/README.md).
pub const DEFAULT_REORIENT: usize = 36;

/// Candidate × code evaluations one component's search costs at the default for four maps
/// at depth 6 (36 orientations, 5,461 codes).
const REORIENT_BUDGET: usize = DEFAULT_REORIENT * 4 * 5461;

/// ifslab's orientations per component for K maps at depth D. A code of one or two maps
/// gets as many as cost what 36 cost four maps at depth 6 (a search costs K × orientations
/// × codes): 3,096 at depth 6, at most 4,096; sets that large are screened on an eighth of
/// the points (`em::reorient`). Its pieces are few and cheap to search, and a piece turned
/// wrong was the commonest way a two-map dust failed; on the robustness suite's two tuning
/// splits the twelve 3-D two-map clouds kept their count (11 of 12) and rose from 0.89 to
/// 0.95 mean agreement. Three or more maps get [`DEFAULT_REORIENT`] (239 for three maps,
/// at the same cost, was better on one tuning split and worse on the other).
pub fn default_reorient(k: usize, depth: usize) -> usize {
    if k > 2 {
        return DEFAULT_REORIENT;
    }
    let per = k.max(1).saturating_mul(code_count(k.max(1), depth).max(1));
    (REORIENT_BUDGET / per).clamp(DEFAULT_REORIENT, 4096)
}

/// ifslab's independent runs for K maps, one kept (`keep`): 8 for up to
/// three maps, 4 for four and five (the robustness suite's range), 1 from six on. Eight runs
/// of two or three maps cost about what four runs of five do: on the three tuning splits'
/// 48 two- and three-map 3-D clouds they recovered 47 against 45 with four (mean agreement
/// 0.936 → 0.962), on the 24 such 2-D clouds 23 either way (mean 0.978 → 0.986). Four runs
/// against one: the held-out likelihood picked a right fit among the runs every time one was
/// there, 24 of 24 two- and three-map 3-D clouds recovered against 20 with one run; for four
/// maps 21 of 24 3-D clouds against 19 and 12 of 12 2-D clouds either way with a higher mean
/// agreement; for five maps 12 of 12 3-D clouds against 11 on the third split and the mean
/// agreement up on all three. With the E-step that skips far codes, four runs of five maps
/// take about what one took before it (a fit of five maps at depth 6: 29 s, now 6 s a run).
pub fn default_runs(k: usize) -> usize {
    match k {
        0..=3 => 8,
        4 | 5 => 4,
        _ => 1,
    }
}

fn choices(paper: bool, k: usize, depth: usize) -> Choices {
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
        if paper {
            e.reorient.rotations
        } else {
            default_reorient(k, depth)
        },
        e.reorient.every,
        e.recentre,
        e.mstep.update,
    )
}

impl PointsConfig {
    /// A config from a parsed TOML table (without the `problem` key), relative file names
    /// read from `origin`'s folder: what `RunConfig` and a resumed run read a table with.
    pub fn from_table(table: toml::Table, origin: &Path) -> crate::Result<Self> {
        let text = toml::to_string(&table).context("re-serialising the config")?;
        Ok(PointsConfig::from_toml(&text, origin)?
            .relative_to(origin.parent().unwrap_or(Path::new(""))))
    }

    /// Parses TOML text (without the `problem` key) and validates it; `origin` names the
    /// text in errors.
    pub fn from_toml(text: &str, origin: &Path) -> crate::Result<Self> {
        let invalid = || format!("{} is not a valid points config", origin.display());
        let cfg: PointsConfig = toml::from_str(text).config_context(origin, invalid)?;
        cfg.validate().config_context(origin, invalid)?;
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
    pub fn resolved(&self) -> crate::Result<Self> {
        let abs = |p: &Path| std::path::absolute(p).doing("resolving", p);
        let file_spec = |spec: &str| -> crate::Result<String> {
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
        c.reflections = Some(self.reflections());
        c.words = Some(self.words());
        c.runs = Some(self.runs());
        c.keep = Some(self.keep());
        c.trim_outliers = Some(self.trim_outliers());
        Ok(c)
    }

    /// Whether isolated points are left out (off unless asked for).
    pub fn trim_outliers(&self) -> bool {
        self.trim_outliers.unwrap_or(false)
    }

    /// Whether the maps may reflect, as given or by the recipe.
    pub fn reflections(&self) -> bool {
        self.reflections
            .unwrap_or_else(|| !self.paper && MStepConfig::default().reflections)
    }

    /// Independent runs, as given or by default ([`default_runs`]).
    pub fn runs(&self) -> usize {
        self.runs
            .unwrap_or_else(|| if self.paper { 1 } else { default_runs(self.k) })
    }

    /// Which run is kept, as given or by the recipe; one run is kept whatever the rule.
    pub fn keep(&self) -> KeepBy {
        if self.runs() == 1 {
            return KeepBy::Likelihood;
        }
        self.keep.unwrap_or(if self.paper {
            KeepBy::Likelihood
        } else {
            KeepBy::Closeness
        })
    }

    /// Whether the word search runs, as given or by the recipe.
    pub fn words(&self) -> bool {
        self.words.unwrap_or(!self.paper)
    }

    /// The six choices `paper` fixes, as given or by default.
    fn choices(&self) -> Choices {
        let d = choices(self.paper, self.k, self.depth);
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
    pub fn validate(&self) -> crate::Result<()> {
        if self.data.is_empty() {
            bail!(
                "`data` is missing: name a point cloud (.csv, .txt or .npy) or `ifs:NAME` to sample one from a code"
            );
        }
        if self.data.starts_with("ifs:") && self.points == 0 {
            bail!("`points` must be at least 1 to sample `{}`", self.data);
        }
        if self.runs == Some(0) {
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
            let paper = choices(true, self.k, self.depth);
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
                ("reflections", self.reflections),
                ("words", self.words),
                ("trim_outliers", self.trim_outliers),
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
            reorient: ReorientConfig {
                rotations,
                every,
                words: self.words(),
            },
            recentre,
            mstep: MStepConfig {
                update,
                reflections: self.reflections(),
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
    pub fn to_toml(&self) -> crate::Result<String> {
        Ok(format!(
            "{PROBLEM_KEY} = \"points\"\n{}",
            toml::to_string_pretty(&self.resolved()?)?
        ))
    }
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
