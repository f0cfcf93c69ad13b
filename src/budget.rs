//! Budgets checked before the work is paid for: what a renderer's buffers will take, from
//! its settings alone, against a memory budget.
//!
//! Every renderer estimates its large buffers ([`MemoryEstimate`]) before allocating any of
//! them and refuses a job over the budget with an error that names the setting to lower and
//! the estimate, instead of allocating until the machine runs out. The budget is, in order:
//! the one set for this process ([`set_process_budget`], the command line's
//! `--max-memory`), the environment variable [`BUDGET_ENV`], or [`DEFAULT_SHARE`] of the
//! machine's physical memory.
//!
//! ```
//! use ifslab::budget::{MemoryBudget, MemoryEstimate};
//! let est = MemoryEstimate::new().with("image", 4 << 30);
//! let budget = MemoryBudget::bytes(2 << 30);
//! let err = budget.check(&est, "--size").unwrap_err().to_string();
//! assert!(err.contains("4.0 GiB") && err.contains("--size"));
//! ```

use std::fmt;
use std::sync::OnceLock;

use crate::error::{Error, Result};

/// The environment variable that sets the memory budget (`8G`, `512M`, `unlimited`, …).
pub const BUDGET_ENV: &str = "IFSLAB_MAX_MEMORY";

/// Share of the physical memory a job may plan to use when no budget is set.
pub const DEFAULT_SHARE: f64 = 0.75;

/// Physical memory assumed where it cannot be read (not Linux).
const FALLBACK_PHYSICAL: u64 = 16 << 30;

/// What a job's large buffers will take, part by part.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MemoryEstimate {
    parts: Vec<(String, u64)>,
}

impl MemoryEstimate {
    /// An empty estimate.
    pub fn new() -> Self {
        MemoryEstimate::default()
    }

    /// Adds a part (`label`, bytes).
    pub fn with(mut self, label: impl Into<String>, bytes: u64) -> Self {
        self.parts.push((label.into(), bytes));
        self
    }

    /// Adds every part of another estimate.
    pub fn and(mut self, other: MemoryEstimate) -> Self {
        self.parts.extend(other.parts);
        self
    }

    /// The total in bytes (saturating).
    pub fn total(&self) -> u64 {
        self.parts.iter().fold(0u64, |a, p| a.saturating_add(p.1))
    }

    /// The parts, largest first.
    pub fn parts(&self) -> Vec<(&str, u64)> {
        let mut p: Vec<(&str, u64)> = self.parts.iter().map(|(l, b)| (l.as_str(), *b)).collect();
        p.sort_by_key(|p| std::cmp::Reverse(p.1));
        p
    }
}

impl fmt::Display for MemoryEstimate {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let parts: Vec<String> = self
            .parts()
            .iter()
            .filter(|p| p.1 > 0)
            .map(|(l, b)| format!("{l} {}", human_bytes(*b)))
            .collect();
        write!(f, "{} ({})", human_bytes(self.total()), parts.join(", "))
    }
}

/// Where a budget came from (said in refusals, so the user knows what to move).
#[derive(Clone, Debug, PartialEq)]
pub enum BudgetSource {
    /// Set for the process (the command line's `--max-memory`).
    Set,
    /// The environment variable [`BUDGET_ENV`].
    Env,
    /// [`DEFAULT_SHARE`] of this much physical memory.
    Machine(u64),
    /// Given in code.
    Explicit,
}

/// A memory budget in bytes (`u64::MAX`: unlimited).
#[derive(Clone, Debug, PartialEq)]
pub struct MemoryBudget {
    /// The most bytes a job may plan to allocate.
    pub bytes: u64,
    /// Where it came from.
    pub source: BudgetSource,
}

static PROCESS_BUDGET: OnceLock<u64> = OnceLock::new();

/// Sets this process's budget (once; later calls are ignored and return false).
pub fn set_process_budget(bytes: u64) -> bool {
    PROCESS_BUDGET.set(bytes).is_ok()
}

impl MemoryBudget {
    /// A budget of `bytes`.
    pub fn bytes(bytes: u64) -> Self {
        MemoryBudget {
            bytes,
            source: BudgetSource::Explicit,
        }
    }

    /// No limit.
    pub fn unlimited() -> Self {
        MemoryBudget::bytes(u64::MAX)
    }

    /// The budget in force: the process's, else [`BUDGET_ENV`]'s, else [`DEFAULT_SHARE`] of
    /// the physical memory. A malformed [`BUDGET_ENV`] is an error that says so.
    pub fn current() -> Result<Self> {
        if let Some(&bytes) = PROCESS_BUDGET.get() {
            return Ok(MemoryBudget {
                bytes,
                source: BudgetSource::Set,
            });
        }
        if let Ok(text) = std::env::var(BUDGET_ENV) {
            let bytes = parse_bytes(&text)
                .map_err(|e| Error::param(BUDGET_ENV, format!("environment variable: {e}")))?;
            return Ok(MemoryBudget {
                bytes,
                source: BudgetSource::Env,
            });
        }
        let physical = physical_memory().unwrap_or(FALLBACK_PHYSICAL);
        Ok(MemoryBudget {
            bytes: (physical as f64 * DEFAULT_SHARE) as u64,
            source: BudgetSource::Machine(physical),
        })
    }

    /// Refuses `estimate` above the budget; `lower` names the settings that shrink it
    /// (`"--size or --supersample"`).
    pub fn check(&self, estimate: &MemoryEstimate, lower: &str) -> Result<()> {
        if estimate.total() <= self.bytes {
            return Ok(());
        }
        let whence = match self.source {
            BudgetSource::Set => "set by --max-memory".to_owned(),
            BudgetSource::Env => format!("set by {BUDGET_ENV}"),
            BudgetSource::Machine(p) => format!(
                "{:.0} % of this machine's {}",
                DEFAULT_SHARE * 100.0,
                human_bytes(p)
            ),
            BudgetSource::Explicit => "given".to_owned(),
        };
        Err(Error::OverBudget(format!(
            "this job needs about {estimate}, over the memory budget of {} ({whence}); lower \
             {lower}, or move the budget with --max-memory (or {BUDGET_ENV})",
            human_bytes(self.bytes)
        )))
    }
}

/// The environment variable that sets the work budget (`24h`, `90m`, `unlimited`).
pub const WORK_ENV: &str = "IFSLAB_MAX_WORK";

/// The work a job may plan when no budget is set: a day.
pub const DEFAULT_WORK_SECONDS: f64 = 24.0 * 3600.0;

static PROCESS_WORK: OnceLock<f64> = OnceLock::new();

/// Sets this process's work budget in seconds (once; later calls return false).
pub fn set_process_work_budget(seconds: f64) -> bool {
    PROCESS_WORK.set(seconds).is_ok()
}

/// The work budget in force, in seconds: the process's (`--max-work`), else [`WORK_ENV`]'s,
/// else [`DEFAULT_WORK_SECONDS`].
pub fn work_budget() -> Result<(f64, &'static str)> {
    if let Some(&s) = PROCESS_WORK.get() {
        return Ok((s, "set by --max-work"));
    }
    if let Ok(text) = std::env::var(WORK_ENV) {
        let s = parse_duration(&text)
            .map_err(|e| Error::param(WORK_ENV, format!("environment variable: {e}")))?;
        return Ok((s, "set by IFSLAB_MAX_WORK"));
    }
    Ok((DEFAULT_WORK_SECONDS, "the default"))
}

/// Refuses a job estimated to take `seconds` (`what` says how it was estimated) above the
/// work budget; `lower` names the settings that shorten it.
pub fn check_work(seconds: f64, what: &str, lower: &str) -> Result<()> {
    let (budget, whence) = work_budget()?;
    if seconds <= budget {
        return Ok(());
    }
    Err(Error::OverBudget(format!(
        "this job would take about {} ({what}), over the work budget of {} ({whence}); lower \
         {lower}, or move the budget with --max-work (or {WORK_ENV})",
        human_duration(seconds),
        human_duration(budget)
    )))
}

/// [`check_work`] for `units` of work done at `per_thread` units per second on each of
/// `threads` threads: `what` says what is done (`1000 iterations of 110000 points`), `unit`
/// names one unit (`points`) for the rate the estimate assumed.
pub fn check_rate(
    units: f64,
    per_thread: f64,
    threads: usize,
    unit: &str,
    what: &str,
    lower: &str,
) -> Result<()> {
    let threads = threads.max(1);
    check_work(
        units / (per_thread * threads as f64),
        &format!("{what} at ~{per_thread:.0e} {unit}/s per thread on {threads} threads"),
        lower,
    )
}

/// Seconds as `40 s`, `12 min`, `5.0 h`, `58 days`, `30 years`, `3.1e5 years`.
pub fn human_duration(s: f64) -> String {
    if !s.is_finite() {
        return "unlimited".into();
    }
    let (v, unit) = if s < 60.0 {
        (s, "s")
    } else if s < 3600.0 {
        (s / 60.0, "min")
    } else if s < 2.0 * 86400.0 {
        (s / 3600.0, "h")
    } else if s < 2.0 * 365.0 * 86400.0 {
        (s / 86400.0, "days")
    } else if s < 1e4 * 365.0 * 86400.0 {
        (s / (365.0 * 86400.0), "years")
    } else {
        return format!("{:.1e} years", s / (365.0 * 86400.0));
    };
    if v < 10.0 {
        format!("{v:.1} {unit}")
    } else {
        format!("{v:.0} {unit}")
    }
}

/// Reads a duration: seconds, or a number with `s`, `m`, `h` or `d`; or `unlimited`.
pub fn parse_duration(text: &str) -> std::result::Result<f64, String> {
    let t = text.trim().to_ascii_lowercase();
    if matches!(t.as_str(), "unlimited" | "none") {
        return Ok(f64::INFINITY);
    }
    let (num, unit) = split_unit(&t);
    let v: f64 = num
        .parse()
        .map_err(|_| format!("`{text}` is not a duration (e.g. 24h, 90m, unlimited)"))?;
    let scale = match unit.trim() {
        "" | "s" => 1.0,
        "m" | "min" => 60.0,
        "h" => 3600.0,
        "d" => 86400.0,
        _ => return Err(format!("`{text}`: unknown unit (use s, m, h or d)")),
    };
    if !(v > 0.0 && v.is_finite()) {
        return Err(format!("`{text}` must be a positive duration"));
    }
    Ok(v * scale)
}

/// Reads a count: an integer, a float in exponent form (`1e15`), or with a suffix `K`, `M`,
/// `G` (thousands, millions, billions); refused when not a whole number ≥ 0 below 2⁶⁴.
pub fn parse_count(text: &str) -> std::result::Result<u64, String> {
    let t = text.trim().replace('_', "");
    let (num, scale) = match t.chars().last() {
        Some('k' | 'K') => (&t[..t.len() - 1], 1e3),
        Some('m' | 'M') => (&t[..t.len() - 1], 1e6),
        Some('g' | 'G' | 'b' | 'B') => (&t[..t.len() - 1], 1e9),
        _ => (t.as_str(), 1.0),
    };
    if scale == 1.0
        && let Ok(n) = num.parse::<u64>()
    {
        return Ok(n);
    }
    let v: f64 = num
        .parse()
        .map_err(|_| format!("`{text}` is not a count (e.g. 50000000, 5e7 or 50M)"))?;
    let v = v * scale;
    if !((0.0..1.8e19).contains(&v) && v.fract() == 0.0) {
        return Err(format!(
            "`{text}` is not a whole number of at least 0 below 1.8e19"
        ));
    }
    Ok(v as u64)
}

/// Checks `estimate` against [`MemoryBudget::current`].
pub fn check_memory(estimate: &MemoryEstimate, lower: &str) -> Result<()> {
    MemoryBudget::current()?.check(estimate, lower)
}

/// Bytes as `1.5 GiB`, `640 MiB`, `12 KiB`, `512 B`.
pub fn human_bytes(b: u64) -> String {
    if b == u64::MAX {
        return "unlimited".into();
    }
    const UNITS: [&str; 6] = ["B", "KiB", "MiB", "GiB", "TiB", "PiB"];
    let mut v = b as f64;
    let mut u = 0;
    while v >= 1024.0 && u + 1 < UNITS.len() {
        v /= 1024.0;
        u += 1;
    }
    if u == 0 {
        format!("{b} B")
    } else if v < 10.0 {
        format!("{v:.1} {}", UNITS[u])
    } else {
        format!("{v:.0} {}", UNITS[u])
    }
}

/// `"8G"` → `("8", "G")`: the leading digits and dots, and the rest.
fn split_unit(t: &str) -> (&str, &str) {
    t.split_at(
        t.find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .unwrap_or(t.len()),
    )
}

/// Reads a size: a number of bytes with an optional unit (`K`, `M`, `G`, `T`, with or
/// without `i`/`B`, powers of 1024), or `unlimited` / `none`.
pub fn parse_bytes(text: &str) -> std::result::Result<u64, String> {
    let t = text.trim();
    if matches!(t.to_ascii_lowercase().as_str(), "unlimited" | "none") {
        return Ok(u64::MAX);
    }
    let (num, unit) = split_unit(t);
    let value: f64 = num
        .parse()
        .map_err(|_| format!("`{text}` is not a size (e.g. 8G, 512M, unlimited)"))?;
    let unit = unit.trim().to_ascii_lowercase();
    let unit = unit.trim_end_matches('b').trim_end_matches('i');
    let scale: u64 = match unit {
        "" => 1,
        "k" => 1 << 10,
        "m" => 1 << 20,
        "g" => 1 << 30,
        "t" => 1 << 40,
        _ => {
            return Err(format!(
                "`{text}`: unknown unit (use K, M, G or T, e.g. 8G)"
            ));
        }
    };
    let bytes = value * scale as f64;
    if !(bytes.is_finite() && bytes >= 1.0) {
        return Err(format!("`{text}` must be at least one byte"));
    }
    Ok(bytes.min(u64::MAX as f64) as u64)
}

/// The machine's physical memory in bytes (Linux: `MemTotal` of `/proc/meminfo`).
pub fn physical_memory() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_and_without_units() {
        assert_eq!(parse_bytes("512").unwrap(), 512);
        assert_eq!(parse_bytes("8G").unwrap(), 8 << 30);
        assert_eq!(parse_bytes("8 GiB").unwrap(), 8 << 30);
        assert_eq!(parse_bytes("1.5g").unwrap(), 3 << 29);
        assert_eq!(parse_bytes("640MB").unwrap(), 640 << 20);
        assert_eq!(parse_bytes("unlimited").unwrap(), u64::MAX);
        for bad in ["", "G", "8 parsecs", "-1G", "0", "nan"] {
            assert!(parse_bytes(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_refusal_names_the_flag_the_estimate_and_the_budget() {
        let est = MemoryEstimate::new()
            .with("coverage bits", 3 << 30)
            .with("image", 40 << 30);
        let err = MemoryBudget::bytes(8 << 30)
            .check(&est, "--size")
            .unwrap_err()
            .to_string();
        assert!(err.contains("43 GiB"), "{err}");
        assert!(err.contains("image 40 GiB, coverage bits 3.0 GiB"), "{err}");
        assert!(err.contains("8.0 GiB") && err.contains("--size"), "{err}");
        assert!(err.contains("--max-memory"), "{err}");
        assert!(MemoryBudget::bytes(43 << 30).check(&est, "--size").is_ok());
        assert!(MemoryBudget::unlimited().check(&est, "--size").is_ok());
    }

    #[test]
    fn counts_and_durations_parse() {
        assert_eq!(parse_count("50000000").unwrap(), 50_000_000);
        assert_eq!(parse_count("5e7").unwrap(), 50_000_000);
        assert_eq!(parse_count("50M").unwrap(), 50_000_000);
        assert_eq!(parse_count("1e15").unwrap(), 1_000_000_000_000_000);
        for bad in ["", "nan", "inf", "-1", "1.5", "1e30", "lots"] {
            assert!(parse_count(bad).is_err(), "{bad}");
        }
        assert_eq!(parse_duration("90m").unwrap(), 5400.0);
        assert_eq!(parse_duration("24h").unwrap(), 86400.0);
        assert_eq!(parse_duration("unlimited").unwrap(), f64::INFINITY);
        for bad in ["", "0", "-1h", "5 parsecs", "nan"] {
            assert!(parse_duration(bad).is_err(), "{bad}");
        }
        assert_eq!(human_duration(5e6), "58 days");
        assert_eq!(human_duration(9.5e8), "30 years");
        assert_eq!(human_duration(1e13), "3.2e5 years");
    }

    #[test]
    fn human_sizes_read_well() {
        assert_eq!(human_bytes(512), "512 B");
        assert_eq!(human_bytes(1536), "1.5 KiB");
        assert_eq!(human_bytes(640 << 20), "640 MiB");
        assert_eq!(human_bytes(u64::MAX), "unlimited");
    }
}
