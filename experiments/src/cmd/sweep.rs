//! `ifslab sweep SWEEP.toml -o DIR`: the runs of a sweep file, here (N at a time), as one
//! shard of several, or as a Slurm job array.

use std::path::PathBuf;

use anyhow::{Context, bail};
use ifslab_experiments::progress::Progress;
use ifslab_experiments::sweep::local::{self, RunStatus};
use ifslab_experiments::sweep::{
    Plan, PlannedRun, RunnerOptions, Shard, check_lpips_weights, run_sweep, slurm,
};
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The sweep file (see experiments/sweeps/).
    pub sweep: PathBuf,
    /// The sweep's output folder (default: out/sweeps/NAME).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Print the resolved runs (id, labels, and whether each is done in the output folder)
    /// and stop.
    #[arg(long)]
    pub dry_run: bool,
    /// Runs at once.
    #[arg(short, long, default_value_t = 1)]
    pub jobs: usize,
    /// Threads of each run (default: the machine's cores shared between the jobs). Results
    /// do not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Print the resolved config of one run (its id or name, as --dry-run lists them) and
    /// stop.
    #[arg(long, value_name = "RUN")]
    pub show: Option<String>,
    /// Run only shard INDEX/COUNT (0-based): the runs whose position is INDEX modulo COUNT,
    /// so COUNT machines split the sweep with no coordinator.
    #[arg(long, value_name = "INDEX/COUNT")]
    pub shard: Option<Shard>,
    /// Only the runs with this label on this axis (AXIS=LABEL; repeat: labels of one axis
    /// are alternatives, different axes must all match). The output folder's sweep.json then
    /// lists only these runs, so `collect` reports on them.
    #[arg(long, value_name = "AXIS=LABEL", value_parser = parse_only)]
    pub only: Vec<(String, String)>,
    /// Take the finished run folders in this folder (made by `ifslab run` or an older
    /// script), and the runs packed beside it in RUNS_DIR.jsonl.gz, whose configs are runs of
    /// the sweep into the output folder, instead of running.
    #[arg(long, value_name = "RUNS_DIR")]
    pub adopt: Option<PathBuf>,
    /// Run even where the LPIPS weights are missing. Without this flag a sweep whose runs
    /// weigh LPIPS in their loss or are scored on a suite refuses to start when the weights
    /// are not there, since those runs would drop the term (and the LPIPS score) while
    /// keeping the ids of runs made with it.
    #[arg(long)]
    pub without_lpips: bool,
    /// Write a Slurm job-array script (one task per shard, resources from the sweep's
    /// [slurm] section) into DIR/slurm/ instead of running.
    #[arg(long)]
    pub slurm: bool,
    /// With --slurm: submit the script with sbatch.
    #[arg(long, requires = "slurm")]
    pub submit: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let mut plan = Plan::load(&a.sweep)?;
    plan.retain(&a.only)?;
    let out = a
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from("out/sweeps").join(&plan.name));
    let shard = a.shard.unwrap_or(Shard::ALL);
    if let Some(which) = &a.show {
        let r = plan
            .runs
            .iter()
            .find(|r| &r.id == which || &r.name == which)
            .with_context(|| format!("the sweep has no run `{which}` (see --dry-run)"))?;
        println!("# run {} ({}) of the sweep {}", r.id, r.name, plan.name);
        print!("{}", toml::to_string_pretty(&r.resolved)?);
        return Ok(());
    }
    if a.dry_run {
        print!("{}", plan.describe());
        let mine: Vec<&PlannedRun> = plan
            .runs
            .iter()
            .enumerate()
            .filter(|(k, _)| shard.contains(*k))
            .map(|(_, r)| r)
            .collect();
        let finished = local::FinishedRuns::of(&out)?;
        let done = mine.iter().filter(|r| finished.contains(&r.id)).count();
        let partial = mine
            .iter()
            .filter(|r| local::partial_dir(&out, &r.id).is_dir())
            .count();
        println!(
            "shard {shard}: {} runs; in {}: {done} finished, {partial} interrupted or failed, {} not started",
            mine.len(),
            out.display(),
            mine.len() - done - partial
        );
        return Ok(());
    }
    if let Some(from) = &a.adopt {
        let r = local::adopt(&plan, &out, from)?;
        println!(
            "{}: adopted {} finished runs from {} ({} were already there); {} folders are no run of the sweep",
            out.display(),
            r.adopted.len(),
            from.display(),
            r.already,
            r.unmatched.len()
        );
        for (d, why) in &r.unmatched {
            println!("  left out {}: {why}", d.display());
        }
        return Ok(());
    }
    if a.slurm {
        if !a.without_lpips {
            // What the array tasks would run, on machines that share this one's files: the
            // unfinished runs of every shard. (A local sweep checks its own in `run_sweep`.)
            let finished = local::FinishedRuns::of(&out)?;
            check_lpips_weights(plan.runs.iter().filter(|r| !finished.contains(&r.id)))?;
        }
        let exe = std::env::current_exe()?;
        let extra: Vec<String> = if a.without_lpips {
            vec!["--without-lpips".into()]
        } else {
            Vec::new()
        };
        let script = slurm::write_script(&plan, &out, &exe, &extra)?;
        println!(
            "{}: {} runs in {} array tasks",
            script.display(),
            plan.runs.len(),
            slurm::shard_count(&plan)
        );
        if a.submit {
            let id = slurm::submit(&script)?;
            println!(
                "submitted job {id}; when it is done: ifslab collect {}",
                out.display()
            );
        } else {
            println!("submit with: sbatch {}", script.display());
        }
        return Ok(());
    }
    let opts = RunnerOptions::new(a.jobs, a.threads, shard)?.without_lpips(a.without_lpips);
    let mp = MultiProgress::new();
    let overall = RunBar::new(&mp, "sweep".into());
    let per_run =
        |r: &PlannedRun| -> Box<dyn Progress> { Box::new(RunBar::new(&mp, r.name.clone())) };
    let outcome = run_sweep(&plan, &out, &opts, &overall, &per_run)?;
    let failures = outcome.failures();
    // Outcomes name runs by their position in the whole sweep (--only may have left gaps).
    let run_at = |i: usize| {
        plan.runs
            .iter()
            .find(|r| r.index == i)
            .expect("outcomes are runs of the plan")
    };
    println!(
        "{}: shard {shard} of the sweep {} ({} runs): {} finished now, {} already done, {} failed, {} running elsewhere ({} jobs × {} threads)",
        out.display(),
        plan.name,
        outcome.runs.len(),
        outcome.finished(),
        outcome.skipped(),
        failures.len(),
        outcome.busy(),
        opts.jobs,
        opts.threads
    );
    for (i, s) in &outcome.runs {
        if let RunStatus::Finished(rec) = s {
            println!("  {} {}: {}", rec.id, run_at(*i).name, rec.headline);
        }
    }
    for (i, e) in &failures {
        let r = run_at(*i);
        eprintln!("  FAILED {} {}: {e}", r.id, r.name);
    }
    if !failures.is_empty() {
        bail!(
            "{} of {} runs failed (their folders are in {}/runs/.ID.partial); run the sweep again to re-do them",
            failures.len(),
            outcome.runs.len(),
            out.display()
        );
    }
    println!("collect with: ifslab collect {}", out.display());
    Ok(())
}

fn parse_only(s: &str) -> Result<(String, String), String> {
    s.split_once('=')
        .map(|(a, l)| (a.trim().to_string(), l.trim().to_string()))
        .ok_or_else(|| format!("`{s}` is not AXIS=LABEL"))
}

/// A bar of a [`MultiProgress`] behind the library's [`Progress`].
struct RunBar {
    mp: MultiProgress,
    pb: ProgressBar,
    name: String,
}

impl RunBar {
    fn new(mp: &MultiProgress, name: String) -> Self {
        RunBar {
            mp: mp.clone(),
            pb: ProgressBar::hidden(),
            name,
        }
    }
}

impl Progress for RunBar {
    fn start(&self, what: &str, len: u64) {
        self.pb.set_style(
            ProgressStyle::with_template(
                "{spinner} {prefix} [{elapsed_precise}] {bar:30} {human_pos}/{human_len} (eta {eta}) {msg}",
            )
            .expect("valid template"),
        );
        self.pb.set_prefix(format!("{} {what}", self.name));
        self.pb.set_length(len);
        self.pb.set_position(0);
        self.mp.add(self.pb.clone());
    }
    fn set_length(&self, len: u64) {
        self.pb.set_length(len);
    }
    fn inc(&self, n: u64) {
        self.pb.inc(n);
    }
    fn set_position(&self, done: u64) {
        self.pb.set_position(done);
    }
    fn message(&self, message: &str) {
        self.pb.set_message(message.to_owned());
    }
    fn finish(&self) {
        self.pb.finish_and_clear();
        self.mp.remove(&self.pb);
    }
}
