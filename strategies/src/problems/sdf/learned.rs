//! Learned symmetry patterns (the paper's proposal, §5): every endpoint of every pair's
//! source and target segment is a softmax-weighted combination of the control points,
//! `q_e = Σ_j softmax(ℓ_e / τ)_j p_j`, with one learnable logit per endpoint and control
//! point, optimised jointly with the points. θ is then the control points (2n numbers)
//! followed by the logits (4 endpoints per pair, n logits each, endpoint-major).
//!
//! The temperature τ may shrink geometrically over the run (`temperature` →
//! `temperature_end`), pushing the weights towards hard assignments. The start's logits are
//! `bias` on the pattern's own assignment plus seeded Gaussian noise of deviation `noise`.
//! The fitted pattern is read back with the hard assignment (arg-max of each endpoint's
//! logits).
//!
//! Soft endpoints make arbitrary segment lengths, so a soft map may stop contracting. By
//! default such a pattern is refused (the fit stops with an error naming the map); with the
//! loss's scale barrier on (`[loss] scale_barrier`, [`super::barrier`]) it is drawn all the
//! same and the barrier pushes its scale back down.

use ifslab::model::segment::{BaseFigure, Pair, Pattern};
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// The `[learned]` section of a `problem = "sdf"` config (absent: the pattern's fixed pairs).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LearnedConfig {
    /// Softmax temperature at iteration 0.
    pub temperature: f64,
    /// Temperature at the last iteration (geometric in between); equal to `temperature`
    /// for none.
    pub temperature_end: f64,
    /// Start logit of each endpoint's own control point in the pattern (0: no prior).
    pub bias: f64,
    /// Standard deviation of the seeded Gaussian noise added to the start logits.
    pub noise: f64,
}

impl Default for LearnedConfig {
    fn default() -> Self {
        LearnedConfig {
            temperature: 1.0,
            temperature_end: 1.0,
            bias: 0.0,
            noise: 1.0,
        }
    }
}

impl LearnedConfig {
    /// Checks the fields; errors name the field.
    pub fn validate(&self) -> Result<()> {
        for (name, t) in [
            ("learned.temperature", self.temperature),
            ("learned.temperature_end", self.temperature_end),
        ] {
            if !(t.is_finite() && t > 0.0) {
                return Err(Error::param(
                    name,
                    format!("must be finite and > 0, got {t}"),
                ));
            }
        }
        if !self.bias.is_finite() {
            return Err(Error::param(
                "learned.bias",
                format!("must be finite, got {}", self.bias),
            ));
        }
        if !(self.noise.is_finite() && self.noise >= 0.0) {
            return Err(Error::param(
                "learned.noise",
                format!("must be finite and ≥ 0, got {}", self.noise),
            ));
        }
        Ok(())
    }
}

/// The soft assignment of a pattern's pair endpoints to its control points.
#[derive(Clone, Debug)]
pub struct LearnedPattern {
    /// The pattern whose number of points, of pairs and base figure are kept.
    pattern: Pattern,
    cfg: LearnedConfig,
    /// Iterations over which τ shrinks.
    iterations: u64,
}

fn softmax(logits: &[f64], tau: f64) -> Vec<f64> {
    let m = logits.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    let e: Vec<f64> = logits.iter().map(|l| ((l - m) / tau).exp()).collect();
    let s: f64 = e.iter().sum();
    e.into_iter().map(|x| x / s).collect()
}

impl LearnedPattern {
    /// Learned pairs for `pattern`, τ shrinking over `iterations`.
    pub fn new(pattern: Pattern, cfg: LearnedConfig, iterations: u64) -> Result<Self> {
        cfg.validate()?;
        Ok(LearnedPattern {
            pattern,
            cfg,
            iterations: iterations.max(1),
        })
    }

    /// Iterations over which τ shrinks.
    pub fn iterations(&self) -> u64 {
        self.iterations
    }

    fn n(&self) -> usize {
        self.pattern.points().len()
    }

    /// Endpoints: 4 per pair (source 0, source 1, target 0, target 1).
    fn n_endpoints(&self) -> usize {
        4 * self.pattern.n_maps()
    }

    /// Length of θ: points then logits.
    pub fn dim(&self) -> usize {
        2 * self.n() + self.n_endpoints() * self.n()
    }

    /// τ at iteration `iter`.
    pub fn temperature_at(&self, iter: u64) -> f64 {
        let f = (iter as f64 / self.iterations as f64).clamp(0.0, 1.0);
        self.cfg.temperature * (self.cfg.temperature_end / self.cfg.temperature).powf(f)
    }

    /// The pattern's own assignment, endpoint by endpoint.
    pub fn own_assignment(&self) -> Vec<usize> {
        self.pattern
            .pairs()
            .iter()
            .flat_map(|p| [p.source[0], p.source[1], p.target[0], p.target[1]])
            .collect()
    }

    /// Start θ: `points` then `bias` on the own assignment plus seeded noise.
    pub fn start(&self, points: &[f64], seed: u64) -> Result<Vec<f64>> {
        if points.len() != 2 * self.n() {
            return Err(Error::InvalidInput(format!(
                "{} coordinates given for {} control points",
                points.len(),
                self.n()
            )));
        }
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed ^ 0x5eed_1061);
        let normal = Normal::new(0.0, self.cfg.noise.max(f64::MIN_POSITIVE))
            .map_err(|e| Error::param("learned.noise", e.to_string()))?;
        let mut theta = points.to_vec();
        for own in self.own_assignment() {
            for j in 0..self.n() {
                let noise = if self.cfg.noise > 0.0 {
                    normal.sample(&mut rng)
                } else {
                    0.0
                };
                theta.push(if j == own { self.cfg.bias } else { 0.0 } + noise);
            }
        }
        Ok(theta)
    }

    fn check(&self, theta: &[f64]) -> Result<()> {
        if theta.len() != self.dim() {
            return Err(Error::InvalidInput(format!(
                "θ has {} numbers; a learned pattern of {} points and {} pairs needs {}",
                theta.len(),
                self.n(),
                self.pattern.n_maps(),
                self.dim()
            )));
        }
        Ok(())
    }

    /// The hard assignment of θ: each endpoint's arg-max control point.
    pub fn assignment(&self, theta: &[f64]) -> Result<Vec<usize>> {
        self.check(theta)?;
        let n = self.n();
        Ok(theta[2 * n..]
            .chunks(n)
            .map(|l| {
                (0..n)
                    .max_by(|&a, &b| l[a].total_cmp(&l[b]).then(b.cmp(&a)))
                    .unwrap_or(0)
            })
            .collect())
    }

    /// The pattern with θ's points and its hard assignment (the fit's result).
    pub fn hard_pattern(&self, theta: &[f64]) -> Result<Pattern> {
        let a = self.assignment(theta)?;
        let n = self.n();
        let pts: Vec<[f64; 2]> = (0..n).map(|k| [theta[2 * k], theta[2 * k + 1]]).collect();
        let pairs = a
            .chunks(4)
            .map(|c| Pair {
                source: [c[0], c[1]],
                target: [c[2], c[3]],
            })
            .collect();
        Ok(Pattern::new(
            self.pattern.name(),
            pts,
            pairs,
            Some(self.pattern.base()),
        )?)
    }

    /// The soft pattern at θ and temperature τ: the control points followed by the
    /// endpoints, pair `i` taking points `n+4i, n+4i+1` onto `n+4i+2, n+4i+3`; the base
    /// figure stays on the control points. Errors as [`Pattern::new`] when the soft maps
    /// degenerate or, unless `any_scale` (the loss has a scale barrier), stop contracting.
    pub fn soft_pattern(&self, theta: &[f64], tau: f64, any_scale: bool) -> Result<Pattern> {
        self.check(theta)?;
        let n = self.n();
        let mut pts: Vec<[f64; 2]> = (0..n).map(|k| [theta[2 * k], theta[2 * k + 1]]).collect();
        for l in theta[2 * n..].chunks(n) {
            let w = softmax(l, tau);
            let mut q = [0.0; 2];
            for j in 0..n {
                q[0] += w[j] * pts[j][0];
                q[1] += w[j] * pts[j][1];
            }
            pts.push(q);
        }
        let pairs = (0..self.pattern.n_maps())
            .map(|i| Pair {
                source: [n + 4 * i, n + 4 * i + 1],
                target: [n + 4 * i + 2, n + 4 * i + 3],
            })
            .collect();
        let base: BaseFigure = self.pattern.base();
        Ok(if any_scale {
            Pattern::new_any_scale(self.pattern.name(), pts, pairs, Some(base))?
        } else {
            Pattern::new(self.pattern.name(), pts, pairs, Some(base))?
        })
    }

    /// Chain rule: ∂loss/∂(soft pattern's points) → ∂loss/∂θ.
    pub fn backward(&self, theta: &[f64], tau: f64, g_soft: &[f64]) -> Result<Vec<f64>> {
        self.check(theta)?;
        let n = self.n();
        if g_soft.len() != 2 * (n + self.n_endpoints()) {
            return Err(Error::InvalidInput(format!(
                "gradient of {} numbers for a soft pattern of {} points",
                g_soft.len(),
                n + self.n_endpoints()
            )));
        }
        let mut g = vec![0.0; self.dim()];
        g[..2 * n].copy_from_slice(&g_soft[..2 * n]);
        for (e, l) in theta[2 * n..].chunks(n).enumerate() {
            let w = softmax(l, tau);
            let ge = [g_soft[2 * (n + e)], g_soft[2 * (n + e) + 1]];
            // g·p_j for each control point, and its weighted mean.
            let gp: Vec<f64> = (0..n)
                .map(|j| ge[0] * theta[2 * j] + ge[1] * theta[2 * j + 1])
                .collect();
            let mean: f64 = (0..n).map(|j| w[j] * gp[j]).sum();
            for j in 0..n {
                g[2 * j] += w[j] * ge[0];
                g[2 * j + 1] += w[j] * ge[1];
                g[2 * n + e * n + j] = w[j] * (gp[j] - mean) / tau;
            }
        }
        Ok(g)
    }
}
