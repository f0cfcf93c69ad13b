//! Variations 31–37: noise, julian, juliascope, blur, gaussian_blur, radial_blur, pie. All
//! draw random numbers (julian and juliascope only to pick a root), so they are
//! forward-only; their draws come in flam3's order.

use std::f64::consts::PI;

use rand::RngCore;

use super::{Pre, c_int, c_int32, four_uniforms, from_polar, rand01};
use crate::model::flame::scalar::FlameScalar;

type P<T> = (T, T);

#[inline(always)]
pub(super) fn noise<T: FlameScalar, R: RngCore + ?Sized>(w: T, f: &Pre<T>, rng: &mut R) -> P<T> {
    let a = rand01(rng) * 2.0 * PI;
    let (s, c) = a.sin_cos();
    let r = w * rand01(rng);
    (f.tx * r * c, f.ty * r * s)
}

/// julian: one of the `|power|` roots of z^dist, drawn at random.
/// `d = [|power|, dist/power/2]`.
#[inline(always)]
pub(super) fn julian<T: FlameScalar, R: RngCore + ?Sized>(
    w: T,
    p: &[T; 8],
    d: &[T; 4],
    f: &Pre<T>,
    rng: &mut R,
) -> P<T> {
    let t = c_int(d[0].v() * rand01(rng));
    let a = (f.atan_yx() + 2.0 * PI * t) / p[0];
    let r = w * f.sumsq.pow(d[1]);
    from_polar(r, a)
}

#[inline(always)]
pub(super) fn juliascope<T: FlameScalar, R: RngCore + ?Sized>(
    w: T,
    p: &[T; 8],
    d: &[T; 4],
    f: &Pre<T>,
    rng: &mut R,
) -> P<T> {
    let t = c_int32(d[0].v() * rand01(rng));
    let a = if t & 1 == 0 {
        (f.atan_yx() + 2.0 * PI * t as f64) / p[0]
    } else {
        (-f.atan_yx() + 2.0 * PI * t as f64) / p[0]
    };
    let r = w * f.sumsq.pow(d[1]);
    from_polar(r, a)
}

#[inline(always)]
pub(super) fn blur<T: FlameScalar, R: RngCore + ?Sized>(w: T, rng: &mut R) -> P<T> {
    let a = rand01(rng) * 2.0 * PI;
    let r = w * rand01(rng);
    from_polar(r, T::cst(a))
}

#[inline(always)]
pub(super) fn gaussian_blur<T: FlameScalar, R: RngCore + ?Sized>(w: T, rng: &mut R) -> P<T> {
    let a = rand01(rng) * 2.0 * PI;
    let r = w * four_uniforms(rng);
    from_polar(r, T::cst(a))
}

/// radial_blur: `d = [sin(angle·π/2), cos(angle·π/2)]` (spin and zoom amounts).
#[inline(always)]
pub(super) fn radial_blur<T: FlameScalar, R: RngCore + ?Sized>(
    w: T,
    d: &[T; 4],
    f: &Pre<T>,
    rng: &mut R,
) -> P<T> {
    let g = w * four_uniforms(rng);
    let ra = f.sqrt;
    let a = f.atan_yx() + d[0] * g;
    let (s, c) = a.sin_cos();
    let rz = d[1] * g - 1.0;
    (ra * c + rz * f.tx, ra * s + rz * f.ty)
}

#[inline(always)]
pub(super) fn pie<T: FlameScalar, R: RngCore + ?Sized>(w: T, p: &[T; 8], rng: &mut R) -> P<T> {
    let (slices, rotation, thickness) = (p[0], p[1], p[2]);
    let sl = c_int(rand01(rng) * slices.v() + 0.5);
    let a = rotation + (thickness * rand01(rng) + sl) * (2.0 * PI) / slices;
    let r = w * rand01(rng);
    from_polar(r, a)
}
