//! Sweeps, their collected results and suite scores: thin bindings over the functions the
//! `ifslab sweep`, `ifslab collect` and `ifslab suite score` commands call
//! ([`run_sweep`], [`collect`](ifslab_experiments::sweep::collect::collect) with
//! [`write_report`], [`score_code`](ifslab_experiments::suite::score_code)), their results
//! crossing to Python as JSON text.

use std::path::{Path, PathBuf};
use std::time::Duration;

use ifslab::loss::lpips::Lpips;
use ifslab_experiments::progress::{Progress, Silent};
use ifslab_experiments::suite;
use ifslab_experiments::sweep::collect::{Aggregate, Collected, collect};
use ifslab_experiments::sweep::local::{self, RunStatus};
use ifslab_experiments::sweep::report::{ReportOptions, write_report};
use ifslab_experiments::sweep::{
    Plan, PlannedRun, RunnerOptions, Shard, check_lpips_weights, run_sweep, slurm,
};
use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;
use serde_json::{Value, json};

use crate::errors::{IfslabError, IntoPy};
use crate::progress::PyProgress;

/// How often the calling thread looks for Ctrl-C while a sweep runs.
const SIGNAL_EVERY: Duration = Duration::from_millis(100);

/// The scores of a code (JSON text of a code document when `is_json`, else a file or a
/// built-in name) against entry `index` of the suite in `suite_dir` — every entry when
/// `None` — as `ifslab suite score --json` prints them (LPIPS where its weights are), JSON
/// text: one score, or a list of them.
#[pyfunction]
#[pyo3(signature = (suite_dir, code, is_json, index=None))]
pub fn suite_score(
    py: Python<'_>,
    suite_dir: PathBuf,
    code: &str,
    is_json: bool,
    index: Option<usize>,
) -> PyResult<String> {
    let code = crate::code::resolve(code, is_json).py()?;
    let scores = py.detach(move || -> anyhow::Result<Value> {
        let manifest = suite::load(&suite_dir)?;
        let net = Lpips::try_load_default()?;
        let score = |i: usize| suite::score_code(&suite_dir, &manifest, i, &code, net.as_ref());
        Ok(match index {
            Some(i) => serde_json::to_value(score(i)?)?,
            None => serde_json::to_value(
                (0..manifest.codes.len())
                    .map(score)
                    .collect::<ifslab_experiments::Result<Vec<_>>>()?,
            )?,
        })
    });
    serde_json::to_string(&scores.py()?).py()
}

/// The sweep file's plan, kept to the runs `only` names (`--only AXIS=LABEL`, repeated).
fn plan_of(sweep_file: &Path, only: &[(String, String)]) -> PyResult<Plan> {
    let mut plan = Plan::load(sweep_file).py()?;
    plan.retain(only).py()?;
    Ok(plan)
}

fn shard_of(shard: Option<&str>) -> PyResult<Shard> {
    match shard {
        Some(s) => s.parse().py(),
        None => Ok(Shard::ALL),
    }
}

/// What `ifslab sweep FILE -o OUT --dry-run [--shard I/N] [--only …]` prints, as JSON text:
/// the plan's description, and each run of the plan with whether it is in the shard and
/// its state in `out` (`finished`, `partial`: interrupted or failed, `not_started`).
#[pyfunction]
#[pyo3(signature = (sweep_file, out, shard=None, only=Vec::new()))]
pub fn sweep_dry_run(
    sweep_file: PathBuf,
    out: PathBuf,
    shard: Option<&str>,
    only: Vec<(String, String)>,
) -> PyResult<String> {
    let plan = plan_of(&sweep_file, &only)?;
    let shard = shard_of(shard)?;
    let finished = local::FinishedRuns::of(&out).py()?;
    let runs: Vec<Value> = plan
        .runs
        .iter()
        .enumerate()
        .map(|(k, r)| {
            let state = if finished.contains(&r.id) {
                "finished"
            } else if local::partial_dir(&out, &r.id).is_dir() {
                "partial"
            } else {
                "not_started"
            };
            json!({
                "index": r.index, "id": r.id, "name": r.name,
                "in_shard": shard.contains(k), "state": state,
            })
        })
        .collect();
    serde_json::to_string(&json!({
        "sweep": plan.name,
        "dir": out,
        "shard": shard.to_string(),
        "description": plan.describe(),
        "runs": runs,
    }))
    .py()
}

/// `ifslab sweep FILE -o OUT --adopt FROM [--only …]`: takes the finished run folders of
/// `from` (and the runs packed beside it) whose configs are runs of the sweep into `out`.
/// JSON text: the runs adopted (index, id, folder), how many were there already, the
/// folders left out and why.
#[pyfunction]
#[pyo3(signature = (sweep_file, out, from, only=Vec::new()))]
pub fn sweep_adopt(
    py: Python<'_>,
    sweep_file: PathBuf,
    out: PathBuf,
    from: PathBuf,
    only: Vec<(String, String)>,
) -> PyResult<String> {
    let plan = plan_of(&sweep_file, &only)?;
    let r = py.detach(|| local::adopt(&plan, &out, &from)).py()?;
    let id_of = |i: usize| {
        plan.runs
            .iter()
            .find(|r| r.index == i)
            .map(|r| r.id.clone())
    };
    serde_json::to_string(&json!({
        "sweep": plan.name,
        "dir": out,
        "adopted": r.adopted.iter().map(|(i, d)| json!({"index": i, "id": id_of(*i), "from": d})).collect::<Vec<_>>(),
        "already": r.already,
        "unmatched": r.unmatched.iter().map(|(d, why)| json!({"folder": d, "why": why})).collect::<Vec<_>>(),
    }))
    .py()
}

/// `ifslab sweep FILE -o OUT --slurm [--submit] [--without-lpips] [--only …]`: writes the
/// Slurm job-array script into `out/slurm/`, its tasks running `exe` (the `ifslab`
/// binary), and submits it with `sbatch` when `submit`. JSON text: the script, the runs,
/// the array's tasks, and the job id when submitted.
#[pyfunction]
#[pyo3(signature = (sweep_file, out, exe, only=Vec::new(), without_lpips=false, submit=false))]
pub fn sweep_slurm(
    sweep_file: PathBuf,
    out: PathBuf,
    exe: PathBuf,
    only: Vec<(String, String)>,
    without_lpips: bool,
    submit: bool,
) -> PyResult<String> {
    let plan = plan_of(&sweep_file, &only)?;
    if !exe.is_file() {
        return Err(IfslabError::new_err(format!(
            "the ifslab binary the Slurm tasks would run is not there: {}",
            exe.display()
        )));
    }
    if !without_lpips {
        // As the command line: what the array tasks would run, the unfinished runs.
        let finished = local::FinishedRuns::of(&out).py()?;
        check_lpips_weights(plan.runs.iter().filter(|r| !finished.contains(&r.id))).py()?;
    }
    let extra: Vec<String> = match without_lpips {
        true => vec!["--without-lpips".into()],
        false => Vec::new(),
    };
    let script = slurm::write_script(&plan, &out, &exe, &extra).py()?;
    let job = match submit {
        true => Some(slurm::submit(&script).py()?),
        false => None,
    };
    serde_json::to_string(&json!({
        "sweep": plan.name,
        "dir": out,
        "script": script,
        "runs": plan.runs.len(),
        "array_tasks": slurm::shard_count(&plan),
        "job": job,
    }))
    .py()
}

/// Runs the sweep file `sweep_file` into `out` on this machine, as `ifslab sweep FILE -o
/// OUT --jobs N [--threads T] [--shard I/N] [--only AXIS=LABEL…] [--without-lpips]` does:
/// finished runs are kept, interrupted ones resumed. The GIL is released; `progress` hears
/// the sweep's overall progress (runs done). Ctrl-C stops the runs under way at their
/// checkpoints and raises `KeyboardInterrupt` with the library's words. Returns JSON text:
/// every run of the shard with its status.
#[pyfunction]
#[pyo3(signature = (sweep_file, out, jobs=1, threads=None, shard=None, progress=None, only=Vec::new(), without_lpips=false))]
#[allow(clippy::too_many_arguments)]
pub fn sweep(
    py: Python<'_>,
    sweep_file: PathBuf,
    out: PathBuf,
    jobs: usize,
    threads: Option<usize>,
    shard: Option<&str>,
    progress: Option<Py<PyAny>>,
    only: Vec<(String, String)>,
    without_lpips: bool,
) -> PyResult<String> {
    let plan = plan_of(&sweep_file, &only)?;
    let shard = shard_of(shard)?;
    let opts = RunnerOptions::new(jobs, threads, shard)
        .py()?
        .without_lpips(without_lpips);
    if !ifslab::interrupt::clear() {
        return Err(IfslabError::new_err(
            "another run in this Python process is stopping at its checkpoint after an \
             interruption: start this one once it has returned",
        ));
    }
    // The runs go on worker threads, where Python sees no signals: this thread watches for
    // Ctrl-C and asks them to stop (`ifslab::interrupt::request`), as the command line's
    // signal handler does.
    let watch = PyProgress::new(progress, true);
    let overall = watch.boxed();
    let mut interrupted: Option<PyErr> = None;
    let outcome = py.detach(|| {
        std::thread::scope(|s| {
            let work = s.spawn(|| {
                let per_run = |_: &PlannedRun| -> Box<dyn Progress> { Box::new(Silent) };
                run_sweep(&plan, &out, &opts, overall.as_ref(), &per_run)
            });
            while !work.is_finished() {
                std::thread::sleep(SIGNAL_EVERY);
                if interrupted.is_none()
                    && let Err(e) = Python::attach(|py| py.check_signals())
                {
                    interrupted = Some(e);
                    ifslab::interrupt::request();
                }
            }
            match work.join() {
                Ok(r) => r.map_err(anyhow::Error::from),
                Err(_) => Err(anyhow::anyhow!("the sweep panicked")),
            }
        })
    });
    let outcome = match (outcome, interrupted) {
        (Err(e), Some(_)) => Err(PyKeyboardInterrupt::new_err(format!("{e:#}"))),
        (_, Some(e)) => Err(e),
        (r, None) => r.py(),
    };
    let outcome = watch.finish(outcome)?;
    let runs: Vec<Value> = outcome
        .runs
        .iter()
        .map(|(i, s)| {
            let r = plan.runs.iter().find(|r| r.index == *i);
            let mut o = json!({
                "index": i,
                "id": r.map(|r| r.id.clone()),
                "name": r.map(|r| r.name.clone()),
            });
            let (status, extra) = match s {
                RunStatus::Skipped => ("skipped", None),
                RunStatus::Finished(rec) => ("finished", Some(("headline", rec.headline.clone()))),
                RunStatus::Failed(e) => ("failed", Some(("error", e.clone()))),
                RunStatus::Busy => ("busy", None),
                RunStatus::Interrupted => ("interrupted", None),
            };
            o["status"] = status.into();
            if let Some((k, v)) = extra {
                o[k] = v.into();
            }
            o
        })
        .collect();
    let failures = outcome.failures();
    if !failures.is_empty() {
        let lines: Vec<String> = failures
            .iter()
            .map(|(i, e)| {
                let name = plan
                    .runs
                    .iter()
                    .find(|r| r.index == *i)
                    .map_or("", |r| &r.name);
                format!("{name}: {e}")
            })
            .collect();
        return Err(IfslabError::new_err(format!(
            "{} of {} runs failed (their folders are in {}/runs/.ID.partial); run the sweep again to re-do them: {}",
            failures.len(),
            outcome.runs.len(),
            out.display(),
            lines.join("; ")
        )));
    }
    serde_json::to_string(&json!({
        "sweep": plan.name,
        "dir": out,
        "jobs": opts.jobs,
        "threads": opts.threads,
        "runs": runs,
    }))
    .py()
}

/// A sweep folder's results as `ifslab collect` reads them: the table (`results.json`'s
/// document, [`Collected::to_json`]), the run counts, and the aggregates grouped by each
/// grouping of `by` (each one or more axes; empty: each varying axis alone). With `out`,
/// the report folder is written there as `ifslab collect DIR -o OUT` writes it. JSON text.
#[pyfunction]
#[pyo3(signature = (dir, by=Vec::new(), out=None))]
pub fn collect_sweep(
    py: Python<'_>,
    dir: PathBuf,
    by: Vec<Vec<String>>,
    out: Option<PathBuf>,
) -> PyResult<String> {
    py.detach(move || -> anyhow::Result<String> {
        let c = collect(&dir)?;
        let groupings: Vec<Vec<String>> = if by.is_empty() {
            c.varying_axes().into_iter().map(|a| vec![a]).collect()
        } else {
            by.clone()
        };
        let aggregates = groupings
            .iter()
            .map(|b| c.aggregate(b).map(|a| aggregate_json(&a)))
            .collect::<ifslab_experiments::Result<Vec<_>>>()?;
        let report = match &out {
            Some(o) => Some(write_report(
                &c,
                o,
                &ReportOptions {
                    by,
                    ..ReportOptions::default()
                },
            )?),
            None => None,
        };
        Ok(serde_json::to_string(&document(
            &c,
            aggregates,
            report.as_deref(),
        ))?)
    })
    .py()
}

fn document(c: &Collected, aggregates: Vec<Value>, report: Option<&Path>) -> Value {
    let (finished, failed, interrupted, missing) = c.counts();
    json!({
        "results": c.to_json(),
        "dir": c.dir,
        "metrics": c.metrics,
        "counts": {
            "finished": finished,
            "failed": failed,
            "interrupted": interrupted,
            "not_started": missing,
        },
        "unplanned": c.unplanned,
        "aggregates": aggregates,
        "report": report,
    })
}

fn aggregate_json(a: &Aggregate) -> Value {
    let groups: Vec<Value> = a
        .groups
        .iter()
        .map(|(labels, runs, stats)| {
            let stats: serde_json::Map<String, Value> = a
                .metrics
                .iter()
                .zip(stats)
                .map(|(m, s)| {
                    let v = s.map_or(
                        Value::Null,
                        |s| json!({"mean": s.mean, "std": s.std, "count": s.count}),
                    );
                    (m.clone(), v)
                })
                .collect();
            json!({"labels": labels, "runs": runs, "stats": stats})
        })
        .collect();
    json!({"by": a.by, "metrics": a.metrics, "groups": groups})
}
