//! Paired comparisons: every group of a sweep against one reference group, run by run on
//! the same problem (the same suite code, the same target, the same seed).
//!
//! A mean over a hundred random codes has a standard error of a few hundredths when the
//! codes themselves differ by tenths; two methods run on the *same* codes are told apart far
//! more sharply by their per-code differences. For each group this gives the number of
//! pairs, on how many the group scores higher, lower or the same as the reference, the mean
//! difference with its standard error, and the two-sided sign test's p-value (ties left
//! out) — what `ifslab collect --versus REF` writes into the report.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use crate::error::bail;

use super::collect::{Collected, RunState, fmt_num};

/// One group against the reference on one metric.
#[derive(Clone, Debug, PartialEq)]
pub struct PairedRow {
    /// The group's labels on the grouping axes, joined with `/`.
    pub group: String,
    /// Pairing keys on which both have a finished run with the metric.
    pub pairs: usize,
    /// Pairs where the group's value is above the reference's.
    pub higher: usize,
    /// Pairs where it is below.
    pub lower: usize,
    /// Pairs where they are equal.
    pub equal: usize,
    /// Mean of (group − reference) over the pairs.
    pub mean_difference: f64,
    /// Standard error of that mean (sample standard deviation / √pairs; 0 for one pair).
    pub standard_error: f64,
    /// Two-sided sign test p-value of higher against lower (ties left out; 1 with none).
    pub sign_test_p: f64,
}

/// Every group against a reference on one metric.
#[derive(Clone, Debug, PartialEq)]
pub struct Paired {
    /// The grouping axes.
    pub by: Vec<String>,
    /// The axes that pair runs (their labels must agree).
    pub on: Vec<String>,
    /// The reference group's labels joined with `/`.
    pub reference: String,
    /// The metric compared.
    pub metric: String,
    /// One row per other group, in sweep order.
    pub rows: Vec<PairedRow>,
}

/// Two-sided sign test: the probability, with `n = higher + lower` fair coin flips, of a
/// split at least as uneven as the one seen (capped at 1).
pub fn sign_test_p(higher: usize, lower: usize) -> f64 {
    let n = higher + lower;
    if n == 0 {
        return 1.0;
    }
    let k = higher.min(lower);
    // P(X ≤ k) for X ~ Binomial(n, ½), term by term from P(X = 0) = 2⁻ⁿ (no overflow up to
    // n ≈ 1000, beyond any sweep's pair count; for larger n the tail underflows to 0).
    let mut term = 0.5f64.powi(n as i32);
    let mut tail = 0.0;
    for i in 0..=k {
        tail += term;
        term *= (n - i) as f64 / (i + 1) as f64;
    }
    (2.0 * tail).min(1.0)
}

impl Collected {
    /// Each group of `by` against the group `reference` (its labels joined with `/`) on
    /// `metric`, runs paired by their labels on `on`. Where a group has several finished
    /// runs with the same pairing labels (seeds along an axis left out of both), their mean
    /// is the group's value there.
    pub fn paired(
        &self,
        by: &[String],
        on: &[String],
        reference: &str,
        metric: &str,
    ) -> crate::Result<Paired> {
        if on.is_empty() {
            bail!(
                "no axis to pair runs on (every axis but {} has one value here; name one with \
                 --pair-on)",
                by.join(", ")
            );
        }
        if let Some(a) = on.iter().find(|a| by.contains(a)) {
            bail!("`{a}` cannot both group and pair the runs");
        }
        let groups = self.keys_of(by)?;
        self.keys_of(on)?;
        if !groups.iter().any(|g| g == reference) {
            bail!(
                "no group `{reference}` by {} (groups: {})",
                by.join(" × "),
                groups.join(", ")
            );
        }
        // group → pairing key → (sum, count)
        let mut values: BTreeMap<(String, String), (f64, usize)> = BTreeMap::new();
        for r in &self.rows {
            if r.state != RunState::Finished {
                continue;
            }
            let Some(v) = Collected::value(r, metric).filter(|v| v.is_finite()) else {
                continue;
            };
            let e = values
                .entry((self.key(by, r), self.key(on, r)))
                .or_insert((0.0, 0));
            e.0 += v;
            e.1 += 1;
        }
        let of = |group: &str| -> BTreeMap<&str, f64> {
            values
                .iter()
                .filter(|((g, _), _)| g == group)
                .map(|((_, k), (s, n))| (k.as_str(), s / *n as f64))
                .collect()
        };
        let base = of(reference);
        let rows = groups
            .iter()
            .filter(|g| *g != reference)
            .map(|g| {
                let diffs: Vec<f64> = of(g)
                    .into_iter()
                    .filter_map(|(k, v)| base.get(k).map(|b| v - b))
                    .collect();
                let n = diffs.len();
                let higher = diffs.iter().filter(|d| **d > 0.0).count();
                let lower = diffs.iter().filter(|d| **d < 0.0).count();
                let mean = if n > 0 {
                    diffs.iter().sum::<f64>() / n as f64
                } else {
                    f64::NAN
                };
                let standard_error = if n > 1 {
                    (diffs.iter().map(|d| (d - mean).powi(2)).sum::<f64>()
                        / (n - 1) as f64
                        / n as f64)
                        .sqrt()
                } else {
                    0.0
                };
                PairedRow {
                    group: g.clone(),
                    pairs: n,
                    higher,
                    lower,
                    equal: n - higher - lower,
                    mean_difference: mean,
                    standard_error,
                    sign_test_p: sign_test_p(higher, lower),
                }
            })
            .collect();
        Ok(Paired {
            by: by.to_vec(),
            on: on.to_vec(),
            reference: reference.to_string(),
            metric: metric.to_string(),
            rows,
        })
    }
}

impl Paired {
    /// As a Markdown table, one row per group.
    pub fn to_markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "| {} | pairs | higher | lower | equal | {} − {} (mean ± s.e.) | sign test p |",
            self.by.join(" × "),
            self.metric,
            self.reference
        );
        let _ = writeln!(s, "|---|---|---|---|---|---|---|");
        for r in &self.rows {
            let diff = if r.pairs == 0 {
                "–".to_string()
            } else {
                format!(
                    "{} ± {}",
                    signed(r.mean_difference),
                    fmt_num(r.standard_error)
                )
            };
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {diff} | {} |",
                r.group,
                r.pairs,
                r.higher,
                r.lower,
                r.equal,
                fmt_p(r.sign_test_p)
            );
        }
        s
    }

    /// As CSV rows (with the metric and reference in each, so several tables concatenate).
    pub fn to_csv_rows(&self) -> String {
        let mut s = String::new();
        for r in &self.rows {
            let _ = writeln!(
                s,
                "{},{},{},{},{},{},{},{},{},{}",
                self.metric,
                self.reference,
                r.group,
                r.pairs,
                r.higher,
                r.lower,
                r.equal,
                r.mean_difference,
                r.standard_error,
                r.sign_test_p
            );
        }
        s
    }

    /// The header of [`Paired::to_csv_rows`].
    pub const CSV_HEADER: &'static str = "metric,reference,group,pairs,higher,lower,equal,mean_difference,standard_error,sign_test_p\n";
}

fn signed(x: f64) -> String {
    if x > 0.0 {
        format!("+{}", fmt_num(x))
    } else {
        fmt_num(x)
    }
}

fn fmt_p(p: f64) -> String {
    if p >= 0.001 {
        format!("{p:.3}")
    } else {
        format!("{p:.1e}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_sign_test_matches_the_binomial_tails() {
        assert_eq!(sign_test_p(0, 0), 1.0);
        assert_eq!(sign_test_p(3, 3), 1.0);
        // 1 of 1: p = 2 · ½ = 1; 5 of 5: 2 · 2⁻⁵.
        assert_eq!(sign_test_p(1, 0), 1.0);
        assert!((sign_test_p(5, 0) - 0.0625).abs() < 1e-15);
        // 8 against 2: 2 · (1 + 10 + 45) / 1024 = 0.109375, either way round.
        assert!((sign_test_p(8, 2) - 0.109375).abs() < 1e-15);
        assert_eq!(sign_test_p(2, 8), sign_test_p(8, 2));
        // 100 against 0 and 64 of 65: far below any threshold, not zero.
        let p = sign_test_p(100, 0);
        assert!(p > 0.0 && (p - 2.0 * 0.5f64.powi(100)).abs() < 1e-40, "{p}");
        let p = sign_test_p(1, 64);
        assert!((p - 2.0 * 66.0 * 0.5f64.powi(65)).abs() < 1e-30, "{p}");
    }
}
