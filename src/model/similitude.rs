//! Similitudes `x ↦ s·R·x + t` in any dimension H (R orthogonal: a rotation, reflected or not), the map family of
//! the EM strategy, and uniform random rotations to initialise them.

use nalgebra::{DMatrix, DVector};
use rand::Rng;
use rand_distr::StandardNormal;

use crate::error::{Error, Result};
use crate::model::affine::AffineN;

/// A similitude `x ↦ s·R·x + t` with `s > 0` and `R ∈ SO(H)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Similitude {
    /// Scale factor (the map is contractive when `s < 1`).
    pub s: f64,
    /// H×H orthogonal matrix: a rotation (determinant +1), or a rotation and a reflection
    /// (−1) where a fit allows reflections.
    pub r: DMatrix<f64>,
    /// Translation of length H.
    pub t: DVector<f64>,
}

impl Similitude {
    /// A similitude from its parts; checks shapes, finiteness and `s > 0`.
    pub fn new(s: f64, r: DMatrix<f64>, t: DVector<f64>) -> Result<Self> {
        if !r.is_square() || r.nrows() != t.len() {
            return Err(Error::Shape(format!(
                "rotation is {}×{} but translation has length {}",
                r.nrows(),
                r.ncols(),
                t.len()
            )));
        }
        if !(s.is_finite() && s > 0.0) {
            return Err(Error::param(
                "s",
                format!("scale must be finite and > 0, got {s}"),
            ));
        }
        if r.iter().chain(t.iter()).any(|v| !v.is_finite()) {
            return Err(Error::NonFinite {
                what: "similitude".into(),
                location: "rotation or translation".into(),
                value: f64::NAN,
            });
        }
        Ok(Similitude { s, r, t })
    }

    /// The identity map in dimension `h`.
    pub fn identity(h: usize) -> Self {
        Similitude {
            s: 1.0,
            r: DMatrix::identity(h, h),
            t: DVector::zeros(h),
        }
    }

    /// Dimension H.
    pub fn dim(&self) -> usize {
        self.t.len()
    }

    /// The image of `x`.
    pub fn apply(&self, x: &DVector<f64>) -> DVector<f64> {
        &self.r * x * self.s + &self.t
    }

    /// The composition `self ∘ other` (apply `other` first), again a similitude.
    pub fn compose(&self, other: &Similitude) -> Similitude {
        Similitude {
            s: self.s * other.s,
            r: &self.r * &other.r,
            t: &self.r * &other.t * self.s + &self.t,
        }
    }

    /// The same map as a general affine map `M = s·R`, `b = t`.
    pub fn to_affine(&self) -> AffineN {
        AffineN {
            m: &self.r * self.s,
            b: self.t.clone(),
        }
    }

    /// Recovers a similitude from an affine map whose linear part is `s·R` with `R ∈ O(H)`
    /// `tol` bounds the allowed deviation of `Mᵀ·M / s²` from the identity.
    pub fn from_affine(a: &AffineN, tol: f64) -> Result<Self> {
        let h = a.dim();
        let det = a.m.determinant();
        if !(det.is_finite() && det != 0.0) {
            return Err(Error::Shape(format!(
                "linear part has determinant {det}; a similitude needs a non-zero one"
            )));
        }
        let s = det.abs().powf(1.0 / h as f64);
        let r = &a.m / s;
        let dev = (r.transpose() * &r - DMatrix::<f64>::identity(h, h)).amax();
        if dev > tol {
            return Err(Error::Shape(format!(
                "linear part is not a scaled rotation (‖RᵀR − I‖max = {dev:.3e} > {tol:.1e})"
            )));
        }
        Similitude::new(s, r, a.b.clone())
    }
}

/// A rotation drawn uniformly (Haar measure) from SO(h): QR of a Gaussian matrix with the
/// sign of R's diagonal folded into Q, then one column flipped if the determinant is −1.
pub fn random_rotation<R: Rng + ?Sized>(h: usize, rng: &mut R) -> DMatrix<f64> {
    let g = DMatrix::<f64>::from_fn(h, h, |_, _| rng.sample(StandardNormal));
    let qr = g.qr();
    let mut q = qr.q();
    let r = qr.r();
    for j in 0..h {
        if r[(j, j)] < 0.0 {
            q.column_mut(j).neg_mut();
        }
    }
    if q.determinant() < 0.0 {
        q.column_mut(0).neg_mut();
    }
    q
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use rand_xoshiro::Xoshiro256PlusPlus;

    #[test]
    fn random_rotations_are_proper() {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
        for h in [2, 3, 5] {
            let r = random_rotation(h, &mut rng);
            let e = (r.transpose() * &r - DMatrix::<f64>::identity(h, h)).amax();
            assert!(e < 1e-12, "RᵀR ≠ I (err {e})");
            assert!((r.determinant() - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn affine_round_trip() {
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(1);
        let s = Similitude::new(
            0.4,
            random_rotation(3, &mut rng),
            DVector::from_vec(vec![1.0, 2.0, 3.0]),
        )
        .unwrap();
        let back = Similitude::from_affine(&s.to_affine(), 1e-9).unwrap();
        assert!((back.s - 0.4).abs() < 1e-12);
        assert!((back.r - &s.r).amax() < 1e-12);
    }
}
