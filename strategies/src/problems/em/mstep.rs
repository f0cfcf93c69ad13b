//! The M-step, in closed form, from the E-step's per-code sums.
//!
//! **Weights and depth weights** are the responsibilities' shares: `v_d ∝ Σ_{|c|=d} W_c`,
//! and `w_k ∝` the responsibility mass of the codes that use map k (counted once per
//! occurrence with [`ComponentUpdate::AllPositions`], once per code whose outermost map it
//! is with [`ComponentUpdate::Outermost`], the paper's rule).
//!
//! **Components.** A code `k·c'` places the Gaussian `N(S_k(μ_{c'}), s_k² s_{c'}² I)`, with
//! `μ_{c'} = S_{c'}(0)`. Holding the inner codes `c'` at their current values, maximising
//! `Σ r_{i,kc'} ln N(y_i | S_k(μ_{c'}), s_k² s_{c'}² I)` over `S_k` is a weighted
//! similitude Procrustes problem between targets y_i and sources μ_{c'} with weights
//! `ω = r/s_{c'}²`:
//!
//! - `t̂ = ȳ − ŝ·R̂·b̄` (ω-weighted means of targets and sources);
//! - `R̂ = U·diag(1, …, 1, det(U·Vᵀ))·Vᵀ` from the SVD `U·Σ·Vᵀ` of the weighted
//!   cross-covariance `C = Σ ω (y − ȳ)(b − b̄)ᵀ` (the determinant fix keeps R̂ proper);
//! - `ŝ` from the stationarity equation of `−N·H·ln s − A/(2s²) + B/s` (the scale sits in
//!   both the mean and the variance): `N·H·s² + B·s − A = 0`, with `A = Σ ω‖y − ȳ‖²`,
//!   `B = tr(R̂ᵀ C)` and `N = Σ r`, whose positive root is taken in a cancellation-free form.
//!
//! The paper pairs each point only with the codes whose *outermost* map is k
//! ([`ComponentUpdate::Outermost`]). The default, [`ComponentUpdate::AllPositions`], also
//! uses the codes that contain k further in, mapping the targets back through the prefix
//! before k (`y' = S_{prefix}⁻¹(y)`, a similitude, so the problem keeps its form): its fixed
//! points are stationary points of the likelihood, since the update's objective has the
//! gradient of the EM objective at the current parameters. Neither is an exact maximisation
//! once D ≥ 2 (a map appears at several places in a code), so neither guarantees a higher
//! likelihood; in measurements the all-positions rule lowers it far more rarely, and
//! [`MStepConfig::monotone`] adds a safeguard that falls back to the exact blocks.
//!
//! **Post-transform.** With the new components, `P ← P ∘ G` where G is the same Procrustes
//! fit over all codes (targets y, sources `μ_c`, weights `r/s_c²`, N = number of points).
//! This step maximises the EM objective exactly, as do the weight updates.
//!
//! **Degenerate cases** are repaired and reported, never turned into NaN: a component whose
//! weight falls below `dead_weight` is re-seeded as a perturbed copy of the heaviest one
//! (their weights halved); a cross-covariance with no rotational information (all sources at
//! one point — always the case at depth 1) keeps the old rotation; a scale outside
//! `[min_scale, max_scale]` is clamped (exact for the one-dimensional problem, which is
//! concave in 1/s); a non-finite fit keeps the old parameters.
//!
//! ## References
//! - P. Bloem and S. de Rooij, *An Expectation-Maximization Algorithm for the Fractal
//!   Inverse Problem*, arXiv:1706.03149, 2017.
//! - S. Umeyama, *Least-squares estimation of transformation parameters between two point
//!   patterns*, IEEE TPAMI 13(4), 1991 (the determinant fix).
//! - X.-L. Meng and D. B. Rubin, *Maximum likelihood estimation via the ECM algorithm*,
//!   Biometrika 80(2), 1993 (updating blocks in turn).

// Index loops over the H coordinates mirror the formulas; iterator chains would hide them.
#![allow(clippy::needless_range_loop)]

use nalgebra::{DMatrix, DVector};
use rand::Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

use ifslab::model::Similitude;

use crate::error::{Error, Result};
use crate::problems::em::estep::Statistics;
use crate::problems::em::model::{CodeTable, EmModel, PROB_FLOOR};

/// Which codes inform a component's update.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ComponentUpdate {
    /// The paper's rule: only codes whose outermost map is k; weights from outermost maps.
    Outermost,
    /// Every occurrence of k in every code, targets mapped back through the prefix;
    /// weights counted per occurrence (the exact M-step for the weights).
    #[default]
    AllPositions,
}

/// Bounds and repair thresholds of the M-step.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MStepConfig {
    /// Which codes inform a component's update.
    pub update: ComponentUpdate,
    /// Smallest component scale (model frame, where the data's RMS radius is 1).
    pub min_scale: f64,
    /// Largest component scale (keeps the code contractive so it can be rendered).
    pub max_scale: f64,
    /// A component whose weight falls below this is re-seeded.
    pub dead_weight: f64,
    /// Standard deviation of the translation noise of a re-seeded component, relative to
    /// the scale of the component it copies.
    pub split_noise: f64,
    /// Let components and the post-transform reflect (orthogonal maps of either
    /// determinant, `R̂ = U·Vᵀ`) instead of rotating only (the paper's `det R = +1`): an
    /// attractor whose pieces are mirror images of the whole is then a model, not a
    /// local optimum to fall into. Serialised only when on, so configs written before it
    /// existed read as they meant.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub reflections: bool,
    /// Safeguard for full-batch runs: when the new model lowers the batch likelihood (the
    /// component update is not an exact maximisation), fall back to the exact blocks only —
    /// weights, depth weights and post-transform with the old components — which cannot
    /// lower it (a generalised EM step). Costs one extra likelihood evaluation per step.
    pub monotone: bool,
}

impl Default for MStepConfig {
    fn default() -> Self {
        MStepConfig {
            update: ComponentUpdate::AllPositions,
            min_scale: 1e-6,
            max_scale: 0.99,
            dead_weight: 1e-4,
            split_noise: 0.1,
            reflections: true,
            monotone: false,
        }
    }
}

impl MStepConfig {
    /// Checks the bounds; the error names the field to change.
    pub fn validate(&self) -> Result<()> {
        if !(self.min_scale > 0.0 && self.min_scale < self.max_scale) {
            return Err(Error::param(
                "min_scale",
                format!(
                    "need 0 < min_scale < max_scale, got {} and {}",
                    self.min_scale, self.max_scale
                ),
            ));
        }
        if !(self.max_scale.is_finite()) {
            return Err(Error::param("max_scale", "must be finite"));
        }
        if !(0.0..0.5).contains(&self.dead_weight) {
            return Err(Error::param(
                "dead_weight",
                format!("must lie in [0, 0.5), got {}", self.dead_weight),
            ));
        }
        if !(self.split_noise.is_finite() && self.split_noise >= 0.0) {
            return Err(Error::param("split_noise", "must be finite and ≥ 0"));
        }
        Ok(())
    }
}

/// Which part of the model a degeneracy concerns.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Part {
    /// Component k.
    Component(usize),
    /// The post-transform.
    Post,
}

impl std::fmt::Display for Part {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Part::Component(k) => write!(f, "component {k}"),
            Part::Post => write!(f, "post-transform"),
        }
    }
}

/// A degenerate case the M-step met and repaired.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum Degeneracy {
    /// A component lost (almost) all responsibility and was re-seeded from another.
    DeadComponent {
        /// The re-seeded component.
        component: usize,
        /// Its weight before re-seeding.
        weight: f64,
        /// The component it was copied from.
        copied_from: usize,
    },
    /// The cross-covariance held no rotational information; the old rotation was kept.
    RotationUndetermined {
        /// Which part.
        part: Part,
    },
    /// The scale's stationary point lay outside the allowed range (or was 0) and was clamped.
    ScaleClamped {
        /// Which part.
        part: Part,
        /// The stationary point (0 when the targets all coincide).
        raw: f64,
        /// The value used.
        clamped: f64,
    },
    /// The fit produced a non-finite number; the old parameters were kept.
    NonFinite {
        /// Which part.
        part: Part,
    },
}

impl std::fmt::Display for Degeneracy {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Degeneracy::DeadComponent {
                component,
                weight,
                copied_from,
            } => write!(
                f,
                "component {component} had weight {weight:.2e}: re-seeded from component {copied_from}"
            ),
            Degeneracy::RotationUndetermined { part } => {
                write!(f, "{part}: no rotational information, rotation kept")
            }
            Degeneracy::ScaleClamped { part, raw, clamped } => {
                write!(f, "{part}: scale {raw:.3e} clamped to {clamped:.3e}")
            }
            Degeneracy::NonFinite { part } => {
                write!(f, "{part}: non-finite fit, parameters kept")
            }
        }
    }
}

/// Weighted sums over (target, source) pairs for a similitude fit `y ≈ s·R·b + t`, where
/// each target is weighted by ω and contributes its plain responsibility to the count N.
#[derive(Clone, Debug, PartialEq)]
pub struct PairSums {
    /// `N = Σ r` (the count in the scale equation).
    pub count: f64,
    /// `Σ ω`.
    pub omega: f64,
    /// `Σ ω·y`.
    pub sy: DVector<f64>,
    /// `Σ ω·‖y‖²`.
    pub syy: f64,
    /// `Σ ω·b`.
    pub sb: DVector<f64>,
    /// `Σ ω·‖b‖²`.
    pub sbb: f64,
    /// `Σ ω·y·bᵀ`.
    pub syb: DMatrix<f64>,
}

impl PairSums {
    /// Empty sums in dimension `h`.
    pub fn new(h: usize) -> Self {
        PairSums {
            count: 0.0,
            omega: 0.0,
            sy: DVector::zeros(h),
            syy: 0.0,
            sb: DVector::zeros(h),
            sbb: 0.0,
            syb: DMatrix::zeros(h, h),
        }
    }

    /// Adds a group of targets sharing one source `b`: their plain mass `count`, and their
    /// sums `Σ r·y`, `Σ r·‖y‖²`, all to be weighted by `1/var`.
    pub fn add_group(&mut self, count: f64, sum_y: &[f64], sum_yy: f64, b: &[f64], var: f64) {
        if count <= 0.0 {
            return;
        }
        let f = 1.0 / var;
        let om = count * f;
        self.count += count;
        self.omega += om;
        self.syy += sum_yy * f;
        let bb: f64 = b.iter().map(|v| v * v).sum();
        self.sbb += om * bb;
        let h = b.len();
        for i in 0..h {
            let yi = sum_y[i] * f;
            self.sy[i] += yi;
            self.sb[i] += om * b[i];
            for j in 0..h {
                self.syb[(i, j)] += yi * b[j];
            }
        }
    }

    /// Adds explicit pairs `(y, b)` with responsibility `r` and variance factor `var`.
    pub fn add_pair(&mut self, r: f64, y: &[f64], b: &[f64], var: f64) {
        let yy: f64 = y.iter().map(|v| v * v).sum();
        let sy: Vec<f64> = y.iter().map(|v| v * r).collect();
        self.add_group(r, &sy, r * yy, b, var);
    }

    /// The EM objective of a similitude on these pairs, up to constants:
    /// `−N·H·ln s − Σ ω ‖y − s·R·b − t‖² / (2 s²)`.
    pub fn objective(&self, sim: &Similitude) -> f64 {
        let h = self.sy.len() as f64;
        let (s, r, t) = (sim.s, &sim.r, &sim.t);
        // Σ ω‖y − s R b − t‖² expanded in the stored sums.
        let rb_sum = r * &self.sb; // Σ ω R b
        let cross = (r.transpose() * &self.syb).trace(); // Σ ω yᵀ R b
        let sq = self.syy + s * s * self.sbb + self.omega * t.dot(t)
            - 2.0 * s * cross
            - 2.0 * t.dot(&self.sy)
            + 2.0 * s * t.dot(&rb_sum);
        -self.count * h * s.ln() - sq / (2.0 * s * s)
    }
}

/// The result of a weighted similitude fit.
#[derive(Clone, Debug, PartialEq)]
pub struct SimilitudeFit {
    /// The fitted map.
    pub sim: Similitude,
    /// Whether the cross-covariance determined the rotation (else the old one was kept).
    pub rotation_determined: bool,
    /// `Some((raw, used))` when the scale was clamped.
    pub scale_clamped: Option<(f64, f64)>,
}

/// The proper rotation R maximising `tr(Rᵀ·C)`: `U·diag(1, …, 1, det(U·Vᵀ))·Vᵀ`, the sign
/// going on the smallest singular value. `None` if the SVD does not converge or `C` is not
/// finite.
pub fn proper_rotation(c: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    if !c.is_square() || c.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let h = c.nrows();
    let svd = c.clone().try_svd(true, true, 1e-15, 10_000)?;
    let u = svd.u?;
    let vt = svd.v_t?;
    let det = (&u * &vt).determinant();
    let smallest = svd
        .singular_values
        .iter()
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map(|(i, _)| i)
        .unwrap_or(h - 1);
    let mut d = DVector::from_element(h, 1.0);
    d[smallest] = if det < 0.0 { -1.0 } else { 1.0 };
    Some(&u * DMatrix::from_diagonal(&d) * &vt)
}

/// The orthogonal matrix R (of either determinant) maximising `tr(Rᵀ·C)`: `U·Vᵀ` from the
/// SVD of `C` (the polar factor). `None` if the SVD does not converge or `C` is not finite.
pub fn nearest_orthogonal(c: &DMatrix<f64>) -> Option<DMatrix<f64>> {
    if !c.is_square() || c.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let svd = c.clone().try_svd(true, true, 1e-15, 10_000)?;
    Some(svd.u? * svd.v_t?)
}

/// The positive root of `n·h·s² + b·s − a = 0` (a ≥ 0), cancellation-free.
fn scale_root(n: f64, h: f64, a: f64, b: f64) -> f64 {
    let nh = n * h;
    let disc = (b * b + 4.0 * nh * a).sqrt();
    if b >= 0.0 {
        2.0 * a / (b + disc)
    } else {
        (disc - b) / (2.0 * nh)
    }
}

/// Fits `y ≈ s·R·b + t` to the pairs (closed form, see the module docs); `old_r` is kept
/// when the rotation is undetermined. `None` when there is no mass or a value is non-finite.
pub fn fit_similitude(
    sums: &PairSums,
    old_r: &DMatrix<f64>,
    min_scale: f64,
    max_scale: f64,
    reflections: bool,
) -> Option<SimilitudeFit> {
    let h = sums.sy.len();
    if !(sums.omega > 0.0 && sums.count > 0.0) {
        return None;
    }
    let ybar = &sums.sy / sums.omega;
    let bbar = &sums.sb / sums.omega;
    let a = (sums.syy - sums.omega * ybar.dot(&ybar)).max(0.0);
    let csrc = (sums.sbb - sums.omega * bbar.dot(&bbar)).max(0.0);
    let cross = &sums.syb - (&ybar * bbar.transpose()) * sums.omega;
    let informative = cross.norm() > 1e-10 * (a * csrc).sqrt() && csrc > 0.0 && a > 0.0;
    let (r, determined) = if informative {
        let fitted = if reflections {
            nearest_orthogonal(&cross)
        } else {
            proper_rotation(&cross)
        };
        match fitted {
            Some(r) => (r, true),
            None => (old_r.clone(), false),
        }
    } else {
        (old_r.clone(), false)
    };
    let b = (r.transpose() * &cross).trace();
    let raw = scale_root(sums.count, h as f64, a, b);
    let s = raw.clamp(min_scale, max_scale);
    let scale_clamped = if s != raw || !raw.is_finite() {
        Some((raw, s))
    } else {
        None
    };
    let t = &ybar - (&r * &bbar) * s;
    if !(s.is_finite() && t.iter().all(|v| v.is_finite()) && r.iter().all(|v| v.is_finite())) {
        return None;
    }
    Some(SimilitudeFit {
        sim: Similitude { s, r, t },
        rotation_determined: determined,
        scale_clamped,
    })
}

/// One M-step: new weights, depth weights, components and post-transform from the E-step's
/// statistics. `table` must be the old model's table built with rotations when the update is
/// [`ComponentUpdate::AllPositions`]. `rng` only serves re-seeding dead components.
pub fn maximise<R: Rng + ?Sized>(
    model: &EmModel,
    table: &CodeTable,
    stats: &Statistics,
    cfg: &MStepConfig,
    rng: &mut R,
) -> Result<(EmModel, Vec<Degeneracy>)> {
    let k = model.k();
    let h = model.dim();
    let depth = model.depth();
    if stats.weight.len() != table.len() || stats.dim != h {
        return Err(Error::InvalidInput(
            "statistics do not match the code table (E-step on another model?)".into(),
        ));
    }
    if cfg.update == ComponentUpdate::AllPositions && depth > 0 && table.rotations.is_empty() {
        return Err(Error::InvalidInput(
            "the all-positions update needs a code table built with rotations".into(),
        ));
    }
    let mut notes = Vec::new();
    let total: f64 = stats.weight.iter().sum();
    if !(total > 0.0 && total.is_finite()) {
        return Err(Error::Numerical(format!(
            "the E-step's responsibilities sum to {total}; the points may be far outside the model"
        )));
    }

    // Depth weights.
    let mut depth_weights: Vec<f64> = (0..=depth)
        .map(|d| stats.weight[table.depth_range(d)].iter().sum::<f64>())
        .collect();
    normalise_with_floor(&mut depth_weights);

    // Component weights and the pair sums of every component.
    let mut mass = vec![0.0; k];
    let mut sums: Vec<PairSums> = (0..k).map(|_| PairSums::new(h)).collect();
    let mut sum_y = vec![0.0; h];
    for d in 1..=depth {
        let range = table.depth_range(d);
        let per_level = range.len();
        for (idx, c) in range.enumerate() {
            let w_c = stats.weight[c];
            if w_c <= 0.0 {
                continue;
            }
            let m_c = &stats.sum[c * h..(c + 1) * h];
            let q_c = stats.sum_sq[c];
            match cfg.update {
                ComponentUpdate::Outermost => {
                    let sub = per_level / k; // K^{d−1}
                    let kk = idx / sub;
                    let inner = table.depth_range(d - 1).start + idx % sub;
                    mass[kk] += w_c;
                    let var = (2.0 * table.log_scales[inner]).exp();
                    sums[kk].add_group(w_c, m_c, q_c, table.mean(inner), var);
                }
                ComponentUpdate::AllPositions => {
                    // Position j (1-based) holds symbol (idx / K^{d−j}) mod K; the prefix is
                    // the first j−1 symbols, the suffix the last d−j.
                    for j in 1..=d {
                        let pow_suffix = k.pow((d - j) as u32);
                        let kk = (idx / pow_suffix) % k;
                        let prefix = table.depth_range(j - 1).start + idx / (pow_suffix * k);
                        let suffix = table.depth_range(d - j).start + idx % pow_suffix;
                        mass[kk] += w_c;
                        // y' = Qᵀ(y − α)/a for the prefix similitude (a, Q, α).
                        let a = table.log_scales[prefix].exp();
                        let alpha = table.mean(prefix);
                        let q = table.rotation(prefix);
                        let mut am = 0.0;
                        let mut aa = 0.0;
                        for e in 0..h {
                            am += alpha[e] * m_c[e];
                            aa += alpha[e] * alpha[e];
                        }
                        for (col, sy) in sum_y.iter_mut().enumerate() {
                            let mut acc = 0.0;
                            for row in 0..h {
                                acc += q[row * h + col] * (m_c[row] - w_c * alpha[row]);
                            }
                            *sy = acc / a;
                        }
                        let sum_yy = ((q_c - 2.0 * am + w_c * aa) / (a * a)).max(0.0);
                        let var = (2.0 * table.log_scales[suffix]).exp();
                        sums[kk].add_group(w_c, &sum_y, sum_yy, table.mean(suffix), var);
                    }
                }
            }
        }
    }
    let mut weights = mass.clone();
    let mass_total: f64 = weights.iter().sum();
    if mass_total > 0.0 {
        normalise_with_floor(&mut weights);
    } else {
        // Depth 0 only (or all mass at depth 0): the weights carry no information.
        weights = model.weights.clone();
    }

    // Components.
    let mut components = model.components.clone();
    let mut alive = vec![true; k];
    for kk in 0..k {
        if weights[kk] < cfg.dead_weight || sums[kk].omega <= 0.0 {
            alive[kk] = false;
            continue;
        }
        match fit_similitude(
            &sums[kk],
            &model.components[kk].r,
            cfg.min_scale,
            cfg.max_scale,
            cfg.reflections,
        ) {
            Some(fit) => {
                if !fit.rotation_determined && depth > 1 {
                    notes.push(Degeneracy::RotationUndetermined {
                        part: Part::Component(kk),
                    });
                }
                if let Some((raw, clamped)) = fit.scale_clamped {
                    notes.push(Degeneracy::ScaleClamped {
                        part: Part::Component(kk),
                        raw,
                        clamped,
                    });
                }
                components[kk] = fit.sim;
            }
            None => notes.push(Degeneracy::NonFinite {
                part: Part::Component(kk),
            }),
        }
    }
    if depth > 0 && mass_total > 0.0 {
        for kk in 0..k {
            if alive[kk] {
                continue;
            }
            let Some(src) = (0..k)
                .filter(|&j| alive[j])
                .max_by(|&a, &b| weights[a].total_cmp(&weights[b]))
            else {
                return Err(Error::Numerical(
                    "every component lost its responsibility; restart from another initialisation"
                        .into(),
                ));
            };
            notes.push(Degeneracy::DeadComponent {
                component: kk,
                weight: weights[kk],
                copied_from: src,
            });
            components[kk] = perturbed(&components[src], cfg.split_noise, rng);
            let half = 0.5 * (weights[src] + weights[kk]);
            weights[src] = half;
            weights[kk] = half;
            alive[kk] = true;
        }
    }

    let interim = EmModel {
        components,
        weights,
        depth_weights,
        post: model.post.clone(),
    };
    let next = with_fitted_post(interim, stats, &mut notes);
    next.validate()?;
    Ok((next, notes))
}

/// The M-step's exact blocks only: depth weights, weights counted per occurrence, and the
/// post-transform, with the components kept. Each block maximises the EM objective given the
/// others, so the likelihood cannot decrease (the fallback of [`MStepConfig::monotone`]).
pub fn maximise_exact_blocks(
    model: &EmModel,
    table: &CodeTable,
    stats: &Statistics,
) -> Result<(EmModel, Vec<Degeneracy>)> {
    let depth = model.depth();
    let k = model.k();
    let mut depth_weights: Vec<f64> = (0..=depth)
        .map(|d| stats.weight[table.depth_range(d)].iter().sum::<f64>())
        .collect();
    normalise_with_floor(&mut depth_weights);
    let mut mass = vec![0.0; k];
    for d in 1..=depth {
        for (idx, c) in table.depth_range(d).enumerate() {
            let mut rest = idx;
            for _ in 0..d {
                mass[rest % k] += stats.weight[c];
                rest /= k;
            }
        }
    }
    let mut weights = mass;
    if weights.iter().sum::<f64>() > 0.0 {
        normalise_with_floor(&mut weights);
    } else {
        weights = model.weights.clone();
    }
    let mut notes = Vec::new();
    let interim = EmModel {
        components: model.components.clone(),
        weights,
        depth_weights,
        post: model.post.clone(),
    };
    let next = with_fitted_post(interim, stats, &mut notes);
    next.validate()?;
    Ok((next, notes))
}

/// `model` with its post-transform refitted (`P ← P ∘ G`, G the weighted similitude fit of
/// every code's mean to its points, in the frame the statistics were taken in).
fn with_fitted_post(
    mut model: EmModel,
    stats: &Statistics,
    notes: &mut Vec<Degeneracy>,
) -> EmModel {
    let h = model.dim();
    let table = CodeTable::build(&model, false);
    let mut post_sums = PairSums::new(h);
    for c in 0..table.len() {
        let w_c = stats.weight[c];
        if w_c <= 0.0 {
            continue;
        }
        let var = (2.0 * table.log_scales[c]).exp();
        post_sums.add_group(
            w_c,
            &stats.sum[c * h..(c + 1) * h],
            stats.sum_sq[c],
            table.mean(c),
            var,
        );
    }
    let identity = DMatrix::<f64>::identity(h, h);
    // The whole model frame turns, never mirrors: a mirror image of the data is the
    // components' to express.
    match fit_similitude(&post_sums, &identity, 1e-9, 1e9, false) {
        Some(fit) => {
            if !fit.rotation_determined && model.depth() > 0 {
                notes.push(Degeneracy::RotationUndetermined { part: Part::Post });
            }
            if let Some((raw, clamped)) = fit.scale_clamped {
                notes.push(Degeneracy::ScaleClamped {
                    part: Part::Post,
                    raw,
                    clamped,
                });
            }
            model.post = model.post.compose(&fit.sim);
        }
        None => notes.push(Degeneracy::NonFinite { part: Part::Post }),
    }
    model
}

/// Normalises to sum 1 with every entry at least [`PROB_FLOOR`].
fn normalise_with_floor(p: &mut [f64]) {
    let s: f64 = p.iter().sum();
    let n = p.len() as f64;
    for v in p.iter_mut() {
        *v = if s > 0.0 { *v / s } else { 1.0 / n };
        *v = v.max(PROB_FLOOR);
    }
    let s: f64 = p.iter().sum();
    p.iter_mut().for_each(|v| *v /= s);
}

/// A copy of `s` with its translation jittered (std `noise·s.s`) and a small random rotation.
fn perturbed<R: Rng + ?Sized>(s: &Similitude, noise: f64, rng: &mut R) -> Similitude {
    let h = s.dim();
    let g = DMatrix::<f64>::from_fn(h, h, |i, j| {
        let e: f64 = rng.sample(StandardNormal);
        (if i == j { 1.0 } else { 0.0 }) + noise * e
    });
    let small = proper_rotation(&g).unwrap_or_else(|| DMatrix::identity(h, h));
    let t = DVector::from_fn(h, |i, _| {
        let e: f64 = rng.sample(StandardNormal);
        s.t[i] + noise * s.s * e
    });
    Similitude {
        s: s.s,
        r: &s.r * small,
        t,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_xoshiro::Xoshiro256PlusPlus;

    #[test]
    fn exact_pairs_give_back_the_similitude() {
        // Targets made by a known similitude from scattered sources: the fit recovers it.
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
        for h in [1, 2, 3, 5] {
            let truth = Similitude {
                s: 0.37,
                r: ifslab::model::similitude::random_rotation(h, &mut rng),
                t: DVector::from_fn(h, |i, _| 0.1 * i as f64 - 0.2),
            };
            let mut sums = PairSums::new(h);
            for _ in 0..50 {
                let b = DVector::<f64>::from_fn(h, |_, _| rng.sample(StandardNormal));
                let y = truth.apply(&b);
                sums.add_pair(1.0, y.as_slice(), b.as_slice(), 1e-6);
            }
            let fit = fit_similitude(&sums, &DMatrix::identity(h, h), 1e-9, 10.0, false).unwrap();
            // With a tiny variance the likelihood optimum is the exact map, up to O(var).
            assert!((fit.sim.s - truth.s).abs() < 1e-4, "h={h} s={}", fit.sim.s);
            assert!((fit.sim.r - &truth.r).amax() < 1e-6);
            assert!((fit.sim.t - &truth.t).amax() < 1e-4);
        }
    }

    #[test]
    fn scale_root_solves_its_equation() {
        for (n, h, a, b) in [
            (10.0, 2.0, 3.0, 1.5),
            (4.0, 3.0, 0.5, -2.0),
            (1.0, 1.0, 1e-9, 5.0),
        ] {
            let s = scale_root(n, h, a, b);
            let res = n * h * s * s + b * s - a;
            assert!(
                s > 0.0 && res.abs() < 1e-9 * (1.0 + a),
                "{n} {h} {a} {b}: {s} {res}"
            );
        }
    }

    #[test]
    fn the_nearest_orthogonal_map_may_reflect_where_a_rotation_may_not() {
        // C = a mirror (x ↦ −x) scaled: the best rotation is not it, the best orthogonal is.
        let c = DMatrix::from_row_slice(2, 2, &[-2.0, 0.0, 0.0, 1.5]);
        let o = nearest_orthogonal(&c).unwrap();
        assert!((o - DMatrix::from_row_slice(2, 2, &[-1.0, 0.0, 0.0, 1.0])).amax() < 1e-12);
        let r = proper_rotation(&c).unwrap();
        assert!((r.determinant() - 1.0).abs() < 1e-12);
    }
}
