//! The SVD parameterisation of the chaotic-splatting paper, taken to 3-D.
//!
//! Each map has 14 raw numbers θ = `(q_U, q_V, σ, β)`: two quaternions (4 each, any
//! non-zero length: [`rotation_from_quaternion`] normalises), three raw singular values and
//! three raw offsets, decoded as
//!
//! `M = R(q_U)·diag(c·sigmoid σ₁, c·sigmoid σ₂, ±c·sigmoid σ₃)·R(q_V)ᵀ`, `b = tanh β`,
//!
//! with `c` = [`SV3_CAP`] just below 1 (as the 2-D [`Svd`](crate::model::Svd)'s cap) and
//! the sign of the third singular value fixed structure (`reflect`): two rotations reach
//! only maps with `det M > 0`, so mirrored maps carry the flag, as
//! [`Similitude2`](crate::model::Similitude2) carries its reflection. Every finite θ is then
//! a contraction (largest singular value ≤ c < 1) with its offset in `(−1, 1)³`.
//!
//! Where the 2-D parameterisation over-parameterises the orthonormal factors by their raw
//! entries and re-orthonormalises them by Gram–Schmidt after each step, a quaternion needs no
//! projection to stay valid: any non-zero 4-vector is a rotation (its length is free, and
//! [`SvdMap3::normalise_rotations`] resets it).
//!
//! The map is a [`DiffMap3`] in θ directly: `∂M/∂θ` is computed when θ is set (a 9 × 11
//! table), so a step of the backward scan costs the 12 products of `λxᵀ` and one pass over
//! the table, not a chain rule through the rotations.
//!
//! ## References
//! - Djeacoumar et al., *Learning Image Fractals Using Chaotic Differentiable Point Splatting*.

use nalgebra::{Matrix3, Vector3};

use super::Affine3;
use super::rotation::{quaternion_from_rotation, rotation_jacobian};
use crate::error::{Error, Result};
use crate::model::map::{DiffMap, Map};

/// Raw numbers per map.
pub const SVD3_PARAMS: usize = 14;

/// Singular values are `SV3_CAP · sigmoid(σ)` (the sigmoid alone rounds to 1 for large σ).
pub const SV3_CAP: f64 = 1.0 - 1e-6;

/// Parameters that move `M` (the two quaternions and the singular values).
const LINEAR_PARAMS: usize = 11;

fn sigmoid(x: f64) -> f64 {
    1.0 / (1.0 + (-x).exp())
}

/// A contractive affine map of space under the SVD parameterisation (see the module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct SvdMap3 {
    theta: [f64; SVD3_PARAMS],
    reflect: bool,
    m: Matrix3<f64>,
    b: [f64; 3],
    /// `∂M_{rc}/∂θ_k` at `[k][3r + c]` for the first [`LINEAR_PARAMS`] parameters.
    dm: [[f64; 9]; LINEAR_PARAMS],
    /// `∂b_r/∂β_r = 1 − tanh²β_r`.
    db: [f64; 3],
}

impl SvdMap3 {
    /// The map of raw parameters `theta` (length [`SVD3_PARAMS`], finite), the third singular
    /// value negated when `reflect` is set.
    pub fn new(theta: &[f64], reflect: bool) -> Result<Self> {
        if theta.len() != SVD3_PARAMS {
            return Err(Error::Shape(format!(
                "an SVD map of space has {SVD3_PARAMS} parameters, got {}",
                theta.len()
            )));
        }
        if let Some((i, v)) = theta.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "θ".into(),
                location: format!("entry {i}"),
                value: *v,
            });
        }
        let mut map = SvdMap3 {
            theta: [0.0; SVD3_PARAMS],
            reflect,
            m: Matrix3::zeros(),
            b: [0.0; 3],
            dm: [[0.0; 9]; LINEAR_PARAMS],
            db: [0.0; 3],
        };
        map.set_params(theta);
        Ok(map)
    }

    /// The θ whose map is `map` (exactly, up to rounding), with the reflection flag set where
    /// `det M < 0`. Refuses a non-finite map, one that is not a contraction (singular value
    /// ≥ [`SV3_CAP`]·(1 − `margin`)) and an offset outside `(−1, 1)³` (less `margin`):
    /// the code must be normalised to that cube first. Singular values below `margin` are
    /// raised to it (a singular map has no finite θ). Errors name map 0;
    /// [`SvdMap3::from_code`] names the map of a code.
    pub fn from_affine(map: &Affine3, margin: f64) -> Result<Self> {
        if !map.is_finite() {
            return Err(Error::NonFinite {
                what: "map".into(),
                location: "its coefficients".into(),
                value: f64::NAN,
            });
        }
        let svd = map.m.svd(true, true);
        let (mut u, mut v) = match (svd.u, svd.v_t) {
            (Some(u), Some(vt)) => (u, vt.transpose()),
            _ => return Err(Error::Shape("the SVD of the map did not converge".into())),
        };
        let s = svd.singular_values;
        let mut sign = 1.0;
        if u.determinant() < 0.0 {
            u.set_column(2, &(-u.column(2)));
            sign = -sign;
        }
        if v.determinant() < 0.0 {
            v.set_column(2, &(-v.column(2)));
            sign = -sign;
        }
        let mut theta = [0.0; SVD3_PARAMS];
        theta[..4].copy_from_slice(&quaternion_from_rotation(&u));
        theta[4..8].copy_from_slice(&quaternion_from_rotation(&v));
        for k in 0..3 {
            if s[k] >= SV3_CAP * (1.0 - margin) {
                return Err(Error::NonContractive {
                    index: 0,
                    sigma_max: s[k],
                });
            }
            let x = (s[k] / SV3_CAP).clamp(margin, 1.0 - margin);
            theta[8 + k] = (x / (1.0 - x)).ln();
        }
        for r in 0..3 {
            let b = map.b[r];
            if b.abs() >= 1.0 - margin {
                return Err(Error::param(
                    "offset",
                    format!(
                        "the map's offset ({}, {}, {}) leaves (−1, 1)³; the SVD \
                         parameterisation needs a code normalised to that cube",
                        map.b[0], map.b[1], map.b[2]
                    ),
                ));
            }
            theta[11 + r] = b.atanh();
        }
        SvdMap3::new(&theta, sign < 0.0)
    }

    /// [`SvdMap3::from_affine`] for every map of a code, the error naming the map.
    pub fn from_code(maps: &[Affine3], margin: f64) -> Result<Vec<Self>> {
        maps.iter()
            .enumerate()
            .map(|(i, m)| {
                SvdMap3::from_affine(m, margin).map_err(|e| match e {
                    Error::NonContractive { sigma_max, .. } => Error::NonContractive {
                        index: i,
                        sigma_max,
                    },
                    Error::InvalidParameter { name, message } => Error::InvalidParameter {
                        name,
                        message: format!("map {i}: {message}"),
                    },
                    Error::NonFinite { what, value, .. } => Error::NonFinite {
                        what,
                        location: format!("map {i}"),
                        value,
                    },
                    e => e,
                })
            })
            .collect()
    }

    /// Whether the third singular value is negated (`det M < 0`).
    pub fn reflect(&self) -> bool {
        self.reflect
    }

    /// The decoded singular values `c·sigmoid σ` (all positive; the reflection is apart).
    pub fn singular_values(&self) -> [f64; 3] {
        std::array::from_fn(|k| SV3_CAP * sigmoid(self.theta[8 + k]))
    }

    /// The decoded map.
    pub fn to_affine(&self) -> Affine3 {
        Affine3 {
            m: self.m,
            b: Vector3::from(self.b),
        }
    }

    /// Rescales both quaternions to unit length (the same map): what an optimiser may apply
    /// after each step so that the rotations' step sizes stay comparable.
    pub fn normalise_rotations(&mut self) {
        let mut t = self.theta;
        for q in [0, 4] {
            let n = t[q..q + 4].iter().map(|v| v * v).sum::<f64>().sqrt();
            if n > 0.0 {
                t[q..q + 4].iter_mut().for_each(|v| *v /= n);
            }
        }
        self.set_params(&t);
    }
}

impl Map<3> for SvdMap3 {
    #[inline(always)]
    fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let m = &self.m;
        std::array::from_fn(|r| m[(r, 0)] * p[0] + m[(r, 1)] * p[1] + m[(r, 2)] * p[2] + self.b[r])
    }
}

impl DiffMap<3> for SvdMap3 {
    const PARAMS: Option<usize> = Some(SVD3_PARAMS);

    #[inline(always)]
    fn n_params(&self) -> usize {
        SVD3_PARAMS
    }

    fn write_params(&self, out: &mut [f64]) {
        out.copy_from_slice(&self.theta);
    }

    /// Decodes θ and tabulates `∂M/∂θ`: with `M = U·S·Vᵀ`, `∂M/∂q_U,i = (∂U/∂q_i)·S·Vᵀ`,
    /// `∂M/∂q_V,i = U·S·(∂V/∂q_i)ᵀ`, `∂M/∂σ_k = ±c·s_k(1 − s_k)·u_k·v_kᵀ` (`s_k` the sigmoid).
    fn set_params(&mut self, p: &[f64]) {
        self.theta.copy_from_slice(&p[..SVD3_PARAMS]);
        let t = &self.theta;
        let (u, du) = rotation_jacobian([t[0], t[1], t[2], t[3]]);
        let (v, dv) = rotation_jacobian([t[4], t[5], t[6], t[7]]);
        let sg: [f64; 3] = std::array::from_fn(|k| sigmoid(t[8 + k]));
        let sign = [1.0, 1.0, if self.reflect { -1.0 } else { 1.0 }];
        let s = Matrix3::from_diagonal(&Vector3::from_fn(|k, _| sign[k] * SV3_CAP * sg[k]));
        let vt = v.transpose();
        self.m = u * s * vt;
        let flat = |a: Matrix3<f64>| -> [f64; 9] { std::array::from_fn(|j| a[(j / 3, j % 3)]) };
        for i in 0..4 {
            self.dm[i] = flat(du[i] * s * vt);
            self.dm[4 + i] = flat(u * s * dv[i].transpose());
        }
        for k in 0..3 {
            let ds = sign[k] * SV3_CAP * sg[k] * (1.0 - sg[k]);
            self.dm[8 + k] = flat(u.column(k) * v.column(k).transpose() * ds);
        }
        for r in 0..3 {
            let tb = t[11 + r].tanh();
            self.b[r] = tb;
            self.db[r] = 1.0 - tb * tb;
        }
    }

    /// `Mᵀλ`.
    #[inline(always)]
    fn vjp_point(&self, _x: [f64; 3], l: [f64; 3]) -> [f64; 3] {
        let m = &self.m;
        std::array::from_fn(|c| m[(0, c)] * l[0] + m[(1, c)] * l[1] + m[(2, c)] * l[2])
    }

    /// `∂L/∂θ_k += ⟨∂M/∂θ_k, λxᵀ⟩` for the rotations and singular values, and
    /// `∂L/∂β_r += λ_r·(1 − tanh²β_r)`.
    #[inline(always)]
    fn vjp_params(&self, x: [f64; 3], l: [f64; 3], grad: &mut [f64]) {
        let g = &mut grad[..SVD3_PARAMS];
        let outer: [f64; 9] = std::array::from_fn(|j| l[j / 3] * x[j % 3]);
        for (gk, dk) in g[..LINEAR_PARAMS].iter_mut().zip(&self.dm) {
            let mut acc = 0.0;
            for j in 0..9 {
                acc += dk[j] * outer[j];
            }
            *gk += acc;
        }
        for r in 0..3 {
            g[LINEAR_PARAMS + r] += l[r] * self.db[r];
        }
    }
}
