//! A sweep as a Slurm job array: one array task per shard, each running
//! `ifslab sweep FILE -o DIR --shard $SLURM_ARRAY_TASK_ID/N`. A task that is requeued (node
//! failure, `scontrol requeue`, or its own request shortly before its time limit) runs the
//! same shard again: finished runs are skipped and interrupted ones resume from their
//! checkpoints.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::Error;
use crate::error::{Context, IoContext};

use super::expand::Plan;

/// Where the script goes inside the sweep's output folder.
pub const SLURM_DIR: &str = "slurm";
/// The script's name.
pub const SCRIPT_FILE: &str = "sweep.sbatch";

/// Seconds before the time limit at which a task asks to be requeued, by default.
pub const DEFAULT_REQUEUE_GRACE: u64 = 120;

/// How many array tasks a plan gets: `slurm.shards`, else one per run.
pub fn shard_count(plan: &Plan) -> usize {
    plan.slurm
        .shards
        .unwrap_or(plan.runs.len())
        .clamp(1, plan.runs.len().max(1))
}

/// The `sbatch` script of a plan whose output folder is `out` (absolute), running the
/// binary `exe` (absolute) with `extra` arguments after its own (`--without-lpips`).
pub fn script(plan: &Plan, out: &Path, exe: &Path, extra: &[String]) -> String {
    let s = &plan.slurm;
    let n = shard_count(plan);
    let q = |p: &Path| shell_quote(&p.to_string_lossy());
    let mut t = String::from("#!/bin/bash\n");
    let _ = writeln!(
        t,
        "# The sweep {} ({} runs) as a job array of {n} tasks, one shard each.",
        plan.name,
        plan.runs.len()
    );
    let _ = writeln!(
        t,
        "# Written by `ifslab sweep --slurm`; submit with `sbatch {}`.",
        out.join(SLURM_DIR).join(SCRIPT_FILE).display()
    );
    let _ = writeln!(t, "#SBATCH --job-name={}", sbatch_word(&plan.name));
    let array = match s.max_parallel {
        Some(m) => format!("0-{}%{m}", n - 1),
        None => format!("0-{}", n - 1),
    };
    let _ = writeln!(t, "#SBATCH --array={array}");
    let _ = writeln!(t, "#SBATCH --requeue");
    let _ = writeln!(t, "#SBATCH --ntasks=1");
    let _ = writeln!(t, "#SBATCH --open-mode=append");
    let logs = out.join(SLURM_DIR).join("logs");
    let _ = writeln!(t, "#SBATCH --output={}/%A_%a.out", logs.display());
    let opt = |t: &mut String, name: &str, v: &Option<String>| {
        if let Some(v) = v {
            let _ = writeln!(t, "#SBATCH --{name}={v}");
        }
    };
    opt(
        &mut t,
        "cpus-per-task",
        &s.cpus_per_task.map(|c| c.to_string()),
    );
    opt(&mut t, "time", &s.time);
    opt(&mut t, "mem", &s.mem);
    opt(&mut t, "partition", &s.partition);
    opt(&mut t, "account", &s.account);
    opt(&mut t, "qos", &s.qos);
    opt(&mut t, "gres", &s.gres);
    let grace = s.requeue_grace.unwrap_or(DEFAULT_REQUEUE_GRACE);
    if s.time.is_some() {
        let _ = writeln!(t, "#SBATCH --signal=B:USR1@{grace}");
    }
    for e in &s.extra {
        let _ = writeln!(t, "#SBATCH {e}");
    }
    t.push_str("set -u\n");
    for line in &s.setup {
        let _ = writeln!(t, "{line}");
    }
    let threads = match s.cpus_per_task {
        Some(c) => format!("${{SLURM_CPUS_PER_TASK:-{c}}}"),
        None => "${SLURM_CPUS_PER_TASK:-1}".into(),
    };
    let only: String = plan
        .filters
        .iter()
        .map(|(a, l)| format!(" --only {}", shell_quote(&format!("{a}={l}"))))
        .collect();
    let extra: String = extra
        .iter()
        .map(|a| format!(" {}", shell_quote(a)))
        .collect();
    let _ = writeln!(
        t,
        "{} sweep {} -o {}{only}{extra} --shard \"${{SLURM_ARRAY_TASK_ID}}/{n}\" --jobs 1 --threads \"{threads}\" &",
        q(exe),
        q(&plan.source),
        q(out)
    );
    t.push_str("pid=$!\n");
    if s.time.is_some() {
        let _ = writeln!(
            t,
            "# Near the time limit: ask to run this task again (it resumes), then stop.\n\
             trap 'scontrol requeue \"${{SLURM_ARRAY_JOB_ID}}_${{SLURM_ARRAY_TASK_ID}}\"; kill -TERM $pid' USR1"
        );
    }
    t.push_str("wait $pid\nstatus=$?\n");
    if s.time.is_some() {
        t.push_str("# A trap interrupts the first wait: wait for the run to stop.\nwait $pid 2>/dev/null\n");
    }
    t.push_str("exit $status\n");
    t
}

/// Writes the plan's script into `out/slurm/` and returns its path.
pub fn write_script(
    plan: &Plan,
    out: &Path,
    exe: &Path,
    extra: &[String],
) -> crate::Result<PathBuf> {
    let out = std::path::absolute(out).doing("resolving", out)?;
    let exe = std::path::absolute(exe).doing("resolving", exe)?;
    std::fs::create_dir_all(out.join(SLURM_DIR).join("logs"))
        .doing("creating", &out.join(SLURM_DIR))?;
    super::local::write_plan(plan, &out)?;
    let path = out.join(SLURM_DIR).join(SCRIPT_FILE);
    ifslab::io::write_atomic(&path, script(plan, &out, &exe, extra).as_bytes())?;
    Ok(path)
}

/// Submits a script with `sbatch` and returns the job id.
pub fn submit(script: &Path) -> crate::Result<String> {
    let out = Command::new("sbatch")
        .arg("--parsable")
        .arg(script)
        .output()
        .context("running sbatch: is Slurm installed here (sbatch on the PATH)?")?;
    if !out.status.success() {
        return Err(Error::Tool {
            tool: "sbatch",
            message: format!(
                "sbatch {} failed: {}",
                script.display(),
                String::from_utf8_lossy(&out.stderr).trim()
            ),
        });
    }
    let text = String::from_utf8_lossy(&out.stdout);
    let id = text.trim().split(';').next().unwrap_or("").to_string();
    if id.is_empty() {
        return Err(Error::Tool {
            tool: "sbatch",
            message: "sbatch printed no job id".into(),
        });
    }
    Ok(id)
}

fn shell_quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', "'\\''"))
}

/// A job name Slurm takes as one word.
fn sbatch_word(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect()
}
