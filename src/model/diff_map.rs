//! Differentiable maps of the plane: [`Affine2`]'s parameters and vector–Jacobian
//! products, [`Similitude2`], and [`AffinePart`], the affine map a non-affine map shows the
//! paper's regulariser.
//!
//! The traits they implement, [`DiffMap<2>`](crate::model::map::DiffMap), and the flat
//! parameter layout live in [`crate::model::map`], once for every dimension; see there for
//! what the splat's reverse pass asks of a map. [`Affine2`] has the six coefficients
//! `a b c d e f`; [`Similitude2`] scale, angle and translation (the reflection is structure,
//! not a parameter). `tests/custom_map.rs` adds a non-linear map outside the crate and trains
//! through it end to end.

use crate::model::affine::Affine2;
use crate::model::map::{DiffMap, Map};
// The former home of the map traits and the flat layout: code written against these paths
// keeps compiling.
pub use crate::model::map::{
    DiffMap2, VjpCheck, flat_params, param_offsets, set_flat_params, vjp_check,
};

/// A map the paper's regulariser (singular values, offsets, conditioning) can act on: it
/// names an affine map derived from its parameters and carries that derivation's chain rule.
///
/// For [`Affine2`] it is the map itself; for [`Similitude2`] its matrix form; for a flame
/// transform it would be the pre-affine step.
pub trait AffinePart: DiffMap2 {
    /// The affine map the regulariser sees.
    fn affine_part(&self) -> Affine2;

    /// Adds `∂L/∂θ` to `grad` given `∂L/∂(affine part)` (`g.m` = `∂L/∂M`, `g.b` = `∂L/∂b`).
    fn affine_part_backward(&self, g: &Affine2, grad: &mut [f64]);
}

impl DiffMap<2> for Affine2 {
    const PARAMS: Option<usize> = Some(6);

    #[inline(always)]
    fn n_params(&self) -> usize {
        6
    }

    fn write_params(&self, out: &mut [f64]) {
        out.copy_from_slice(&self.coefficients());
    }

    fn set_params(&mut self, p: &[f64]) {
        *self = Affine2::from_coefficients(p);
    }

    /// `Mᵀλ`.
    #[inline(always)]
    fn vjp_point(&self, _x: [f64; 2], lambda: [f64; 2]) -> [f64; 2] {
        let m = &self.m;
        [
            m[(0, 0)] * lambda[0] + m[(1, 0)] * lambda[1],
            m[(0, 1)] * lambda[0] + m[(1, 1)] * lambda[1],
        ]
    }

    /// `∂L/∂M += λxᵀ`, `∂L/∂b += λ`, in the order `a b c d e f`.
    #[inline(always)]
    fn vjp_params(&self, x: [f64; 2], lambda: [f64; 2], grad: &mut [f64]) {
        let g = &mut grad[..6];
        g[0] += lambda[0] * x[0];
        g[1] += lambda[0] * x[1];
        g[2] += lambda[1] * x[0];
        g[3] += lambda[1] * x[1];
        g[4] += lambda[0];
        g[5] += lambda[1];
    }
}

impl AffinePart for Affine2 {
    fn affine_part(&self) -> Affine2 {
        *self
    }

    fn affine_part_backward(&self, g: &Affine2, grad: &mut [f64]) {
        for (t, v) in grad.iter_mut().zip(g.coefficients()) {
            *t += v;
        }
    }
}

/// A similitude of the plane `x ↦ s·R(φ)·F·x + t`, with `F` the reflection `y ↦ −y` when
/// `reflect` is set and the identity otherwise.
///
/// Parameters `[s, φ, t_x, t_y]`; the reflection is fixed structure (a discrete choice has no
/// gradient). The scale is a raw real: a negative `s` is the same map as `|s|` with `φ + π`,
/// and contractivity (`|s| < 1`) is a constraint for the layer above, as the SVD
/// parameterisation is for affine maps. `cos φ` and `sin φ` are cached, so the chaos game
/// pays no trigonometry per point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Similitude2 {
    s: f64,
    angle: f64,
    reflect: bool,
    t: [f64; 2],
    cos: f64,
    sin: f64,
}

impl Similitude2 {
    /// `s·R(angle)·F·x + t`.
    pub fn new(s: f64, angle: f64, reflect: bool, t: [f64; 2]) -> Self {
        let (sin, cos) = angle.sin_cos();
        Similitude2 {
            s,
            angle,
            reflect,
            t,
            cos,
            sin,
        }
    }

    /// Scale factor `s`.
    pub fn scale(&self) -> f64 {
        self.s
    }

    /// Rotation angle `φ` in radians.
    pub fn angle(&self) -> f64 {
        self.angle
    }

    /// Whether the reflection `y ↦ −y` is applied before the rotation.
    pub fn reflect(&self) -> bool {
        self.reflect
    }

    /// Translation `t`.
    pub fn translation(&self) -> [f64; 2] {
        self.t
    }

    /// The same map as an [`Affine2`] (equal to [`Affine2::similitude`] with these values).
    pub fn to_affine(&self) -> Affine2 {
        Affine2::similitude(self.s, self.angle, self.reflect, self.t)
    }

    /// `F·x`.
    #[inline(always)]
    fn flip(&self, x: [f64; 2]) -> [f64; 2] {
        if self.reflect { [x[0], -x[1]] } else { x }
    }

    /// `R(φ)·y`.
    #[inline(always)]
    fn rotate(&self, y: [f64; 2]) -> [f64; 2] {
        [
            self.cos * y[0] - self.sin * y[1],
            self.sin * y[0] + self.cos * y[1],
        ]
    }
}

impl Map<2> for Similitude2 {
    #[inline(always)]
    fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let z = self.rotate(self.flip(p));
        [self.s * z[0] + self.t[0], self.s * z[1] + self.t[1]]
    }

    fn affine(&self) -> Option<([[f64; 2]; 2], [f64; 2])> {
        Map::<2>::affine(&self.to_affine())
    }
}

impl DiffMap<2> for Similitude2 {
    const PARAMS: Option<usize> = Some(4);

    #[inline(always)]
    fn n_params(&self) -> usize {
        4
    }

    fn write_params(&self, out: &mut [f64]) {
        out.copy_from_slice(&[self.s, self.angle, self.t[0], self.t[1]]);
    }

    fn set_params(&mut self, p: &[f64]) {
        *self = Similitude2::new(p[0], p[1], self.reflect, [p[2], p[3]]);
    }

    /// `s·Fᵀ·R(φ)ᵀ·λ`.
    #[inline(always)]
    fn vjp_point(&self, _x: [f64; 2], lambda: [f64; 2]) -> [f64; 2] {
        let r = [
            self.cos * lambda[0] + self.sin * lambda[1],
            -self.sin * lambda[0] + self.cos * lambda[1],
        ];
        let r = self.flip(r);
        [self.s * r[0], self.s * r[1]]
    }

    /// With `z = R(φ)·F·x`: `∂f/∂s = z`, `∂f/∂φ = s·R′(φ)·F·x = s·(−z_y, z_x)`, `∂f/∂t = I`.
    #[inline(always)]
    fn vjp_params(&self, x: [f64; 2], lambda: [f64; 2], grad: &mut [f64]) {
        let g = &mut grad[..4];
        let z = self.rotate(self.flip(x));
        g[0] += lambda[0] * z[0] + lambda[1] * z[1];
        g[1] += self.s * (lambda[1] * z[0] - lambda[0] * z[1]);
        g[2] += lambda[0];
        g[3] += lambda[1];
    }
}

impl AffinePart for Similitude2 {
    fn affine_part(&self) -> Affine2 {
        self.to_affine()
    }

    /// `M = s·R(φ)·F`: `∂L/∂s = ⟨G, R F⟩`, `∂L/∂φ = ⟨G, s·R′ F⟩`, `∂L/∂t = ∂L/∂b`.
    fn affine_part_backward(&self, g: &Affine2, grad: &mut [f64]) {
        let grad = &mut grad[..4];
        let rf = Similitude2::new(1.0, self.angle, self.reflect, [0.0, 0.0]).to_affine();
        // R′(φ) = R(φ + π/2).
        let drf = Similitude2::new(
            1.0,
            self.angle + std::f64::consts::FRAC_PI_2,
            self.reflect,
            [0.0, 0.0],
        )
        .to_affine();
        grad[0] += g.m.component_mul(&rf.m).sum();
        grad[1] += self.s * g.m.component_mul(&drf.m).sum();
        grad[2] += g.b[0];
        grad[3] += g.b[1];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn similitude_matches_its_affine_form() {
        for reflect in [false, true] {
            let s = Similitude2::new(0.6, 0.9, reflect, [0.3, -0.2]);
            let a = s.to_affine();
            let p = [0.7, -1.3];
            let (u, v) = (s.apply(p), a.apply(p));
            assert!((u[0] - v[0]).abs() < 1e-15 && (u[1] - v[1]).abs() < 1e-15);
        }
    }

    #[test]
    fn flat_layout_round_trips_and_refuses_bad_input() {
        let mut maps = vec![
            Similitude2::new(0.5, 0.1, false, [0.0, 1.0]),
            Similitude2::new(0.4, -0.3, true, [1.0, 0.0]),
        ];
        assert_eq!(param_offsets(&maps), vec![0, 4, 8]);
        let mut flat = flat_params(&maps);
        flat[5] = 0.25;
        set_flat_params(&mut maps, &flat).unwrap();
        assert_eq!(maps[1].angle(), 0.25);
        assert!(maps[1].reflect(), "structure survives new parameters");
        let e = set_flat_params(&mut maps, &flat[..7]).unwrap_err();
        assert!(
            e.to_string().contains("7 parameters given for 2 maps"),
            "{e}"
        );
        flat[6] = f64::NAN;
        let e = set_flat_params(&mut maps, &flat).unwrap_err();
        assert!(e.to_string().contains("map 1, parameter 2"), "{e}");
    }
}
