//! Map probabilities for the chaos game: uniform (what the optimisers use), proportional
//! to |det M| with a floor (what evaluation renders use, so thin maps still get points),
//! or explicit.

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// The default floor for [`ProbabilityRule::Determinant`]: a degenerate map (det = 0, like
/// the fern's stem) still gets 1% of the points.
pub const DEFAULT_DET_FLOOR: f64 = 0.01;

/// How to choose the probability of each map.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ProbabilityRule {
    /// Every map equally likely.
    Uniform,
    /// `p_i ∝ max(|det M_i| / Σ|det M|, floor)`, renormalised.
    Determinant {
        /// Minimum share of a map before renormalising.
        floor: f64,
    },
    /// Given explicitly (validated like a code file's probabilities).
    Explicit(Vec<f64>),
}

impl Default for ProbabilityRule {
    fn default() -> Self {
        ProbabilityRule::Determinant {
            floor: DEFAULT_DET_FLOOR,
        }
    }
}

impl ProbabilityRule {
    /// The probabilities for maps with the given absolute determinants.
    pub fn resolve(&self, abs_dets: &[f64]) -> Result<Vec<f64>> {
        let n = abs_dets.len();
        if n == 0 {
            return Err(Error::Empty("a code needs at least one map".into()));
        }
        match self {
            ProbabilityRule::Uniform => Ok(vec![1.0 / n as f64; n]),
            ProbabilityRule::Determinant { floor } => {
                if !(floor.is_finite() && (0.0..1.0).contains(floor)) {
                    return Err(Error::param(
                        "floor",
                        format!("must lie in [0, 1), got {floor}"),
                    ));
                }
                let total: f64 = abs_dets.iter().sum();
                if !(total.is_finite() && total > 0.0) {
                    return Ok(vec![1.0 / n as f64; n]);
                }
                let raw: Vec<f64> = abs_dets.iter().map(|d| (d / total).max(*floor)).collect();
                let s: f64 = raw.iter().sum();
                Ok(raw.into_iter().map(|p| p / s).collect())
            }
            ProbabilityRule::Explicit(p) => {
                validate_probabilities(p, n)?;
                Ok(p.clone())
            }
        }
    }
}

/// Tolerance on `|Σp − 1|` for probabilities read from files.
pub const PROBABILITY_SUM_TOL: f64 = 1e-6;

/// Checks length, finiteness, sign and sum of a probability vector.
pub fn validate_probabilities(p: &[f64], n_maps: usize) -> Result<()> {
    if p.len() != n_maps {
        return Err(Error::Probabilities(format!(
            "{} probabilities for {} maps; give one per map",
            p.len(),
            n_maps
        )));
    }
    for (i, &v) in p.iter().enumerate() {
        if !v.is_finite() {
            return Err(Error::NonFinite {
                what: "probabilities".into(),
                location: format!("entry {i}"),
                value: v,
            });
        }
        if v < 0.0 {
            return Err(Error::Probabilities(format!(
                "probability {i} is negative ({v})"
            )));
        }
    }
    let sum: f64 = p.iter().sum();
    if (sum - 1.0).abs() > PROBABILITY_SUM_TOL {
        return Err(Error::Probabilities(format!(
            "they sum to {sum}, not 1 (tolerance {PROBABILITY_SUM_TOL:e}); normalise them or leave them out to use ∝|det|"
        )));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn determinant_rule_floors_degenerate_maps() {
        let p = ProbabilityRule::default()
            .resolve(&[0.0, 0.7, 0.3])
            .unwrap();
        assert!((p.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(p[0] > 0.009 && p[0] < 0.011);
        assert!(p[1] > p[2]);
    }

    #[test]
    fn explicit_probabilities_are_checked() {
        assert!(
            ProbabilityRule::Explicit(vec![0.5, 0.6])
                .resolve(&[1.0, 1.0])
                .is_err()
        );
        assert!(
            ProbabilityRule::Explicit(vec![0.5])
                .resolve(&[1.0, 1.0])
                .is_err()
        );
    }
}
