//! The collected table's uses: a metric of a row, aggregates by any axes (mean, standard
//! deviation, count: [`Stat`]) and the table and its aggregates written as CSV, JSON and
//! Markdown.

use super::*;

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

pub(super) fn csv_line(cells: &[String]) -> String {
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
