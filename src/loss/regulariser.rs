//! The chaotic-splatting paper's regulariser on the maps (not on the image).
//!
//! For maps `x ↦ M_i·x + b_i`, `i = 1 … n`, with singular values `σ₁ᵢ ≥ σ₂ᵢ` of `M_i` and
//! `rᵢ = (σ₁ᵢ + 1)/(σ₂ᵢ + 1)` (a stable stand-in for the condition number), the paper's
//! Eq. 6 with its weights `λ_reg = 1e-2`, `λ_cond = 10` is
//!
//! `R = λ_s·Σ_i (σ₁ᵢ² + σ₂ᵢ² + ‖b_i‖²) + λ_c·Σ_i (rᵢ − 1)²`,  `λ_s = λ_reg`, `λ_c = λ_reg·λ_cond = 0.1`
//!
//! ([`ConditionTerm::Paper`], the default). The authors' reference code instead adds
//! `λ_c·(1/n)·Σ_i rᵢ²` ([`ConditionTerm::Reference`]): the mean rather than the sum, and
//! `r²` rather than `(r − 1)²`, which adds the linear push `2λ_c(r − 1)/n` towards
//! similitudes. Both are available; `paper_repro/chaotic_splatting/README.md` compares them.
//! ifslab adds an optional area term `λ_a·Σ_i |det M_i|` (`area_weight`, 0 unless set): the
//! share of the plane the maps' images cover, which a picture blurred or enlarged past its
//! filaments does not bound (a filled code and a filigree with the same outline draw alike),
//! so the term prefers the thinnest code the picture allows — the 3-D fit's `volume` term in
//! the plane. `∂|det M|/∂M = sign(det M)·[[d, −c], [−b, a]]` for `M = [[a, b], [c, d]]`.
//!
//! The first term (weight decay on singular values and offsets) keeps the maps contractive
//! and the attractor near the origin; the condition term pulls each map towards a
//! similitude, whose `r` is 1 (a near-singular map draws as a streak).
//!
//! **Gradient** with respect to `M_i` and `b_i` (what [`Parameterisation::backward`] takes):
//! `Σ_k σ_k² = ‖M‖_F²`, so the first term's gradient is `2λ_s·M` exactly, SVD-free; the
//! offsets give `2λ_s·b`. For a condition term `f(r)` we use `∂σ_k/∂M = u_k v_kᵀ`
//! (`M = U·diag(σ)·Vᵀ`):
//!
//! `∂f/∂M = f′(r)·(u₁v₁ᵀ/(σ₂ + 1) − (σ₁ + 1)/(σ₂ + 1)²·u₂v₂ᵀ)`, with `f′ = 2(r − 1)` (paper)
//! or `2r/n` (reference).
//!
//! **Degenerate maps** (`σ₁ = σ₂`, e.g. a rotation-scaling or the zero matrix): the singular
//! vectors are not unique and `r`, which uses max and min, has a kink. But `r ≥ 1` everywhere
//! with equality exactly when `σ₁ = σ₂`, so such a map is a global minimiser of either
//! condition term and `0` is a valid (the minimum-norm) subgradient: we return it whenever
//! `σ₁ − σ₂ ≤ 1e-12·(1 + σ₁)`. Near-degenerate maps get the formula above, which stays
//! bounded (`|∂r/∂σ_k| ≤ r`) even though the individual `u_k v_kᵀ` turn.
//!
//! [`Parameterisation::backward`]: crate::model::param::Parameterisation::backward
//!
//! ## References
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point
//!   Splatting*, Eurographics 2025 (Eq. 6 and its weights).

use nalgebra::{Matrix2, Vector2};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::model::affine::Affine2;

/// Relative gap below which σ₁ = σ₂ is treated as degenerate.
const DEGENERATE_GAP: f64 = 1e-12;

/// Which condition term the regulariser adds (see the module docs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ConditionTerm {
    /// The paper's Eq. 6: `λ_c·Σ_i (rᵢ − 1)²`.
    #[default]
    Paper,
    /// The reference code's: `λ_c·(1/n)·Σ_i rᵢ²`.
    Reference,
}

/// The paper's map regulariser (see the module docs); also its config section.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Regulariser {
    /// `λ_s`, weight of `Σσ² + Σ‖b‖²` (the paper's λ_reg: 1e-2).
    pub scale_weight: f64,
    /// `λ_c`, weight of the condition term (the paper's λ_reg·λ_cond: 1e-1).
    pub condition_weight: f64,
    /// The paper's condition term or the reference code's.
    pub condition: ConditionTerm,
    /// `λ_a`, weight of `Σ|det M_i|` (ifslab's; 0: off, and then not written, so configs
    /// and run ids from before it are unchanged).
    #[serde(skip_serializing_if = "is_zero")]
    pub area_weight: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

impl Default for Regulariser {
    fn default() -> Self {
        Regulariser {
            scale_weight: 1e-2,
            condition_weight: 1e-1,
            condition: ConditionTerm::Paper,
            area_weight: 0.0,
        }
    }
}

/// The SVD of a 2×2 matrix with singular values sorted, largest first.
fn sorted_svd(m: &Matrix2<f64>) -> (f64, f64, Matrix2<f64>, Matrix2<f64>) {
    let svd = m.svd(true, true);
    // Both were requested, so both are present; the fallbacks keep this panic-free.
    let u = svd.u.unwrap_or_else(Matrix2::identity);
    let v = svd
        .v_t
        .map(|vt| vt.transpose())
        .unwrap_or_else(Matrix2::identity);
    let s = svd.singular_values;
    if s[0] >= s[1] {
        (s[0], s[1], u, v)
    } else {
        let swap = |a: Matrix2<f64>| Matrix2::from_columns(&[a.column(1), a.column(0)]);
        (s[1], s[0], swap(u), swap(v))
    }
}

impl Regulariser {
    /// Checks that both weights are finite and non-negative.
    pub fn validate(&self) -> Result<()> {
        for (name, v) in [
            ("scale_weight", self.scale_weight),
            ("condition_weight", self.condition_weight),
            ("area_weight", self.area_weight),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(Error::param(name, format!("must be ≥ 0, got {v}")));
            }
        }
        Ok(())
    }

    fn check_maps(maps: &[Affine2]) -> Result<()> {
        if maps.is_empty() {
            return Err(Error::Empty(
                "the regulariser needs at least one map".into(),
            ));
        }
        if let Some(i) = maps.iter().position(|m| !m.is_finite()) {
            let v = maps[i]
                .coefficients()
                .into_iter()
                .find(|v| !v.is_finite())
                .unwrap_or(f64::NAN);
            return Err(Error::NonFinite {
                what: "maps".into(),
                location: format!("map {i}"),
                value: v,
            });
        }
        Ok(())
    }

    /// `(f(r), f′(r))` of the condition term for one map of `n`.
    fn condition(&self, r: f64, n: f64) -> (f64, f64) {
        match self.condition {
            ConditionTerm::Paper => ((r - 1.0).powi(2), 2.0 * (r - 1.0)),
            ConditionTerm::Reference => (r * r / n, 2.0 * r / n),
        }
    }

    /// `R(maps)`.
    pub fn value(&self, maps: &[Affine2]) -> Result<f64> {
        self.validate()?;
        Self::check_maps(maps)?;
        let n = maps.len() as f64;
        let (mut scale, mut cond, mut area) = (0.0, 0.0, 0.0);
        for map in maps {
            let (s1, s2) = map.singular_values();
            scale += map.m.norm_squared() + map.b.norm_squared();
            cond += self.condition((s1 + 1.0) / (s2 + 1.0), n).0;
            area += map.m.determinant().abs();
        }
        let r = self.scale_weight * scale + self.condition_weight * cond;
        // Added only when weighted, so the paper's value is bit for bit what it was.
        Ok(if self.area_weight > 0.0 {
            r + self.area_weight * area
        } else {
            r
        })
    }

    /// `(R(maps), ∂R/∂maps)`; each gradient [`Affine2`] holds `∂R/∂M` in `m` and `∂R/∂b` in `b`.
    pub fn value_and_grad(&self, maps: &[Affine2]) -> Result<(f64, Vec<Affine2>)> {
        let value = self.value(maps)?;
        let n = maps.len() as f64;
        let grads = maps
            .iter()
            .map(|map| {
                let mut gm = map.m * (2.0 * self.scale_weight);
                let gb: Vector2<f64> = map.b * (2.0 * self.scale_weight);
                let (s1, s2, u, v) = sorted_svd(&map.m);
                if s1 - s2 > DEGENERATE_GAP * (1.0 + s1) {
                    let r = (s1 + 1.0) / (s2 + 1.0);
                    let df = self.condition_weight * self.condition(r, n).1;
                    // ∂r/∂σ₁ = 1/(σ₂ + 1), ∂r/∂σ₂ = −r/(σ₂ + 1).
                    gm += (u.column(0) * v.column(0).transpose()) * (df / (s2 + 1.0));
                    gm += (u.column(1) * v.column(1).transpose()) * (-df * r / (s2 + 1.0));
                }
                if self.area_weight > 0.0 {
                    let m = &map.m;
                    let sign = m.determinant().signum();
                    let cof = Matrix2::new(m[(1, 1)], -m[(1, 0)], -m[(0, 1)], m[(0, 0)]);
                    gm += cof * (self.area_weight * sign);
                }
                Affine2 { m: gm, b: gb }
            })
            .collect();
        Ok((value, grads))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn similitudes_pay_only_the_scale_term() {
        // A rotation-scaling has σ₁ = σ₂ = s: condition term exactly 1, gradient 2λ_s·M.
        let map = Affine2::similitude(0.5, 0.7, false, [0.2, -0.1]);
        // Paper: (r − 1)² = 0; reference code: r²/n = 1.
        for (condition, cond_value) in [
            (ConditionTerm::Paper, 0.0),
            (ConditionTerm::Reference, 1e-1),
        ] {
            let reg = Regulariser {
                condition,
                ..Regulariser::default()
            };
            let (v, g) = reg.value_and_grad(&[map]).unwrap();
            let expected = 1e-2 * (2.0 * 0.25 + 0.05) + cond_value;
            assert!((v - expected).abs() < 1e-14, "{v} vs {expected}");
            assert!((g[0].m - map.m * 2e-2).norm() < 1e-14);
            assert!((g[0].b - map.b * 2e-2).norm() < 1e-14);
        }
    }

    #[test]
    fn paper_form_is_eq_6_summed_over_maps() {
        // diag(0.6, 0.2) twice: r = 1.6/1.2, Σ(r − 1)² = 2/9; diag(0.5, 0.5): r = 1.
        let a = Affine2::new(0.6, 0.0, 0.0, 0.2, 0.1, 0.0);
        let b = Affine2::new(0.5, 0.0, 0.0, 0.5, 0.0, 0.0);
        let scale = 2.0 * (0.36 + 0.04 + 0.01) + 0.5;
        let paper = Regulariser::default().value(&[a, a, b]).unwrap();
        assert!(
            (paper - (1e-2 * scale + 1e-1 * 2.0 / 9.0)).abs() < 1e-14,
            "{paper}"
        );
        let reference = Regulariser {
            condition: ConditionTerm::Reference,
            ..Regulariser::default()
        }
        .value(&[a, a, b])
        .unwrap();
        let r2 = (1.6f64 / 1.2).powi(2);
        assert!((reference - (1e-2 * scale + 1e-1 * (2.0 * r2 + 1.0) / 3.0)).abs() < 1e-14);
    }

    #[test]
    fn the_area_term_is_the_sum_of_determinants_and_its_gradient_matches_differences() {
        let maps = [
            Affine2::new(0.6, 0.1, -0.2, 0.3, 0.1, 0.0),
            Affine2::new(-0.4, 0.3, 0.2, 0.5, -0.2, 0.3),
            Affine2::new(0.2, -0.5, 0.4, -0.1, 0.0, -0.1),
        ];
        let off = Regulariser::default();
        let on = Regulariser {
            area_weight: 0.3,
            ..off
        };
        let dets: f64 = maps.iter().map(|m| m.m.determinant().abs()).sum();
        let (v, g) = on.value_and_grad(&maps).unwrap();
        assert!((v - off.value(&maps).unwrap() - 0.3 * dets).abs() < 1e-14);
        // Central differences in f64 on every coefficient of every map.
        let h = 1e-6;
        for (i, map) in maps.iter().enumerate() {
            for (k, analytic) in [
                g[i].m[(0, 0)],
                g[i].m[(0, 1)],
                g[i].m[(1, 0)],
                g[i].m[(1, 1)],
            ]
            .into_iter()
            .enumerate()
            {
                let at = |d: f64| {
                    let mut ms = maps;
                    ms[i].m[(k / 2, k % 2)] = map.m[(k / 2, k % 2)] + d;
                    on.value(&ms).unwrap()
                };
                let numeric = (at(h) - at(-h)) / (2.0 * h);
                assert!(
                    (numeric - analytic).abs() < 1e-7,
                    "map {i} entry {k}: {numeric} vs {analytic}"
                );
            }
        }
        // Off, the term is not written: configs and run ids from before it are unchanged.
        let written = |r: Regulariser| serde_json::to_value(r).unwrap();
        assert!(written(off).get("area_weight").is_none());
        assert!(written(on).get("area_weight").is_some());
    }

    #[test]
    fn zero_matrix_is_degenerate_not_nan() {
        let (v, g) = Regulariser::default()
            .value_and_grad(&[Affine2::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0)])
            .unwrap();
        assert_eq!(v, 0.0);
        assert!(g[0].is_finite() && g[0].m.norm() == 0.0);
    }

    #[test]
    fn bad_input_is_refused() {
        let reg = Regulariser::default();
        assert!(reg.value(&[]).is_err());
        let nan = Affine2::new(f64::NAN, 0.0, 0.0, 0.5, 0.0, 0.0);
        assert!(reg.value(&[nan]).unwrap_err().to_string().contains("map 0"));
        let neg = Regulariser {
            scale_weight: -1.0,
            ..Default::default()
        };
        assert!(
            neg.validate()
                .unwrap_err()
                .to_string()
                .contains("scale_weight")
        );
    }
}
