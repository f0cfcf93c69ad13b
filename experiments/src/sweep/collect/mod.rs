//! A sweep's results in one place: every planned run's summary in one table (CSV and
//! JSON, one row per run, so per seed), aggregated by any axis or combination of axes
//! (mean, standard deviation, count); the report drawn from it is `report.rs`'s.
//!
//! Collect reads only the output folder (`sweep.json`, `runs/` and the packed runs of
//! `runs.jsonl.gz`, [`super::pack`]), so it works on the merged folder of any number of
//! shards or array tasks, finished or not: runs not finished yet are rows with their status
//! and no numbers.
//!
//! `mod.rs` reads the runs into the table ([`collect`]); `table.rs` aggregates it and writes
//! it out.

mod table;

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::error::{Context, IoContext};
use serde_json::{Map, Value};

use super::expand::PlanIndex;
use super::local::{ERROR_FILE, PLAN_FILE, RECORD_FILE, RUNS_DIR, RunRecord, partial_dir, run_dir};
use super::pack::{LOG_FILE, LogColumns, Pack};

pub use table::{Aggregate, Stat, fmt_num};

/// Columns that measure wall time, not results: the only ones that differ between two
/// runs of the same sweep (here or on a cluster, in one go or resumed).
pub const WALL_TIME_COLUMNS: &[&str] = &["seconds", "run_seconds", "resumed", "threads"];

/// Groupings with more categories than this get a table and no plots.
pub const MAX_CATEGORIES: usize = 16;

/// Where a planned run stands.
#[derive(Clone, Debug, PartialEq)]
pub enum RunState {
    /// Finished: `runs/ID/`.
    Finished,
    /// An attempt failed (its error).
    Failed(String),
    /// Started and not finished (under way, or stopped without an error: cancelled, killed).
    Interrupted,
    /// Not started.
    Missing,
}

impl RunState {
    /// One word for tables.
    pub fn word(&self) -> &'static str {
        match self {
            RunState::Finished => "finished",
            RunState::Failed(_) => "failed",
            RunState::Interrupted => "interrupted",
            RunState::Missing => "missing",
        }
    }
}

/// One planned run and what it produced.
#[derive(Clone, Debug)]
pub struct Row {
    /// Stable id.
    pub id: String,
    /// Labels joined.
    pub name: String,
    /// The problem.
    pub problem: String,
    /// Where it stands.
    pub state: RunState,
    /// Label per axis ([`Collected::axes`] order).
    pub labels: Vec<String>,
    /// Its `summary.json`, nested objects flattened to dotted keys (empty if not finished).
    pub summary: Map<String, Value>,
    /// Its `run.json` (finished runs).
    pub record: Option<RunRecord>,
    /// Its folder (finished runs that have one).
    pub dir: Option<PathBuf>,
    /// Its loss curve, when the run was read from the pack (a folder's is read from its
    /// `log.csv` when it is plotted).
    pub packed_curve: Option<Vec<(f64, f64)>>,
    /// The files its pack left out (pictures), when it was read from the pack.
    pub left_out: Vec<String>,
}

impl Row {
    /// Whether the run was read from the sweep's pack rather than a folder.
    pub fn is_packed(&self) -> bool {
        self.state == RunState::Finished && self.dir.is_none()
    }

    /// Its `loss` against the iteration: from its folder's `log.csv`, or the pack's columns.
    pub fn loss_curve(&self) -> Option<Vec<(f64, f64)>> {
        match &self.dir {
            Some(d) => {
                LogColumns::parse(&std::fs::read_to_string(d.join(LOG_FILE)).ok()?)?.curve("loss")
            }
            None => self.packed_curve.clone(),
        }
    }
}

/// Every planned run of a sweep folder.
#[derive(Clone, Debug)]
pub struct Collected {
    /// The sweep's name.
    pub name: String,
    /// The sweep folder.
    pub dir: PathBuf,
    /// Label columns.
    pub axes: Vec<String>,
    /// One row per planned run, in sweep order.
    pub rows: Vec<Row>,
    /// Summary fields that are numbers in some finished run, in first-seen order.
    pub metrics: Vec<String>,
    /// Summary fields, in first-seen order.
    pub fields: Vec<String>,
    /// Finished run folders that the current plan does not name (an earlier version of the
    /// sweep file).
    pub unplanned: usize,
}

/// Reads a sweep folder.
pub fn collect(dir: &Path) -> crate::Result<Collected> {
    let plan_path = dir.join(PLAN_FILE);
    let text = std::fs::read_to_string(&plan_path).io_context(&plan_path, || {
        format!(
            "reading {}: is {} the output folder of `ifslab sweep`?",
            plan_path.display(),
            dir.display()
        )
    })?;
    let plan: PlanIndex = serde_json::from_str(&text).config_context(&plan_path, || {
        format!("{} is not a sweep index", plan_path.display())
    })?;
    let pack = Pack::beside(&dir.join(RUNS_DIR))?;
    let mut rows = Vec::new();
    let mut metrics: Vec<String> = Vec::new();
    let mut fields: Vec<String> = Vec::new();
    for r in &plan.runs {
        let done = run_dir(dir, &r.id);
        let partial = partial_dir(dir, &r.id);
        let mut packed_curve = None;
        let mut left_out = Vec::new();
        let (state, summary, record, run_folder) = if done.join(RECORD_FILE).is_file() {
            let record: RunRecord = read_json(&done.join(RECORD_FILE))?;
            let summary_path = done.join("summary.json");
            let mut summary = Map::new();
            if summary_path.is_file() {
                let v: Value = read_json(&summary_path)?;
                flatten_json("", &v, &mut summary);
            }
            (RunState::Finished, summary, Some(record), Some(done))
        } else if let Some(p) = pack.get(&r.id)
            && let Some(record) = p.json::<RunRecord>(RECORD_FILE)?
        {
            let mut summary = Map::new();
            if let Some(v) = p.json::<Value>("summary.json")? {
                flatten_json("", &v, &mut summary);
            }
            packed_curve = p.loss_curve();
            left_out.clone_from(&p.left_out);
            (RunState::Finished, summary, Some(record), None)
        } else if partial.join(ERROR_FILE).is_file() {
            let e = std::fs::read_to_string(partial.join(ERROR_FILE)).unwrap_or_default();
            (
                RunState::Failed(e.trim().to_string()),
                Map::new(),
                None,
                None,
            )
        } else if partial.is_dir() {
            (RunState::Interrupted, Map::new(), None, None)
        } else {
            (RunState::Missing, Map::new(), None, None)
        };
        for (k, v) in &summary {
            if !fields.contains(k) {
                fields.push(k.clone());
            }
            if v.is_number() && !metrics.contains(k) {
                metrics.push(k.clone());
            }
        }
        rows.push(Row {
            id: r.id.clone(),
            name: r.name.clone(),
            problem: r.problem.clone(),
            state,
            labels: r.labels.clone(),
            summary,
            record,
            dir: run_folder,
            packed_curve,
            left_out,
        });
    }
    let planned: BTreeSet<&str> = plan.runs.iter().map(|r| r.id.as_str()).collect();
    let mut unplanned: BTreeSet<String> = std::fs::read_dir(dir.join(RUNS_DIR))
        .map(|rd| {
            rd.filter_map(Result::ok)
                .filter(|e| e.path().join(RECORD_FILE).is_file())
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| !n.starts_with('.') && !planned.contains(n.as_str()))
                .collect()
        })
        .unwrap_or_default();
    unplanned.extend(
        pack.runs
            .iter()
            .filter(|p| !planned.contains(p.name.as_str()) && p.file(RECORD_FILE).is_some())
            .map(|p| p.name.clone()),
    );
    let unplanned = unplanned.len();
    Ok(Collected {
        name: plan.name,
        dir: dir.to_path_buf(),
        axes: plan.axes,
        rows,
        metrics,
        fields,
        unplanned,
    })
}

fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> crate::Result<T> {
    let text = std::fs::read_to_string(path).doing("reading", path)?;
    serde_json::from_str(&text)
        .config_context(path, || format!("{} is not valid JSON", path.display()))
}

fn flatten_json(prefix: &str, v: &Value, out: &mut Map<String, Value>) {
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                let key = if prefix.is_empty() {
                    k.clone()
                } else {
                    format!("{prefix}.{k}")
                };
                flatten_json(&key, x, out);
            }
        }
        // A list of records (a points run's pool sizes, …): one key per entry and field,
        // `list.0.field`, so each entry's numbers are metrics; other lists stay one value.
        Value::Array(items) if !items.is_empty() && items.iter().all(Value::is_object) => {
            for (i, x) in items.iter().enumerate() {
                flatten_json(&format!("{prefix}.{i}"), x, out);
            }
        }
        other => {
            out.insert(prefix.to_string(), other.clone());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn lists_of_records_become_one_metric_per_entry_and_field() {
        let v = json!({
            "fits": 8,
            "best": {"heldout": 1.5, "scales": [0.5, 0.5]},
            "sweep": [{"pool": 1, "proportion": 0.25}, {"pool": 4, "proportion": 1.0}],
            "empty": [],
        });
        let mut out = Map::new();
        flatten_json("", &v, &mut out);
        assert_eq!(out["fits"], json!(8));
        assert_eq!(out["best.heldout"], json!(1.5));
        assert_eq!(
            out["best.scales"],
            json!([0.5, 0.5]),
            "a list of numbers stays one value"
        );
        assert_eq!(out["sweep.0.pool"], json!(1));
        assert_eq!(out["sweep.1.proportion"], json!(1.0));
        assert_eq!(out["empty"], json!([]));
        assert!(!out.contains_key("sweep"));
    }
}
