//! Affine maps x ↦ M·x + b: the fixed-size 2-D map every renderer uses, and the
//! dimension-generic map that code files and similitudes convert to.

use nalgebra::{DMatrix, DVector, Matrix2, Vector2};

use crate::error::{Error, Result};
use crate::model::map::Map;

// The former home of the plane's map trait: code written against this path keeps compiling.
pub use crate::model::map::Map2;

/// A 2-D affine map `x ↦ M·x + b`.
///
/// In the classic "a b c d e f" notation of IFS tables, `M = [[a, b], [c, d]]` and
/// `b = (e, f)`, i.e. `x' = a·x + b·y + e`, `y' = c·x + d·y + f`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Affine2 {
    /// Linear part.
    pub m: Matrix2<f64>,
    /// Offset.
    pub b: Vector2<f64>,
}

impl Affine2 {
    /// The affine map `m` is, where it is one ([`Map::affine`]): how the deep zoom, the
    /// code file and the IoU polish see a map of any type.
    pub fn of_map<M: Map<2>>(m: &M) -> Option<Affine2> {
        m.affine()
            .map(|([[a, b], [c, d]], [e, f])| Affine2::new(a, b, c, d, e, f))
    }

    /// The map from the six classic table coefficients.
    pub fn new(a: f64, b: f64, c: f64, d: f64, e: f64, f: f64) -> Self {
        Affine2 {
            m: Matrix2::new(a, b, c, d),
            b: Vector2::new(e, f),
        }
    }

    /// The six coefficients `[a, b, c, d, e, f]` (row-major matrix, then offset).
    pub fn coefficients(&self) -> [f64; 6] {
        [
            self.m[(0, 0)],
            self.m[(0, 1)],
            self.m[(1, 0)],
            self.m[(1, 1)],
            self.b[0],
            self.b[1],
        ]
    }

    /// Inverse of [`Affine2::coefficients`].
    pub fn from_coefficients(c: &[f64]) -> Self {
        Affine2::new(c[0], c[1], c[2], c[3], c[4], c[5])
    }

    /// A similitude `s·R(angle)·x + t` (R a rotation, optionally preceded by the reflection y ↦ −y).
    pub fn similitude(s: f64, angle: f64, reflect: bool, t: [f64; 2]) -> Self {
        let (sn, cs) = angle.sin_cos();
        let r = Matrix2::new(cs, -sn, sn, cs);
        let f = if reflect {
            Matrix2::new(1.0, 0.0, 0.0, -1.0)
        } else {
            Matrix2::identity()
        };
        Affine2 {
            m: r * f * s,
            b: Vector2::new(t[0], t[1]),
        }
    }

    /// Both singular values of `M`, largest first, in closed form.
    pub fn singular_values(&self) -> (f64, f64) {
        singular_values_2x2(&self.m)
    }

    /// Largest singular value of `M`: the map's Lipschitz constant in the Euclidean norm.
    pub fn sigma_max(&self) -> f64 {
        self.singular_values().0
    }

    /// Determinant of `M` (the map's area scale, signed).
    pub fn det(&self) -> f64 {
        self.m.determinant()
    }

    /// Whether every coefficient is finite.
    pub fn is_finite(&self) -> bool {
        self.coefficients().iter().all(|v| v.is_finite())
    }

    /// The composition `self ∘ other` (apply `other` first).
    pub fn compose(&self, other: &Affine2) -> Affine2 {
        Affine2 {
            m: self.m * other.m,
            b: self.m * other.b + self.b,
        }
    }

    /// The map's unique fixed point, if `I − M` is invertible.
    pub fn fixed_point(&self) -> Option<[f64; 2]> {
        let a = Matrix2::identity() - self.m;
        a.try_inverse().map(|inv| {
            let p = inv * self.b;
            [p[0], p[1]]
        })
    }

    /// The same map as a dimension-generic [`AffineN`].
    pub fn to_affine_n(&self) -> AffineN {
        AffineN {
            m: DMatrix::from_row_slice(2, 2, &self.coefficients()[..4]),
            b: DVector::from_row_slice(&[self.b[0], self.b[1]]),
        }
    }
}

impl Map<2> for Affine2 {
    #[inline(always)]
    fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let m = &self.m;
        [
            m[(0, 0)].mul_add(p[0], m[(0, 1)].mul_add(p[1], self.b[0])),
            m[(1, 0)].mul_add(p[0], m[(1, 1)].mul_add(p[1], self.b[1])),
        ]
    }

    fn affine(&self) -> Option<([[f64; 2]; 2], [f64; 2])> {
        let m = &self.m;
        Some((
            [[m[(0, 0)], m[(0, 1)]], [m[(1, 0)], m[(1, 1)]]],
            [self.b[0], self.b[1]],
        ))
    }
}

/// Singular values of a 2×2 matrix, largest first, without an iterative SVD.
pub fn singular_values_2x2(m: &Matrix2<f64>) -> (f64, f64) {
    // σ1,2² = (‖M‖_F² ± sqrt(‖M‖_F⁴ − 4·det²)) / 2.
    let f2 = m.norm_squared();
    let det = m.determinant();
    let disc = (f2 * f2 - 4.0 * det * det).max(0.0).sqrt();
    let s1 = ((f2 + disc) * 0.5).max(0.0).sqrt();
    // σ1·σ2 = |det| is the numerically stable way to the smaller one.
    let s2 = if s1 > 0.0 { det.abs() / s1 } else { 0.0 };
    (s1, s2)
}

/// An affine map `x ↦ M·x + b` in any dimension H.
#[derive(Clone, Debug, PartialEq)]
pub struct AffineN {
    /// H×H linear part.
    pub m: DMatrix<f64>,
    /// Offset of length H.
    pub b: DVector<f64>,
}

impl AffineN {
    /// A map from its parts; the shapes must agree.
    pub fn new(m: DMatrix<f64>, b: DVector<f64>) -> Result<Self> {
        if !m.is_square() || m.nrows() != b.len() {
            return Err(Error::Shape(format!(
                "matrix is {}×{} but offset has length {}",
                m.nrows(),
                m.ncols(),
                b.len()
            )));
        }
        Ok(AffineN { m, b })
    }

    /// Dimension H of the space the map acts on.
    pub fn dim(&self) -> usize {
        self.b.len()
    }

    /// Largest singular value of `M`.
    pub fn sigma_max(&self) -> f64 {
        if self.dim() == 2 {
            return singular_values_2x2(&Matrix2::from_iterator(self.m.iter().copied())).0;
        }
        self.m
            .singular_values()
            .iter()
            .copied()
            .fold(0.0_f64, f64::max)
    }

    /// |det M|.
    pub fn abs_det(&self) -> f64 {
        self.m.determinant().abs()
    }

    /// The image of `p`, written into `out` (no allocation).
    pub fn apply_into(&self, p: &[f64], out: &mut [f64]) {
        let h = self.dim();
        for (i, o) in out.iter_mut().enumerate().take(h) {
            let mut acc = self.b[i];
            for (j, pj) in p.iter().enumerate().take(h) {
                acc += self.m[(i, j)] * pj;
            }
            *o = acc;
        }
    }

    /// The 2-D map, if this one is 2-D.
    pub fn to_affine2(&self) -> Result<Affine2> {
        if self.dim() != 2 {
            return Err(Error::Shape(format!(
                "expected a 2-D map, got dimension {}",
                self.dim()
            )));
        }
        Ok(Affine2::new(
            self.m[(0, 0)],
            self.m[(0, 1)],
            self.m[(1, 0)],
            self.m[(1, 1)],
            self.b[0],
            self.b[1],
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_form_singular_values_match_svd() {
        let m = Matrix2::new(0.3, -0.7, 0.2, 0.45);
        let (s1, s2) = singular_values_2x2(&m);
        let svd = m.svd(false, false).singular_values;
        let (a, b) = (svd[0].max(svd[1]), svd[0].min(svd[1]));
        assert!((s1 - a).abs() < 1e-12 && (s2 - b).abs() < 1e-12);
    }

    #[test]
    fn fixed_point_is_fixed() {
        let f = Affine2::new(0.5, 0.1, -0.2, 0.4, 1.0, -2.0);
        let p = f.fixed_point().unwrap();
        let q = f.apply(p);
        assert!((p[0] - q[0]).abs() < 1e-12 && (p[1] - q[1]).abs() < 1e-12);
    }
}
