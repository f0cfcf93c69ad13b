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

/// Reads a size: a number of bytes with an optional unit (`K`, `M`, `G`, `T`, with or
/// without `i`/`B`, powers of 1024), or `unlimited` / `none`.
pub fn parse_bytes(text: &str) -> std::result::Result<u64, String> {
    let t = text.trim();
    if matches!(t.to_ascii_lowercase().as_str(), "unlimited" | "none") {
        return Ok(u64::MAX);
    }
    let split = t
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
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
    fn human_sizes_read_well() {
        assert_eq!(human_bytes(512), "512 B");
        assert_eq!(human_bytes(1536), "1.5 KiB");
        assert_eq!(human_bytes(640 << 20), "640 MiB");
        assert_eq!(human_bytes(u64::MAX), "unlimited");
    }
}
