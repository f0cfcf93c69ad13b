//! Affine maps of space `x ↦ M·x + b`, and the Sierpiński tetrahedron.

use nalgebra::{Matrix3, Vector3};

use crate::error::{Error, Result};
use crate::model::AffineN;
use crate::model::code::IfsCode;
use crate::model::map::{DiffMap, Map};

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
    pub fn to_affine_n(&self) -> AffineN {
        AffineN {
            m: nalgebra::DMatrix::from_fn(3, 3, |r, c| self.m[(r, c)]),
            b: nalgebra::DVector::from_column_slice(self.b.as_slice()),
        }
    }

    /// The 3-D map of a dimension-generic one; refuses another dimension.
    pub fn from_affine_n(map: &AffineN) -> Result<Affine3> {
        if map.dim() != 3 || map.m.nrows() != 3 || map.m.ncols() != 3 {
            return Err(Error::Shape(format!(
                "expected a 3-D map, got dimension {}",
                map.dim()
            )));
        }
        Ok(Affine3 {
            m: Matrix3::from_fn(|r, c| map.m[(r, c)]),
            b: Vector3::new(map.b[0], map.b[1], map.b[2]),
        })
    }

    /// The maps of a 3-D code file (`ifslab-code/1` with `"dim": 3`: a 3 × 3 `matrix` and
    /// an `offset` of 3 per map); refuses a code of another dimension.
    pub fn from_code(code: &IfsCode) -> Result<Vec<Affine3>> {
        if code.dim() != 3 {
            return Err(Error::Shape(format!(
                "the code is {}-dimensional; a code of space has \"dim\": 3",
                code.dim()
            )));
        }
        code.maps.iter().map(Affine3::from_affine_n).collect()
    }

    /// A 3-D code of `maps` (what a recovered code is saved as, [`IfsCode::save`]),
    /// validated: finite and contractive.
    pub fn to_code(name: Option<&str>, maps: &[Affine3]) -> Result<IfsCode> {
        IfsCode::from_affine_n(name, maps.iter().map(Affine3::to_affine_n).collect())
    }
}

impl Map<3> for Affine3 {
    #[inline(always)]
    fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let m = &self.m;
        std::array::from_fn(|r| m[(r, 0)] * p[0] + m[(r, 1)] * p[1] + m[(r, 2)] * p[2] + self.b[r])
    }

    fn affine(&self) -> Option<([[f64; 3]; 3], [f64; 3])> {
        let m = &self.m;
        Some((
            std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)])),
            std::array::from_fn(|r| self.b[r]),
        ))
    }
}

impl DiffMap<3> for Affine3 {
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

/// A 3-D fern: the classic four-map fern of space (a stem `diag(0, 0.18, 0)`; the frond's
/// main map `0.85·I` turned by 0.1 about the stem's cross axis and lifted by 1.6 along the
/// stem; two leaflet maps `[[±0.2, ∓0.2, 0], [0.2, 0.2, 0], [0, 0, 0.3]]` lifted by 0.8),
/// with probabilities `(0.01, 0.85, 0.07, 0.07)` — conjugated by
/// `x ↦ 0.17·P·x + (0, 0.45, −0.86)`, `P` swapping the `y` and `z` axes, so that the stem
/// stands along `+z` (the turntables' up), the frond curling towards `−y`, and the attractor
/// lies in `[−0.9, 0.9]³` (about `±0.35 × [−0.46, 0.47] × [−0.87, 0.87]`) with every offset
/// inside `(−1, 1)³`.
/// Conjugation keeps each map's singular values (the stem's is singular: rank 1).
pub fn fern_3d() -> (Vec<Affine3>, Vec<f64>) {
    let classic = [
        (
            [[0.0, 0.0, 0.0], [0.0, 0.18, 0.0], [0.0, 0.0, 0.0]],
            [0.0, 0.0, 0.0],
        ),
        (
            [[0.85, 0.0, 0.0], [0.0, 0.85, 0.1], [0.0, -0.1, 0.85]],
            [0.0, 1.6, 0.0],
        ),
        (
            [[0.2, -0.2, 0.0], [0.2, 0.2, 0.0], [0.0, 0.0, 0.3]],
            [0.0, 0.8, 0.0],
        ),
        (
            [[-0.2, 0.2, 0.0], [0.2, 0.2, 0.0], [0.0, 0.0, 0.3]],
            [0.0, 0.8, 0.0],
        ),
    ];
    let p = Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0);
    let a = p * 0.17;
    let a_inv = p / 0.17;
    let c = Vector3::new(0.0, 0.45, -0.86);
    let maps = classic
        .iter()
        .map(|(m, b)| {
            let f = Affine3::new(*m, *b);
            // T∘f∘T⁻¹ with T(x) = A·x + c: y ↦ A·M·A⁻¹·y + A·b + c − A·M·A⁻¹·c.
            let m2 = a * f.m * a_inv;
            Affine3 {
                m: m2,
                b: a * f.b + c - m2 * c,
            }
        })
        .collect();
    (maps, vec![0.01, 0.85, 0.07, 0.07])
}
