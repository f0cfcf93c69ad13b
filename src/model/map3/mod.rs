//! Maps of space (R³): what the 3-D chaos game iterates and the multi-view splat
//! differentiates.
//!
//! The 3-D counterpart of [`Map2`](crate::model::Map2) and
//! [`DiffMap2`](crate::model::DiffMap2): a map needs its forward [`Map3::apply`] and, to be
//! trained through the multi-view splat ([`crate::render::splat3d`]), a flat parameter
//! vector and the two vector–Jacobian products at a point, `(∂f/∂x)(x)ᵀ·λ` and
//! `(∂f/∂θ)(x)ᵀ·λ`, which the backward scan of [`crate::chaos::Tape3`] calls once per step.
//! The traits are separate from the 2-D ones rather than generic over the dimension: the
//! 2-D traits' fixed `[f64; 2]` signatures are what the 2-D splat's hot loops and every
//! existing map type are written against, and a `const D: usize` version would touch all of
//! them for no gain in the 3-D code.
//!
//! Implementations:
//! - [`Affine3`]: the twelve coefficients of `x ↦ M·x + b` (row-major `M`, then `b`): the
//!   form codes are written in and ground truths are drawn with;
//! - [`SvdMap3`]: the chaotic-splatting paper's SVD parameterisation taken to 3-D,
//!   `M = R(q_U)·diag(c·sigmoid σ)·R(q_V)ᵀ`, `b = tanh β`, the rotations unit quaternions
//!   (any non-zero 4-vector, normalised when decoded): every θ is a contraction;
//! - [`Similitude3`]: `x ↦ s·R(q)·F·x + t` (`F` an optional mirror), the EM family in 3-D.
//!
//! [`vjp_check`] is the finite-difference check every implementation should pass.

mod affine3;
mod rotation;
mod similitude3;
mod svd3;

pub use affine3::{Affine3, fern_3d, sierpinski_tetrahedron};
pub use rotation::{quaternion_from_rotation, rotation_from_quaternion, rotation_jacobian};
pub use similitude3::Similitude3;
pub use svd3::{SVD3_PARAMS, SvdMap3};

use crate::error::{Error, Result};

/// A map of space that a chaos game can iterate.
pub trait Map3: Send + Sync {
    /// The image of `p` under the map.
    fn apply(&self, p: [f64; 3]) -> [f64; 3];
}

/// A map of space with a flat vector of real parameters and the vector–Jacobian products
/// the 3-D backward scan needs (the 3-D form of [`DiffMap2`](crate::model::DiffMap2)).
pub trait DiffMap3: Map3 + Clone {
    /// The parameter count when every map of the type has the same one (`Some(12)` for
    /// [`Affine3`]); `None` when it depends on the map.
    const PARAMS: Option<usize> = None;

    /// Number of parameters of this map.
    fn n_params(&self) -> usize;

    /// Writes the parameters into `out` (`out.len() == self.n_params()`).
    fn write_params(&self, out: &mut [f64]);

    /// Sets the parameters from `p` (`p.len() == self.n_params()`); structure that is not a
    /// parameter (a mirror flag) is kept.
    fn set_params(&mut self, p: &[f64]);

    /// `(∂f/∂x)(x)ᵀ·λ`: the vector–Jacobian product with respect to the point.
    fn vjp_point(&self, x: [f64; 3], lambda: [f64; 3]) -> [f64; 3];

    /// Adds `(∂f/∂θ)(x)ᵀ·λ` to `grad` (`grad.len() == self.n_params()`).
    fn vjp_params(&self, x: [f64; 3], lambda: [f64; 3], grad: &mut [f64]);

    /// Both products at once, as the backward scan uses them: adds `(∂f/∂θ)ᵀ·λ` to `grad`
    /// and returns `(∂f/∂x)ᵀ·λ`.
    #[inline(always)]
    fn vjp(&self, x: [f64; 3], lambda: [f64; 3], grad: &mut [f64]) -> [f64; 3] {
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

/// Where each map's parameters start in the flat layout, plus the total at the end.
pub fn param_offsets<M: DiffMap3>(maps: &[M]) -> Vec<usize> {
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
pub fn flat_params<M: DiffMap3>(maps: &[M]) -> Vec<f64> {
    let off = param_offsets(maps);
    let mut out = vec![0.0; off[maps.len()]];
    for (i, m) in maps.iter().enumerate() {
        m.write_params(&mut out[off[i]..off[i + 1]]);
    }
    out
}

/// Sets the parameters of `maps` from the flat layout; refuses a wrong length or a
/// non-finite value (naming the map and parameter).
pub fn set_flat_params<M: DiffMap3>(maps: &mut [M], flat: &[f64]) -> Result<()> {
    let off = param_offsets(maps);
    if flat.len() != off[maps.len()] {
        return Err(Error::Shape(format!(
            "{} parameters given for {} maps that have {} together",
            flat.len(),
            maps.len(),
            off[maps.len()]
        )));
    }
    crate::model::diff_map::check_finite_params(flat, &off)?;
    for (i, m) in maps.iter_mut().enumerate() {
        m.set_params(&flat[off[i]..off[i + 1]]);
    }
    Ok(())
}

/// Largest discrepancies between a map's vjps and central finite differences of `λᵀf`
/// (the 3-D [`VjpCheck`](crate::model::diff_map::VjpCheck)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VjpCheck3 {
    /// `max |vjp_point − FD|` over the three coordinates.
    pub point: f64,
    /// `max |vjp_params − FD|` over the parameters.
    pub params: f64,
    /// `max |FD|` over all entries, to judge the errors against.
    pub scale: f64,
    /// `|vjp − (vjp_params, vjp_point)|`: the fused product agrees with the separate ones.
    pub fused: f64,
}

/// Checks [`DiffMap3::vjp_point`], [`DiffMap3::vjp_params`] and [`DiffMap3::vjp`] at `x`
/// against central differences of `θ, x ↦ λᵀf_θ(x)` with step `h`, in f64.
pub fn vjp_check<M: DiffMap3>(map: &M, x: [f64; 3], lambda: [f64; 3], h: f64) -> VjpCheck3 {
    let dot = |m: &M, p: [f64; 3]| {
        let y = m.apply(p);
        lambda[0] * y[0] + lambda[1] * y[1] + lambda[2] * y[2]
    };
    let mut scale = 0.0f64;
    let gx = map.vjp_point(x, lambda);
    let mut point = 0.0f64;
    for k in 0..3 {
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
    VjpCheck3 {
        point,
        params,
        scale,
        fused,
    }
}
