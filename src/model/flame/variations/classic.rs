//! Variations 0–30: those of Draves & Reckase, "The Fractal Flame Algorithm" (linear …
//! perspective), in flam3's form. Several use flam3's angle θ = atan2(x, y) and its
//! `sina = x/r`, `cosa = y/r`; waves, popcorn, rings and fan read the transform's
//! pre-affine coefficients `c`, `e`, `f` as their parameters.

use std::f64::consts::{FRAC_1_PI, PI};

use rand::RngCore;

use super::{EPS, Pre, c_int, from_polar, rand_bit};
use crate::model::flame::scalar::FlameScalar;

type P<T> = (T, T);

#[inline(always)]
pub(super) fn linear<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    (w * f.tx, w * f.ty)
}

#[inline(always)]
pub(super) fn sinusoidal<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    (w * f.tx.sin(), w * f.ty.sin())
}

#[inline(always)]
pub(super) fn spherical<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let r2 = w / (f.sumsq + EPS);
    (r2 * f.tx, r2 * f.ty)
}

#[inline(always)]
pub(super) fn swirl<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let (c1, c2) = f.sumsq.sin_cos();
    let nx = c1 * f.tx - c2 * f.ty;
    let ny = c2 * f.tx + c1 * f.ty;
    (w * nx, w * ny)
}

#[inline(always)]
pub(super) fn horseshoe<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let r = w / (f.sqrt + EPS);
    ((f.tx - f.ty) * (f.tx + f.ty) * r, f.tx * 2.0 * f.ty * r)
}

#[inline(always)]
pub(super) fn polar<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let nx = f.atan_xy() * FRAC_1_PI;
    let ny = f.sqrt - 1.0;
    (w * nx, w * ny)
}

#[inline(always)]
pub(super) fn handkerchief<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let a = f.atan_xy();
    let r = f.sqrt;
    (w * r * (a + r).sin(), w * r * (a - r).cos())
}

#[inline(always)]
pub(super) fn heart<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let a = f.sqrt * f.atan_xy();
    let (sa, ca) = a.sin_cos();
    let r = w * f.sqrt;
    (r * sa, (-r) * ca)
}

#[inline(always)]
pub(super) fn disc<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let a = f.atan_xy() * FRAC_1_PI;
    let r = f.sqrt * PI;
    let (sr, cr) = r.sin_cos();
    (w * sr * a, w * cr * a)
}

#[inline(always)]
pub(super) fn spiral<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let r = f.sqrt + EPS;
    let r1 = w / r;
    let (sr, cr) = r.sin_cos();
    (r1 * (f.cosa() + sr), r1 * (f.sina() - cr))
}

#[inline(always)]
pub(super) fn hyperbolic<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let r = f.sqrt + EPS;
    (w * f.sina() / r, w * f.cosa() * r)
}

#[inline(always)]
pub(super) fn diamond<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let (sr, cr) = f.sqrt.sin_cos();
    (w * f.sina() * cr, w * f.cosa() * sr)
}

#[inline(always)]
pub(super) fn ex<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let a = f.atan_xy();
    let r = f.sqrt;
    let n0 = (a + r).sin();
    let n1 = (a - r).cos();
    let m0 = n0 * n0 * n0 * r;
    let m1 = n1 * n1 * n1 * r;
    (w * (m0 + m1), w * (m0 - m1))
}

/// julia: the square root z ↦ ±√z, the branch drawn at random (one bit).
#[inline(always)]
pub(super) fn julia<T: FlameScalar, R: RngCore + ?Sized>(w: T, f: &Pre<T>, rng: &mut R) -> P<T> {
    let mut a = f.atan_xy() * 0.5;
    if rand_bit(rng) {
        a = a + PI;
    }
    let r = w * f.sqrt.sqrt();
    from_polar(r, a)
}

#[inline(always)]
pub(super) fn bent<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let mut nx = f.tx;
    let mut ny = f.ty;
    if nx.v() < 0.0 {
        nx = nx * 2.0;
    }
    if ny.v() < 0.0 {
        ny = ny / 2.0;
    }
    (w * nx, w * ny)
}

/// waves: amplitudes are the coefficients `c`, `d`, periods `e²`, `f²`.
#[inline(always)]
pub(super) fn waves<T: FlameScalar>(w: T, c: &[T; 6], f: &Pre<T>) -> P<T> {
    let dx2 = T::cst(1.0) / (c[4] * c[4] + EPS);
    let dy2 = T::cst(1.0) / (c[5] * c[5] + EPS);
    let nx = f.tx + c[2] * (f.ty * dx2).sin();
    let ny = f.ty + c[3] * (f.tx * dy2).sin();
    (w * nx, w * ny)
}

/// fisheye, with flam3's swapped output (x' ∝ y, y' ∝ x).
#[inline(always)]
pub(super) fn fisheye<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let r = w * 2.0 / (f.sqrt + 1.0);
    (r * f.ty, r * f.tx)
}

/// popcorn: amplitudes are the offsets `e`, `f`.
#[inline(always)]
pub(super) fn popcorn<T: FlameScalar>(w: T, c: &[T; 6], f: &Pre<T>) -> P<T> {
    let dx = (f.ty * 3.0).tan();
    let dy = (f.tx * 3.0).tan();
    let nx = f.tx + c[4] * dx.sin();
    let ny = f.ty + c[5] * dy.sin();
    (w * nx, w * ny)
}

#[inline(always)]
pub(super) fn exponential<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let dx = w * (f.tx - 1.0).exp();
    let dy = f.ty * PI;
    from_polar(dx, dy)
}

#[inline(always)]
pub(super) fn power<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let sina = f.sina();
    let r = w * f.sqrt.pow(sina);
    (r * f.cosa(), r * sina)
}

#[inline(always)]
pub(super) fn cosine<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let a = f.tx * PI;
    let (sa, ca) = a.sin_cos();
    let nx = ca * f.ty.cosh();
    let ny = (-sa) * f.ty.sinh();
    (w * nx, w * ny)
}

/// rings: the ring spacing is `e² + ε`.
#[inline(always)]
pub(super) fn rings<T: FlameScalar>(w: T, c: &[T; 6], f: &Pre<T>) -> P<T> {
    let dx = c[4] * c[4] + EPS;
    let r = f.sqrt;
    let r = w * ((r + dx).fmod(dx * 2.0) - dx + r * (T::cst(1.0) - dx));
    (r * f.cosa(), r * f.sina())
}

/// fan: blade width π(e² + ε), phase `f`.
#[inline(always)]
pub(super) fn fan<T: FlameScalar>(w: T, c: &[T; 6], f: &Pre<T>) -> P<T> {
    let dx = (c[4] * c[4] + EPS) * PI;
    let dy = c[5];
    let dx2 = dx * 0.5;
    let mut a = f.atan_xy();
    let r = w * f.sqrt;
    if (a + dy).fmod(dx).v() > dx2.v() {
        a = a - dx2;
    } else {
        a = a + dx2;
    }
    from_polar(r, a)
}

#[inline(always)]
pub(super) fn blob<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let (low, high, waves) = (p[0], p[1], p[2]);
    let a = f.atan_xy();
    let bdiff = high - low;
    let r = f.sqrt * (low + bdiff * ((waves * a).sin() * 0.5 + 0.5));
    (w * f.sina() * r, w * f.cosa() * r)
}

#[inline(always)]
pub(super) fn pdj<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let nx1 = (p[1] * f.tx).cos();
    let nx2 = (p[2] * f.tx).sin();
    let ny1 = (p[0] * f.ty).sin();
    let ny2 = (p[3] * f.ty).cos();
    (w * (ny1 - nx1), w * (nx2 - ny2))
}

#[inline(always)]
pub(super) fn fan2<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let dy = p[1];
    let dx = (p[0] * p[0] + EPS) * PI;
    let dx2 = dx * 0.5;
    let mut a = f.atan_xy();
    let r = w * f.sqrt;
    let t = a + dy - dx * c_int(((a + dy) / dx).v());
    if t.v() > dx2.v() {
        a = a - dx2;
    } else {
        a = a + dx2;
    }
    let (sa, ca) = a.sin_cos();
    (r * sa, r * ca)
}

#[inline(always)]
pub(super) fn rings2<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let r = f.sqrt;
    let dx = p[0] * p[0] + EPS;
    let n = c_int(((r + dx) / (dx * 2.0)).v());
    let r = r + (dx * -2.0 * n + r * (T::cst(1.0) - dx));
    (w * f.sina() * r, w * f.cosa() * r)
}

#[inline(always)]
pub(super) fn eyefish<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let r = w * 2.0 / (f.sqrt + 1.0);
    (r * f.tx, r * f.ty)
}

#[inline(always)]
pub(super) fn bubble<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let r = w / (f.sumsq * 0.25 + 1.0);
    (r * f.tx, r * f.ty)
}

#[inline(always)]
pub(super) fn cylinder<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    (w * f.tx.sin(), w * f.ty)
}

/// perspective: `d = [sin(angle·π/2), dist·cos(angle·π/2)]`.
#[inline(always)]
pub(super) fn perspective<T: FlameScalar>(w: T, p: &[T; 8], d: &[T; 4], f: &Pre<T>) -> P<T> {
    let dist = p[1];
    let t = T::cst(1.0) / (dist - f.ty * d[0]);
    (w * dist * f.tx * t, w * d[1] * f.ty * t)
}
