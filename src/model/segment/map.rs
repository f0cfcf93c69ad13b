//! The map a pair of segments defines: the similitude `z ↦ w·z + t` (complex `w`, `t`) that
//! takes the source segment onto the target segment, and its chain rule back to the four
//! endpoints.
//!
//! The paper ("Calculating Transformations") composes a translation taking `e₁` to `p₁`, the
//! rotation aligning `e₂ − e₁` with `p₂ − p₁`, and the uniform scale matching their lengths.
//! In complex numbers that composition is one formula,
//!
//! `f(z) = p₁ + (z − e₁)·w`,   `w = (p₂ − p₁)/(e₂ − e₁)`,   so `t = p₁ − w·e₁`,
//!
//! orientation-preserving (the paper names no reflection, so there is none: `arg w` is the
//! rotation, `|w|` the scale). It is differentiable wherever `e₁ ≠ e₂`.

use crate::model::segment::complex::{abs, acc, cmul, conj, div, mul, sub};
use crate::model::{Affine2, Map};
use crate::model::{AffinePart, DiffMap};

/// A similitude of the plane without reflection, `z ↦ w·z + t` in complex notation:
/// `x′ = w_re·x − w_im·y + t_x`, `y′ = w_im·x + w_re·y + t_y`.
///
/// Parameters `[w_re, w_im, t_x, t_y]`: linear in the map, so its vector–Jacobian products are
/// products of complex numbers. Scale `|w|`, rotation `arg w`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SegmentMap {
    /// The complex factor `w` (`[re, im]`).
    pub w: [f64; 2],
    /// The translation `t`.
    pub t: [f64; 2],
}

impl SegmentMap {
    /// The identity.
    pub const IDENTITY: SegmentMap = SegmentMap {
        w: [1.0, 0.0],
        t: [0.0, 0.0],
    };

    /// The map taking segment `(e1, e2)` onto `(p1, p2)` (`e1 ↦ p1`, `e2 ↦ p2`); `None` when
    /// the source segment has zero length.
    pub fn between(e1: [f64; 2], e2: [f64; 2], p1: [f64; 2], p2: [f64; 2]) -> Option<Self> {
        let e = sub(e2, e1);
        if e == [0.0, 0.0] {
            return None;
        }
        let w = div(sub(p2, p1), e);
        Some(SegmentMap {
            w,
            t: sub(p1, mul(w, e1)),
        })
    }

    /// The chain rule of [`SegmentMap::between`]: given `G_w`, `G_t` (the loss gradient with
    /// respect to `w` and `t`), the gradients with respect to `[e1, e2, p1, p2]`.
    ///
    /// With `D = p₂ − p₁`, `E = e₂ − e₁`, `w = D/E`, `t = p₁ − w·e₁`:
    /// `G_w += −conj(e₁)·G_t`, `G_e₁ = −conj(w)·G_t`, `G_p₁ = G_t`, then
    /// `G_D = conj(1/E)·G_w`, `G_E = −conj(w/E)·G_w`, and `D`, `E` are differences.
    pub fn between_backward(
        e1: [f64; 2],
        e2: [f64; 2],
        p1: [f64; 2],
        p2: [f64; 2],
        g_w: [f64; 2],
        g_t: [f64; 2],
    ) -> [[f64; 2]; 4] {
        let e = sub(e2, e1);
        let w = div(sub(p2, p1), e);
        let mut gw = g_w;
        let cg = cmul(e1, g_t);
        gw = sub(gw, cg);
        let mut ge1 = [-cmul(w, g_t)[0], -cmul(w, g_t)[1]];
        let mut gp1 = g_t;
        let inv_e = div([1.0, 0.0], e);
        let gd = cmul(inv_e, gw);
        let ge = cmul(mul(w, inv_e), gw);
        // D = p2 − p1, E = e2 − e1 (G_E carries the minus sign of ∂w/∂E = −w/E).
        let gp2 = gd;
        gp1 = sub(gp1, gd);
        let ge2 = [-ge[0], -ge[1]];
        acc(&mut ge1, ge);
        [ge1, ge2, gp1, gp2]
    }

    /// The scale factor `|w|` (the map's Lipschitz constant).
    pub fn scale(&self) -> f64 {
        abs(self.w)
    }

    /// `self ∘ inner` (apply `inner` first): `w = w₁·w₂`, `t = w₁·t₂ + t₁`.
    #[inline(always)]
    pub fn compose(&self, inner: &SegmentMap) -> SegmentMap {
        let t = mul(self.w, inner.t);
        SegmentMap {
            w: mul(self.w, inner.w),
            t: [t[0] + self.t[0], t[1] + self.t[1]],
        }
    }

    /// The same map as an [`Affine2`].
    pub fn to_affine(&self) -> Affine2 {
        Affine2::new(
            self.w[0], -self.w[1], self.w[1], self.w[0], self.t[0], self.t[1],
        )
    }
}

impl Map<2> for SegmentMap {
    #[inline(always)]
    fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let z = mul(self.w, p);
        [z[0] + self.t[0], z[1] + self.t[1]]
    }
}

impl DiffMap<2> for SegmentMap {
    const PARAMS: Option<usize> = Some(4);

    #[inline(always)]
    fn n_params(&self) -> usize {
        4
    }

    fn write_params(&self, out: &mut [f64]) {
        out.copy_from_slice(&[self.w[0], self.w[1], self.t[0], self.t[1]]);
    }

    fn set_params(&mut self, p: &[f64]) {
        self.w = [p[0], p[1]];
        self.t = [p[2], p[3]];
    }

    /// `conj(w)·λ`.
    #[inline(always)]
    fn vjp_point(&self, _x: [f64; 2], lambda: [f64; 2]) -> [f64; 2] {
        cmul(self.w, lambda)
    }

    /// `G_w += conj(x)·λ`, `G_t += λ`.
    #[inline(always)]
    fn vjp_params(&self, x: [f64; 2], lambda: [f64; 2], grad: &mut [f64]) {
        let gw = mul(conj(x), lambda);
        let g = &mut grad[..4];
        g[0] += gw[0];
        g[1] += gw[1];
        g[2] += lambda[0];
        g[3] += lambda[1];
    }
}

impl AffinePart for SegmentMap {
    fn affine_part(&self) -> Affine2 {
        self.to_affine()
    }

    /// `M = [[w_re, −w_im], [w_im, w_re]]`: `∂L/∂w_re = G₀₀ + G₁₁`, `∂L/∂w_im = G₁₀ − G₀₁`.
    fn affine_part_backward(&self, g: &Affine2, grad: &mut [f64]) {
        let grad = &mut grad[..4];
        grad[0] += g.m[(0, 0)] + g.m[(1, 1)];
        grad[1] += g.m[(1, 0)] - g.m[(0, 1)];
        grad[2] += g.b[0];
        grad[3] += g.b[1];
    }
}
