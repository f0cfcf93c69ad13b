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

/// Per-code constants of the log-joint (`ln prior − H·ln s_c` and `1/(2 s_c²)`), and the
/// bounds that let [`log_joints`] skip a whole subtree of codes.
///
/// Codes are words `c = u∘v` (u the outer maps): `S_c(0) = S_u(S_v(0))` lies within
/// `s_u·‖S_v(0)‖` of `S_u(0)`, `s_c = s_u·s_v` and the prior splits the same way, so for
/// every code of depth `d` below a prefix `u` of depth `m`
///
/// ```text
/// ℓ_c(y) ≤ ln v_d + (Σ ln w_u − H·ln s_u) + A_j − max(0, ‖y − S_u(0)‖ − s_u·M_j)² / (2 s_u² S_j²)
/// ```
///
/// with `j = d − m` and, over the codes `v` of depth `j`, `A_j` the largest
/// `Σ ln w_v − H·ln s_v`, `M_j` the largest `‖S_v(0)‖` and `S_j` the largest `s_v`.
struct Terms {
    base: Vec<f64>,
    half_inv_var: Vec<f64>,
    /// `−(H/2)·ln 2π − H·ln s_P`: turns model-frame log-joints into data-space densities.
    constant: f64,
    k: usize,
    /// First index of each depth's codes, D + 2 entries.
    offsets: Vec<usize>,
    /// `ln v_d`, d = 0..=D.
    log_depth: Vec<f64>,
    /// `Σ ln w_c − H·ln s_c` per code.
    inner: Vec<f64>,
    /// `s_c` per code.
    scale: Vec<f64>,
    /// Per remaining depth j = 0..=D: (A_j, M_j, 1/(2 S_j²)).
    below: Vec<(f64, f64, f64)>,
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
    let inner: Vec<f64> = table
        .log_word_priors
        .iter()
        .zip(&table.log_scales)
        .map(|(lw, ls)| lw - h * ls)
        .collect();
    let scale: Vec<f64> = table.log_scales.iter().map(|ls| ls.exp()).collect();
    let offsets: Vec<usize> = (0..=table.depth())
        .map(|d| table.depth_range(d).start)
        .chain(std::iter::once(table.len()))
        .collect();
    let below = (0..=table.depth())
        .map(|j| {
            let r = table.depth_range(j);
            let a = inner[r.clone()]
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max);
            let m = r
                .clone()
                .map(|c| table.mean(c).iter().map(|v| v * v).sum::<f64>().sqrt())
                .fold(0.0, f64::max);
            let s = scale[r].iter().copied().fold(0.0, f64::max);
            (a, m, 0.5 / (s * s))
        })
        .collect();
    Terms {
        base,
        half_inv_var,
        constant,
        k: table.k(),
        offsets,
        log_depth: table.log_depth_weights.clone(),
        inner,
        scale,
        below,
    }
}

/// Slack (nats) on the subtree bounds, far above their rounding error: a subtree is skipped
/// only when its bound is this much below the cut, so the skipped codes are exactly those the
/// dense sum would have zeroed.
const BOUND_SLACK: f64 = 1.0;

/// Reused buffers of [`log_joints`]: the prefixes still open at a depth, and the next's.
#[derive(Default)]
struct Scratch {
    open: Vec<usize>,
    next: Vec<usize>,
    terms: Vec<(u32, f64)>,
}

/// Fills `lp` with the codes whose log-joint at `y` is within [`SKIP_NATS`] of the largest,
/// in code order, as `(code, exp(ℓ_c − max))`, and returns their log-sum-exp and the maximum.
///
/// The codes are taken depth by depth, each open code's `K` children together (they are
/// contiguous), so they come in code order. A code stays open for the next depth unless the
/// bound on every code below it (see [`Terms`]) is more than `SKIP_NATS` below the largest
/// log-joint found so far: those terms are below `max − SKIP_NATS`, which a dense sum zeroes
/// too, and the kept terms are added in code order, so the result has the bits of the sum
/// over every code (`tests::pruned_e_step_has_the_dense_bits`).
///
/// `H` is the dimension where it is known when compiling (2 and 3: the loops over the
/// coordinates unroll), 0 for any dimension; the sums are taken in the same order either
/// way, so every `H` gives the same bits.
#[inline]
fn log_joints<const H: usize>(
    y: &[f64],
    table: &CodeTable,
    t: &Terms,
    lp: &mut Vec<(u32, f64)>,
    scratch: &mut Scratch,
) -> (f64, f64) {
    let h = if H == 0 { y.len() } else { H };
    let y = &y[..h];
    let depth = t.offsets.len() - 2;
    let k = t.k;
    let dist2 = |c: usize| {
        let mu = &table.means[c * h..c * h + h];
        let mut d2 = 0.0;
        for j in 0..h {
            let d = y[j] - mu[j];
            d2 += d * d;
        }
        d2
    };
    // A first largest term: the root, then down the nearest child at every depth.
    let root = t.base[0] - dist2(0) * t.half_inv_var[0];
    let mut max = root;
    let mut at = 0; // index within its depth
    for d in 1..=depth {
        let mut best = (f64::INFINITY, 0);
        for i in at * k..at * k + k {
            let d2 = dist2(t.offsets[d] + i);
            if d2 < best.0 {
                best = (d2, i);
            }
        }
        at = best.1;
        let c = t.offsets[d] + at;
        max = max.max(t.base[c] - best.0 * t.half_inv_var[c]);
    }
    // Whether a code of depth m at squared distance d2 may have a term worth keeping below it.
    let open_below = |c: usize, m: usize, d2: f64, max: f64| {
        let cut = max - SKIP_NATS - BOUND_SLACK - t.inner[c];
        let r = d2.sqrt() / t.scale[c];
        t.below[1..=depth - m]
            .iter()
            .enumerate()
            .any(|(j, &(a, rad, inv))| {
                let gap = (r - rad).max(0.0);
                t.log_depth[m + 1 + j] + a - gap * gap * inv >= cut
            })
    };
    let Scratch { open, next, terms } = scratch;
    terms.clear();
    open.clear();
    terms.push((0, root));
    open.push(0);
    for d in 1..=depth {
        next.clear();
        let last = d == depth;
        for &p in open.iter() {
            for i in p * k..p * k + k {
                let c = t.offsets[d] + i;
                let d2 = dist2(c);
                let l = t.base[c] - d2 * t.half_inv_var[c];
                max = max.max(l);
                terms.push((c as u32, l));
                if !last && open_below(c, d, d2, max) {
                    next.push(i);
                }
            }
        }
        std::mem::swap(open, next);
    }
    lp.clear();
    let mut s = 0.0;
    for &(c, l) in terms.iter() {
        let z = l - max;
        if z > -SKIP_NATS {
            let e = z.exp();
            lp.push((c, e));
            s += e;
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
            let (mut lp, mut scratch) = (Vec::new(), Scratch::default());
            let mut y = vec![0.0; h];
            for x in block.chunks_exact(h) {
                map.apply(x, &mut y);
                let (lse, max) = log_joints::<H>(&y, table, &t, &mut lp, &mut scratch);
                let y = &y[..hc];
                let yy: f64 = y.iter().map(|v| v * v).sum();
                // lp now holds exp(ℓ_c − max) of the kept codes; r_c = that · exp(max − lse).
                let scale = (max - lse).exp();
                for &(c, e) in lp.iter() {
                    let c = c as usize;
                    let r = e * scale;
                    st.weight[c] += r;
                    st.sum_sq[c] += r * yy;
                    let sum = &mut st.sum[c * hc..c * hc + hc];
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
            let (mut lp, mut scratch) = (Vec::new(), Scratch::default());
            let mut y = vec![0.0; h];
            for (oi, x) in o.iter_mut().zip(block.chunks_exact(h)) {
                map.apply(x, &mut y);
                *oi = match h {
                    2 => log_joints::<2>(&y, table, &t, &mut lp, &mut scratch).0,
                    3 => log_joints::<3>(&y, table, &t, &mut lp, &mut scratch).0,
                    _ => log_joints::<0>(&y, table, &t, &mut lp, &mut scratch).0,
                } + t.constant;
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problems::em::init::{normalising_post, random_model};
    use ifslab::chaos::trajectory_rng;
    use ifslab::model::Similitude;

    /// The E-step over every code, as it was before the subtrees were skipped: the oracle.
    fn dense_expectation(model: &EmModel, table: &CodeTable, points: &PointSet) -> Statistics {
        let h = model.dim();
        let t = terms(model, table);
        let map = ToModel::new(model);
        let mut total = Statistics::zeros(table.len(), h);
        for block in points.as_slice().chunks(BLOCK * h) {
            let mut st = Statistics::zeros(table.len(), h);
            let mut lp = vec![0.0; table.len()];
            let mut y = vec![0.0; h];
            for x in block.chunks_exact(h) {
                map.apply(x, &mut y);
                for (c, l) in lp.iter_mut().enumerate() {
                    let mu = table.mean(c);
                    let mut d2 = 0.0;
                    for j in 0..h {
                        let d = y[j] - mu[j];
                        d2 += d * d;
                    }
                    *l = t.base[c] - d2 * t.half_inv_var[c];
                }
                let max = lp.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                let mut s = 0.0;
                for l in lp.iter_mut() {
                    let z = *l - max;
                    *l = if z > -SKIP_NATS {
                        let e = z.exp();
                        s += e;
                        e
                    } else {
                        0.0
                    };
                }
                let lse = max + s.ln();
                let yy: f64 = y.iter().map(|v| v * v).sum();
                let scale = (max - lse).exp();
                for (c, &e) in lp.iter().enumerate() {
                    if e == 0.0 {
                        continue;
                    }
                    let r = e * scale;
                    st.weight[c] += r;
                    st.sum_sq[c] += r * yy;
                    for j in 0..h {
                        st.sum[c * h + j] += r * y[j];
                    }
                }
                st.log_likelihood += lse + t.constant;
                st.points += 1;
            }
            total.add(&st);
        }
        total
    }

    /// Models of 2–5 maps in 2, 3 and 4 dimensions, at depths up to 6, on points of the model
    /// itself (most codes far from a point: much is skipped) and of another code (little is):
    /// the skipping E-step gives the dense one's sums and likelihoods to the last bit.
    #[test]
    fn pruned_e_step_has_the_dense_bits() {
        for (case, (k, h, depth)) in [
            (2, 2, 6),
            (3, 2, 5),
            (3, 3, 4),
            (4, 3, 4),
            (5, 2, 3),
            (3, 4, 3),
            (10, 2, 3),
        ]
        .into_iter()
        .enumerate()
        {
            let mut rng = trajectory_rng(7, case as u64);
            let truth = random_model(k, depth, 0.45, Similitude::identity(h), &mut rng).unwrap();
            let other = random_model(k, depth, 0.5, Similitude::identity(h), &mut rng).unwrap();
            let points = truth.sample(700, case as u64).unwrap();
            for model in [&truth, &other] {
                let mut model = model.clone();
                model.post = normalising_post(&points);
                // Weight on the deepest codes, as a fit has it, and uniform.
                for concentrated in [false, true] {
                    if concentrated {
                        let n = model.depth_weights.len();
                        for (d, v) in model.depth_weights.iter_mut().enumerate() {
                            *v = if d + 1 == n {
                                0.97
                            } else {
                                0.03 / (n - 1) as f64
                            };
                        }
                    }
                    let table = model.code_table();
                    let dense = dense_expectation(&model, &table, &points);
                    let pruned = expectation(&model, &table, &points);
                    assert_eq!(pruned, dense, "K {k}, H {h}, D {depth}");
                    let per_point: f64 = model.log_densities(&points).unwrap().iter().sum();
                    assert!(
                        (per_point - dense.log_likelihood).abs()
                            < 1e-9 * dense.log_likelihood.abs()
                    );
                }
            }
        }
    }
}
