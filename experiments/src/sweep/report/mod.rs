//! A sweep's report: `results.csv` and `results.json` (one row per run), an aggregate
//! table per grouping, paired comparisons against a reference group (`--versus`), plots of
//! every metric per axis value, the loss curves overlaid, a grid of targets and results, and
//! `report.md` tying them together — all from a [`Collected`] table.

use std::collections::BTreeSet;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::error::{IoContext, bail};
use image::{GrayImage, RgbImage};
use plotters::prelude::*;

use super::collect::{Collected, MAX_CATEGORIES, Row, RunState, WALL_TIME_COLUMNS, fmt_num};
use super::paired::Paired;
use crate::plot::{Series, category_chart, ensure_font, line_chart};
mod pictures;
use pictures::{GRID_PICTURES, loss_curves, picture_grid};

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
pub fn write_report(c: &Collected, out: &Path, opts: &ReportOptions) -> crate::Result<PathBuf> {
    std::fs::create_dir_all(out).doing("creating", out)?;
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
    } else if c.rows.iter().any(|r| {
        r.is_packed()
            && r.left_out
                .iter()
                .any(|f| GRID_PICTURES.contains(&f.as_str()))
    }) {
        let _ = writeln!(
            md,
            "\n## Targets and results\n\nThe runs are packed without their pictures \
             (`runs.jsonl.gz`): `ifslab unpack DIR --pictures` writes their folders back and \
             draws an image inversion's again (other problems' runs are drawn by running them \
             again), and `ifslab collect` then shows them here."
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
