//! Differentiable maps of the plane: what the splatter's reverse pass asks of a map.
//!
//! The fused splat op (`render::splat`) runs the chaos game forward, keeping every state
//! `x_k` of every trajectory, and differentiates it by a backward scan
//! `λ_k = (∂f_{i_k}/∂x)(x_k)ᵀ·λ_{k+1} + ∂L/∂x_k`, accumulating
//! `∂L/∂θ_{i_k} += (∂f_{i_k}/∂θ)(x_k)ᵀ·λ_{k+1}` into the parameters of the map applied at
//! step k. So a map needs, besides its forward [`Map2::apply`], the two vector–Jacobian
//! products at a point: with respect to the point and with respect to its own parameters.
//! For an affine map both Jacobians are constant; for a non-linear one (a flame transform's
//! variations) they depend on the point, which is why the vjps take `x`.
//!
//! Each map owns a flat parameter vector of [`DiffMap2::n_params`] numbers. A set of maps
//! lays its parameters out map after map ([`param_offsets`]); the splat's reverse pass
//! returns its gradient in that layout. Parameters shared between maps (segment maps driven
//! by common control points) live in a layer above: it gathers each map's parameters from
//! the shared vector and scatters each map's gradient back, as
//! [`Parameterisation`](crate::model::param::Parameterisation) does for affine maps.
//!
//! Implementations here: [`Affine2`] (the six coefficients `a b c d e f`) and
//! [`Similitude2`] (scale, angle, translation; the reflection is structure, not a
//! parameter). `tests/custom_map.rs` adds a non-linear map outside the crate and trains
//! through it end to end; [`vjp_check`] is the finite-difference check every implementation
//! should pass.

use crate::error::{Error, Result};
use crate::model::affine::{Affine2, Map2};

/// A map of the plane with a flat vector of real parameters and the vector–Jacobian
/// products the splat's reverse pass needs (see the module docs).
///
/// Everything is `#[inline]`-friendly and monomorphised by the splatter: a map type is a
/// type parameter of the hot loops, never a trait object.
pub trait DiffMap2: Map2 + Clone {
    /// The parameter count, when every map of the type has the same one (`Some(6)` for
    /// [`Affine2`]); `None` when it depends on the map (a flame transform's variations).
    /// It lets the backward scan index gradients with a compile-time stride; a type that
    /// sets it must return the same number from [`DiffMap2::n_params`] (the scan falls back
    /// to per-map offsets when they disagree).
    const PARAMS: Option<usize> = None;

    /// Number of parameters of this map.
    fn n_params(&self) -> usize;

    /// Writes the parameters into `out` (`out.len() == self.n_params()`).
    fn write_params(&self, out: &mut [f64]);

    /// Sets the parameters from `p` (`p.len() == self.n_params()`); everything that is not a
    /// parameter (a reflection flag, which variations a flame transform has) is kept.
    fn set_params(&mut self, p: &[f64]);

    /// `(∂f/∂x)(x)ᵀ·λ`: the vector–Jacobian product with respect to the point.
    fn vjp_point(&self, x: [f64; 2], lambda: [f64; 2]) -> [f64; 2];

    /// Adds `(∂f/∂θ)(x)ᵀ·λ` to `grad` (`grad.len() == self.n_params()`).
    fn vjp_params(&self, x: [f64; 2], lambda: [f64; 2], grad: &mut [f64]);

    /// Both products at once, as the backward scan uses them: adds `(∂f/∂θ)ᵀ·λ` to `grad`
    /// and returns `(∂f/∂x)ᵀ·λ`. Override it when the two share work (a non-linear map
    /// evaluates its inner affine step once).
    #[inline(always)]
    fn vjp(&self, x: [f64; 2], lambda: [f64; 2], grad: &mut [f64]) -> [f64; 2] {
        self.vjp_params(x, lambda, grad);
        self.vjp_point(x, lambda)
    }

    /// The parameters as a vector.
    fn params(&self) -> Vec<f64> {
        let mut p = vec![0.0; self.n_params()];
        self.write_params(&mut p);
        p
    }
}

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

/// Where each map's parameters start in the flat layout, plus the total at the end
/// (`n + 1` entries: map `i` owns `offsets[i]..offsets[i + 1]`).
pub fn param_offsets<M: DiffMap2>(maps: &[M]) -> Vec<usize> {
    let mut off = Vec::with_capacity(maps.len() + 1);
    let mut acc = 0;
    off.push(0);
    for m in maps {
        acc += m.n_params();
        off.push(acc);
    }
    off
}

/// All parameters of `maps`, map after map.
pub fn flat_params<M: DiffMap2>(maps: &[M]) -> Vec<f64> {
    let off = param_offsets(maps);
    let mut out = vec![0.0; off[maps.len()]];
    for (i, m) in maps.iter().enumerate() {
        m.write_params(&mut out[off[i]..off[i + 1]]);
    }
    out
}

/// Sets the parameters of `maps` from the flat layout; refuses a wrong length or a
/// non-finite value (naming the map and parameter).
pub fn set_flat_params<M: DiffMap2>(maps: &mut [M], flat: &[f64]) -> Result<()> {
    let off = param_offsets(maps);
    if flat.len() != off[maps.len()] {
        return Err(Error::Shape(format!(
            "{} parameters given for {} maps that have {} together",
            flat.len(),
            maps.len(),
            off[maps.len()]
        )));
    }
    check_finite_params(flat, &off)?;
    for (i, m) in maps.iter_mut().enumerate() {
        m.set_params(&flat[off[i]..off[i + 1]]);
    }
    Ok(())
}

/// Refuses the first non-finite parameter of a flat layout with offsets `off`.
pub(crate) fn check_finite_params(flat: &[f64], off: &[usize]) -> Result<()> {
    if let Some((j, v)) = flat.iter().enumerate().find(|(_, v)| !v.is_finite()) {
        let i = off.partition_point(|&o| o <= j) - 1;
        return Err(Error::NonFinite {
            what: "maps".into(),
            location: format!("map {i}, parameter {}", j - off[i]),
            value: *v,
        });
    }
    Ok(())
}

/// Largest discrepancies between a map's vjps and central finite differences of `λᵀf`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VjpCheck {
    /// `max |vjp_point − FD|` over the two coordinates.
    pub point: f64,
    /// `max |vjp_params − FD|` over the parameters.
    pub params: f64,
    /// `max |FD|` over all entries, to judge the errors against.
    pub scale: f64,
    /// `|vjp − (vjp_params, vjp_point)|`: the fused product agrees with the separate ones.
    pub fused: f64,
}

/// Checks [`DiffMap2::vjp_point`], [`DiffMap2::vjp_params`] and [`DiffMap2::vjp`] at `x`
/// against central differences of `θ, x ↦ λᵀf_θ(x)` with step `h`; f64 throughout, so with
/// `h ≈ 1e-6` a correct smooth map shows errors around 1e-9 of [`VjpCheck::scale`].
pub fn vjp_check<M: DiffMap2>(map: &M, x: [f64; 2], lambda: [f64; 2], h: f64) -> VjpCheck {
    let dot = |m: &M, p: [f64; 2]| {
        let y = m.apply(p);
        lambda[0] * y[0] + lambda[1] * y[1]
    };
    let mut scale = 0.0f64;
    let gx = map.vjp_point(x, lambda);
    let mut point = 0.0f64;
    for k in 0..2 {
        let (mut up, mut down) = (x, x);
        up[k] += h;
        down[k] -= h;
        let fd = (dot(map, up) - dot(map, down)) / (2.0 * h);
        point = point.max((fd - gx[k]).abs());
        scale = scale.max(fd.abs());
    }
    let theta = map.params();
    let mut gp = vec![0.0; theta.len()];
    map.vjp_params(x, lambda, &mut gp);
    let mut params = 0.0f64;
    for k in 0..theta.len() {
        let bumped = |d: f64| {
            let mut t = theta.clone();
            t[k] += d;
            let mut m = map.clone();
            m.set_params(&t);
            m
        };
        let fd = (dot(&bumped(h), x) - dot(&bumped(-h), x)) / (2.0 * h);
        params = params.max((fd - gp[k]).abs());
        scale = scale.max(fd.abs());
    }
    let mut gf = vec![0.0; theta.len()];
    let gxf = map.vjp(x, lambda, &mut gf);
    let fused = gf
        .iter()
        .zip(&gp)
        .chain(gxf.iter().zip(&gx))
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    VjpCheck {
        point,
        params,
        scale,
        fused,
    }
}

impl DiffMap2 for Affine2 {
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

impl Map2 for Similitude2 {
    #[inline(always)]
    fn apply(&self, p: [f64; 2]) -> [f64; 2] {
        let z = self.rotate(self.flip(p));
        [self.s * z[0] + self.t[0], self.s * z[1] + self.t[1]]
    }
}

impl DiffMap2 for Similitude2 {
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
