//! The EM model: K similitudes `S_k(x) = s_k·R_k·x + t_k` with weights `w_k`, depth weights
//! `v_0 … v_D` and a post-transform similitude `P`.
//!
//! A code `c = (c_1, …, c_d)` names the composition `S_c = S_{c_1} ∘ … ∘ S_{c_d}` (the last
//! symbol is applied first); the empty code is the identity. The model's density is the
//! mixture, over every code of length 0 … D, of the standard Gaussian pushed through
//! `P ∘ S_c`:
//!
//! ```text
//! p(x) = Σ_{|c| ≤ D} v_{|c|} · Π_j w_{c_j} · N(x | P(S_c(0)), (s_P·s_c)² I),   s_c = Π_j s_{c_j}
//! ```
//!
//! so a model of depth D is a Gaussian mixture with (K^{D+1} − 1)/(K − 1) tied components.
//! [`CodeTable`] enumerates them once per iteration, building every depth from the one
//! below (`S_{k·c'} = S_k ∘ S_{c'}`), which costs O(H²) per code.
//!
//! In data space the IFS is the conjugate `T_k = P ∘ S_k ∘ P⁻¹` (same scale, rotation
//! `R_P·R_k·R_Pᵀ`); that is the code written to code files, with the model-frame parts,
//! depth weights and post-transform kept in `meta.em` so the model reads back exactly.
//!
//! ## References
//! - P. Bloem and S. de Rooij, *An Expectation-Maximization Algorithm for the Fractal
//!   Inverse Problem*, arXiv:1706.03149, 2017.

use nalgebra::{DMatrix, DVector};
use rand::Rng;
use rand_distr::StandardNormal;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use ifslab::chaos::trajectory_rng;
use ifslab::model::{AffineN, IfsCode, Similitude};

use crate::error::{Error, Result};
use crate::problems::em::data::PointSet;

/// Probability floor for weights and depth weights: keeps every log finite.
pub const PROB_FLOOR: f64 = 1e-12;

/// An IFS of similitudes with depth weights and a post-transform: the EM model.
#[derive(Clone, Debug, PartialEq)]
pub struct EmModel {
    /// The K components, in the model frame.
    pub components: Vec<Similitude>,
    /// Component weights w (sum 1).
    pub weights: Vec<f64>,
    /// Depth weights v_0 … v_D (sum 1).
    pub depth_weights: Vec<f64>,
    /// The post-transform P from the model frame to data space.
    pub post: Similitude,
}

impl EmModel {
    /// A model from its parts, validated: shapes, finiteness, probabilities.
    pub fn new(
        components: Vec<Similitude>,
        weights: Vec<f64>,
        depth_weights: Vec<f64>,
        post: Similitude,
    ) -> Result<Self> {
        let m = EmModel {
            components,
            weights,
            depth_weights,
            post,
        };
        m.validate()?;
        Ok(m)
    }

    /// Checks shapes, finiteness, positive scales and normalised probabilities.
    pub fn validate(&self) -> Result<()> {
        let h = self.post.dim();
        if self.components.is_empty() {
            return Err(Error::param("k", "the model needs at least one component"));
        }
        if self.weights.len() != self.components.len() {
            return Err(Error::InvalidInput(format!(
                "{} weights for {} components",
                self.weights.len(),
                self.components.len()
            )));
        }
        if self.depth_weights.is_empty() {
            return Err(Error::param(
                "depth",
                "at least one depth weight (depth 0) is needed",
            ));
        }
        let check_sim = |what: String, s: &Similitude| -> Result<()> {
            if s.dim() != h || s.r.nrows() != h || s.r.ncols() != h {
                return Err(Error::InvalidInput(format!(
                    "{what} is {}-dimensional, the model is {h}-dimensional",
                    s.dim()
                )));
            }
            if !(s.s.is_finite() && s.s > 0.0)
                || s.r.iter().chain(s.t.iter()).any(|v| !v.is_finite())
            {
                return Err(Error::Numerical(format!(
                    "{what} has a non-finite or non-positive part"
                )));
            }
            Ok(())
        };
        check_sim("the post-transform".into(), &self.post)?;
        for (k, c) in self.components.iter().enumerate() {
            check_sim(format!("component {k}"), c)?;
        }
        for (name, p) in [
            ("weights", &self.weights),
            ("depth_weights", &self.depth_weights),
        ] {
            if p.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(Error::InvalidInput(format!(
                    "{name} must be finite and ≥ 0: {p:?}"
                )));
            }
            let sum: f64 = p.iter().sum();
            if (sum - 1.0).abs() > 1e-6 {
                return Err(Error::InvalidInput(format!("{name} sum to {sum}, not 1")));
            }
        }
        Ok(())
    }

    /// Dimension H.
    pub fn dim(&self) -> usize {
        self.post.dim()
    }

    /// Number of components K.
    pub fn k(&self) -> usize {
        self.components.len()
    }

    /// Maximum depth D.
    pub fn depth(&self) -> usize {
        self.depth_weights.len() - 1
    }

    /// Mean depth Σ d·v_d: how deep the model explains the data.
    pub fn mean_depth(&self) -> f64 {
        self.depth_weights
            .iter()
            .enumerate()
            .map(|(d, v)| d as f64 * v)
            .sum()
    }

    /// The weight of the deepest level, v_D.
    pub fn deepest_weight(&self) -> f64 {
        *self
            .depth_weights
            .last()
            .expect("validated: at least depth 0")
    }

    /// The paper's convergence criterion: at least `threshold` of the depth weight on depth D.
    pub fn is_converged(&self, threshold: f64) -> bool {
        self.deepest_weight() >= threshold
    }

    /// The same model at another depth, with uniform depth weights over 0 … `depth`.
    pub fn with_depth(&self, depth: usize) -> EmModel {
        EmModel {
            depth_weights: vec![1.0 / (depth + 1) as f64; depth + 1],
            ..self.clone()
        }
    }

    /// Number of free parameters: per component a scale, H(H−1)/2 rotation angles, H
    /// translations; K − 1 weights, D depth weights, and the post-transform.
    pub fn parameter_count(&self) -> usize {
        let h = self.dim();
        let sim = 1 + h * (h - 1) / 2 + h;
        self.k() * sim + (self.k() - 1) + self.depth() + sim
    }

    /// Every code up to depth D, composed (see [`CodeTable`]).
    pub fn code_table(&self) -> CodeTable {
        CodeTable::build(self, false)
    }

    /// Mean μ and RMS spread σ (per coordinate) of the IFS's invariant measure, in the model
    /// frame: μ solves `μ = Σ_k w_k S_k(μ)`, and the second moment about μ is
    /// `M = Σ_k w_k ‖S_k(μ) − μ‖² / (1 − Σ_k w_k s_k²)`, σ = √(M/H). Needs every `s_k < 1`
    /// (then `I − Σ w_k s_k R_k` is invertible); `None` otherwise.
    pub fn invariant_moments(&self) -> Option<(DVector<f64>, f64)> {
        let h = self.dim();
        let mut a = DMatrix::<f64>::identity(h, h);
        let mut b = DVector::<f64>::zeros(h);
        let mut contraction = 0.0;
        for (c, w) in self.components.iter().zip(&self.weights) {
            a -= &c.r * (c.s * w);
            b += &c.t * *w;
            contraction += w * c.s * c.s;
        }
        if contraction.is_nan() || contraction >= 1.0 || self.components.iter().any(|c| c.s >= 1.0)
        {
            return None;
        }
        let mu = a.lu().solve(&b)?;
        let spread: f64 = self
            .components
            .iter()
            .zip(&self.weights)
            .map(|(c, w)| w * (c.apply(&mu) - &mu).norm_squared())
            .sum();
        let sigma = (spread / (1.0 - contraction) / h as f64).sqrt();
        (sigma.is_finite() && mu.iter().all(|v| v.is_finite())).then_some((mu, sigma))
    }

    /// The same IFS in data space with the model frame moved so that the depth-0 Gaussian
    /// `P(N(0, I))` has the invariant measure's mean and spread: `P ← P ∘ G`,
    /// `S_k ← G⁻¹ ∘ S_k ∘ G` with `G(x) = σ·x + μ` (see [`EmModel::invariant_moments`]).
    ///
    /// Every code's Gaussian is the base Gaussian pushed through the data-space maps, so the
    /// base sets the width of the deepest Gaussians. After a shallow pre-selection that width
    /// can be far from the attractor's, and EM at depth D then settles with depth weight
    /// split between D and D − 1 although the maps are right; matching the base to the
    /// attractor's moments removes that equilibrium. Returns the model unchanged when the
    /// moments are undefined (a scale ≥ 1) or degenerate (σ = 0).
    pub fn recentred(&self) -> EmModel {
        let Some((mu, sigma)) = self.invariant_moments() else {
            return self.clone();
        };
        if sigma.is_nan() || sigma <= 0.0 {
            return self.clone();
        }
        let h = self.dim();
        let g = Similitude {
            s: sigma,
            r: DMatrix::identity(h, h),
            t: mu,
        };
        let gi = inverse(&g);
        EmModel {
            components: self
                .components
                .iter()
                .map(|c| gi.compose(&c.compose(&g)))
                .collect(),
            post: self.post.compose(&g),
            ..self.clone()
        }
    }

    /// The conjugated maps `P ∘ S_k ∘ P⁻¹`: the IFS in data space.
    pub fn data_space_maps(&self) -> Vec<Similitude> {
        let p = &self.post;
        let inv = inverse(p);
        self.components
            .iter()
            .map(|c| p.compose(&c.compose(&inv)))
            .collect()
    }

    /// Mean log-likelihood per point (nats).
    pub fn mean_log_likelihood(&self, points: &PointSet) -> Result<f64> {
        if points.is_empty() {
            return Err(Error::InvalidInput("no points to evaluate".into()));
        }
        Ok(self.log_likelihood(points)? / points.len() as f64)
    }

    pub(crate) fn check_points(&self, points: &PointSet) -> Result<()> {
        if points.dim() != self.dim() {
            return Err(Error::InvalidInput(format!(
                "the points are {}-dimensional but the model is {}-dimensional",
                points.dim(),
                self.dim()
            )));
        }
        Ok(())
    }

    /// `n` independent samples from the model's own (finite-depth) distribution: a depth
    /// d ~ v, d maps drawn from w applied to a standard normal point, then P. Seeded and
    /// independent of the thread count (one generator per block of 1024 samples).
    pub fn sample(&self, n: usize, seed: u64) -> Result<PointSet> {
        let h = self.dim();
        if n == 0 {
            return Err(Error::param("n", "ask for at least one sample"));
        }
        let cum_w = cumulative(&self.weights);
        let cum_v = cumulative(&self.depth_weights);
        const BLOCK: usize = 1024;
        let mut data = vec![0.0; n * h];
        data.par_chunks_mut(BLOCK * h)
            .enumerate()
            .for_each(|(b, out)| {
                let mut rng = trajectory_rng(seed, b as u64);
                let mut z = DVector::<f64>::zeros(h);
                for p in out.chunks_exact_mut(h) {
                    for v in z.iter_mut() {
                        *v = rng.sample(StandardNormal);
                    }
                    let d = pick(&cum_v, rng.random::<f64>());
                    for _ in 0..d {
                        let k = pick(&cum_w, rng.random::<f64>());
                        z = self.components[k].apply(&z);
                    }
                    let x = self.post.apply(&z);
                    p.copy_from_slice(x.as_slice());
                }
            });
        PointSet::new(h, data)
    }

    /// The fitted IFS as a code file: the conjugated maps in data space, the weights as
    /// probabilities, and the full model under `meta.em` (read back by [`EmModel::from_code`]).
    pub fn to_code(&self, name: Option<&str>) -> Result<IfsCode> {
        let maps: Vec<AffineN> = self
            .data_space_maps()
            .iter()
            .map(Similitude::to_affine)
            .collect();
        let record = ModelRecord {
            depth: self.depth(),
            depth_weights: self.depth_weights.clone(),
            weights: self.weights.clone(),
            post: SimRecord::from(&self.post),
            components: self.components.iter().map(SimRecord::from).collect(),
            mean_depth: self.mean_depth(),
        };
        let mut meta = serde_json::Map::new();
        meta.insert("strategy".into(), "em (Bloem & de Rooij)".into());
        meta.insert(
            "em".into(),
            serde_json::to_value(&record).map_err(|e| Error::Numerical(e.to_string()))?,
        );
        let code = IfsCode {
            name: name.map(str::to_owned),
            maps,
            probabilities: Some(self.weights.clone()),
            framing: None,
            allow_non_contractive: self.components.iter().any(|c| c.s >= 1.0),
            meta,
        };
        code.validate()?;
        Ok(code)
    }

    /// Reads a model back from a code file written by [`EmModel::to_code`]. A code without
    /// `meta.em` is taken as an IFS of similitudes in data space (post-transform = identity)
    /// with all depth weight on depth `default_depth`.
    pub fn from_code(code: &IfsCode, default_depth: usize) -> Result<Self> {
        if let Some(v) = code.meta.get("em") {
            let rec: ModelRecord = serde_json::from_value(v.clone()).map_err(|e| {
                Error::InvalidInput(format!("the code's `meta.em` block does not parse: {e}"))
            })?;
            let post = rec.post.to_similitude()?;
            let components = rec
                .components
                .iter()
                .map(SimRecord::to_similitude)
                .collect::<Result<Vec<_>>>()?;
            if rec.depth_weights.len() != rec.depth + 1 {
                return Err(Error::InvalidInput(format!(
                    "`meta.em`: {} depth weights for depth {}",
                    rec.depth_weights.len(),
                    rec.depth
                )));
            }
            return EmModel::new(components, rec.weights, rec.depth_weights, post);
        }
        let h = code.dim();
        let components = code
            .maps
            .iter()
            .enumerate()
            .map(|(i, m)| {
                Similitude::from_affine(m, 1e-6)
                    .map_err(|e| Error::InvalidInput(format!("map {i} is not a similitude: {e}")))
            })
            .collect::<Result<Vec<_>>>()?;
        let k = components.len();
        let weights = code
            .probabilities
            .clone()
            .unwrap_or_else(|| vec![1.0 / k as f64; k]);
        let mut depth_weights = vec![0.0; default_depth + 1];
        depth_weights[default_depth] = 1.0;
        EmModel::new(components, weights, depth_weights, Similitude::identity(h))
    }
}

/// The inverse of a similitude: `x ↦ (1/s)·Rᵀ·(x − t)`.
pub fn inverse(s: &Similitude) -> Similitude {
    let rt = s.r.transpose();
    let t = -(&rt * &s.t) / s.s;
    Similitude {
        s: 1.0 / s.s,
        r: rt,
        t,
    }
}

fn cumulative(p: &[f64]) -> Vec<f64> {
    let mut acc = 0.0;
    p.iter()
        .map(|v| {
            acc += v;
            acc
        })
        .collect()
}

fn pick(cum: &[f64], u: f64) -> usize {
    let total = *cum.last().unwrap_or(&1.0);
    let x = u * total;
    cum.iter().position(|&c| x < c).unwrap_or(cum.len() - 1)
}

/// A similitude as stored in `meta.em`: scale, row-major rotation, translation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimRecord {
    /// Scale.
    pub s: f64,
    /// Rotation rows.
    pub r: Vec<Vec<f64>>,
    /// Translation.
    pub t: Vec<f64>,
}

impl From<&Similitude> for SimRecord {
    fn from(s: &Similitude) -> Self {
        let h = s.dim();
        SimRecord {
            s: s.s,
            r: (0..h)
                .map(|i| (0..h).map(|j| s.r[(i, j)]).collect())
                .collect(),
            t: s.t.iter().copied().collect(),
        }
    }
}

impl SimRecord {
    /// Back to a similitude (shape and rotation checked).
    pub fn to_similitude(&self) -> Result<Similitude> {
        let h = self.t.len();
        if self.r.len() != h || self.r.iter().any(|row| row.len() != h) {
            return Err(Error::InvalidInput(format!(
                "`meta.em`: rotation must be {h}×{h} to match a translation of length {h}"
            )));
        }
        let r = DMatrix::from_fn(h, h, |i, j| self.r[i][j]);
        Ok(Similitude::new(
            self.s,
            r,
            DVector::from_vec(self.t.clone()),
        )?)
    }
}

/// The `meta.em` block of a fitted code.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModelRecord {
    /// Maximum depth D.
    pub depth: usize,
    /// v_0 … v_D.
    pub depth_weights: Vec<f64>,
    /// Component weights.
    pub weights: Vec<f64>,
    /// Post-transform (model frame → data space).
    pub post: SimRecord,
    /// Components in the model frame.
    pub components: Vec<SimRecord>,
    /// Σ d·v_d, for readers of the file.
    pub mean_depth: f64,
}

/// Every code of length 0 … D, composed: the Gaussian mixture a model stands for.
///
/// Codes are stored depth by depth; within depth d, code `(c_1, …, c_d)` sits at
/// `offset(d) + Σ_j c_j·K^{d−j}` (the outermost symbol most significant), so the child
/// `k·c'` of a depth-(d−1) code `c'` sits at `offset(d) + k·K^{d−1} + index(c')`, the
/// prefix of length p of a code is `index / K^{d−p}` and its suffix of length q is
/// `index mod K^q`.
#[derive(Clone, Debug)]
pub struct CodeTable {
    k: usize,
    depth: usize,
    dim: usize,
    offsets: Vec<usize>,
    /// S_c(0) in the model frame, H numbers per code.
    pub means: Vec<f64>,
    /// ln s_c.
    pub log_scales: Vec<f64>,
    /// ln v_{|c|} + Σ_j ln w_{c_j}.
    pub log_priors: Vec<f64>,
    /// Σ_j ln w_{c_j} (the prior within its depth).
    pub log_word_priors: Vec<f64>,
    /// ln v_d for d = 0..=D (floored as in `log_priors`).
    pub log_depth_weights: Vec<f64>,
    /// R_c row-major for codes of depth < D (the prefixes the M-step needs); empty unless asked.
    pub rotations: Vec<f64>,
}

impl CodeTable {
    /// Enumerates the codes of `model`; with `with_rotations`, also the composed rotations
    /// of all codes shorter than D.
    pub fn build(model: &EmModel, with_rotations: bool) -> Self {
        let k = model.k();
        let depth = model.depth();
        let h = model.dim();
        let mut offsets = Vec::with_capacity(depth + 2);
        let mut n = 0usize;
        let mut level = 1usize;
        for _ in 0..=depth {
            offsets.push(n);
            n += level;
            level *= k;
        }
        offsets.push(n);
        let log_w: Vec<f64> = model
            .weights
            .iter()
            .map(|w| w.max(PROB_FLOOR).ln())
            .collect();
        let log_v: Vec<f64> = model
            .depth_weights
            .iter()
            .map(|v| v.max(PROB_FLOOR).ln())
            .collect();
        let mut means = vec![0.0; n * h];
        let mut log_scales = vec![0.0; n];
        // Within-depth prior Σ ln w, the depth term is added at the end.
        let mut code_w = vec![0.0; n];
        let n_rot = if with_rotations && depth > 0 {
            offsets[depth]
        } else {
            0
        };
        let mut rotations = vec![0.0; n_rot * h * h];
        if n_rot > 0 {
            for i in 0..h {
                rotations[i * h + i] = 1.0;
            }
        }
        let comps: Vec<(f64, Vec<f64>, Vec<f64>, f64)> = model
            .components
            .iter()
            .map(|c| {
                let r: Vec<f64> = (0..h * h).map(|e| c.r[(e / h, e % h)]).collect();
                (c.s, r, c.t.iter().copied().collect(), c.s.ln())
            })
            .collect();
        for d in 1..=depth {
            let parent_n = offsets[d] - offsets[d - 1];
            for (kk, (s, r, t, ls)) in comps.iter().enumerate() {
                for j in 0..parent_n {
                    let parent = offsets[d - 1] + j;
                    let child = offsets[d] + kk * parent_n + j;
                    let (pm, cm) = (parent * h, child * h);
                    for a in 0..h {
                        let mut acc = 0.0;
                        for b in 0..h {
                            acc += r[a * h + b] * means[pm + b];
                        }
                        means[cm + a] = s * acc + t[a];
                    }
                    log_scales[child] = ls + log_scales[parent];
                    code_w[child] = log_w[kk] + code_w[parent];
                    if child < n_rot {
                        let (pr, cr) = (parent * h * h, child * h * h);
                        for a in 0..h {
                            for b in 0..h {
                                let mut acc = 0.0;
                                for e in 0..h {
                                    acc += r[a * h + e] * rotations[pr + e * h + b];
                                }
                                rotations[cr + a * h + b] = acc;
                            }
                        }
                    }
                }
            }
        }
        let mut log_priors = code_w.clone();
        for d in 0..=depth {
            for lp in &mut log_priors[offsets[d]..offsets[d + 1]] {
                *lp += log_v[d];
            }
        }
        CodeTable {
            k,
            depth,
            dim: h,
            offsets,
            means,
            log_scales,
            log_priors,
            log_word_priors: code_w,
            log_depth_weights: log_v,
            rotations,
        }
    }

    /// Number of codes, (K^{D+1} − 1)/(K − 1).
    pub fn len(&self) -> usize {
        *self.offsets.last().expect("at least depth 0")
    }

    /// Always false: the empty code is always there.
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Number of components K.
    pub fn k(&self) -> usize {
        self.k
    }

    /// Maximum depth D.
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// Dimension H.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Index range of the codes of length `d`.
    pub fn depth_range(&self, d: usize) -> std::ops::Range<usize> {
        self.offsets[d]..self.offsets[d + 1]
    }

    /// Mean of code `c` (model frame).
    pub fn mean(&self, c: usize) -> &[f64] {
        &self.means[c * self.dim..(c + 1) * self.dim]
    }

    /// Composed rotation of code `c` (row-major), for codes shorter than D when built with
    /// rotations.
    pub fn rotation(&self, c: usize) -> &[f64] {
        let hh = self.dim * self.dim;
        &self.rotations[c * hh..(c + 1) * hh]
    }
}
