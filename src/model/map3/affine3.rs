//! Affine maps of space `x ↦ M·x + b`, and the Sierpiński tetrahedron.

use nalgebra::{Matrix3, Vector3};

use super::{DiffMap3, Map3};

/// A 3-D affine map `x ↦ M·x + b`; its parameters are `M` row-major, then `b` (12).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Affine3 {
    /// Linear part.
    pub m: Matrix3<f64>,
    /// Offset.
    pub b: Vector3<f64>,
}

impl Affine3 {
    /// The map from its linear part (rows) and offset.
    pub fn new(m: [[f64; 3]; 3], b: [f64; 3]) -> Self {
        Affine3 {
            m: Matrix3::from_fn(|r, c| m[r][c]),
            b: Vector3::from(b),
        }
    }

    /// `x ↦ s·x + (1 − s)·v`: the homothety of ratio `s` about `v`.
    pub fn homothety(s: f64, v: [f64; 3]) -> Self {
        Affine3 {
            m: Matrix3::identity() * s,
            b: Vector3::from(v) * (1.0 - s),
        }
    }

    /// Singular values, largest first.
    pub fn singular_values(&self) -> [f64; 3] {
        let s = self.m.singular_values();
        let mut v = [s[0], s[1], s[2]];
        v.sort_by(|a, b| b.total_cmp(a));
        v
    }

    /// Largest singular value (the Lipschitz constant; < 1 for a contraction).
    pub fn sigma_max(&self) -> f64 {
        self.singular_values()[0]
    }

    /// `|det M|`, the volume factor (what ∝-|det| map probabilities use).
    pub fn abs_det(&self) -> f64 {
        self.m.determinant().abs()
    }

    /// Whether every coefficient is finite.
    pub fn is_finite(&self) -> bool {
        self.m.iter().chain(self.b.iter()).all(|v| v.is_finite())
    }

    /// The map as the dimension-generic [`AffineN`](crate::model::AffineN) (code files,
    /// EM).
    pub fn to_affine_n(&self) -> crate::model::AffineN {
        crate::model::AffineN {
            m: nalgebra::DMatrix::from_fn(3, 3, |r, c| self.m[(r, c)]),
            b: nalgebra::DVector::from_column_slice(self.b.as_slice()),
        }
    }
}

impl Map3 for Affine3 {
    #[inline(always)]
    fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let m = &self.m;
        std::array::from_fn(|r| m[(r, 0)] * p[0] + m[(r, 1)] * p[1] + m[(r, 2)] * p[2] + self.b[r])
    }
}

impl DiffMap3 for Affine3 {
    const PARAMS: Option<usize> = Some(12);

    #[inline(always)]
    fn n_params(&self) -> usize {
        12
    }

    fn write_params(&self, out: &mut [f64]) {
        for r in 0..3 {
            for c in 0..3 {
                out[3 * r + c] = self.m[(r, c)];
            }
            out[9 + r] = self.b[r];
        }
    }

    fn set_params(&mut self, p: &[f64]) {
        self.m = Matrix3::from_fn(|r, c| p[3 * r + c]);
        self.b = Vector3::new(p[9], p[10], p[11]);
    }

    /// `Mᵀλ`.
    #[inline(always)]
    fn vjp_point(&self, _x: [f64; 3], l: [f64; 3]) -> [f64; 3] {
        let m = &self.m;
        std::array::from_fn(|c| m[(0, c)] * l[0] + m[(1, c)] * l[1] + m[(2, c)] * l[2])
    }

    /// `∂L/∂M += λxᵀ` (row-major), `∂L/∂b += λ`.
    #[inline(always)]
    fn vjp_params(&self, x: [f64; 3], l: [f64; 3], grad: &mut [f64]) {
        let g = &mut grad[..12];
        for r in 0..3 {
            for c in 0..3 {
                g[3 * r + c] += l[r] * x[c];
            }
            g[9 + r] += l[r];
        }
    }
}

/// The Sierpiński tetrahedron: four homotheties of ratio ½ towards the vertices of the
/// regular tetrahedron `0.8·(1, 1, 1), 0.8·(1, −1, −1), 0.8·(−1, 1, −1), 0.8·(−1, −1, 1)`
/// (offsets `0.4·(±1, ±1, ±1)`, inside the `(−1, 1)³` the SVD parameterisation's tanh
/// offsets reach; the attractor is that tetrahedron's Sierpiński set, centred on the origin).
pub fn sierpinski_tetrahedron() -> Vec<Affine3> {
    [
        [1.0, 1.0, 1.0],
        [1.0, -1.0, -1.0],
        [-1.0, 1.0, -1.0],
        [-1.0, -1.0, 1.0],
    ]
    .iter()
    .map(|v| Affine3::homothety(0.5, v.map(|c| 0.8 * c)))
    .collect()
}
