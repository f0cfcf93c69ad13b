//! Similitudes of space `x ↦ s·R(q)·F·x + t`.

use nalgebra::{Matrix3, Vector3};

use super::Affine3;
use super::rotation::rotation_jacobian;
use crate::model::map::{DiffMap, Map};

/// A similitude of space `x ↦ s·R(q)·F·x + t`, with `R(q)` the rotation of the quaternion
/// `q = (w, x, y, z)` (any non-zero length) and `F` the mirror `z ↦ −z` when `reflect` is
/// set, the identity otherwise.
///
/// Parameters `[s, w, x, y, z, t_x, t_y, t_z]` (8); the mirror is structure. As for
/// [`Similitude2`](crate::model::Similitude2) the scale is a raw real and contractivity
/// (`|s| < 1`) is the layer above's constraint. `R` and `∂R/∂q` are cached when the
/// parameters are set.
#[derive(Clone, Debug, PartialEq)]
pub struct Similitude3 {
    s: f64,
    q: [f64; 4],
    t: [f64; 3],
    reflect: bool,
    r: Matrix3<f64>,
    dr: [Matrix3<f64>; 4],
}

impl Similitude3 {
    /// `s·R(q)·F·x + t`.
    pub fn new(s: f64, q: [f64; 4], reflect: bool, t: [f64; 3]) -> Self {
        let (r, dr) = rotation_jacobian(q);
        Similitude3 {
            s,
            q,
            t,
            reflect,
            r,
            dr,
        }
    }

    /// Scale factor `s`.
    pub fn scale(&self) -> f64 {
        self.s
    }

    /// The rotation's quaternion as given.
    pub fn quaternion(&self) -> [f64; 4] {
        self.q
    }

    /// Whether the mirror `z ↦ −z` is applied before the rotation.
    pub fn reflect(&self) -> bool {
        self.reflect
    }

    /// Translation `t`.
    pub fn translation(&self) -> [f64; 3] {
        self.t
    }

    /// The same map as an [`Affine3`].
    pub fn to_affine(&self) -> Affine3 {
        let mut m = self.r * self.s;
        if self.reflect {
            m.set_column(2, &(-m.column(2)));
        }
        Affine3 {
            m,
            b: Vector3::from(self.t),
        }
    }

    /// `F·x`.
    #[inline(always)]
    fn flip(&self, x: [f64; 3]) -> [f64; 3] {
        if self.reflect { [x[0], x[1], -x[2]] } else { x }
    }
}

#[inline(always)]
fn mul(a: &Matrix3<f64>, x: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|r| a[(r, 0)] * x[0] + a[(r, 1)] * x[1] + a[(r, 2)] * x[2])
}

#[inline(always)]
fn mul_t(a: &Matrix3<f64>, l: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|c| a[(0, c)] * l[0] + a[(1, c)] * l[1] + a[(2, c)] * l[2])
}

impl Map<3> for Similitude3 {
    #[inline(always)]
    fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let z = mul(&self.r, self.flip(p));
        std::array::from_fn(|k| self.s * z[k] + self.t[k])
    }
}

impl DiffMap<3> for Similitude3 {
    const PARAMS: Option<usize> = Some(8);

    #[inline(always)]
    fn n_params(&self) -> usize {
        8
    }

    fn write_params(&self, out: &mut [f64]) {
        out[0] = self.s;
        out[1..5].copy_from_slice(&self.q);
        out[5..8].copy_from_slice(&self.t);
    }

    fn set_params(&mut self, p: &[f64]) {
        *self = Similitude3::new(
            p[0],
            [p[1], p[2], p[3], p[4]],
            self.reflect,
            [p[5], p[6], p[7]],
        );
    }

    /// `s·Fᵀ·Rᵀ·λ`.
    #[inline(always)]
    fn vjp_point(&self, _x: [f64; 3], l: [f64; 3]) -> [f64; 3] {
        self.flip(mul_t(&self.r, l)).map(|v| self.s * v)
    }

    /// With `z = R·F·x`: `∂f/∂s = z`, `∂f/∂q_i = s·(∂R/∂q_i)·F·x`, `∂f/∂t = I`.
    #[inline(always)]
    fn vjp_params(&self, x: [f64; 3], l: [f64; 3], grad: &mut [f64]) {
        let g = &mut grad[..8];
        let fx = self.flip(x);
        let z = mul(&self.r, fx);
        let dot = |a: [f64; 3]| l[0] * a[0] + l[1] * a[1] + l[2] * a[2];
        g[0] += dot(z);
        for i in 0..4 {
            g[1 + i] += self.s * dot(mul(&self.dr[i], fx));
        }
        for k in 0..3 {
            g[5 + k] += l[k];
        }
    }
}
