//! Gaussian-mixture baselines for held-out log-likelihoods in the same units as the IFS
//! model: isotropic components (`σ_m²·I`) and full covariances, fitted by plain EM.
//!
//! Written here rather than taken from `linfa-clustering`: its `GaussianMixtureModel` only
//! offers full covariances (no isotropic variant, which is the closest baseline to the IFS
//! model's isotropic Gaussians), and it would bring the ndarray stack next to nalgebra. The
//! algorithm is the textbook one: k-means++ seeding, hard first assignment, then EM with a
//! log-sum-exp E-step and a covariance floor `reg·I` (relative to the data's variance);
//! several seeded restarts, keeping the best training likelihood. Data are standardised
//! internally (mean 0, RMS radius 1) so the moment sums keep their precision; densities are
//! reported in the original units.
//!
//! ## References
//! - A. P. Dempster, N. M. Laird and D. B. Rubin, *Maximum likelihood from incomplete data
//!   via the EM algorithm*, JRSS B 39(1), 1977.
//! - D. Arthur and S. Vassilvitskii, *k-means++: the advantages of careful seeding*, SODA 2007.

// Index loops over the H coordinates mirror the formulas; iterator chains would hide them.
#![allow(clippy::needless_range_loop)]

use nalgebra::{DMatrix, DVector};
use rand::Rng;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use ifslab::chaos::trajectory_rng;

use crate::error::{Error, Result};
use crate::problems::em::data::PointSet;

/// Covariance structure of the mixture components.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Covariance {
    /// `σ_m²·I` per component.
    Isotropic,
    /// A full symmetric positive-definite matrix per component.
    Full,
}

/// Settings of a Gaussian-mixture fit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GmmConfig {
    /// Number of components M.
    pub components: usize,
    /// Covariance structure.
    pub covariance: Covariance,
    /// EM iterations per restart at most.
    pub max_iterations: usize,
    /// Stop when the mean log-likelihood per point improves by less than this (nats).
    pub tolerance: f64,
    /// Seeded restarts; the best training likelihood is kept.
    pub restarts: usize,
    /// Variance floor added to every covariance, relative to the data's variance per axis.
    pub reg: f64,
    /// Seed.
    pub seed: u64,
}

impl Default for GmmConfig {
    fn default() -> Self {
        GmmConfig {
            components: 3,
            covariance: Covariance::Full,
            max_iterations: 500,
            tolerance: 1e-7,
            restarts: 3,
            reg: 1e-6,
            seed: 0,
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
enum Cov {
    /// Variance.
    Iso(f64),
    /// Lower Cholesky factor of Σ and ln det Σ.
    Full(DMatrix<f64>, f64),
}

/// A fitted Gaussian mixture.
#[derive(Clone, Debug, PartialEq)]
pub struct Gmm {
    covariance: Covariance,
    weights: Vec<f64>,
    means: Vec<DVector<f64>>,
    covs: Vec<Cov>,
    /// Standardisation: x_std = (x − shift)/scale.
    shift: Vec<f64>,
    scale: f64,
    /// Iterations of the kept restart.
    iterations: usize,
}

const BLOCK: usize = 256;

/// Per-component moment sums `(N_m, Σ r z, Σ r z zᵀ)` (the last 1×1 `Σ r‖z‖²` when isotropic).
type Moments = (f64, DVector<f64>, DMatrix<f64>);

impl Gmm {
    /// Fits a mixture to `data` (see the module docs).
    pub fn fit(data: &PointSet, cfg: &GmmConfig) -> Result<Gmm> {
        if cfg.components == 0 {
            return Err(Error::param("components", "need at least one component"));
        }
        if data.len() < cfg.components {
            return Err(Error::InvalidInput(format!(
                "{} points for a {}-component mixture: give at least as many points as components",
                data.len(),
                cfg.components
            )));
        }
        if cfg.restarts == 0 {
            return Err(Error::param("restarts", "must be at least 1"));
        }
        if !(cfg.reg > 0.0 && cfg.reg.is_finite()) {
            return Err(Error::param("reg", "must be finite and > 0"));
        }
        let shift = data.mean();
        let scale = {
            let r = data.rms_radius();
            if r > 0.0 { r } else { 1.0 }
        };
        let h = data.dim();
        let std: Vec<f64> = data
            .iter()
            .flat_map(|p| p.iter().zip(&shift).map(|(a, b)| (a - b) / scale))
            .collect();
        let z = PointSet::new(h, std)?;
        // Per-axis variance of standardised data is 1/H on average.
        let floor = cfg.reg / h as f64;
        let mut best: Option<(f64, Gmm)> = None;
        for restart in 0..cfg.restarts {
            let mut rng = trajectory_rng(cfg.seed, restart as u64);
            let mut g = init(&z, cfg, floor, &mut rng);
            g.shift = shift.clone();
            g.scale = scale;
            let mut prev = f64::NEG_INFINITY;
            let mut its = 0;
            for it in 0..cfg.max_iterations {
                let (ll, stats) = g.e_step(&z);
                g.m_step(&stats, floor, &z, &mut rng);
                its = it + 1;
                if (ll - prev).abs() < cfg.tolerance * z.len() as f64 {
                    break;
                }
                prev = ll;
            }
            g.iterations = its;
            let ll = g.e_step(&z).0;
            if !ll.is_finite() {
                continue;
            }
            if best.as_ref().is_none_or(|(b, _)| ll > *b) {
                best = Some((ll, g));
            }
        }
        best.map(|(_, g)| g).ok_or_else(|| {
            Error::Numerical("every Gaussian-mixture restart gave a non-finite likelihood".into())
        })
    }

    /// Number of components.
    pub fn components(&self) -> usize {
        self.weights.len()
    }

    /// Covariance structure.
    pub fn covariance(&self) -> Covariance {
        self.covariance
    }

    /// EM iterations the kept restart ran.
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// Free parameters: M−1 weights, M·H means, and M variances or M·H(H+1)/2 covariances.
    pub fn parameter_count(&self) -> usize {
        let m = self.components();
        let h = self.shift.len();
        let cov = match self.covariance {
            Covariance::Isotropic => 1,
            Covariance::Full => h * (h + 1) / 2,
        };
        m - 1 + m * h + m * cov
    }

    /// `ln p(x_i)` for every point (nats, original units).
    pub fn log_densities(&self, points: &PointSet) -> Result<Vec<f64>> {
        let h = self.shift.len();
        if points.dim() != h {
            return Err(Error::InvalidInput(format!(
                "points are {}-dimensional, the mixture {h}-dimensional",
                points.dim()
            )));
        }
        let jac = -(h as f64) * self.scale.ln();
        let mut out = vec![0.0; points.len()];
        out.par_chunks_mut(BLOCK)
            .zip(points.as_slice().par_chunks(BLOCK * h))
            .for_each(|(o, block)| {
                let mut lp = vec![0.0; self.components()];
                let mut z = vec![0.0; h];
                for (oi, x) in o.iter_mut().zip(block.chunks_exact(h)) {
                    for j in 0..h {
                        z[j] = (x[j] - self.shift[j]) / self.scale;
                    }
                    *oi = self.log_joint(&z, &mut lp) + jac;
                }
            });
        Ok(out)
    }

    /// Mean log-likelihood per point (nats, original units).
    pub fn mean_log_likelihood(&self, points: &PointSet) -> Result<f64> {
        if points.is_empty() {
            return Err(Error::InvalidInput("no points to evaluate".into()));
        }
        Ok(self.log_densities(points)?.iter().sum::<f64>() / points.len() as f64)
    }

    /// Fills `lp` with `ln w_m + ln N(z | μ_m, Σ_m)` (standardised z) and returns their
    /// log-sum-exp; `lp` then holds the responsibilities.
    fn log_joint(&self, z: &[f64], lp: &mut [f64]) -> f64 {
        let h = z.len();
        let c = -0.5 * h as f64 * (2.0 * std::f64::consts::PI).ln();
        let mut max = f64::NEG_INFINITY;
        let mut d = vec![0.0; h];
        for (m, l) in lp.iter_mut().enumerate() {
            for j in 0..h {
                d[j] = z[j] - self.means[m][j];
            }
            let v = match &self.covs[m] {
                Cov::Iso(var) => {
                    let d2: f64 = d.iter().map(|v| v * v).sum();
                    -0.5 * d2 / var - 0.5 * h as f64 * var.ln()
                }
                Cov::Full(l_chol, log_det) => {
                    // Forward substitution L·u = d, then ‖u‖² is the Mahalanobis term.
                    let mut u2 = 0.0;
                    for i in 0..h {
                        let mut acc = d[i];
                        for k in 0..i {
                            acc -= l_chol[(i, k)] * d[k];
                        }
                        d[i] = acc / l_chol[(i, i)];
                        u2 += d[i] * d[i];
                    }
                    -0.5 * u2 - 0.5 * log_det
                }
            };
            *l = self.weights[m].ln() + v + c;
            max = max.max(*l);
        }
        let mut s = 0.0;
        for l in lp.iter_mut() {
            *l = (*l - max).exp();
            s += *l;
        }
        for l in lp.iter_mut() {
            *l /= s;
        }
        max + s.ln()
    }

    /// Log-likelihood (standardised units) and per-component sums: (N_m, Σ r z, Σ r z zᵀ).
    fn e_step(&self, z: &PointSet) -> (f64, Vec<Moments>) {
        let h = z.dim();
        let m = self.components();
        let full = self.covariance == Covariance::Full;
        let zero = || -> Vec<Moments> {
            (0..m)
                .map(|_| {
                    (
                        0.0,
                        DVector::zeros(h),
                        DMatrix::zeros(if full { h } else { 1 }, if full { h } else { 1 }),
                    )
                })
                .collect()
        };
        let parts: Vec<(f64, Vec<Moments>)> = z
            .as_slice()
            .par_chunks(BLOCK * h)
            .map(|block| {
                let mut acc = zero();
                let mut ll = 0.0;
                let mut lp = vec![0.0; m];
                for x in block.chunks_exact(h) {
                    ll += self.log_joint(x, &mut lp);
                    let xx: f64 = x.iter().map(|v| v * v).sum();
                    for (k, r) in lp.iter().enumerate() {
                        if *r == 0.0 {
                            continue;
                        }
                        let a = &mut acc[k];
                        a.0 += r;
                        for j in 0..h {
                            a.1[j] += r * x[j];
                        }
                        if full {
                            for i in 0..h {
                                for j in 0..=i {
                                    a.2[(i, j)] += r * x[i] * x[j];
                                }
                            }
                        } else {
                            a.2[(0, 0)] += r * xx;
                        }
                    }
                }
                (ll, acc)
            })
            .collect();
        let mut total = zero();
        let mut ll = 0.0;
        for (l, acc) in parts {
            ll += l;
            for (t, a) in total.iter_mut().zip(acc) {
                t.0 += a.0;
                t.1 += a.1;
                t.2 += a.2;
            }
        }
        (ll, total)
    }

    fn m_step<R: Rng + ?Sized>(
        &mut self,
        stats: &[Moments],
        floor: f64,
        z: &PointSet,
        rng: &mut R,
    ) {
        let h = z.dim();
        let n: f64 = stats.iter().map(|s| s.0).sum();
        for (k, (nk, sx, sxx)) in stats.iter().enumerate() {
            if *nk < 1e-8 * n {
                // An empty component restarts at a random point with the data's variance.
                let i = rng.random_range(0..z.len());
                self.means[k] = DVector::from_column_slice(z.point(i));
                self.weights[k] = 1.0 / self.components() as f64;
                self.covs[k] = self.cov_from(DMatrix::identity(h, h) / h as f64, floor);
                continue;
            }
            let mu = sx / *nk;
            self.weights[k] = nk / n;
            let cov = match self.covariance {
                Covariance::Isotropic => {
                    let var = (sxx[(0, 0)] / nk - mu.dot(&mu)).max(0.0) / h as f64;
                    DMatrix::identity(h, h) * var
                }
                Covariance::Full => {
                    let mut c = DMatrix::from_fn(h, h, |i, j| {
                        let (a, b) = if i >= j { (i, j) } else { (j, i) };
                        sxx[(a, b)] / nk
                    });
                    c -= &mu * mu.transpose();
                    c
                }
            };
            self.means[k] = mu;
            self.covs[k] = self.cov_from(cov, floor);
        }
        let s: f64 = self.weights.iter().sum();
        self.weights.iter_mut().for_each(|w| *w /= s);
    }

    fn cov_from(&self, cov: DMatrix<f64>, floor: f64) -> Cov {
        let h = cov.nrows();
        match self.covariance {
            Covariance::Isotropic => Cov::Iso(cov[(0, 0)].max(0.0) + floor),
            Covariance::Full => {
                let reg = &cov + DMatrix::identity(h, h) * floor;
                match reg.clone().cholesky() {
                    Some(ch) => {
                        let l = ch.l();
                        let log_det = 2.0 * (0..h).map(|i| l[(i, i)].ln()).sum::<f64>();
                        Cov::Full(l, log_det)
                    }
                    None => {
                        // Not positive definite by round-off: fall back to its diagonal.
                        let d = DMatrix::from_diagonal(&reg.diagonal().map(|v| v.max(floor)));
                        let l = d.map(f64::sqrt);
                        let log_det = (0..h).map(|i| d[(i, i)].ln()).sum::<f64>();
                        Cov::Full(l, log_det)
                    }
                }
            }
        }
    }
}

/// k-means++ seeding, then one hard assignment and M-step.
fn init<R: Rng + ?Sized>(z: &PointSet, cfg: &GmmConfig, floor: f64, rng: &mut R) -> Gmm {
    let h = z.dim();
    let n = z.len();
    let m = cfg.components;
    let mut centres: Vec<Vec<f64>> = vec![z.point(rng.random_range(0..n)).to_vec()];
    let d2 = |p: &[f64], c: &[f64]| p.iter().zip(c).map(|(a, b)| (a - b) * (a - b)).sum::<f64>();
    let mut dist: Vec<f64> = z.iter().map(|p| d2(p, &centres[0])).collect();
    while centres.len() < m {
        let total: f64 = dist.iter().sum();
        let i = if total > 0.0 {
            let mut u = rng.random::<f64>() * total;
            let mut pick = n - 1;
            for (i, d) in dist.iter().enumerate() {
                if u < *d {
                    pick = i;
                    break;
                }
                u -= d;
            }
            pick
        } else {
            rng.random_range(0..n)
        };
        let c = z.point(i).to_vec();
        for (dd, p) in dist.iter_mut().zip(z.iter()) {
            *dd = dd.min(d2(p, &c));
        }
        centres.push(c);
    }
    let full = cfg.covariance == Covariance::Full;
    let mut g = Gmm {
        covariance: cfg.covariance,
        weights: vec![1.0 / m as f64; m],
        means: centres
            .iter()
            .map(|c| DVector::from_column_slice(c))
            .collect(),
        covs: vec![],
        shift: vec![0.0; h],
        scale: 1.0,
        iterations: 0,
    };
    g.covs = (0..m)
        .map(|_| g.cov_from(DMatrix::identity(h, h) / h as f64, floor))
        .collect();
    // Hard assignment to the nearest centre gives the first moments.
    let mut stats: Vec<Moments> = (0..m)
        .map(|_| {
            let s = if full { h } else { 1 };
            (0.0, DVector::zeros(h), DMatrix::zeros(s, s))
        })
        .collect();
    for p in z.iter() {
        let k = (0..m)
            .min_by(|&a, &b| d2(p, &centres[a]).total_cmp(&d2(p, &centres[b])))
            .unwrap_or(0);
        let s = &mut stats[k];
        s.0 += 1.0;
        for j in 0..h {
            s.1[j] += p[j];
        }
        if full {
            for i in 0..h {
                for j in 0..=i {
                    s.2[(i, j)] += p[i] * p[j];
                }
            }
        } else {
            s.2[(0, 0)] += p.iter().map(|v| v * v).sum::<f64>();
        }
    }
    g.m_step(&stats, floor, z, rng);
    g
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand_distr::StandardNormal;

    #[test]
    fn recovers_two_separated_clusters() {
        let mut rng = trajectory_rng(1, 0);
        let mut rows = Vec::new();
        for i in 0..2000 {
            let c = if i % 4 == 0 { [5.0, 0.0] } else { [-5.0, 1.0] };
            let e: [f64; 2] = [rng.sample(StandardNormal), rng.sample(StandardNormal)];
            rows.push(vec![c[0] + 0.5 * e[0], c[1] + 0.5 * e[1]]);
        }
        let data = PointSet::from_rows(&rows).unwrap();
        for cov in [Covariance::Isotropic, Covariance::Full] {
            let cfg = GmmConfig {
                components: 2,
                covariance: cov,
                ..GmmConfig::default()
            };
            let g = Gmm::fit(&data, &cfg).unwrap();
            let mut w = g.weights.clone();
            w.sort_by(f64::total_cmp);
            assert!((w[0] - 0.25).abs() < 0.02, "{cov:?}: weights {w:?}");
            // Two isotropic Gaussians of σ = 0.5 in 2-D: entropy ln(2πe·0.25) ≈ 1.452 plus
            // the mixing entropy 0.562 gives about −2.01 nats per point.
            let ll = g.mean_log_likelihood(&data).unwrap();
            assert!((ll + 2.01).abs() < 0.05, "{cov:?}: mean ll {ll}");
        }
    }
}
