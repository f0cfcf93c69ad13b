//! The SVD parameterisation of the chaotic-splatting paper.
//!
//! Each map has 12 raw numbers: a 2×2 raw `U` (row-major), a 2×2 raw `V`, two raw singular
//! values and two raw offsets. Decoding orthonormalises the columns of U and V by
//! Gram–Schmidt, squashes the singular values with a sigmoid and the offsets with tanh:
//!
//! `M = GS(U)·diag(c·sigmoid σ)·GS(V)ᵀ`, `b = tanh(β)`, with `c` = [`SV_CAP`] just below 1.
//!
//! So every θ gives a contractive map (σ ∈ (0, 1)) with its offset in (−1, 1)²: the model
//! lives in a normalised frame and renderers re-frame its points.
//!
//! ## References
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point Splatting*.

use nalgebra::{Matrix2, Vector2};

use crate::error::{Error, Result};
use crate::model::affine::Affine2;
use crate::model::param::Parameterisation;

/// Raw numbers per map.
pub const SVD_PARAMS_PER_MAP: usize = 12;

/// Singular values are `SV_CAP · sigmoid(σ)`: the sigmoid alone rounds to exactly 1 in
/// floating point for σ ≳ 37 (f64) or ≳ 17 (f32), which would make a map non-contractive.
pub const SV_CAP: f64 = 1.0 - 1e-6;

/// `U·diag(sigmoid σ)·Vᵀ`, `tanh` offsets.
#[derive(Clone, Copy, Debug)]
pub struct Svd {
    /// Singular values and offsets are kept this far inside their open ranges when encoding.
    pub encode_margin: f64,
}

impl Default for Svd {
    fn default() -> Self {
        Svd {
            encode_margin: 1e-6,
        }
    }
}

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

/// Gram–Schmidt on the columns of a 2×2 matrix, with what the backward pass needs.
struct Gs {
    q: Matrix2<f64>,
    n1: f64,
    nw: f64,
    dot: f64,
}

fn gram_schmidt(a: &Matrix2<f64>) -> Gs {
    let c1 = a.column(0).into_owned();
    let c2 = a.column(1).into_owned();
    let n1 = c1.norm().max(1e-300);
    let u1 = c1 / n1;
    let dot = u1.dot(&c2);
    let mut w = c2 - u1 * dot;
    let mut nw = w.norm();
    if nw < 1e-12 * (1.0 + c2.norm()) {
        // Degenerate second column: complete the basis with the perpendicular.
        w = Vector2::new(-u1[1], u1[0]);
        nw = 1.0;
    }
    let u2 = w / nw;
    Gs {
        q: Matrix2::from_columns(&[u1, u2]),
        n1,
        nw,
        dot,
    }
}

/// ∂L/∂A for `Q = GS(A)`, given ∂L/∂Q.
fn gram_schmidt_backward(a: &Matrix2<f64>, gs: &Gs, gq: &Matrix2<f64>) -> Matrix2<f64> {
    let u1 = gs.q.column(0).into_owned();
    let u2 = gs.q.column(1).into_owned();
    let c2 = a.column(1).into_owned();
    let gu2 = gq.column(1).into_owned();
    let mut gu1 = gq.column(0).into_owned();
    // u2 = w / |w|,  w = c2 − (u1·c2)·u1
    let gw = (gu2 - u2 * u2.dot(&gu2)) / gs.nw;
    let gc2 = gw - u1 * u1.dot(&gw);
    gu1 += -gw * gs.dot - c2 * u1.dot(&gw);
    // u1 = c1 / |c1|
    let gc1 = (gu1 - u1 * u1.dot(&gu1)) / gs.n1;
    Matrix2::from_columns(&[gc1, gc2])
}

fn raw_parts(t: &[f64]) -> (Matrix2<f64>, Matrix2<f64>, [f64; 2], [f64; 2]) {
    (
        Matrix2::new(t[0], t[1], t[2], t[3]),
        Matrix2::new(t[4], t[5], t[6], t[7]),
        [t[8], t[9]],
        [t[10], t[11]],
    )
}

impl Parameterisation for Svd {
    fn name(&self) -> &'static str {
        "svd"
    }

    fn params_per_map(&self) -> usize {
        SVD_PARAMS_PER_MAP
    }

    fn decode(&self, theta: &[f64]) -> Result<Vec<Affine2>> {
        self.n_maps(theta)?;
        Ok(theta
            .chunks_exact(SVD_PARAMS_PER_MAP)
            .map(|t| {
                let (ur, vr, sr, br) = raw_parts(t);
                let u = gram_schmidt(&ur).q;
                let v = gram_schmidt(&vr).q;
                let s = Matrix2::new(SV_CAP * sigmoid(sr[0]), 0.0, 0.0, SV_CAP * sigmoid(sr[1]));
                Affine2 {
                    m: u * s * v.transpose(),
                    b: Vector2::new(br[0].tanh(), br[1].tanh()),
                }
            })
            .collect())
    }

    fn encode(&self, maps: &[Affine2]) -> Result<Vec<f64>> {
        let eps = self.encode_margin;
        let mut theta = Vec::with_capacity(maps.len() * SVD_PARAMS_PER_MAP);
        for (i, map) in maps.iter().enumerate() {
            if !map.is_finite() {
                return Err(Error::NonFinite {
                    what: "map".into(),
                    location: format!("map {i}"),
                    value: f64::NAN,
                });
            }
            let (s1, _) = map.singular_values();
            if s1 >= SV_CAP * (1.0 - eps) {
                return Err(Error::NonContractive {
                    index: i,
                    sigma_max: s1,
                });
            }
            if map.b.iter().any(|b| b.abs() >= 1.0 - eps) {
                return Err(Error::param(
                    "offset",
                    format!(
                        "map {i} has offset ({}, {}) outside (−1, 1)²; the SVD parameterisation \
                         needs a code normalised to that square",
                        map.b[0], map.b[1]
                    ),
                ));
            }
            let svd = map.m.svd(true, true);
            let (u, vt) = (svd.u.expect("requested"), svd.v_t.expect("requested"));
            let sv = svd.singular_values;
            for x in [u[(0, 0)], u[(0, 1)], u[(1, 0)], u[(1, 1)]] {
                theta.push(x);
            }
            let v = vt.transpose();
            for x in [v[(0, 0)], v[(0, 1)], v[(1, 0)], v[(1, 1)]] {
                theta.push(x);
            }
            for k in 0..2 {
                let s = (sv[k] / SV_CAP).clamp(eps, 1.0 - eps);
                theta.push((s / (1.0 - s)).ln());
            }
            theta.push(map.b[0].atanh());
            theta.push(map.b[1].atanh());
        }
        Ok(theta)
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
        for (t, g) in theta.chunks_exact(SVD_PARAMS_PER_MAP).zip(grad_maps) {
            let (ur, vr, sr, br) = raw_parts(t);
            let gu = gram_schmidt(&ur);
            let gv = gram_schmidt(&vr);
            let (u, v) = (gu.q, gv.q);
            let sg = [sigmoid(sr[0]), sigmoid(sr[1])];
            let s = [SV_CAP * sg[0], SV_CAP * sg[1]];
            let sd = Matrix2::new(s[0], 0.0, 0.0, s[1]);
            // M = U·S·Vᵀ:  ∂L/∂U = G·V·S,  ∂L/∂V = Gᵀ·U·S,  ∂L/∂s_k = u_kᵀ·G·v_k.
            let gm = g.m;
            let g_u = gm * v * sd;
            let g_v = gm.transpose() * u * sd;
            let g_ur = gram_schmidt_backward(&ur, &gu, &g_u);
            let g_vr = gram_schmidt_backward(&vr, &gv, &g_v);
            out.extend_from_slice(&[g_ur[(0, 0)], g_ur[(0, 1)], g_ur[(1, 0)], g_ur[(1, 1)]]);
            out.extend_from_slice(&[g_vr[(0, 0)], g_vr[(0, 1)], g_vr[(1, 0)], g_vr[(1, 1)]]);
            for (k, s) in sg.iter().enumerate() {
                let gs = u.column(k).dot(&(gm * v.column(k)));
                out.push(gs * SV_CAP * s * (1.0 - s));
            }
            for (k, b) in br.iter().enumerate() {
                let tb = b.tanh();
                out.push(g.b[k] * (1.0 - tb * tb));
            }
        }
        Ok(out)
    }

    fn project(&self, theta: &mut [f64]) {
        for t in theta.chunks_exact_mut(SVD_PARAMS_PER_MAP) {
            for off in [0, 4] {
                let a = Matrix2::new(t[off], t[off + 1], t[off + 2], t[off + 3]);
                let q = gram_schmidt(&a).q;
                t[off..off + 4].copy_from_slice(&[q[(0, 0)], q[(0, 1)], q[(1, 0)], q[(1, 1)]]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn encode_decode_round_trip() {
        let maps = vec![
            Affine2::new(0.5, 0.1, -0.2, 0.3, 0.2, -0.4),
            Affine2::new(-0.3, 0.4, 0.25, 0.1, -0.7, 0.5),
        ];
        let p = Svd::default();
        let back = p.decode(&p.encode(&maps).unwrap()).unwrap();
        for (a, b) in maps.iter().zip(&back) {
            for (x, y) in a.coefficients().iter().zip(b.coefficients()) {
                assert!((x - y).abs() < 1e-9, "{x} vs {y}");
            }
        }
    }

    #[test]
    fn chain_rule_matches_finite_differences() {
        // L(θ) = Σ W ⊙ M + w·b for fixed weights, so ∂L/∂M = W and ∂L/∂b = w.
        let theta = [
            0.3, -1.2, 0.8, 0.4, 1.1, 0.2, -0.5, 0.9, 0.3, -0.7, 0.4, -1.3,
        ];
        let g = Affine2::new(0.7, -0.3, 0.2, 1.1, -0.6, 0.9);
        let loss = |th: &[f64]| {
            let m = Svd::default().decode(th).unwrap()[0];
            m.coefficients()
                .iter()
                .zip(g.coefficients())
                .map(|(a, b)| a * b)
                .sum::<f64>()
        };
        let grad = Svd::default().backward(&theta, &[g]).unwrap();
        for i in 0..theta.len() {
            let h = 1e-6;
            let mut tp = theta;
            let mut tm = theta;
            tp[i] += h;
            tm[i] -= h;
            let fd = (loss(&tp) - loss(&tm)) / (2.0 * h);
            assert!(
                (fd - grad[i]).abs() < 1e-7,
                "θ[{i}]: analytic {} vs fd {fd}",
                grad[i]
            );
        }
    }
}
