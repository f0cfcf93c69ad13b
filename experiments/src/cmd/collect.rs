//! `ifslab collect DIR`: a sweep folder's results in one table, aggregates, plots and a
//! Markdown report.

use std::path::PathBuf;

use ifslab_experiments::sweep::collect::collect;
use ifslab_experiments::sweep::report::{ReportOptions, write_report};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The sweep's output folder (what `ifslab sweep -o` wrote; shards and array tasks
    /// merge into it).
    pub dir: PathBuf,
    /// Report folder (default: DIR/report).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Group by these axes (comma-separated for a combination, e.g. `group,strategy`;
    /// repeat for several tables). Default: each axis that varies, one at a time.
    #[arg(long)]
    pub by: Vec<String>,
    /// Metrics in tables and plots (repeatable). Default: every metric that varies.
    #[arg(long)]
    pub metric: Vec<String>,
    /// At most this many runs in the picture grid.
    #[arg(long, default_value_t = 48)]
    pub max_pictures: usize,
    /// Compare every group with this one run by run (labels joined with `/` for a
    /// combination, e.g. `ours_em_sched`): pairs, higher/lower counts, mean difference ±
    /// standard error, sign test, per metric, under each grouping that has it.
    #[arg(long)]
    pub versus: Option<String>,
    /// The axes that pair runs for `--versus` (comma-separated). Default: every varying
    /// axis the grouping leaves out (a suite's `index`).
    #[arg(long, value_delimiter = ',')]
    pub pair_on: Vec<String>,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let c = collect(&a.dir)?;
    let out = a.output.unwrap_or_else(|| a.dir.join("report"));
    let opts = ReportOptions {
        by: a
            .by
            .iter()
            .map(|b| b.split(',').map(|s| s.trim().to_string()).collect())
            .collect(),
        metrics: a.metric,
        max_pictures: a.max_pictures,
        versus: a.versus,
        pair_on: a.pair_on,
    };
    let report = write_report(&c, &out, &opts)?;
    let (finished, failed, interrupted, missing) = c.counts();
    println!(
        "{}: {} runs ({finished} finished, {failed} failed, {interrupted} interrupted, {missing} not started)",
        report.display(),
        c.rows.len()
    );
    let notes = c.notes();
    if let Some((r, field, text)) = notes.first() {
        eprintln!(
            "warning: notes in the runs' summaries: {} (see the report's Notes), e.g. {} {}: {field}: {}",
            notes.len(),
            r.id,
            r.name,
            text.trim()
        );
    }
    Ok(())
}
