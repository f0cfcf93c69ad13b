//! A sweep expanded into its runs: every combination of axis values applied to the base
//! config, validated, with a stable id (a hash of the resolved run config).
//!
//! `mod.rs` expands a sweep into its [`Plan`]; `axis.rs` applies an axis value to a config;
//! `id.rs` gives each run its id.

mod axis;
mod id;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::error::{Context, IoContext, bail};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::config::{AxisConfig, BaseConfig, SlurmConfig, SweepConfig};
use crate::runs::RunConfig;
pub use crate::runs::table::set_dotted;

use axis::{Axis, flatten};
use id::join_labels;
pub use id::run_id;

/// The config key of the output folder: sweeps choose the folder.
const OUTPUT_KEY: &str = "output";

/// Config keys that say how a run is carried out, not what it computes, so they take no
/// part in its id: where it writes, and how often it checkpoints (a resumed run is
/// bit-identical to an uninterrupted one, so checkpointing more often to survive a time
/// limit leaves finished runs finished).
pub const OPERATIONAL_KEYS: &[&str] = &[OUTPUT_KEY, "checkpoint_every"];

/// One run of a sweep.
#[derive(Clone, Debug)]
pub struct PlannedRun {
    /// Its position in the whole sweep (shards split the positions in the plan's list,
    /// which `--only` may have shortened).
    pub index: usize,
    /// The stable id: a hash of the resolved config (same config, same id, whatever the
    /// axes that produced it or the order of the sweep).
    pub id: String,
    /// Its labels joined (`em-adam-sierpinski-s0`), for people.
    pub name: String,
    /// (axis, label) pairs, in axis order.
    pub labels: Vec<(String, String)>,
    /// The validated config.
    pub config: RunConfig,
    /// The resolved config as TOML (what the id hashes).
    pub resolved: toml::Table,
}

/// A sweep ready to run.
#[derive(Clone, Debug)]
pub struct Plan {
    /// The sweep's name.
    pub name: String,
    /// The sweep file, absolute.
    pub source: PathBuf,
    /// Column names of the labels, in order (`group` first when the sweep has groups).
    pub axes: Vec<String>,
    /// Every run, in sweep order.
    pub runs: Vec<PlannedRun>,
    /// Slurm resources.
    pub slurm: SlurmConfig,
    /// The `--only` filters applied by [`Plan::retain`] (a job-array script repeats them).
    pub filters: Vec<(String, String)>,
}

/// What `DIR/sweep.json` holds: the plan without its configs (collect reads it).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PlanIndex {
    /// The sweep's name.
    pub name: String,
    /// The sweep file.
    pub source: PathBuf,
    /// Label columns.
    pub axes: Vec<String>,
    /// Every run.
    pub runs: Vec<RunIndex>,
}

/// One run of [`PlanIndex`].
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct RunIndex {
    /// Stable id (its folder under `runs/`).
    pub id: String,
    /// Labels joined.
    pub name: String,
    /// The problem (`image`, …).
    pub problem: String,
    /// Label per axis, in [`PlanIndex::axes`] order.
    pub labels: Vec<String>,
}

impl Plan {
    /// Reads, expands and validates a sweep file.
    pub fn load(path: &Path) -> crate::Result<Self> {
        let cfg = SweepConfig::load(path)?;
        Plan::expand(&cfg, path)
    }

    /// Expands a parsed sweep (`path`: the file it came from, for relative names).
    pub fn expand(cfg: &SweepConfig, path: &Path) -> crate::Result<Self> {
        let source = std::path::absolute(path).doing("resolving", path)?;
        let here = source.parent().unwrap_or(Path::new("/")).to_path_buf();
        let (base, origin) = match &cfg.base {
            BaseConfig::File(f) => {
                let f = here.join(f);
                let text = std::fs::read_to_string(&f)
                    .io_context(&f, || format!("reading the base config {}", f.display()))?;
                let table: toml::Table = text
                    .parse()
                    .config_context(&f, || format!("{} is not valid TOML", f.display()))?;
                (table, f)
            }
            BaseConfig::Inline(t) => (t.clone(), source.clone()),
        };
        let name = cfg.name.clone().unwrap_or_else(|| {
            source
                .file_stem()
                .map_or("sweep".into(), |s| s.to_string_lossy().into_owned())
        });
        let top: Vec<Axis> = cfg
            .axis
            .iter()
            .map(|a| Axis::resolve(a, &here))
            .collect::<crate::Result<_>>()?;
        // Each group (or the whole sweep when there are none): its overrides and axes.
        let mut blocks: Vec<(Option<String>, toml::Table, Vec<Axis>)> = Vec::new();
        if cfg.group.is_empty() {
            blocks.push((None, toml::Table::new(), Vec::new()));
        }
        for g in &cfg.group {
            let axes = g
                .axis
                .iter()
                .map(|a| Axis::resolve(a, &here))
                .collect::<crate::Result<_>>()
                .with_context(|| format!("in group `{}`", g.name))?;
            blocks.push((Some(g.name.clone()), g.set.clone(), axes));
        }
        let mut axes_names: Vec<String> = Vec::new();
        if !cfg.group.is_empty() {
            axes_names.push("group".into());
        }
        for a in top.iter().chain(blocks.iter().flat_map(|b| b.2.iter())) {
            if !axes_names.contains(&a.name) {
                axes_names.push(a.name.clone());
            }
        }
        let mut runs: Vec<PlannedRun> = Vec::new();
        for (group, group_set, group_axes) in &blocks {
            let axes: Vec<&Axis> = top.iter().chain(group_axes.iter()).collect();
            let counts: Vec<usize> = axes.iter().map(|a| a.values.len()).collect();
            let total: usize = counts.iter().product();
            for combo in 0..total {
                // Mixed radix, first axis slowest: runs come in the order the axes read.
                let mut rest = combo;
                let mut picks = vec![0; axes.len()];
                for (k, &n) in counts.iter().enumerate().rev() {
                    picks[k] = rest % n;
                    rest /= n;
                }
                let mut labels: Vec<(String, String)> = Vec::new();
                if let Some(g) = group {
                    labels.push(("group".into(), g.clone()));
                }
                let mut table = base.clone();
                let mut applied: Vec<String> = Vec::new();
                let mut apply = |table: &mut toml::Table, set: &[(String, toml::Value)]| {
                    for (k, v) in set {
                        set_dotted(table, k, v.clone())?;
                        applied.push(format!("{k} = {v}"));
                    }
                    Ok::<_, crate::Error>(())
                };
                let index = runs.len();
                let what = |labels: &[(String, String)]| {
                    if labels.is_empty() {
                        format!("run {index}")
                    } else {
                        format!("run {index} ({})", join_labels(labels, ", ", true))
                    }
                };
                apply(&mut table, &flatten(&cfg.set)).context("in the sweep's [set]")?;
                apply(&mut table, &flatten(group_set)).with_context(|| {
                    format!("in group `{}`'s set", group.as_deref().unwrap_or(""))
                })?;
                for (a, &p) in axes.iter().zip(&picks) {
                    let v = &a.values[p];
                    labels.push((a.name.clone(), v.label.clone()));
                    apply(&mut table, &v.set).with_context(|| what(&labels))?;
                }
                table.remove(OUTPUT_KEY);
                let config = RunConfig::from_table(table, &origin).with_context(|| {
                    format!(
                        "{} is not a valid run config (overrides: {})",
                        what(&labels),
                        if applied.is_empty() {
                            "none".to_string()
                        } else {
                            applied.join(", ")
                        }
                    )
                })?;
                let mut resolved = config.to_table()?;
                resolved.remove(OUTPUT_KEY);
                let id = run_id(&resolved, &here);
                if let Some(other) = runs.iter().find(|r| r.id == id) {
                    bail!(
                        "{} and run {} ({}) resolve to the same config (id {id}): an axis value changes nothing",
                        what(&labels),
                        other.index,
                        join_labels(&other.labels, ", ", true)
                    );
                }
                let name = if labels.is_empty() {
                    id.clone()
                } else {
                    join_labels(&labels, "-", false)
                };
                runs.push(PlannedRun {
                    index,
                    id,
                    name,
                    labels,
                    config,
                    resolved,
                });
            }
        }
        Ok(Plan {
            name,
            source,
            axes: axes_names,
            runs,
            slurm: cfg.slurm.clone(),
            filters: Vec::new(),
        })
    }

    /// Keeps only the runs whose labels match: `filters` are (axis, label) pairs; runs
    /// must match one label of every axis named (`--only group=em --only seed=0`). Shards
    /// split what is left (every task of a job array applies the same filters).
    pub fn retain(&mut self, filters: &[(String, String)]) -> crate::Result<()> {
        let mut axes: Vec<&str> = Vec::new();
        for (axis, label) in filters {
            if !self.axes.contains(axis) {
                bail!(
                    "--only {axis}={label}: the sweep has no axis `{axis}` (its axes: {})",
                    self.axes.join(", ")
                );
            }
            if !self
                .runs
                .iter()
                .any(|r| r.labels.iter().any(|(a, l)| a == axis && l == label))
            {
                bail!("--only {axis}={label}: no run has {axis} = {label}");
            }
            if !axes.contains(&axis.as_str()) {
                axes.push(axis);
            }
        }
        self.filters.extend(filters.iter().cloned());
        self.runs.retain(|r| {
            axes.iter().all(|axis| {
                filters
                    .iter()
                    .any(|(a, l)| a == axis && r.labels.iter().any(|(ra, rl)| ra == a && rl == l))
            })
        });
        Ok(())
    }

    /// The plan as `sweep.json` holds it.
    pub fn index(&self) -> PlanIndex {
        PlanIndex {
            name: self.name.clone(),
            source: self.source.clone(),
            axes: self.axes.clone(),
            runs: self
                .runs
                .iter()
                .map(|r| RunIndex {
                    id: r.id.clone(),
                    name: r.name.clone(),
                    problem: r.config.problem().into(),
                    labels: self
                        .axes
                        .iter()
                        .map(|a| {
                            r.labels
                                .iter()
                                .find(|(n, _)| n == a)
                                .map_or_else(String::new, |(_, l)| l.clone())
                        })
                        .collect(),
                })
                .collect(),
        }
    }

    /// The resolved list, one run a line (`--dry-run`).
    pub fn describe(&self) -> String {
        let mut s = format!(
            "sweep `{}` ({}): {} runs\n",
            self.name,
            self.source.display(),
            self.runs.len()
        );
        for r in &self.runs {
            let _ = writeln!(
                s,
                "{:>4}  {}  {:<6} {}",
                r.index,
                r.id,
                r.config.problem(),
                join_labels(&r.labels, "  ", true)
            );
        }
        s
    }
}
