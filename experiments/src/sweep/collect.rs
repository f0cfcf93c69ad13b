//! A sweep's results in one place: every planned run's summary in one table (CSV and
//! JSON, one row per run, so per seed), aggregated by any axis or combination of axes
//! (mean, standard deviation, count); the report drawn from it is `report.rs`'s.
//!
//! Collect reads only the output folder (`sweep.json`, `runs/` and the packed runs of
//! `runs.jsonl.gz`, [`super::pack`]), so it works on the merged folder of any number of
//! shards or array tasks, finished or not: runs not finished yet are rows with their status
//! and no numbers.

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::error::{Context, IoContext};
use serde_json::{Map, Value};

use super::expand::PlanIndex;
use super::local::{ERROR_FILE, PLAN_FILE, RECORD_FILE, RUNS_DIR, RunRecord, partial_dir, run_dir};
use super::pack::{LOG_FILE, LogColumns, Pack};

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

/// Mean, sample standard deviation and count of a metric in one group.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stat {
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation (n − 1; 0 for one value).
    pub std: f64,
    /// Finite values.
    pub count: usize,
}

impl Stat {
    /// The statistics of some values (non-finite ones left out); `None` if none is finite.
    pub fn of(values: impl IntoIterator<Item = f64>) -> Option<Stat> {
        let v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        let n = v.len() as f64;
        let mean = v.iter().sum::<f64>() / n;
        let std = if v.len() > 1 {
            (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
        } else {
            0.0
        };
        Some(Stat {
            mean,
            std,
            count: v.len(),
        })
    }
}

/// Runs grouped by the labels of some axes.
#[derive(Clone, Debug)]
pub struct Aggregate {
    /// The axes grouped by.
    pub by: Vec<String>,
    /// The metrics, in [`Collected::metrics`] order.
    pub metrics: Vec<String>,
    /// (labels of the `by` axes, runs in the group (finished or not), stat per metric), in
    /// order of first appearance in the sweep.
    pub groups: Vec<(Vec<String>, usize, Vec<Option<Stat>>)>,
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

impl Collected {
    /// A metric of a row, if it is a number there.
    pub fn value(row: &Row, metric: &str) -> Option<f64> {
        row.summary.get(metric).and_then(Value::as_f64)
    }

    /// Counts of rows per state: (finished, failed, interrupted, missing).
    pub fn counts(&self) -> (usize, usize, usize, usize) {
        let c = |w: &str| self.rows.iter().filter(|r| r.state.word() == w).count();
        (c("finished"), c("failed"), c("interrupted"), c("missing"))
    }

    /// The notes finished runs left in their summaries (fields named `…note` holding text,
    /// such as `lpips_note`: a run that went without something its config asks for), as (row,
    /// field, text). A table mixing such runs with others is not one method's: the report
    /// lists them.
    pub fn notes(&self) -> Vec<(&Row, &str, &str)> {
        let mut out = Vec::new();
        for r in &self.rows {
            for (k, v) in &r.summary {
                if let Value::String(t) = v
                    && k.ends_with("note")
                    && !t.trim().is_empty()
                {
                    out.push((r, k.as_str(), t.as_str()));
                }
            }
        }
        out
    }

    fn axis_index(&self, axis: &str) -> crate::Result<usize> {
        self.axes.iter().position(|a| a == axis).with_context(|| {
            format!(
                "the sweep has no axis `{axis}` (its axes: {})",
                if self.axes.is_empty() {
                    "none".to_string()
                } else {
                    self.axes.join(", ")
                }
            )
        })
    }

    /// The distinct labels of an axis, in sweep order.
    pub fn values_of(&self, axis: &str) -> crate::Result<Vec<String>> {
        let k = self.axis_index(axis)?;
        let mut v: Vec<String> = Vec::new();
        for r in &self.rows {
            if !v.contains(&r.labels[k]) {
                v.push(r.labels[k].clone());
            }
        }
        Ok(v)
    }

    /// A row's labels on some axes, joined with `/` (a category of a grouped plot).
    pub fn key(&self, axes: &[String], row: &Row) -> String {
        axes.iter()
            .filter_map(|a| self.axes.iter().position(|x| x == a))
            .map(|k| row.labels[k].as_str())
            .collect::<Vec<_>>()
            .join("/")
    }

    /// The distinct [`Collected::key`]s of some axes, in sweep order; an unknown axis is
    /// an error.
    pub fn keys_of(&self, axes: &[String]) -> crate::Result<Vec<String>> {
        for a in axes {
            self.axis_index(a)?;
        }
        let mut v: Vec<String> = Vec::new();
        for r in &self.rows {
            let k = self.key(axes, r);
            if !v.contains(&k) {
                v.push(k);
            }
        }
        Ok(v)
    }

    /// The axes whose runs take more than one value: what a report groups by when told
    /// nothing.
    pub fn varying_axes(&self) -> Vec<String> {
        self.axes
            .iter()
            .filter(|a| self.values_of(a).is_ok_and(|v| v.len() > 1))
            .cloned()
            .collect()
    }

    /// The runs grouped by the labels of `by` (one or more axes), each metric's statistics
    /// over the finished runs of each group.
    pub fn aggregate(&self, by: &[String]) -> crate::Result<Aggregate> {
        let ks: Vec<usize> = by
            .iter()
            .map(|a| self.axis_index(a))
            .collect::<crate::Result<_>>()?;
        let mut keys: Vec<Vec<String>> = Vec::new();
        for r in &self.rows {
            let key: Vec<String> = ks.iter().map(|&k| r.labels[k].clone()).collect();
            if !keys.contains(&key) {
                keys.push(key);
            }
        }
        let groups = keys
            .into_iter()
            .map(|key| {
                let members: Vec<&Row> = self
                    .rows
                    .iter()
                    .filter(|r| ks.iter().zip(&key).all(|(&k, l)| &r.labels[k] == l))
                    .collect();
                let stats = self
                    .metrics
                    .iter()
                    .map(|m| Stat::of(members.iter().filter_map(|r| Collected::value(r, m))))
                    .collect();
                (key, members.len(), stats)
            })
            .collect();
        Ok(Aggregate {
            by: by.to_vec(),
            metrics: self.metrics.clone(),
            groups,
        })
    }

    /// The table as CSV: id, name, problem, status, one column per axis, the run's wall
    /// time, then every summary field.
    pub fn to_csv(&self) -> String {
        let mut header: Vec<String> = ["id", "name", "problem", "status"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        header.extend(self.axes.iter().cloned());
        header.extend(["run_seconds", "resumed"].iter().map(|s| s.to_string()));
        // A summary field called like an axis (an image run's `strategy`) is told apart.
        header.extend(self.fields.iter().map(|f| {
            if self.axes.contains(f) {
                format!("summary.{f}")
            } else {
                f.clone()
            }
        }));
        let mut out = csv_line(&header);
        for r in &self.rows {
            let mut cells = vec![
                r.id.clone(),
                r.name.clone(),
                r.problem.clone(),
                r.state.word().to_string(),
            ];
            cells.extend(r.labels.iter().cloned());
            cells.push(
                r.record
                    .as_ref()
                    .map_or_else(String::new, |x| x.seconds.to_string()),
            );
            cells.push(
                r.record
                    .as_ref()
                    .map_or_else(String::new, |x| x.resumed.to_string()),
            );
            for f in &self.fields {
                cells.push(match r.summary.get(f) {
                    None | Some(Value::Null) => String::new(),
                    Some(Value::String(s)) => s.clone(),
                    Some(v) => v.to_string(),
                });
            }
            out.push_str(&csv_line(&cells));
        }
        out
    }

    /// The table as JSON: one object per run with its labels (by axis), status, record and
    /// summary.
    pub fn to_json(&self) -> Value {
        let runs: Vec<Value> = self
            .rows
            .iter()
            .map(|r| {
                let labels: Map<String, Value> = self
                    .axes
                    .iter()
                    .zip(&r.labels)
                    .map(|(a, l)| (a.clone(), Value::String(l.clone())))
                    .collect();
                let mut o = Map::new();
                o.insert("id".into(), r.id.clone().into());
                o.insert("name".into(), r.name.clone().into());
                o.insert("problem".into(), r.problem.clone().into());
                o.insert("status".into(), r.state.word().into());
                if let RunState::Failed(e) = &r.state {
                    o.insert("error".into(), e.clone().into());
                }
                o.insert("labels".into(), Value::Object(labels));
                if let Some(rec) = &r.record {
                    o.insert("run_seconds".into(), rec.seconds.into());
                    o.insert("resumed".into(), rec.resumed.into());
                    o.insert("threads".into(), rec.threads.into());
                }
                o.insert("summary".into(), Value::Object(r.summary.clone()));
                Value::Object(o)
            })
            .collect();
        serde_json::json!({
            "sweep": self.name,
            "axes": self.axes,
            "runs": runs,
        })
    }
}

fn csv_line(cells: &[String]) -> String {
    let mut s = cells
        .iter()
        .map(|c| {
            if c.contains([',', '"', '\n', '\r']) {
                format!("\"{}\"", c.replace('"', "\"\""))
            } else {
                c.clone()
            }
        })
        .collect::<Vec<_>>()
        .join(",");
    s.push('\n');
    s
}

/// A number for a table: four significant digits, or fewer decimals for large values.
pub fn fmt_num(x: f64) -> String {
    if !x.is_finite() {
        return x.to_string();
    }
    let a = x.abs();
    if x == 0.0 {
        "0".into()
    } else if a >= 1000.0 || (x.fract() == 0.0 && a < 1e15) {
        format!("{x:.0}")
    } else if a >= 1.0 {
        format!("{x:.3}")
    } else if a >= 1e-3 {
        format!("{x:.4}")
    } else {
        format!("{x:.3e}")
    }
}

impl Aggregate {
    /// As a Markdown table: one row per group, `mean ± std (n)` per metric (the value
    /// alone for a group of one run).
    pub fn to_markdown(&self, metrics: &[String]) -> String {
        let idx: Vec<usize> = metrics
            .iter()
            .filter_map(|m| self.metrics.iter().position(|x| x == m))
            .collect();
        let mut s = String::new();
        let mut head: Vec<String> = self.by.clone();
        head.push("runs".into());
        head.extend(idx.iter().map(|&i| self.metrics[i].clone()));
        let _ = writeln!(s, "| {} |", head.join(" | "));
        let _ = writeln!(s, "|{}", "---|".repeat(head.len()));
        for (key, n, stats) in &self.groups {
            let mut cells = key.clone();
            cells.push(n.to_string());
            for &i in &idx {
                cells.push(match stats[i] {
                    None => "–".into(),
                    Some(st) if st.count > 1 => {
                        format!("{} ± {} ({})", fmt_num(st.mean), fmt_num(st.std), st.count)
                    }
                    Some(st) => fmt_num(st.mean),
                });
            }
            let _ = writeln!(s, "| {} |", cells.join(" | "));
        }
        s
    }

    /// As CSV: the `by` labels, the group size, then mean, std and count of every metric.
    pub fn to_csv(&self) -> String {
        let mut head: Vec<String> = self.by.clone();
        head.push("runs".into());
        for m in &self.metrics {
            head.push(format!("{m}_mean"));
            head.push(format!("{m}_std"));
            head.push(format!("{m}_count"));
        }
        let mut out = csv_line(&head);
        for (key, n, stats) in &self.groups {
            let mut cells = key.clone();
            cells.push(n.to_string());
            for st in stats {
                match st {
                    Some(st) => {
                        cells.push(st.mean.to_string());
                        cells.push(st.std.to_string());
                        cells.push(st.count.to_string());
                    }
                    None => cells.extend([String::new(), String::new(), "0".into()]),
                }
            }
            out.push_str(&csv_line(&cells));
        }
        out
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
