//! Variations 96–98, the last added to flam3: auger, flux and mobius.

use super::Pre;
use crate::model::flame::scalar::FlameScalar;

type P<T> = (T, T);

/// auger: `p = [sym, weight, freq, scale]`.
#[inline(always)]
pub(super) fn auger<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let (sym, aw, freq, scale) = (p[0], p[1], p[2], p[3]);
    let s = (freq * f.tx).sin();
    let t = (freq * f.ty).sin();
    let dy = f.ty + aw * (scale * s / 2.0 + f.ty.abs() * s);
    let dx = f.tx + aw * (scale * t / 2.0 + f.tx.abs() * t);
    (w * (f.tx + sym * (dx - f.tx)), w * dy)
}

/// flux: the weight also places the two poles at (±weight, 0).
#[inline(always)]
pub(super) fn flux<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let xpw = f.tx + w;
    let xmw = f.tx - w;
    let avgr = w
        * (p[0] + 2.0)
        * ((f.ty * f.ty + xpw * xpw).sqrt() / (f.ty * f.ty + xmw * xmw).sqrt()).sqrt();
    let avga = (f.ty.atan2(xmw) - f.ty.atan2(xpw)) * 0.5;
    (avgr * avga.cos(), avgr * avga.sin())
}

/// mobius: (a·z + b)/(c·z + d) with `p = [re a, im a, re b, im b, re c, im c, re d, im d]`.
#[inline(always)]
pub(super) fn mobius<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let (ra, ia, rb, ib, rc, ic, rd, id) = (p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7]);
    let re_u = ra * f.tx - ia * f.ty + rb;
    let im_u = ra * f.ty + ia * f.tx + ib;
    let re_v = rc * f.tx - ic * f.ty + rd;
    let im_v = rc * f.ty + ic * f.tx + id;
    let rad_v = w / (re_v * re_v + im_v * im_v);
    (
        rad_v * (re_u * re_v + im_u * im_v),
        rad_v * (im_u * re_v - re_u * im_v),
    )
}
