//! The E-step: responsibilities of every code for every point, in log space.
//!
//! For a point x, mapped into the model frame `y = P⁻¹(x)`, code c has the log-joint
//!
//! ```text
//! ℓ_c(y) = ln v_|c| + Σ_j ln w_{c_j} − H·ln s_c − ‖y − S_c(0)‖² / (2 s_c²)   (+ constants)
//! ```
//!
//! and its responsibility is `r_c = exp(ℓ_c − logsumexp_c' ℓ_c')`. The log-sum-exp is taken
//! around the largest term, so nothing underflows at depth 6 or far beyond (at depth 6 a
//! cell's scale is 2⁻⁶ of the attractor's and plain densities underflow long before the
//! mixture does); terms more than 50 nats below the largest are skipped without an `exp`
//! (their share is below 2·10⁻²²).
//!
//! The M-step needs only per-code sums, so the E-step never stores the N′×|codes| matrix:
//! each block of 64 points accumulates `W_c = Σ_i r_ic`, `Σ_i r_ic·y_i` and `Σ_i r_ic·‖y_i‖²`
//! (model frame), and the blocks, computed in parallel, are added in block order — the
//! same sums whatever the number of threads.
//!
//! ## References
//! - P. Bloem and S. de Rooij, *An Expectation-Maximization Algorithm for the Fractal
//!   Inverse Problem*, arXiv:1706.03149, 2017 (the E-step over codes).

// Index loops over the H coordinates mirror the formulas; iterator chains would hide them.
#![allow(clippy::needless_range_loop)]

use rayon::prelude::*;

use crate::problems::em::data::PointSet;
use crate::problems::em::model::{CodeTable, EmModel};

/// Points per parallel work item; fixed so the sums do not depend on the thread count.
const BLOCK: usize = 64;

/// Terms this far (nats) below a point's largest term are treated as zero.
const SKIP_NATS: f64 = 50.0;

/// Per-code sufficient statistics of one E-step (model frame).
#[derive(Clone, Debug, PartialEq)]
pub struct Statistics {
    /// Dimension H.
    pub dim: usize,
    /// `W_c = Σ_i r_ic`, one per code.
    pub weight: Vec<f64>,
    /// `Σ_i r_ic·y_i`, H numbers per code.
    pub sum: Vec<f64>,
    /// `Σ_i r_ic·‖y_i‖²`, one per code.
    pub sum_sq: Vec<f64>,
    /// `Σ_i ln p(x_i)` of the points under the model the E-step used (nats, data space).
    pub log_likelihood: f64,
    /// Number of points.
    pub points: usize,
}

impl Statistics {
    fn zeros(n_codes: usize, dim: usize) -> Self {
        Statistics {
            dim,
            weight: vec![0.0; n_codes],
            sum: vec![0.0; n_codes * dim],
            sum_sq: vec![0.0; n_codes],
            log_likelihood: 0.0,
            points: 0,
        }
    }

    fn add(&mut self, o: &Statistics) {
        for (a, b) in self.weight.iter_mut().zip(&o.weight) {
            *a += b;
        }
        for (a, b) in self.sum.iter_mut().zip(&o.sum) {
            *a += b;
        }
        for (a, b) in self.sum_sq.iter_mut().zip(&o.sum_sq) {
            *a += b;
        }
        self.log_likelihood += o.log_likelihood;
        self.points += o.points;
    }

    /// Mean log-likelihood per point (nats).
    pub fn mean_log_likelihood(&self) -> f64 {
        self.log_likelihood / self.points.max(1) as f64
    }
}

/// Per-code constants of the log-joint: `ln prior − H·ln s_c` and `1/(2 s_c²)`.
struct Terms {
    base: Vec<f64>,
    half_inv_var: Vec<f64>,
    /// `−(H/2)·ln 2π − H·ln s_P`: turns model-frame log-joints into data-space densities.
    constant: f64,
}

fn terms(model: &EmModel, table: &CodeTable) -> Terms {
    let h = table.dim() as f64;
    let base = table
        .log_priors
        .iter()
        .zip(&table.log_scales)
        .map(|(lp, ls)| lp - h * ls)
        .collect();
    let half_inv_var = table
        .log_scales
        .iter()
        .map(|ls| 0.5 * (-2.0 * ls).exp())
        .collect();
    let constant = -0.5 * h * (2.0 * std::f64::consts::PI).ln() - h * model.post.s.ln();
    Terms {
        base,
        half_inv_var,
        constant,
    }
}

/// Fills `lp` with `exp(ℓ_c − max)` of the log-joints of `y` (zero for a term more than
/// [`SKIP_NATS`] below the largest) and returns their log-sum-exp and maximum.
///
/// `H` is the dimension where it is known when compiling (2 and 3: the loops over the
/// coordinates unroll), 0 for any dimension; the sums are taken in the same order either
/// way, so every `H` gives the same bits.
#[inline]
fn log_joints<const H: usize>(
    y: &[f64],
    table: &CodeTable,
    t: &Terms,
    lp: &mut [f64],
) -> (f64, f64) {
    let h = if H == 0 { y.len() } else { H };
    let y = &y[..h];
    let per_code = table
        .means
        .chunks_exact(h)
        .zip(&t.base)
        .zip(&t.half_inv_var);
    for (l, ((mu, base), half_inv_var)) in lp.iter_mut().zip(per_code) {
        let mu = &mu[..h];
        let mut d2 = 0.0;
        for j in 0..h {
            let d = y[j] - mu[j];
            d2 += d * d;
        }
        *l = base - d2 * half_inv_var;
    }
    // The largest term, in four lanes (a maximum does not depend on the order).
    let mut lanes = [f64::NEG_INFINITY; 4];
    let (quads, rest) = lp.as_chunks::<4>();
    for q in quads {
        for k in 0..4 {
            lanes[k] = if q[k] > lanes[k] { q[k] } else { lanes[k] };
        }
    }
    let mut max = f64::NEG_INFINITY;
    for &v in lanes.iter().chain(rest) {
        if v > max {
            max = v;
        }
    }
    let mut s = 0.0;
    for l in lp.iter_mut() {
        let z = *l - max;
        if z > -SKIP_NATS {
            let e = z.exp();
            *l = e;
            s += e;
        } else {
            *l = 0.0;
        }
    }
    (max + s.ln(), max)
}

/// Maps a data point into the model frame: `y = P⁻¹(x)`.
struct ToModel {
    rt: Vec<f64>,
    t: Vec<f64>,
    inv_s: f64,
}

impl ToModel {
    fn new(model: &EmModel) -> Self {
        let h = model.dim();
        let p = &model.post;
        ToModel {
            rt: (0..h * h).map(|e| p.r[(e % h, e / h)]).collect(),
            t: p.t.iter().copied().collect(),
            inv_s: 1.0 / p.s,
        }
    }

    #[inline]
    fn apply(&self, x: &[f64], y: &mut [f64]) {
        let h = x.len();
        for (a, ya) in y.iter_mut().enumerate() {
            let mut acc = 0.0;
            for b in 0..h {
                acc += self.rt[a * h + b] * (x[b] - self.t[b]);
            }
            *ya = acc * self.inv_s;
        }
    }
}

/// One E-step on `points`: the per-code statistics and the log-likelihood.
pub fn expectation(model: &EmModel, table: &CodeTable, points: &PointSet) -> Statistics {
    match model.dim() {
        2 => expectation_in::<2>(model, table, points),
        3 => expectation_in::<3>(model, table, points),
        _ => expectation_in::<0>(model, table, points),
    }
}

/// [`expectation`] with the dimension `H` known when compiling (0: any; see [`log_joints`]).
fn expectation_in<const H: usize>(
    model: &EmModel,
    table: &CodeTable,
    points: &PointSet,
) -> Statistics {
    let h = model.dim();
    // The dimension as a constant where `H` gives it, so the coordinate loops unroll.
    let hc = if H == 0 { h } else { H };
    let n_codes = table.len();
    let t = terms(model, table);
    let map = ToModel::new(model);
    let blocks: Vec<Statistics> = points
        .as_slice()
        .par_chunks(BLOCK * h)
        .map(|block| {
            let mut st = Statistics::zeros(n_codes, h);
            let mut lp = vec![0.0; n_codes];
            let mut y = vec![0.0; h];
            for x in block.chunks_exact(h) {
                map.apply(x, &mut y);
                let (lse, max) = log_joints::<H>(&y, table, &t, &mut lp);
                let y = &y[..hc];
                let yy: f64 = y.iter().map(|v| v * v).sum();
                // lp now holds exp(ℓ_c − max); r_c = that · exp(max − lse).
                let scale = (max - lse).exp();
                let per_code = st
                    .weight
                    .iter_mut()
                    .zip(st.sum_sq.iter_mut())
                    .zip(st.sum.chunks_exact_mut(hc));
                for (e, ((weight, sum_sq), sum)) in lp.iter().zip(per_code) {
                    if *e == 0.0 {
                        continue;
                    }
                    let r = e * scale;
                    *weight += r;
                    *sum_sq += r * yy;
                    let sum = &mut sum[..hc];
                    for j in 0..hc {
                        sum[j] += r * y[j];
                    }
                }
                st.log_likelihood += lse + t.constant;
                st.points += 1;
            }
            st
        })
        .collect();
    let mut total = Statistics::zeros(n_codes, h);
    for b in &blocks {
        total.add(b);
    }
    total
}

/// The model's likelihood, written beside the E-step that computes it.
impl EmModel {
    /// Per-point log-densities log p(x_i) (nats), in point order.
    pub fn log_densities(&self, points: &PointSet) -> crate::error::Result<Vec<f64>> {
        self.check_points(points)?;
        let table = self.code_table();
        Ok(log_densities(self, &table, points))
    }

    /// Total log-likelihood Σ_i log p(x_i) (nats).
    pub fn log_likelihood(&self, points: &PointSet) -> crate::error::Result<f64> {
        Ok(self.log_densities(points)?.iter().sum())
    }
}

/// `ln p(x_i)` for every point (nats, data space), in point order.
pub fn log_densities(model: &EmModel, table: &CodeTable, points: &PointSet) -> Vec<f64> {
    let h = model.dim();
    let t = terms(model, table);
    let map = ToModel::new(model);
    let mut out = vec![0.0; points.len()];
    out.par_chunks_mut(BLOCK)
        .zip(points.as_slice().par_chunks(BLOCK * h))
        .for_each(|(o, block)| {
            let mut lp = vec![0.0; table.len()];
            let mut y = vec![0.0; h];
            for (oi, x) in o.iter_mut().zip(block.chunks_exact(h)) {
                map.apply(x, &mut y);
                *oi = match h {
                    2 => log_joints::<2>(&y, table, &t, &mut lp).0,
                    3 => log_joints::<3>(&y, table, &t, &mut lp).0,
                    _ => log_joints::<0>(&y, table, &t, &mut lp).0,
                } + t.constant;
            }
        });
    out
}
