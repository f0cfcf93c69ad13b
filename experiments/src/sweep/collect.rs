//! A sweep's results in one place: every planned run's summary in one table (CSV and
//! JSON, one row per run, so per seed), aggregated by any axis or combination of axes
//! (mean, standard deviation, count), and a Markdown report with its plots: each metric per
//! axis value, the loss curves overlaid, a grid of targets and results.
//!
//! Collect reads only the output folder (`sweep.json` and `runs/`), so it works on the
//! merged folder of any number of shards or array tasks, finished or not: runs not finished
//! yet are rows with their status and no numbers.

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, bail};
use image::{GrayImage, RgbImage};
use plotters::prelude::*;
use serde_json::{Map, Value};

use super::expand::PlanIndex;
use super::local::{ERROR_FILE, PLAN_FILE, RECORD_FILE, RUNS_DIR, RunRecord, partial_dir, run_dir};
use super::paired::Paired;
use crate::plot::{Series, category_chart, ensure_font, line_chart};

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
    /// Its folder (finished runs).
    pub dir: Option<PathBuf>,
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
pub fn collect(dir: &Path) -> anyhow::Result<Collected> {
    let plan_path = dir.join(PLAN_FILE);
    let text = std::fs::read_to_string(&plan_path).with_context(|| {
        format!(
            "reading {}: is {} the output folder of `ifslab sweep`?",
            plan_path.display(),
            dir.display()
        )
    })?;
    let plan: PlanIndex = serde_json::from_str(&text)
        .with_context(|| format!("{} is not a sweep index", plan_path.display()))?;
    let mut rows = Vec::new();
    let mut metrics: Vec<String> = Vec::new();
    let mut fields: Vec<String> = Vec::new();
    for r in &plan.runs {
        let done = run_dir(dir, &r.id);
        let partial = partial_dir(dir, &r.id);
        let (state, summary, record, run_folder) = if done.join(RECORD_FILE).is_file() {
            let record: RunRecord = read_json(&done.join(RECORD_FILE))?;
            let summary_path = done.join("summary.json");
            let mut summary = Map::new();
            if summary_path.is_file() {
                let v: Value = read_json(&summary_path)?;
                flatten_json("", &v, &mut summary);
            }
            (RunState::Finished, summary, Some(record), Some(done))
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
        });
    }
    let planned: BTreeSet<&str> = plan.runs.iter().map(|r| r.id.as_str()).collect();
    let unplanned = std::fs::read_dir(dir.join(RUNS_DIR))
        .map(|rd| {
            rd.filter_map(Result::ok)
                .filter(|e| {
                    let n = e.file_name().to_string_lossy().into_owned();
                    !n.starts_with('.')
                        && !planned.contains(n.as_str())
                        && e.path().join(RECORD_FILE).is_file()
                })
                .count()
        })
        .unwrap_or(0);
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

fn read_json<T: serde::de::DeserializeOwned>(path: &Path) -> anyhow::Result<T> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{} is not valid JSON", path.display()))
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

    fn axis_index(&self, axis: &str) -> anyhow::Result<usize> {
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
    pub fn values_of(&self, axis: &str) -> anyhow::Result<Vec<String>> {
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
    pub fn keys_of(&self, axes: &[String]) -> anyhow::Result<Vec<String>> {
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
    pub fn aggregate(&self, by: &[String]) -> anyhow::Result<Aggregate> {
        let ks: Vec<usize> = by
            .iter()
            .map(|a| self.axis_index(a))
            .collect::<anyhow::Result<_>>()?;
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

/// What a report shows.
#[derive(Clone, Debug, Default)]
pub struct ReportOptions {
    /// Groupings (each one or more axes); empty: each axis that varies, one at a time.
    pub by: Vec<Vec<String>>,
    /// Metrics in the tables and plots; empty: every metric that varies, wall time last
    /// in tables and not plotted.
    pub metrics: Vec<String>,
    /// At most this many runs in the picture grid (0: 48).
    pub max_pictures: usize,
    /// A group (labels joined with `/`) to compare every other group of its grouping with,
    /// run by run ([`Paired`]): each grouping that has it gets a paired table per metric.
    pub versus: Option<String>,
    /// The axes that pair runs for `versus`; empty: every varying axis the grouping leaves
    /// out (the suite code of a table, say).
    pub pair_on: Vec<String>,
}

/// Writes `results.csv`, `results.json`, `aggregate_*.csv`, the plots and `report.md` into
/// `out`; returns the report's path.
pub fn write_report(c: &Collected, out: &Path, opts: &ReportOptions) -> anyhow::Result<PathBuf> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let write = |name: &str, bytes: &[u8]| ifslab::io::write_atomic(&out.join(name), bytes);
    write("results.csv", c.to_csv().as_bytes())?;
    write(
        "results.json",
        serde_json::to_string_pretty(&c.to_json())?.as_bytes(),
    )?;
    let by: Vec<Vec<String>> = if opts.by.is_empty() {
        c.varying_axes().into_iter().map(|a| vec![a]).collect()
    } else {
        opts.by.clone()
    };
    for m in &opts.metrics {
        if !c.metrics.contains(m) {
            bail!(
                "no run reports the metric `{m}` (metrics: {})",
                c.metrics.join(", ")
            );
        }
    }
    let varies = |m: &String| {
        let vals: Vec<u64> = c
            .rows
            .iter()
            .filter_map(|r| Collected::value(r, m))
            .map(f64::to_bits)
            .collect();
        vals.iter().any(|v| *v != vals[0])
    };
    let wall = |m: &String| WALL_TIME_COLUMNS.contains(&m.as_str());
    let plotted: Vec<String> = if opts.metrics.is_empty() {
        c.metrics
            .iter()
            .filter(|m| !wall(m) && varies(m))
            .cloned()
            .collect()
    } else {
        opts.metrics.iter().filter(|m| !wall(m)).cloned().collect()
    };
    let tabled: Vec<String> = if opts.metrics.is_empty() {
        let mut t = plotted.clone();
        t.extend(c.metrics.iter().filter(|m| wall(m)).cloned());
        t
    } else {
        opts.metrics.clone()
    };

    let pair_on = |group: &[String]| -> Vec<String> {
        if opts.pair_on.is_empty() {
            c.varying_axes()
                .into_iter()
                .filter(|a| !group.contains(a))
                .collect()
        } else {
            opts.pair_on.clone()
        }
    };
    if let Some(reference) = &opts.versus
        && !by
            .iter()
            .any(|g| c.keys_of(g).is_ok_and(|k| k.contains(reference)))
    {
        bail!(
            "--versus {reference}: no grouping has that group (groups: {})",
            by.iter()
                .filter_map(|g| c.keys_of(g).ok())
                .flatten()
                .collect::<Vec<_>>()
                .join(", ")
        );
    }

    let (finished, failed, interrupted, missing) = c.counts();
    let mut md = format!("# Sweep `{}`\n\n", c.name);
    let _ = writeln!(
        md,
        "{} runs: {finished} finished, {failed} failed, {interrupted} interrupted or under way, {missing} not started{}.\n",
        c.rows.len(),
        if c.unplanned > 0 {
            format!(
                " ({} finished runs in the folder belong to no run of the current sweep file and are left out)",
                c.unplanned
            )
        } else {
            String::new()
        }
    );
    let notes = c.notes();
    if !notes.is_empty() {
        let _ = writeln!(
            md,
            "**Runs that left notes in their summaries: {}** (listed under Notes at the end): \
             read them before comparing those runs' numbers — a run that went without a term \
             its config asks for is not the method its labels name.\n",
            notes
                .iter()
                .map(|(r, ..)| &r.id)
                .collect::<BTreeSet<_>>()
                .len()
        );
    }
    md.push_str("Full tables: [results.csv](results.csv), [results.json](results.json). ");
    md.push_str("Aggregates are over finished runs: mean ± sample standard deviation (count); a group of one run shows its value.\n\n");
    for group in &by {
        let agg = c.aggregate(group)?;
        let tag = group.join("+");
        write(
            &format!("aggregate_{}.csv", file_word(&tag)),
            agg.to_csv().as_bytes(),
        )?;
        let _ = writeln!(md, "## By {}\n", group.join(" × "));
        md.push_str(&agg.to_markdown(&tabled));
        md.push('\n');
        if let Some(reference) = &opts.versus
            && c.keys_of(group)?.contains(reference)
        {
            let on = pair_on(group);
            let _ = writeln!(
                md,
                "### Paired against {reference}\n\nRuns paired on {}: on how many pairs each \
                 group scores higher, lower or the same as {reference}, the mean difference \
                 ± its standard error, and the two-sided sign test (ties left out).\n",
                on.join(" × ")
            );
            let mut csv = Paired::CSV_HEADER.to_string();
            for m in tabled.iter().filter(|m| !wall(m)) {
                let p = c.paired(group, &on, reference, m)?;
                let _ = writeln!(md, "**{m}**\n");
                md.push_str(&p.to_markdown());
                md.push('\n');
                csv.push_str(&p.to_csv_rows());
            }
            write(&format!("paired_{}.csv", file_word(&tag)), csv.as_bytes())?;
        }
        // Plots: one category per combination of the group's labels ("random/adam").
        let cats = c.keys_of(group)?;
        let tag = file_word(&group.join("+"));
        let what = group.join(" × ");
        if cats.len() > MAX_CATEGORIES {
            let _ = writeln!(
                md,
                "({} combinations: too many to plot; the table has them.)\n",
                cats.len()
            );
            continue;
        }
        for m in &plotted {
            let points: Vec<(usize, f64)> = c
                .rows
                .iter()
                .filter_map(|r| {
                    let v = Collected::value(r, m)?;
                    Some((cats.iter().position(|x| *x == c.key(group, r))?, v))
                })
                .collect();
            if points.is_empty() {
                continue;
            }
            let file = format!("{}_by_{tag}.png", file_word(m));
            category_chart(
                &out.join(&file),
                &format!("{m} by {what}"),
                m,
                &cats,
                &points,
            )?;
            let _ = writeln!(md, "![{m} by {what}]({file})");
        }
        if let Some(file) = loss_curves(c, group, &cats, out)? {
            let _ = writeln!(md, "\nLoss curves by {what}:\n\n![loss by {what}]({file})");
        }
        md.push('\n');
    }
    md.push_str("## Every run\n\n");
    md.push_str(&runs_markdown(c, &tabled));
    let max = if opts.max_pictures == 0 {
        48
    } else {
        opts.max_pictures
    };
    if let Some(file) = picture_grid(c, &out.join("pictures.png"), max)? {
        let _ = writeln!(
            md,
            "\n## Targets and results\n\n![targets and results]({file})"
        );
    }
    let failures: Vec<&Row> = c
        .rows
        .iter()
        .filter(|r| matches!(r.state, RunState::Failed(_)))
        .collect();
    if !failures.is_empty() {
        md.push_str("\n## Failures\n\n");
        for r in failures {
            if let RunState::Failed(e) = &r.state {
                let _ = writeln!(
                    md,
                    "- `{}` {}: {}",
                    r.id,
                    r.name,
                    e.lines().next().unwrap_or("")
                );
            }
        }
    }
    if !notes.is_empty() {
        md.push_str("\n## Notes\n\n");
        for (r, field, text) in &notes {
            let _ = writeln!(md, "- `{}` {}: {field}: {}", r.id, r.name, text.trim());
        }
    }
    let path = out.join("report.md");
    ifslab::io::write_atomic(&path, md.as_bytes())?;
    Ok(path)
}

/// One row per run (so per seed): labels, status and the metrics.
fn runs_markdown(c: &Collected, metrics: &[String]) -> String {
    let mut s = String::new();
    let mut head: Vec<String> = c.axes.clone();
    head.push("status".into());
    head.extend(metrics.iter().cloned());
    head.push("id".into());
    let _ = writeln!(s, "| {} |", head.join(" | "));
    let _ = writeln!(s, "|{}", "---|".repeat(head.len()));
    for r in &c.rows {
        let mut cells = r.labels.clone();
        cells.push(r.state.word().into());
        for m in metrics {
            cells.push(Collected::value(r, m).map_or_else(|| "–".into(), fmt_num));
        }
        cells.push(format!("`{}`", r.id));
        let _ = writeln!(s, "| {} |", cells.join(" | "));
    }
    s
}

/// A name usable in a file name.
fn file_word(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The `loss` column of a run's `log.csv` against its first column (the iteration).
fn loss_curve(dir: &Path) -> Option<Vec<(f64, f64)>> {
    let text = std::fs::read_to_string(dir.join("log.csv")).ok()?;
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next()?.split(',').collect();
    let col = header.iter().position(|h| *h == "loss")?;
    let pts: Vec<(f64, f64)> = lines
        .filter_map(|l| {
            let v: Vec<&str> = l.split(',').collect();
            Some((v.first()?.parse().ok()?, v.get(col)?.parse().ok()?))
        })
        .filter(|&(_, y): &(f64, f64)| y.is_finite() && y > 0.0)
        .collect();
    (!pts.is_empty()).then_some(pts)
}

/// A run's loss curve with the position of its label on the axis.
type Curve<'a> = (usize, &'a Row, Vec<(f64, f64)>);

/// The loss curves of the finished runs, one colour per value of `axis`: every run's curve
/// when there are at most 12, else the mean curve of each value.
fn loss_curves(
    c: &Collected,
    group: &[String],
    cats: &[String],
    out: &Path,
) -> anyhow::Result<Option<String>> {
    let axis = group.join(" × ");
    let curves: Vec<Curve<'_>> = c
        .rows
        .iter()
        .filter_map(|r| {
            let curve = loss_curve(r.dir.as_deref()?)?;
            Some((cats.iter().position(|x| *x == c.key(group, r))?, r, curve))
        })
        .collect();
    if curves.is_empty() {
        return Ok(None);
    }
    let names: Vec<String>;
    let mut series = Vec::new();
    if curves.len() <= 12 {
        names = curves.iter().map(|(_, r, _)| r.name.clone()).collect();
        for ((_, _, pts), n) in curves.iter().zip(&names) {
            series.push(Series {
                name: n,
                points: pts.clone(),
            });
        }
    } else {
        names = cats.iter().map(|v| format!("{v} (mean)")).collect();
        for (ci, n) in names.iter().enumerate() {
            let mine: Vec<&Vec<(f64, f64)>> =
                curves.iter().filter(|x| x.0 == ci).map(|x| &x.2).collect();
            let Some(shortest) = mine.iter().map(|p| p.len()).min() else {
                continue;
            };
            let points = (0..shortest)
                .map(|i| {
                    let y = mine.iter().map(|p| p[i].1).sum::<f64>() / mine.len() as f64;
                    (mine[0][i].0, y)
                })
                .collect();
            series.push(Series { name: n, points });
        }
    }
    let file = format!("loss_by_{}.png", file_word(&group.join("+")));
    line_chart(
        &out.join(&file),
        &format!("loss by {axis}"),
        "iteration",
        "loss",
        &series,
        true,
    )?;
    Ok(Some(file))
}

/// A grid with one row per finished run (at most `max`): its target (or ground truth) and
/// its result, captioned with its name. `None` when no run has pictures.
fn picture_grid(c: &Collected, path: &Path, max: usize) -> anyhow::Result<Option<String>> {
    const TILE: u32 = 128;
    const CAPTION: u32 = 220;
    const GAP: u32 = 4;
    let load = |p: PathBuf| -> Option<GrayImage> {
        let img = image::open(&p).ok()?.to_luma8();
        Some(image::imageops::resize(
            &img,
            TILE,
            TILE,
            image::imageops::FilterType::Triangle,
        ))
    };
    let mut rows: Vec<(String, Option<GrayImage>, Option<GrayImage>)> = Vec::new();
    for r in c.rows.iter().filter(|r| r.dir.is_some()).take(max) {
        let d = r.dir.as_deref().unwrap_or(Path::new(""));
        let target = load(d.join("truth.png")).or_else(|| load(d.join("target.png")));
        let result = load(d.join("render.png"));
        if target.is_some() || result.is_some() {
            rows.push((r.name.clone(), target, result));
        }
    }
    if rows.is_empty() {
        return Ok(None);
    }
    let w = CAPTION + 2 * (TILE + GAP);
    let h = 24 + rows.len() as u32 * (TILE + GAP);
    let mut img = RgbImage::from_pixel(w, h, image::Rgb([255, 255, 255]));
    for (i, (_, t, r)) in rows.iter().enumerate() {
        let y0 = 24 + i as u32 * (TILE + GAP);
        for (j, tile) in [t, r].into_iter().enumerate() {
            let Some(tile) = tile else { continue };
            let x0 = CAPTION + j as u32 * (TILE + GAP);
            for (x, y, p) in tile.enumerate_pixels() {
                img.put_pixel(x0 + x, y0 + y, image::Rgb([p[0], p[0], p[0]]));
            }
        }
    }
    let mut buf = img.into_raw();
    ensure_font();
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        let font = ("sans-serif", 14).into_font().color(&BLACK);
        root.draw(&Text::new("target", (CAPTION as i32 + 4, 4), font.clone()))?;
        root.draw(&Text::new(
            "result",
            ((CAPTION + TILE + GAP) as i32 + 4, 4),
            font.clone(),
        ))?;
        for (i, (name, _, _)) in rows.iter().enumerate() {
            let y = 24 + i as i32 * (TILE + GAP) as i32 + TILE as i32 / 2 - 7;
            let mut n = name.clone();
            if n.chars().count() > 34 {
                n = n.chars().take(33).collect::<String>() + "…";
            }
            root.draw(&Text::new(n, (6, y), font.clone()))?;
        }
        root.present()?;
    }
    let img = RgbImage::from_raw(w, h, buf).context("picture grid buffer")?;
    let mut bytes = std::io::Cursor::new(Vec::new());
    img.write_to(&mut bytes, image::ImageFormat::Png)?;
    ifslab::io::write_atomic(path, bytes.get_ref())?;
    Ok(path.file_name().map(|f| f.to_string_lossy().into_owned()))
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
