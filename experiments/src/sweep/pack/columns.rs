//! A packed run's `log.csv`: cut to the iteration and a few columns ([`LogColumns`]), each
//! rounded to [`LOG_DIGITS`] significant digits.

use super::*;

/// A numeric CSV log as columns (`None`: an empty or non-numeric cell, NaN included).
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct LogColumns {
    /// Column names, the iteration first.
    pub columns: Vec<String>,
    /// One list of values per column.
    pub values: Vec<Vec<Option<f64>>>,
}

impl LogColumns {
    /// Reads a CSV log with a header line; rows of the wrong width are skipped.
    pub fn parse(text: &str) -> Option<LogColumns> {
        let mut lines = text.lines();
        let columns: Vec<String> = lines.next()?.split(',').map(str::to_owned).collect();
        let mut values = vec![Vec::new(); columns.len()];
        for l in lines {
            let cells: Vec<&str> = l.split(',').collect();
            if cells.len() != columns.len() {
                continue;
            }
            for (col, c) in values.iter_mut().zip(cells) {
                col.push(c.trim().parse::<f64>().ok().filter(|v| !v.is_nan()));
            }
        }
        Some(LogColumns { columns, values })
    }

    /// The first column and the named ones that exist, the latter rounded to `digits`
    /// significant digits.
    pub fn compact(&self, keep: &[String], digits: usize) -> LogColumns {
        let mut out = LogColumns {
            columns: Vec::new(),
            values: Vec::new(),
        };
        for (k, (name, vals)) in self.columns.iter().zip(&self.values).enumerate() {
            if k == 0 {
                out.columns.push(name.clone());
                out.values.push(vals.clone());
            } else if keep.contains(name) {
                out.columns.push(name.clone());
                out.values.push(
                    vals.iter()
                        .map(|v| v.map(|x| round_sig(x, digits)))
                        .collect(),
                );
            }
        }
        out
    }

    /// The log as CSV again (missing cells as `NaN`, as the run wrote them).
    pub fn to_csv(&self) -> String {
        let mut s = self.columns.join(",");
        s.push('\n');
        let rows = self.values.first().map_or(0, Vec::len);
        for i in 0..rows {
            let cells: Vec<String> = self
                .values
                .iter()
                .map(|c| c[i].map_or_else(|| "NaN".to_string(), |v| v.to_string()))
                .collect();
            s.push_str(&cells.join(","));
            s.push('\n');
        }
        s
    }

    /// A column against the first (the iteration), where both are numbers and the value is
    /// positive and finite (what a log-scale plot can show); `None` without such a point.
    pub fn curve(&self, column: &str) -> Option<Vec<(f64, f64)>> {
        let c = self.columns.iter().position(|n| n == column)?;
        let pts: Vec<(f64, f64)> = self.values[0]
            .iter()
            .zip(&self.values[c])
            .filter_map(|(x, y)| Some(((*x)?, (*y)?)))
            .filter(|&(_, y)| y.is_finite() && y > 0.0)
            .collect();
        (!pts.is_empty()).then_some(pts)
    }
}

/// `x` to `digits` significant digits.
pub fn round_sig(x: f64, digits: usize) -> f64 {
    if !x.is_finite() || x == 0.0 || digits == 0 {
        return x;
    }
    format!("{x:.*e}", digits - 1).parse().unwrap_or(x)
}
