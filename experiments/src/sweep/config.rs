//! The sweep file: a base run config, overrides for every run, axes to expand and the
//! cluster resources of a Slurm job array.
//!
//! ```toml
//! name = "strategies"            # job name and report title (default: the file's stem)
//! base = "../configs/sierpinski.toml"   # any `ifslab run` config, or an inline [base] table
//! [set]                          # overrides of the base for every run (dotted keys)
//! iterations = 400
//! [[axis]]                       # one value per run, crossed with the other axes
//! key = "seed"
//! values = [0, 1, 2]
//! labels = ["s0", "s1", "s2"]    # optional: how the values are named in reports
//! [[axis]]                       # several keys per value: named sets of overrides
//! name = "strategy"
//! [[axis.value]]
//! label = "adam"
//! set = { "strategy.kind" = "adam" }
//! [[axis]]                       # every image of a folder as the target
//! key = "target.image"
//! folder = "targets"
//! [[group]]                      # optional: sub-sweeps with their own overrides and axes
//! name = "em"
//! set = { "model.init" = "em" }
//! [[group.axis]]
//! key = "strategy.kind"
//! values = ["adam", "cold_hybrid"]
//! [slurm]                        # resources of each array task (see [`SlurmConfig`])
//! time = "02:00:00"
//! cpus_per_task = 4
//! ```

use std::path::{Path, PathBuf};

use crate::error::{Context, IoContext, bail};
use serde::{Deserialize, Serialize};

/// A parsed sweep file, before expansion.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepConfig {
    /// The sweep's name (Slurm job name, report title); the file's stem when absent.
    #[serde(default)]
    pub name: Option<String>,
    /// The base run config: a file name (relative to the sweep file) or an inline table.
    pub base: BaseConfig,
    /// Overrides of the base applied to every run (dotted keys or nested tables).
    #[serde(default)]
    pub set: toml::Table,
    /// Axes crossed with each other (and with every group's own axes), in this order.
    #[serde(default)]
    pub axis: Vec<AxisConfig>,
    /// Sub-sweeps: each adds its own overrides and axes; the runs are their union.
    #[serde(default)]
    pub group: Vec<GroupConfig>,
    /// Resources of a Slurm job array (`ifslab sweep --slurm`).
    #[serde(default)]
    pub slurm: SlurmConfig,
}

/// Where the base config comes from.
#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
pub enum BaseConfig {
    /// A config file; its relative file names are read from its folder.
    File(PathBuf),
    /// A config written into the sweep file.
    Inline(toml::Table),
}

/// One axis: the values a key (or a set of keys) takes across the runs.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AxisConfig {
    /// The axis's name in tables and reports (default: `key`).
    #[serde(default)]
    pub name: Option<String>,
    /// The dotted config key the values go to (`seed`, `strategy.kind`, `target.code`).
    #[serde(default)]
    pub key: Option<String>,
    /// The values `key` takes.
    #[serde(default)]
    pub values: Option<Vec<toml::Value>>,
    /// Names of `values` in reports, one per value (default: the values written out).
    #[serde(default)]
    pub labels: Option<Vec<String>>,
    /// A folder whose images (`.png`, `.jpg`, `.jpeg`, sorted by name) are the values of
    /// `key`, labelled by their stems; relative to the sweep file.
    #[serde(default)]
    pub folder: Option<PathBuf>,
    /// Named sets of overrides, one per value (for axes that change several keys at once).
    #[serde(default)]
    pub value: Vec<SetValue>,
}

/// One value of a several-key axis.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SetValue {
    /// Its name in tables and reports.
    pub label: String,
    /// The overrides it applies (dotted keys or nested tables).
    #[serde(default)]
    pub set: toml::Table,
}

/// A sub-sweep.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GroupConfig {
    /// Its name (the value of the `group` column).
    pub name: String,
    /// Overrides for its runs, applied after the sweep's `set`.
    #[serde(default)]
    pub set: toml::Table,
    /// Its own axes, crossed after the sweep's.
    #[serde(default)]
    pub axis: Vec<AxisConfig>,
}

/// Resources and options of each task of a Slurm job array (`sbatch` options).
#[derive(Clone, Debug, Default, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SlurmConfig {
    /// Array tasks (shards); default: one per run.
    #[serde(default)]
    pub shards: Option<usize>,
    /// At most this many tasks at once (`--array=…%N`).
    #[serde(default)]
    pub max_parallel: Option<usize>,
    /// Wall-time limit of a task (`--time`, e.g. `"02:00:00"`); a task that reaches it is
    /// requeued and resumes from its checkpoints.
    #[serde(default)]
    pub time: Option<String>,
    /// CPU cores per task (`--cpus-per-task`); also the run's thread budget.
    #[serde(default)]
    pub cpus_per_task: Option<usize>,
    /// Memory per task (`--mem`, e.g. `"8G"`).
    #[serde(default)]
    pub mem: Option<String>,
    /// Partition (`--partition`).
    #[serde(default)]
    pub partition: Option<String>,
    /// Account (`--account`).
    #[serde(default)]
    pub account: Option<String>,
    /// Quality of service (`--qos`).
    #[serde(default)]
    pub qos: Option<String>,
    /// Generic resources (`--gres`, e.g. `"gpu:1"`).
    #[serde(default)]
    pub gres: Option<String>,
    /// Seconds before the time limit at which a task asks to be requeued (default 120).
    #[serde(default)]
    pub requeue_grace: Option<u64>,
    /// Further `#SBATCH` options, written as given (`"--constraint=avx2"`).
    #[serde(default)]
    pub extra: Vec<String>,
    /// Shell lines run before the sweep (`module load …`, `source venv/bin/activate`).
    #[serde(default)]
    pub setup: Vec<String>,
}

impl SweepConfig {
    /// Parses a sweep file's text; `origin` names it in errors.
    pub fn from_toml(text: &str, origin: &Path) -> crate::Result<Self> {
        let invalid = || format!("{} is not a valid sweep file", origin.display());
        let cfg: SweepConfig = toml::from_str(text).config_context(origin, invalid)?;
        cfg.validate().config_context(origin, invalid)?;
        Ok(cfg)
    }

    /// Reads and parses a sweep file.
    pub fn load(path: &Path) -> crate::Result<Self> {
        let text = std::fs::read_to_string(path).doing("reading", path)?;
        SweepConfig::from_toml(&text, path)
    }

    /// The checks that need no base config: every axis well formed, names unique.
    pub fn validate(&self) -> crate::Result<()> {
        let mut names = Vec::new();
        for a in &self.axis {
            a.validate()?;
            names.push(a.display_name());
        }
        let mut groups = Vec::new();
        for g in &self.group {
            if groups.contains(&g.name.as_str()) {
                bail!("two groups are called `{}`", g.name);
            }
            groups.push(g.name.as_str());
            for a in &g.axis {
                a.validate()
                    .with_context(|| format!("in group `{}`", g.name))?;
            }
        }
        for (i, n) in names.iter().enumerate() {
            if names[..i].contains(n) {
                bail!("two axes are called `{n}`; give one a `name`");
            }
            if !self.group.is_empty() && n == "group" {
                bail!("`group` names the group column; call the axis something else");
            }
        }
        if let Some(0) = self.slurm.shards {
            bail!("slurm.shards must be at least 1");
        }
        if let Some(0) = self.slurm.max_parallel {
            bail!("slurm.max_parallel must be at least 1");
        }
        if let Some(0) = self.slurm.cpus_per_task {
            bail!("slurm.cpus_per_task must be at least 1");
        }
        Ok(())
    }
}

impl AxisConfig {
    /// The axis's column name.
    pub fn display_name(&self) -> String {
        self.name
            .clone()
            .or_else(|| self.key.clone())
            .unwrap_or_default()
    }

    fn validate(&self) -> crate::Result<()> {
        let kinds = [
            self.values.is_some(),
            self.folder.is_some(),
            !self.value.is_empty(),
        ];
        let what = || match (&self.name, &self.key) {
            (Some(n), _) => format!("axis `{n}`"),
            (None, Some(k)) => format!("axis `{k}`"),
            (None, None) => "an axis".to_string(),
        };
        match kinds.iter().filter(|k| **k).count() {
            1 => {}
            0 => bail!(
                "{} has no values: give `values = [...]`, `folder = \"...\"` or [[axis.value]] sets",
                what()
            ),
            _ => bail!(
                "{} mixes `values`, `folder` and [[axis.value]]: give one of them",
                what()
            ),
        }
        if self.value.is_empty() {
            match &self.key {
                Some(k) if !k.is_empty() && !k.split('.').any(str::is_empty) => {}
                Some(k) => bail!("{}: `{k}` is not a dotted config key", what()),
                None => bail!("{} needs the `key` its values go to", what()),
            }
        } else {
            if self.name.is_none() {
                bail!("{} of [[axis.value]] sets needs a `name`", what());
            }
            if self.key.is_some() {
                bail!(
                    "{}: [[axis.value]] sets name their own keys; drop `key`",
                    what()
                );
            }
        }
        if let Some(values) = &self.values
            && values.is_empty()
        {
            bail!("{} has an empty `values` list", what());
        }
        // Two values with one label would be one row in every report.
        let given: Vec<&str> = self
            .value
            .iter()
            .map(|v| v.label.as_str())
            .chain(self.labels.iter().flatten().map(String::as_str))
            .collect();
        for (i, l) in given.iter().enumerate() {
            if given[..i].contains(l) {
                bail!(
                    "{} has the label `{l}` twice: each value needs a label of its own",
                    what()
                );
            }
        }
        if let Some(labels) = &self.labels {
            let n = self.values.as_ref().map_or(0, Vec::len);
            if labels.len() != n {
                bail!(
                    "{} has {} labels for {n} values: give one label per value",
                    what(),
                    labels.len()
                );
            }
        }
        Ok(())
    }
}
