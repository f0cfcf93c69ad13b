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

/// What [`adopt`] did.
#[derive(Debug, Default)]
pub struct Adopted {
    /// (run index, the folder it came from) of the runs copied in.
    pub adopted: Vec<(usize, PathBuf)>,
    /// Runs of the plan that were already finished in the sweep folder.
    pub already: usize,
    /// Folders whose config is no run of the plan (or could not be read: why).
    pub unmatched: Vec<(PathBuf, String)>,
}

/// Takes finished run folders made outside the sweep (`ifslab run`, an older script) into
/// the sweep folder: each folder of `from` — and each run packed in `from.jsonl.gz` beside it
/// that has no folder there ([`super::pack`]; `from` may name the pack itself) — whose
/// `config.toml` resolves to one of the plan's runs (same id) and which has a `summary.json`
/// is copied to `runs/ID/` as a finished run, so that `collect` tables it and the sweep does
/// not run it again. Folders of other configs (other settings, or defaults that changed
/// since) are left out and listed.
pub fn adopt(plan: &Plan, out: &Path, from: &Path) -> crate::Result<Adopted> {
    write_plan(plan, out)?;
    let sweep_dir = plan.source.parent().unwrap_or(Path::new("/"));
    let folder = pack::runs_folder(from);
    let packed = Pack::beside(&folder)?;
    let mut candidates: Vec<(PathBuf, Option<&PackedRun>)> = Vec::new();
    if folder.is_dir() {
        for e in std::fs::read_dir(&folder).doing("reading", &folder)? {
            let p = e?.path();
            if p.is_dir() {
                candidates.push((p, None));
            }
        }
    } else if packed.runs.is_empty() {
        bail!(
            "{} is neither a folder of runs nor beside a pack of them ({})",
            folder.display(),
            pack::pack_path(&folder).display()
        );
    }
    for r in &packed.runs {
        let p = folder.join(&r.name);
        if !p.is_dir() {
            candidates.push((p, Some(r)));
        }
    }
    candidates.sort_by(|a, b| a.0.cmp(&b.0));
    let finished = FinishedRuns::of(out)?;
    // A packed run is written out here to be read like a folder.
    let staging = out.join(RUNS_DIR).join(".adopting");
    let mut result = Adopted::default();
    for (source, packed_run) in candidates {
        let d = match packed_run {
            None => source.clone(),
            Some(r) => {
                if staging.exists() {
                    std::fs::remove_dir_all(&staging).doing("clearing", &staging)?;
                }
                r.write_folder(&staging)?;
                staging.clone()
            }
        };
        let cfg_path = d.join("config.toml");
        if !cfg_path.is_file() || !d.join("summary.json").is_file() {
            result.unmatched.push((
                source,
                "no config.toml and summary.json: not a finished run".into(),
            ));
            continue;
        }
        let id = match crate::runs::RunConfig::load_resolved(&cfg_path).and_then(|c| c.to_table()) {
            Ok(t) => super::expand::run_id(&t, sweep_dir),
            Err(e) => {
                result.unmatched.push((source, format!("{e:#}")));
                continue;
            }
        };
        let Some(r) = plan.runs.iter().find(|r| r.id == id) else {
            result.unmatched.push((
                source,
                format!("its config (id {id}) is no run of the sweep"),
            ));
            continue;
        };
        if finished.contains(&id) {
            result.already += 1;
            continue;
        }
        let partial = partial_dir(out, &id);
        if partial.exists() {
            std::fs::remove_dir_all(&partial).doing("clearing", &partial)?;
        }
        if packed_run.is_some() {
            std::fs::rename(&d, &partial).io_context(&d, || {
                format!("moving {} to {}", d.display(), partial.display())
            })?;
        } else {
            copy_dir(&d, &partial)?;
        }
        let summary: serde_json::Value = serde_json::from_slice(
            &std::fs::read(partial.join("summary.json"))
                .doing("reading", &source.join("summary.json"))?,
        )
        .config_context(&source.join("summary.json"), || {
            format!(
                "{} is not valid JSON",
                source.join("summary.json").display()
            )
        })?;
        let record = RunRecord {
            id: id.clone(),
            name: r.name.clone(),
            problem: r.config.problem().into(),
            labels: r.labels.clone(),
            headline: format!("adopted from {}", source.display()),
            seconds: summary["seconds"].as_f64().unwrap_or(f64::NAN),
            resumed: false,
            threads: 0,
        };
        ifslab::io::write_atomic(
            &partial.join(RECORD_FILE),
            serde_json::to_string_pretty(&record)?.as_bytes(),
        )?;
        std::fs::rename(&partial, run_dir(out, &id)).io_context(&partial, || {
            format!("moving {} into place", partial.display())
        })?;
        result.adopted.push((r.index, source));
    }
    if staging.exists() {
        std::fs::remove_dir_all(&staging).doing("clearing", &staging)?;
    }
    Ok(result)
}

fn copy_dir(from: &Path, to: &Path) -> crate::Result<()> {
    std::fs::create_dir_all(to).doing("creating", to)?;
    for e in std::fs::read_dir(from).doing("reading", from)? {
        let p = e?.path();
        let dest = to.join(p.file_name().unwrap_or_default());
        if p.is_dir() {
            copy_dir(&p, &dest)?;
        } else {
            std::fs::copy(&p, &dest).io_context(&p, || {
                format!("copying {} to {}", p.display(), dest.display())
            })?;
        }
    }
    Ok(())
}
