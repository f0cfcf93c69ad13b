//! Variations 38–48: ngon, curl, rectangles and flam3's "Z+" set (arch, tangent, square,
//! rays, blade, secant2, twintrian, cross). arch, rays, blade, secant2 and twintrian use
//! the weight non-linearly, as flam3 does.

use std::f64::consts::PI;

use rand::RngCore;

use super::{EPS, Pre, rand01};
use crate::model::flame::scalar::FlameScalar;

type P<T> = (T, T);

#[inline(always)]
pub(super) fn ngon<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let (sides, power, circle, corners) = (p[0], p[1], p[2], p[3]);
    let r_factor = f.sumsq.pow(power / 2.0);
    let theta = f.atan_yx();
    let b = T::cst(2.0 * PI) / sides;
    let mut phi = theta - b * (theta / b).v().floor();
    if phi.v() > (b / 2.0).v() {
        phi = phi - b;
    }
    let amp = corners * (T::cst(1.0) / (phi.cos() + EPS) - 1.0) + circle;
    let amp = amp / (r_factor + EPS);
    (w * f.tx * amp, w * f.ty * amp)
}

#[inline(always)]
pub(super) fn curl<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let (c1, c2) = (p[0], p[1]);
    let re = c1 * f.tx + 1.0 + c2 * (f.tx * f.tx - f.ty * f.ty);
    let im = c1 * f.ty + c2 * 2.0 * f.tx * f.ty;
    let r = w / (re * re + im * im);
    ((f.tx * re + f.ty * im) * r, (f.ty * re - f.tx * im) * r)
}

#[inline(always)]
pub(super) fn rectangles<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let fold = |t: T, s: T| {
        if s.v() == 0.0 {
            w * t
        } else {
            w * (s * ((t / s).v().floor() * 2.0 + 1.0) - t)
        }
    };
    (fold(f.tx, p[0]), fold(f.ty, p[1]))
}

#[inline(always)]
pub(super) fn arch<T: FlameScalar, R: RngCore + ?Sized>(w: T, rng: &mut R) -> P<T> {
    let a = w * rand01(rng) * PI;
    let (s, c) = a.sin_cos();
    (w * s, w * (s * s) / c)
}

#[inline(always)]
pub(super) fn tangent<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    (w * f.tx.sin() / f.ty.cos(), w * f.ty.tan())
}

#[inline(always)]
pub(super) fn square<T: FlameScalar, R: RngCore + ?Sized>(w: T, rng: &mut R) -> P<T> {
    let x = w * (rand01(rng) - 0.5);
    let y = w * (rand01(rng) - 0.5);
    (x, y)
}

#[inline(always)]
pub(super) fn rays<T: FlameScalar, R: RngCore + ?Sized>(w: T, f: &Pre<T>, rng: &mut R) -> P<T> {
    let a = w * rand01(rng) * PI;
    let r = w / (f.sumsq + EPS);
    let tanr = w * a.tan() * r;
    (tanr * f.tx.cos(), tanr * f.ty.sin())
}

#[inline(always)]
pub(super) fn blade<T: FlameScalar, R: RngCore + ?Sized>(w: T, f: &Pre<T>, rng: &mut R) -> P<T> {
    let r = w * rand01(rng) * f.sqrt;
    let (s, c) = r.sin_cos();
    (w * f.tx * (c + s), w * f.tx * (c - s))
}

#[inline(always)]
pub(super) fn secant2<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let r = w * f.sqrt;
    let cr = r.cos();
    let icr = T::cst(1.0) / cr;
    let y = if cr.v() < 0.0 {
        w * (icr + 1.0)
    } else {
        w * (icr - 1.0)
    };
    (w * f.tx, y)
}

#[inline(always)]
pub(super) fn twintrian<T: FlameScalar, R: RngCore + ?Sized>(
    w: T,
    f: &Pre<T>,
    rng: &mut R,
) -> P<T> {
    let r = w * rand01(rng) * f.sqrt;
    let (s, c) = r.sin_cos();
    let mut diff = (s * s).log10() + c;
    let dv = diff.v();
    if dv.is_nan() || !(-1e10..=1e10).contains(&dv) {
        diff = T::cst(-30.0);
    }
    (w * f.tx * diff, w * f.tx * (diff - s * PI))
}

#[inline(always)]
pub(super) fn cross<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let s = f.tx * f.tx - f.ty * f.ty;
    let r = w * (T::cst(1.0) / (s * s + EPS)).sqrt();
    (f.tx * r, f.ty * r)
}
