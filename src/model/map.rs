//! The map traits, once for every dimension: what a chaos game iterates ([`Map`]) and what
//! a differentiable renderer's reverse pass asks of a map ([`DiffMap`]).
//!
//! The splats run the chaos game forward, keeping every state `x_k` of every trajectory,
//! and differentiate it by a backward scan
//! `λ_k = (∂f_{i_k}/∂x)(x_k)ᵀ·λ_{k+1} + ∂L/∂x_k`, accumulating
//! `∂L/∂θ_{i_k} += (∂f_{i_k}/∂θ)(x_k)ᵀ·λ_{k+1}` into the parameters of the map applied at
//! step k. So a map needs, besides its forward [`Map::apply`], the two vector–Jacobian
//! products at a point: with respect to the point and with respect to its own parameters.
//! For an affine map both Jacobians are constant; for a non-linear one (a flame transform's
//! variations, a segment map) they depend on the point, which is why the vjps take `x`.
//!
//! The dimension is a const parameter, `[f64; D]` points: a map of the plane implements
//! `Map<2>` and `DiffMap<2>`, a map of space `Map<3>` and `DiffMap<3>`. The hot loops are
//! monomorphised per map type either way, so the 2-D code compiles to what it did when its
//! traits had fixed `[f64; 2]` signatures. [`Map2`], [`Map3`], [`DiffMap2`] and [`DiffMap3`]
//! are the names the renderers' bounds are written with: each is implemented for every type
//! that implements the dimension's trait, so nothing implements them by hand.
//!
//! Each map owns a flat parameter vector of [`DiffMap::n_params`] numbers. A set of maps lays
//! its parameters out map after map ([`param_offsets`]); the reverse passes return their
//! gradients in that layout. Parameters shared between maps (segment maps driven by common
//! control points) live in a layer above: it gathers each map's parameters from the shared
//! vector and scatters each map's gradient back, as
//! [`Parameterisation`](crate::model::param::Parameterisation) does for affine maps.
//! [`vjp_check`] is the finite-difference check every implementation should pass, in any
//! dimension.

use crate::error::{Error, Result};

/// A map of `R^D` that a chaos game can iterate.
///
/// Generators and the evaluation renderers are written once against it (through [`Map2`]
/// and [`Map3`]); a map a differentiable renderer should train also implements [`DiffMap`].
pub trait Map<const D: usize>: Send + Sync {
    /// The image of `p` under the map.
    fn apply(&self, p: [f64; D]) -> [f64; D];

    /// The map as `x ↦ M·x + b`, rows of `M` then `b`, when it is affine (what the deep-zoom
    /// sampler composes, [`crate::chaos::WindowWords`]); `None`, the default, for non-linear
    /// maps.
    fn affine(&self) -> Option<([[f64; D]; D], [f64; D])> {
        None
    }
}

/// A map of `R^D` with a flat vector of real parameters and the vector–Jacobian products
/// the reverse passes need (see the module docs).
///
/// Everything is `#[inline]`-friendly and monomorphised by the renderers: a map type is a
/// type parameter of the hot loops, never a trait object.
pub trait DiffMap<const D: usize>: Map<D> + Clone {
    /// The parameter count, when every map of the type has the same one (`Some(6)` for
    /// [`Affine2`](crate::model::Affine2), `Some(12)` for
    /// [`Affine3`](crate::model::map3::Affine3)); `None` when it depends on the map (a flame
    /// transform's variations). It lets a backward scan index gradients with a compile-time
    /// stride; a type that sets it must return the same number from [`DiffMap::n_params`]
    /// (the 2-D scan falls back to per-map offsets when they disagree).
    const PARAMS: Option<usize> = None;

    /// Number of parameters of this map.
    fn n_params(&self) -> usize;

    /// Writes the parameters into `out` (`out.len() == self.n_params()`).
    fn write_params(&self, out: &mut [f64]);

    /// Sets the parameters from `p` (`p.len() == self.n_params()`); everything that is not a
    /// parameter (a reflection flag, which variations a flame transform has) is kept.
    fn set_params(&mut self, p: &[f64]);

    /// `(∂f/∂x)(x)ᵀ·λ`: the vector–Jacobian product with respect to the point.
    fn vjp_point(&self, x: [f64; D], lambda: [f64; D]) -> [f64; D];

    /// Adds `(∂f/∂θ)(x)ᵀ·λ` to `grad` (`grad.len() == self.n_params()`).
    fn vjp_params(&self, x: [f64; D], lambda: [f64; D], grad: &mut [f64]);

    /// Both products at once, as the backward scans use them: adds `(∂f/∂θ)ᵀ·λ` to `grad`
    /// and returns `(∂f/∂x)ᵀ·λ`. Override it when the two share work (a non-linear map
    /// evaluates its inner affine step once).
    #[inline(always)]
    fn vjp(&self, x: [f64; D], lambda: [f64; D], grad: &mut [f64]) -> [f64; D] {
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

/// A map of the plane: every [`Map<2>`](Map).
pub trait Map2: Map<2> {}
impl<T: Map<2> + ?Sized> Map2 for T {}

/// A map of space: every [`Map<3>`](Map).
pub trait Map3: Map<3> {}
impl<T: Map<3> + ?Sized> Map3 for T {}

/// A differentiable map of the plane, what the 2-D splat trains: every
/// [`DiffMap<2>`](DiffMap).
pub trait DiffMap2: DiffMap<2> + Map2 {}
impl<T: DiffMap<2>> DiffMap2 for T {}

/// A differentiable map of space, what the multi-view splat trains: every
/// [`DiffMap<3>`](DiffMap).
pub trait DiffMap3: DiffMap<3> + Map3 {}
impl<T: DiffMap<3>> DiffMap3 for T {}

/// Where each map's parameters start in the flat layout, plus the total at the end
/// (`n + 1` entries: map `i` owns `offsets[i]..offsets[i + 1]`).
pub fn param_offsets<const D: usize, M: DiffMap<D>>(maps: &[M]) -> Vec<usize> {
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
pub fn flat_params<const D: usize, M: DiffMap<D>>(maps: &[M]) -> Vec<f64> {
    let off = param_offsets(maps);
    let mut out = vec![0.0; off[maps.len()]];
    for (i, m) in maps.iter().enumerate() {
        m.write_params(&mut out[off[i]..off[i + 1]]);
    }
    out
}

/// Sets the parameters of `maps` from the flat layout; refuses a wrong length or a
/// non-finite value (naming the map and parameter).
pub fn set_flat_params<const D: usize, M: DiffMap<D>>(maps: &mut [M], flat: &[f64]) -> Result<()> {
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
    /// `max |vjp_point − FD|` over the coordinates.
    pub point: f64,
    /// `max |vjp_params − FD|` over the parameters.
    pub params: f64,
    /// `max |FD|` over all entries, to judge the errors against.
    pub scale: f64,
    /// `|vjp − (vjp_params, vjp_point)|`: the fused product agrees with the separate ones.
    pub fused: f64,
}

/// Checks [`DiffMap::vjp_point`], [`DiffMap::vjp_params`] and [`DiffMap::vjp`] at `x`
/// against central differences of `θ, x ↦ λᵀf_θ(x)` with step `h`; f64 throughout, so with
/// `h ≈ 1e-6` a correct smooth map shows errors around 1e-9 of [`VjpCheck::scale`].
pub fn vjp_check<const D: usize, M: DiffMap<D>>(
    map: &M,
    x: [f64; D],
    lambda: [f64; D],
    h: f64,
) -> VjpCheck {
    let dot = |m: &M, p: [f64; D]| {
        let y = m.apply(p);
        (0..D).map(|k| lambda[k] * y[k]).sum::<f64>()
    };
    let mut scale = 0.0f64;
    let gx = map.vjp_point(x, lambda);
    let mut point = 0.0f64;
    for k in 0..D {
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
