//! Running a sweep's runs on this machine: N at a time, each in its own rayon pool of T
//! threads; finished runs are skipped, interrupted ones resumed, failed ones re-done.
//!
//! A run works in `runs/.ID.partial/` and becomes `runs/ID/` by one rename once its
//! `run.json` is written, so a crashed or cancelled task never leaves a folder that looks
//! finished. A lock file (`runs/.locks/ID`, released by the kernel when its process dies)
//! keeps two processes off the same run. Runs packed into `runs.jsonl.gz`
//! ([`super::pack`]) are finished runs too.

use std::collections::HashSet;
use std::fs::{File, TryLockError};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use crate::error::{Context, IoContext, bail};
use serde::{Deserialize, Serialize};

use super::expand::{Plan, PlannedRun};
use super::pack::{self, Pack, PackedRun};
use super::shard::Shard;
use crate::progress::Progress;

pub use super::layout::{ERROR_FILE, PLAN_FILE, RECORD_FILE, RUNS_DIR, partial_dir, run_dir};
mod adopt;
pub use adopt::{Adopted, adopt};

/// Whether the run with this id is finished in a folder of its own in `out`.
pub fn is_finished(out: &Path, id: &str) -> bool {
    run_dir(out, id).join(RECORD_FILE).is_file()
}

/// The runs finished in a sweep folder: its run folders and the runs of its pack
/// (`runs.jsonl.gz`), read once.
#[derive(Clone, Debug)]
pub struct FinishedRuns {
    out: PathBuf,
    packed: HashSet<String>,
}

impl FinishedRuns {
    /// Looks at the sweep folder `out` (a folder without runs or pack has none).
    pub fn of(out: &Path) -> crate::Result<Self> {
        let pack = Pack::beside(&out.join(RUNS_DIR))?;
        Ok(FinishedRuns {
            out: out.to_path_buf(),
            packed: pack
                .runs
                .iter()
                .filter(|r| r.file(RECORD_FILE).is_some())
                .map(|r| r.name.clone())
                .collect(),
        })
    }

    /// Whether the run with this id is finished, in its folder or packed.
    pub fn contains(&self, id: &str) -> bool {
        self.packed.contains(id) || is_finished(&self.out, id)
    }
}

/// What a finished run folder's `run.json` says.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct RunRecord {
    /// The stable id.
    pub id: String,
    /// The labels joined.
    pub name: String,
    /// The problem.
    pub problem: String,
    /// (axis, label) pairs.
    pub labels: Vec<(String, String)>,
    /// The run's one-line report.
    pub headline: String,
    /// Wall-clock seconds of the attempt that finished it.
    pub seconds: f64,
    /// Whether that attempt continued an interrupted one.
    pub resumed: bool,
    /// Threads it had.
    pub threads: usize,
}

/// How the local runner runs.
#[derive(Clone, Copy, Debug)]
pub struct RunnerOptions {
    /// Runs at once.
    pub jobs: usize,
    /// Threads of each run.
    pub threads: usize,
    /// Which runs of the sweep.
    pub shard: Shard,
    /// Run even where the LPIPS weights some runs need are missing (see
    /// [`check_lpips_weights`]); off unless asked for.
    pub without_lpips: bool,
}

impl RunnerOptions {
    /// `jobs` at once, the machine's cores shared between them.
    pub fn new(jobs: usize, threads: Option<usize>, shard: Shard) -> crate::Result<Self> {
        if jobs == 0 {
            bail!("--jobs must be at least 1");
        }
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        let threads = threads.unwrap_or((cores / jobs).max(1));
        if threads == 0 {
            bail!("--threads must be at least 1");
        }
        Ok(RunnerOptions {
            jobs,
            threads,
            shard,
            without_lpips: false,
        })
    }

    /// The same options, running (or not) where LPIPS weights are missing.
    pub fn without_lpips(self, without_lpips: bool) -> Self {
        RunnerOptions {
            without_lpips,
            ..self
        }
    }
}

/// Refuses runs that would weigh or score LPIPS without its weights file: such a run drops the
/// term (or the score) and says so in its summary, but its id — a hash of its config — is the
/// id of the run made with the weights, so a table would silently mix two methods. The error
/// names how many of `runs` are affected and the missing file.
pub fn check_lpips_weights<'a>(
    runs: impl IntoIterator<Item = &'a PlannedRun>,
) -> crate::Result<()> {
    let missing: Vec<PathBuf> = runs
        .into_iter()
        .filter_map(|r| r.config.missing_lpips_weights())
        .collect();
    if let Some(path) = missing.first() {
        let (n, verb) = match missing.len() {
            1 => ("1 run of the sweep weighs".to_string(), "it would drop"),
            n => (format!("{n} runs of the sweep weigh"), "they would drop"),
        };
        bail!(
            "{n} LPIPS in its loss or is scored on a suite, and there are no LPIPS weights at {}: \
             {verb} the LPIPS term and score while keeping the ids of runs made with it. Get the \
             weights with `ifslab weights fetch` (or set IFSLAB_LPIPS_WEIGHTS), or pass \
             --without-lpips to run without them",
            path.display()
        );
    }
    Ok(())
}

/// How one run went.
#[derive(Clone, Debug)]
pub enum RunStatus {
    /// Finished before this call.
    Skipped,
    /// Finished now.
    Finished(RunRecord),
    /// Failed with this error; its partial folder stays for a look and a resume.
    Failed(String),
    /// Another process holds it.
    Busy,
    /// Stopped by a signal at a checkpoint; the next attempt resumes it.
    Interrupted,
}

/// What a call of [`run_sweep`] did, run by run (the shard's runs, in sweep order).
#[derive(Debug, Default)]
pub struct SweepOutcome {
    /// (run index, status).
    pub runs: Vec<(usize, RunStatus)>,
}

impl SweepOutcome {
    fn count(&self, f: impl Fn(&RunStatus) -> bool) -> usize {
        self.runs.iter().filter(|(_, s)| f(s)).count()
    }
    /// Runs finished by this call.
    pub fn finished(&self) -> usize {
        self.count(|s| matches!(s, RunStatus::Finished(_)))
    }
    /// Runs that were already finished.
    pub fn skipped(&self) -> usize {
        self.count(|s| matches!(s, RunStatus::Skipped))
    }
    /// Runs held by another process.
    pub fn busy(&self) -> usize {
        self.count(|s| matches!(s, RunStatus::Busy))
    }
    /// The failures: (run index, error).
    pub fn failures(&self) -> Vec<(usize, &str)> {
        self.runs
            .iter()
            .filter_map(|(i, s)| match s {
                RunStatus::Failed(e) => Some((*i, e.as_str())),
                _ => None,
            })
            .collect()
    }
}

/// Writes the plan's index into `out` (every call does: shards write the same bytes).
pub fn write_plan(plan: &Plan, out: &Path) -> crate::Result<()> {
    std::fs::create_dir_all(out.join(RUNS_DIR)).doing("creating", &out.join(RUNS_DIR))?;
    let text = serde_json::to_string_pretty(&plan.index())?;
    ifslab::io::write_atomic(&out.join(PLAN_FILE), text.as_bytes())?;
    Ok(())
}

/// Runs the shard's unfinished runs of `plan` into `out`. `overall` counts the runs to do;
/// `per_run` gives each run its own progress. A failing run does not stop the others.
pub fn run_sweep(
    plan: &Plan,
    out: &Path,
    opts: &RunnerOptions,
    overall: &dyn Progress,
    per_run: &(dyn Fn(&PlannedRun) -> Box<dyn Progress> + Sync),
) -> crate::Result<SweepOutcome> {
    let mine: Vec<&PlannedRun> = plan
        .runs
        .iter()
        .enumerate()
        .filter(|(k, _)| opts.shard.contains(*k))
        .map(|(_, r)| r)
        .collect();
    let mut outcome = SweepOutcome::default();
    let mut todo = Vec::new();
    let finished = FinishedRuns::of(out)?;
    for r in mine {
        if finished.contains(&r.id) {
            outcome.runs.push((r.index, RunStatus::Skipped));
        } else {
            todo.push(r);
        }
    }
    if !opts.without_lpips {
        check_lpips_weights(todo.iter().copied())?;
    }
    write_plan(plan, out)?;
    overall.start("runs", todo.len() as u64);
    let next = AtomicUsize::new(0);
    let results = Mutex::new(Vec::new());
    let failed = AtomicUsize::new(0);
    // A signal stops a run under way at its next checkpoint where the run can (a strategy
    // run holds the watch); then no other run is started.
    std::thread::scope(|s| {
        for _ in 0..opts.jobs.min(todo.len()) {
            s.spawn(|| {
                loop {
                    if ifslab::interrupt::requested() {
                        break;
                    }
                    let k = next.fetch_add(1, Ordering::SeqCst);
                    let Some(r) = todo.get(k) else { break };
                    let status = match run_one(r, out, opts.threads, per_run) {
                        Ok(s) => s,
                        Err(e) => RunStatus::Failed(format!("{e:#}")),
                    };
                    if matches!(status, RunStatus::Failed(_)) {
                        let n = failed.fetch_add(1, Ordering::SeqCst) + 1;
                        overall.message(&format!("{n} failed"));
                    }
                    overall.inc(1);
                    results
                        .lock()
                        .unwrap_or_else(|p| p.into_inner())
                        .push((r.index, status));
                }
            });
        }
    });
    overall.finish();
    if ifslab::interrupt::requested() {
        return Err(crate::Error::Interrupted(
            "interrupted: the runs under way stopped at a checkpoint; run the same sweep \
             command again to resume them and do the rest"
                .into(),
        ));
    }
    outcome
        .runs
        .extend(results.into_inner().unwrap_or_else(|p| p.into_inner()));
    outcome.runs.sort_by_key(|(i, _)| *i);
    Ok(outcome)
}

/// Runs (or resumes) one run and moves it into place.
fn run_one(
    r: &PlannedRun,
    out: &Path,
    threads: usize,
    per_run: &(dyn Fn(&PlannedRun) -> Box<dyn Progress> + Sync),
) -> crate::Result<RunStatus> {
    let locks = out.join(RUNS_DIR).join(".locks");
    std::fs::create_dir_all(&locks).doing("creating", &locks)?;
    let lock_path = locks.join(&r.id);
    let lock = File::options()
        .create(true)
        .truncate(false)
        .write(true)
        .open(&lock_path)
        .doing("opening", &lock_path)?;
    match lock.try_lock() {
        Ok(()) => {}
        Err(TryLockError::WouldBlock) => return Ok(RunStatus::Busy),
        Err(TryLockError::Error(e)) => {
            return Err(e).doing("locking", &lock_path);
        }
    }
    // Another process may have finished it between the first look and the lock.
    if is_finished(out, &r.id) {
        return Ok(RunStatus::Skipped);
    }
    let partial = partial_dir(out, &r.id);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .context("starting the run's thread pool")?;
    let started = Instant::now();
    let had_partial = partial.is_dir();
    let _ = std::fs::remove_file(partial.join(ERROR_FILE));
    // Resume what an interrupted attempt left; if it left nothing to resume from (no
    // checkpoint yet), start again from nothing.
    let mut report = None;
    let mut resumed = false;
    if had_partial {
        match pool.install(|| r.config.run(&partial, true, per_run(r))) {
            Ok(rep) => {
                report = Some(rep);
                resumed = true;
            }
            // Stopped by a signal: its checkpoint stays for the next attempt.
            Err(_) if ifslab::interrupt::requested() => return Ok(RunStatus::Interrupted),
            Err(_) => {
                std::fs::remove_dir_all(&partial).doing("clearing", &partial)?;
            }
        }
    }
    let report = match report {
        Some(r) => r,
        None => {
            if partial.exists() {
                std::fs::remove_dir_all(&partial).doing("clearing", &partial)?;
            }
            std::fs::create_dir_all(&partial).doing("creating", &partial)?;
            match pool.install(|| r.config.run(&partial, false, per_run(r))) {
                Ok(rep) => rep,
                Err(_) if ifslab::interrupt::requested() => return Ok(RunStatus::Interrupted),
                Err(e) => {
                    let text = format!("{e:#}\n");
                    let _ = ifslab::io::write_atomic(&partial.join(ERROR_FILE), text.as_bytes());
                    return Ok(RunStatus::Failed(format!("{e:#}")));
                }
            }
        }
    };
    let record = RunRecord {
        id: r.id.clone(),
        name: r.name.clone(),
        problem: report.problem.clone(),
        labels: r.labels.clone(),
        headline: report.headline.clone(),
        seconds: started.elapsed().as_secs_f64(),
        resumed,
        threads,
    };
    ifslab::io::write_atomic(
        &partial.join(RECORD_FILE),
        serde_json::to_string_pretty(&record)?.as_bytes(),
    )?;
    let done = run_dir(out, &r.id);
    std::fs::rename(&partial, &done).io_context(&partial, || {
        format!(
            "moving the finished run {} to {}",
            partial.display(),
            done.display()
        )
    })?;
    drop(lock);
    Ok(RunStatus::Finished(record))
}
