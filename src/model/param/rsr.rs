//! The rotation–scale–rotation parameterisation of *Learning Fractals by Gradient Descent*
//! (Tu et al., AAAI 2023), the baseline of the chaotic-splatting paper's Table 3.
//!
//! Each map has 8 raw numbers `(θ₁, θ₂, σ₁, σ₂, d₁, d₂, e, f)`:
//!
//! `M = R(θ₁)·diag(sigmoid σ₁, sigmoid σ₂)·R(θ₂)·diag(sign d₁, sign d₂)`, `b = (e, f)`,
//!
//! with `R(θ)` the rotation by θ. The signs make reflections reachable; their derivative is
//! taken as 1 (the straight-through estimator of the reference code, where the sign enters
//! as `sign(d) − d.detach() + d`), so a gradient can push `d` through zero. The offsets are
//! not squashed: the reference code renders in a fixed window and lets points leave it.

use nalgebra::{Matrix2, Vector2};

use crate::error::{Error, Result};
use crate::model::affine::Affine2;
use crate::model::param::Parameterisation;

/// Raw numbers per map.
pub const RSR_PARAMS_PER_MAP: usize = 8;

/// The magnitude an encoded `d` gets (the reference code initialises `d` to 0.005).
pub const RSR_SIGN_MAGNITUDE: f64 = 0.005;

/// `R(θ₁)·diag(sigmoid σ)·R(θ₂)·diag(sign d)`, raw offsets.
#[derive(Clone, Copy, Debug, Default)]
pub struct Rsr;

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

fn rot(t: f64) -> Matrix2<f64> {
    let (s, c) = t.sin_cos();
    Matrix2::new(c, -s, s, c)
}

/// dR(θ)/dθ.
fn drot(t: f64) -> Matrix2<f64> {
    let (s, c) = t.sin_cos();
    Matrix2::new(-s, -c, c, -s)
}

fn sign(d: f64) -> f64 {
    if d < 0.0 { -1.0 } else { 1.0 }
}

/// The four factors of one map.
struct Factors {
    r1: Matrix2<f64>,
    s: Matrix2<f64>,
    r2: Matrix2<f64>,
    d: Matrix2<f64>,
    sg: [f64; 2],
}

fn factors(t: &[f64]) -> Factors {
    let sg = [sigmoid(t[2]), sigmoid(t[3])];
    Factors {
        r1: rot(t[0]),
        s: Matrix2::new(sg[0], 0.0, 0.0, sg[1]),
        r2: rot(t[1]),
        d: Matrix2::new(sign(t[4]), 0.0, 0.0, sign(t[5])),
        sg,
    }
}

/// `⟨G, A⟩ = Σ Gᵢⱼ Aᵢⱼ`.
fn inner(g: &Matrix2<f64>, a: &Matrix2<f64>) -> f64 {
    g.component_mul(a).sum()
}

impl Parameterisation for Rsr {
    fn name(&self) -> &'static str {
        "rsr"
    }

    fn params_per_map(&self) -> usize {
        RSR_PARAMS_PER_MAP
    }

    fn decode(&self, theta: &[f64]) -> Result<Vec<Affine2>> {
        self.n_maps(theta)?;
        Ok(theta
            .chunks_exact(RSR_PARAMS_PER_MAP)
            .map(|t| {
                let f = factors(t);
                Affine2 {
                    m: f.r1 * f.s * f.r2 * f.d,
                    b: Vector2::new(t[6], t[7]),
                }
            })
            .collect())
    }

    /// From the SVD `M = U·S·Vᵀ`: writing `U = R(α)·diag(1, u)` and `Vᵀ = diag(1, v)·R(β)`
    /// (u, v = ±1 the determinants), `M = R(α)·S·R(r·β)·diag(1, r)` with `r = u·v`, since a
    /// reflection `diag(1, −1)` turns `R(β)` into `R(−β)` as it passes. Singular values
    /// must lie in (0, 1) (contractive maps); they are kept `1e-9` inside.
    fn encode(&self, maps: &[Affine2]) -> Result<Vec<f64>> {
        let mut out = Vec::with_capacity(maps.len() * RSR_PARAMS_PER_MAP);
        for (i, m) in maps.iter().enumerate() {
            let svd = m.m.svd(true, true);
            let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
                return Err(Error::param("maps", format!("no SVD of map {i}")));
            };
            let sv = svd.singular_values;
            if sv[0] >= 1.0 {
                return Err(Error::param(
                    "maps",
                    format!(
                        "map {i} is not contractive (σ₁ = {}); the rsr parameterisation holds singular values in (0, 1)",
                        sv[0]
                    ),
                ));
            }
            let du = u.determinant().signum();
            let dv = vt.determinant().signum();
            // U·diag(1, du) is a rotation; so is diag(1, dv)·Vᵀ.
            let alpha = (u[(1, 0)]).atan2(u[(0, 0)]);
            let vr = Matrix2::new(1.0, 0.0, 0.0, dv) * vt;
            let beta = vr[(1, 0)].atan2(vr[(0, 0)]);
            let r = du * dv;
            let logit = |s: f64| {
                let s = s.clamp(1e-9, 1.0 - 1e-9);
                (s / (1.0 - s)).ln()
            };
            out.extend_from_slice(&[
                alpha,
                r * beta,
                logit(sv[0]),
                logit(sv[1]),
                RSR_SIGN_MAGNITUDE,
                r * RSR_SIGN_MAGNITUDE,
                m.b[0],
                m.b[1],
            ]);
        }
        Ok(out)
    }

    fn backward(&self, theta: &[f64], grad_maps: &[Affine2]) -> Result<Vec<f64>> {
        let n = self.n_maps(theta)?;
        if grad_maps.len() != n {
            return Err(Error::Shape(format!(
                "{} map gradients for {n} maps",
                grad_maps.len()
            )));
        }
        let mut out = Vec::with_capacity(theta.len());
        for (t, g) in theta.chunks_exact(RSR_PARAMS_PER_MAP).zip(grad_maps) {
            let f = factors(t);
            let gm = &g.m;
            let ds1 = Matrix2::new(f.sg[0] * (1.0 - f.sg[0]), 0.0, 0.0, 0.0);
            let ds2 = Matrix2::new(0.0, 0.0, 0.0, f.sg[1] * (1.0 - f.sg[1]));
            // Straight-through: ∂sign(d)/∂d taken as 1.
            let dd1 = Matrix2::new(1.0, 0.0, 0.0, 0.0);
            let dd2 = Matrix2::new(0.0, 0.0, 0.0, 1.0);
            out.extend_from_slice(&[
                inner(gm, &(drot(t[0]) * f.s * f.r2 * f.d)),
                inner(gm, &(f.r1 * f.s * drot(t[1]) * f.d)),
                inner(gm, &(f.r1 * ds1 * f.r2 * f.d)),
                inner(gm, &(f.r1 * ds2 * f.r2 * f.d)),
                inner(gm, &(f.r1 * f.s * f.r2 * dd1)),
                inner(gm, &(f.r1 * f.s * f.r2 * dd2)),
                g.b[0],
                g.b[1],
            ]);
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encode_decode_round_trip_with_and_without_reflections() {
        let maps = vec![
            Affine2::new(0.5, 0.1, -0.2, 0.3, 0.2, -0.4),
            Affine2::new(-0.3, 0.4, 0.25, 0.1, -0.7, 0.5),
            Affine2::new(0.4, 0.0, 0.0, -0.3, 0.1, 0.1),
            Affine2::new(0.0, 0.6, 0.6, 0.0, 0.0, 0.0),
        ];
        let back = Rsr.decode(&Rsr.encode(&maps).unwrap()).unwrap();
        for (a, b) in maps.iter().zip(&back) {
            for (x, y) in a.coefficients().iter().zip(b.coefficients()) {
                assert!((x - y).abs() < 1e-9, "{a:?} vs {b:?}");
            }
        }
        assert!(
            Rsr.encode(&[Affine2::new(1.2, 0.0, 0.0, 0.5, 0.0, 0.0)])
                .is_err()
        );
    }

    #[test]
    fn chain_rule_matches_finite_differences_away_from_the_sign_jumps() {
        // L(θ) = Σ W ⊙ M + w·b for fixed weights, so ∂L/∂M = W and ∂L/∂b = w.
        let theta = [0.3, -1.2, 0.8, -0.4, 0.7, -0.2, -0.5, 0.9];
        let g = Affine2::new(0.7, -0.3, 0.2, 1.1, -0.6, 0.9);
        let loss = |th: &[f64]| {
            let m = Rsr.decode(th).unwrap()[0];
            m.coefficients()
                .iter()
                .zip(g.coefficients())
                .map(|(a, b)| a * b)
                .sum::<f64>()
        };
        let grad = Rsr.backward(&theta, &[g]).unwrap();
        for i in (0..4).chain(6..8) {
            let h = 1e-6;
            let (mut tp, mut tm) = (theta, theta);
            tp[i] += h;
            tm[i] -= h;
            let fd = (loss(&tp) - loss(&tm)) / (2.0 * h);
            assert!(
                (fd - grad[i]).abs() < 1e-7,
                "θ[{i}]: analytic {} vs fd {fd}",
                grad[i]
            );
        }
        // The signs: the straight-through gradient is ∂L/∂(sign d) — the change of L when
        // the sign flips, per unit of sign (half the jump from −1 to +1).
        for (i, k) in [(4, 0), (5, 1)] {
            let (mut tp, mut tm) = (theta, theta);
            tp[i] = 1.0;
            tm[i] = -1.0;
            let jump = (loss(&tp) - loss(&tm)) / 2.0;
            // L is linear in each sign with the other factors fixed.
            assert!(
                (jump - grad[i]).abs() < 1e-12,
                "d{k}: {jump} vs {}",
                grad[i]
            );
        }
    }
}
