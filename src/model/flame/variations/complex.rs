//! Variations 82–95: the complex exponential, logarithm, and the complex trigonometric and
//! hyperbolic functions of z = x + iy (as flam3 writes them: `den` factors and signs
//! included).

use super::Pre;
use crate::model::flame::scalar::FlameScalar;

type P<T> = (T, T);

#[inline(always)]
pub(super) fn exp<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let e = f.tx.exp();
    let (s, c) = f.ty.sin_cos();
    (w * e * c, w * e * s)
}

#[inline(always)]
pub(super) fn log<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    (w * 0.5 * f.sumsq.ln(), w * f.atan_yx())
}

#[inline(always)]
pub(super) fn sin<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let (s, c) = f.tx.sin_cos();
    let (sh, ch) = (f.ty.sinh(), f.ty.cosh());
    (w * s * ch, w * c * sh)
}

#[inline(always)]
pub(super) fn cos<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let (s, c) = f.tx.sin_cos();
    let (sh, ch) = (f.ty.sinh(), f.ty.cosh());
    (w * c * ch, -(w * s * sh))
}

#[inline(always)]
pub(super) fn tan<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let (s, c) = (f.tx * 2.0).sin_cos();
    let (sh, ch) = ((f.ty * 2.0).sinh(), (f.ty * 2.0).cosh());
    let den = T::cst(1.0) / (c + ch);
    (w * den * s, w * den * sh)
}

#[inline(always)]
pub(super) fn sec<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let (s, c) = f.tx.sin_cos();
    let (sh, ch) = (f.ty.sinh(), f.ty.cosh());
    let den = T::cst(2.0) / ((f.tx * 2.0).cos() + (f.ty * 2.0).cosh());
    (w * den * c * ch, w * den * s * sh)
}

#[inline(always)]
pub(super) fn csc<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let (s, c) = f.tx.sin_cos();
    let (sh, ch) = (f.ty.sinh(), f.ty.cosh());
    let den = T::cst(2.0) / ((f.ty * 2.0).cosh() - (f.tx * 2.0).cos());
    (w * den * s * ch, -(w * den * c * sh))
}

#[inline(always)]
pub(super) fn cot<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let (s, c) = (f.tx * 2.0).sin_cos();
    let (sh, ch) = ((f.ty * 2.0).sinh(), (f.ty * 2.0).cosh());
    let den = T::cst(1.0) / (ch - c);
    (w * den * s, w * den * -1.0 * sh)
}

#[inline(always)]
pub(super) fn sinh<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let (s, c) = f.ty.sin_cos();
    let (sh, ch) = (f.tx.sinh(), f.tx.cosh());
    (w * sh * c, w * ch * s)
}

#[inline(always)]
pub(super) fn cosh<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let (s, c) = f.ty.sin_cos();
    let (sh, ch) = (f.tx.sinh(), f.tx.cosh());
    (w * ch * c, w * sh * s)
}

#[inline(always)]
pub(super) fn tanh<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let (s, c) = (f.ty * 2.0).sin_cos();
    let (sh, ch) = ((f.tx * 2.0).sinh(), (f.tx * 2.0).cosh());
    let den = T::cst(1.0) / (c + ch);
    (w * den * sh, w * den * s)
}

#[inline(always)]
pub(super) fn sech<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let (s, c) = f.ty.sin_cos();
    let (sh, ch) = (f.tx.sinh(), f.tx.cosh());
    let den = T::cst(2.0) / ((f.ty * 2.0).cos() + (f.tx * 2.0).cosh());
    (w * den * c * ch, -(w * den * s * sh))
}

#[inline(always)]
pub(super) fn csch<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let (s, c) = f.ty.sin_cos();
    let (sh, ch) = (f.tx.sinh(), f.tx.cosh());
    let den = T::cst(2.0) / ((f.tx * 2.0).cosh() - (f.ty * 2.0).cos());
    (w * den * sh * c, -(w * den * ch * s))
}

#[inline(always)]
pub(super) fn coth<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let (s, c) = (f.ty * 2.0).sin_cos();
    let (sh, ch) = ((f.tx * 2.0).sinh(), (f.tx * 2.0).cosh());
    let den = T::cst(1.0) / (ch - c);
    (w * den * sh, w * den * s)
}
