//! Variations 49–81: disc2 … waves2, flam3's versions of the Apophysis plugin pack.
//! super_shape, flower, conic, parabola, boarders, cpow and wedge_julia draw random numbers;
//! loonie, scry, lazysusan and whorl use the weight non-linearly.

use std::f64::consts::{FRAC_1_PI, FRAC_2_PI, FRAC_PI_2, FRAC_PI_4, PI};

use rand::RngCore;

use super::{EPS, Pre, c_int, c_int32, from_polar, rand01, rint};
use crate::model::flame::scalar::FlameScalar;

type P<T> = (T, T);

/// disc2: `d = [rot·π, sin add, cos add − 1]` (add = twist, scaled beyond ±2π as flam3).
#[inline(always)]
pub(super) fn disc2<T: FlameScalar>(w: T, d: &[T; 4], f: &Pre<T>) -> P<T> {
    let t = d[0] * (f.tx + f.ty);
    let (s, c) = t.sin_cos();
    let r = w * f.atan_xy() / PI;
    ((s + d[2]) * r, (c + d[1]) * r)
}

/// super_shape: `p = [rnd, m, n1, n2, n3, holes]`, `d = [m/4, −1/n1]`. Draws one number
/// whatever `rnd` (which mixes it with the radius).
#[inline(always)]
pub(super) fn super_shape<T: FlameScalar, R: RngCore + ?Sized>(
    w: T,
    p: &[T; 8],
    d: &[T; 4],
    f: &Pre<T>,
    rng: &mut R,
) -> P<T> {
    let theta = d[0] * f.atan_yx() + FRAC_PI_4;
    let (st, ct) = theta.sin_cos();
    let t1 = ct.abs().pow(p[3]);
    let t2 = st.abs().pow(p[4]);
    let rnd = p[0];
    let r = w * (rnd * rand01(rng) + (T::cst(1.0) - rnd) * f.sqrt - p[5]) * (t1 + t2).pow(d[1])
        / f.sqrt;
    (r * f.tx, r * f.ty)
}

#[inline(always)]
pub(super) fn flower<T: FlameScalar, R: RngCore + ?Sized>(
    w: T,
    p: &[T; 8],
    f: &Pre<T>,
    rng: &mut R,
) -> P<T> {
    let theta = f.atan_yx();
    let r = w * (-p[1] + rand01(rng)) * (p[0] * theta).cos() / f.sqrt;
    (r * f.tx, r * f.ty)
}

#[inline(always)]
pub(super) fn conic<T: FlameScalar, R: RngCore + ?Sized>(
    w: T,
    p: &[T; 8],
    f: &Pre<T>,
    rng: &mut R,
) -> P<T> {
    let (ecc, holes) = (p[0], p[1]);
    let ct = f.tx / f.sqrt;
    let r = w * (-holes + rand01(rng)) * ecc / (ecc * ct + 1.0) / f.sqrt;
    (r * f.tx, r * f.ty)
}

#[inline(always)]
pub(super) fn parabola<T: FlameScalar, R: RngCore + ?Sized>(
    w: T,
    p: &[T; 8],
    f: &Pre<T>,
    rng: &mut R,
) -> P<T> {
    let (sr, cr) = f.sqrt.sin_cos();
    let x = p[0] * w * sr * sr * rand01(rng);
    let y = p[1] * w * cr * rand01(rng);
    (x, y)
}

#[inline(always)]
pub(super) fn bent2<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let mut nx = f.tx;
    let mut ny = f.ty;
    if nx.v() < 0.0 {
        nx = nx * p[0];
    }
    if ny.v() < 0.0 {
        ny = ny * p[1];
    }
    (w * nx, w * ny)
}

#[inline(always)]
pub(super) fn bipolar<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let x2y2 = f.sumsq;
    let t = x2y2 + 1.0;
    let x2 = f.tx * 2.0;
    let ps = p[0] * -FRAC_PI_2;
    let mut y = (f.ty * 2.0).atan2(x2y2 - 1.0) * 0.5 + ps;
    if y.v() > FRAC_PI_2 {
        y = (y + FRAC_PI_2).fmod(T::cst(PI)) + -FRAC_PI_2;
    } else if y.v() < -FRAC_PI_2 {
        y = -(-y + FRAC_PI_2).fmod(T::cst(PI)) + FRAC_PI_2;
    }
    (
        w * 0.25 * FRAC_2_PI * ((t + x2) / (t - x2)).ln(),
        w * FRAC_2_PI * y,
    )
}

#[inline(always)]
pub(super) fn boarders<T: FlameScalar, R: RngCore + ?Sized>(w: T, f: &Pre<T>, rng: &mut R) -> P<T> {
    let rx = T::cst(rint(f.tx.v()));
    let ry = T::cst(rint(f.ty.v()));
    let ox = f.tx - rx;
    let oy = f.ty - ry;
    if rand01(rng) >= 0.75 {
        return (w * (ox * 0.5 + rx), w * (oy * 0.5 + ry));
    }
    if ox.v().abs() >= oy.v().abs() {
        if ox.v() >= 0.0 {
            (
                w * (ox * 0.5 + rx + 0.25),
                w * (oy * 0.5 + ry + oy * 0.25 / ox),
            )
        } else {
            (
                w * (ox * 0.5 + rx - 0.25),
                w * (oy * 0.5 + ry - oy * 0.25 / ox),
            )
        }
    } else if oy.v() >= 0.0 {
        (
            w * (ox * 0.5 + rx + ox / oy * 0.25),
            w * (oy * 0.5 + ry + 0.25),
        )
    } else {
        (
            w * (ox * 0.5 + rx - ox / oy * 0.25),
            w * (oy * 0.5 + ry - 0.25),
        )
    }
}

#[inline(always)]
pub(super) fn butterfly<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    // 4/√(3π)
    let wx = w * 1.302_940_031_741_119_7;
    let y2 = f.ty * 2.0;
    let r = wx * ((f.ty * f.tx).abs() / (f.tx * f.tx + EPS + y2 * y2)).sqrt();
    (r * f.tx, r * y2)
}

#[inline(always)]
pub(super) fn cell<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let size = p[0];
    let inv = T::cst(1.0) / size;
    let mut x = c_int32((f.tx * inv).v().floor());
    let mut y = c_int32((f.ty * inv).v().floor());
    let dx = f.tx - size * x as f64;
    let dy = f.ty - size * y as f64;
    // Interleave the cells of the four quadrants.
    if y >= 0 {
        y = y.wrapping_mul(2);
    } else {
        y = -(y.wrapping_mul(2) + 1);
    }
    if x >= 0 {
        x = x.wrapping_mul(2);
    } else {
        x = -(x.wrapping_mul(2) + 1);
    }
    (w * (dx + size * x as f64), -(w * (dy + size * y as f64)))
}

#[inline(always)]
pub(super) fn cpow<T: FlameScalar, R: RngCore + ?Sized>(
    w: T,
    p: &[T; 8],
    f: &Pre<T>,
    rng: &mut R,
) -> P<T> {
    let (cr, ci, power) = (p[0], p[1], p[2]);
    let a = f.atan_yx();
    let lnr = f.sumsq.ln() * 0.5;
    let va = T::cst(2.0 * PI) / power;
    let vc = cr / power;
    let vd = ci / power;
    let k = (power.v() * rand01(rng)).floor();
    let ang = vc * a + vd * lnr + va * k;
    let m = w * (vc * lnr - vd * a).exp();
    from_polar(m, ang)
}

#[inline(always)]
pub(super) fn curve<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let (xamp, yamp) = (p[0], p[1]);
    let mut xlen = p[2] * p[2];
    let mut ylen = p[3] * p[3];
    if xlen.v() < 1e-20 {
        xlen = T::cst(1e-20);
    }
    if ylen.v() < 1e-20 {
        ylen = T::cst(1e-20);
    }
    (
        w * (f.tx + xamp * ((-f.ty) * f.ty / xlen).exp()),
        w * (f.ty + yamp * ((-f.tx) * f.tx / ylen).exp()),
    )
}

#[inline(always)]
pub(super) fn edisc<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let tmp = f.sumsq + 1.0;
    let tmp2 = f.tx * 2.0;
    let r1 = (tmp + tmp2).sqrt();
    let r2 = (tmp - tmp2).sqrt();
    let xmax = (r1 + r2) * 0.5;
    let a1 = (xmax + (xmax - 1.0).sqrt()).ln();
    let a2 = -(f.tx / xmax).acos();
    let w = w / 11.570_346_32;
    let (mut snv, csv) = a1.sin_cos();
    let snhu = a2.sinh();
    let cshu = a2.cosh();
    if f.ty.v() > 0.0 {
        snv = -snv;
    }
    (w * cshu * csv, w * snhu * snv)
}

#[inline(always)]
pub(super) fn elliptic<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let tmp = f.sumsq + 1.0;
    let x2 = f.tx * 2.0;
    let xmax = ((tmp + x2).sqrt() + (tmp - x2).sqrt()) * 0.5;
    let a = f.tx / xmax;
    let mut b = T::cst(1.0) - a * a;
    let mut ssx = xmax - 1.0;
    let w = w / FRAC_PI_2;
    b = if b.v() < 0.0 { T::cst(0.0) } else { b.sqrt() };
    ssx = if ssx.v() < 0.0 {
        T::cst(0.0)
    } else {
        ssx.sqrt()
    };
    let x = w * a.atan2(b);
    let l = w * (xmax + ssx).ln();
    (x, if f.ty.v() > 0.0 { l } else { -l })
}

#[inline(always)]
pub(super) fn escher<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let a = f.atan_yx();
    let lnr = f.sumsq.ln() * 0.5;
    let (seb, ceb) = p[0].sin_cos();
    let vc = (ceb + 1.0) * 0.5;
    let vd = seb * 0.5;
    let m = w * (vc * lnr - vd * a).exp();
    let n = vc * a + vd * lnr;
    from_polar(m, n)
}

#[inline(always)]
pub(super) fn foci<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let expx = f.tx.exp() * 0.5;
    let expnx = T::cst(0.25) / expx;
    let (sn, cn) = f.ty.sin_cos();
    let tmp = w / (expx + expnx - cn);
    (tmp * (expx - expnx), tmp * sn)
}

/// lazysusan: `p = [spin, space, twist, x, y]`; the disc of radius `weight` around
/// `(x, −y)` turns, the rest is pushed out by `space`.
#[inline(always)]
pub(super) fn lazysusan<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let (spin, space, twist, lx, ly) = (p[0], p[1], p[2], p[3], p[4]);
    let x = f.tx - lx;
    let y = f.ty + ly;
    let r = (x * x + y * y).sqrt();
    if r.v() < w.v() {
        let a = y.atan2(x) + spin + twist * (w - r);
        let (s, c) = a.sin_cos();
        let r = w * r;
        (r * c + lx, r * s - ly)
    } else {
        let r = w * (space / r + 1.0);
        (r * x + lx, r * y - ly)
    }
}

#[inline(always)]
pub(super) fn loonie<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let r2 = f.sumsq;
    let w2 = w * w;
    if r2.v() < w2.v() {
        let r = w * (w2 / r2 - 1.0).sqrt();
        (r * f.tx, r * f.ty)
    } else {
        (w * f.tx, w * f.ty)
    }
}

#[inline(always)]
pub(super) fn modulus<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let wrap = |t: T, m: T| {
        let r = m * 2.0;
        if t.v() > m.v() {
            w * (-m + (t + m).fmod(r))
        } else if t.v() < -m.v() {
            w * (m - (m - t).fmod(r))
        } else {
            w * t
        }
    };
    (wrap(f.tx, p[0]), wrap(f.ty, p[1]))
}

/// oscilloscope: `p = [separation, frequency, amplitude, damping]`.
#[inline(always)]
pub(super) fn oscilloscope<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let (sep, freq, amp, damp) = (p[0], p[1], p[2], p[3]);
    let tpf = freq * (2.0 * PI);
    let t = if damp.v() == 0.0 {
        amp * (tpf * f.tx).cos() + sep
    } else {
        amp * (-f.tx.abs() * damp).exp() * (tpf * f.tx).cos() + sep
    };
    if f.ty.abs().v() <= t.v() {
        (w * f.tx, -(w * f.ty))
    } else {
        (w * f.tx, w * f.ty)
    }
}

#[inline(always)]
pub(super) fn polar2<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let p2v = w / PI;
    (p2v * f.atan_xy(), p2v / 2.0 * f.sumsq.ln())
}

#[inline(always)]
pub(super) fn popcorn2<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let (px, py, pc) = (p[0], p[1], p[2]);
    (
        w * (f.tx + px * (f.ty * pc).tan().sin()),
        w * (f.ty + py * (f.tx * pc).tan().sin()),
    )
}

#[inline(always)]
pub(super) fn scry<T: FlameScalar>(w: T, f: &Pre<T>) -> P<T> {
    let t = f.sumsq;
    let r = T::cst(1.0) / (f.sqrt * (t + T::cst(1.0) / (w + EPS)));
    (f.tx * r, f.ty * r)
}

/// separation: `p = [x, xinside, y, yinside]`.
#[inline(always)]
pub(super) fn separation<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let side = |t: T, s: T, inside: T| {
        let s2 = s * s;
        if t.v() > 0.0 {
            w * ((t * t + s2).sqrt() - t * inside)
        } else {
            -(w * ((t * t + s2).sqrt() + t * inside))
        }
    };
    (side(f.tx, p[0], p[1]), side(f.ty, p[2], p[3]))
}

#[inline(always)]
pub(super) fn split<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let y = if (f.tx * p[0] * PI).cos().v() >= 0.0 {
        w * f.ty
    } else {
        -(w * f.ty)
    };
    let x = if (f.ty * p[1] * PI).cos().v() >= 0.0 {
        w * f.tx
    } else {
        -(w * f.tx)
    };
    (x, y)
}

#[inline(always)]
pub(super) fn splits<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let x = if f.tx.v() >= 0.0 {
        w * (f.tx + p[0])
    } else {
        w * (f.tx - p[0])
    };
    let y = if f.ty.v() >= 0.0 {
        w * (f.ty + p[1])
    } else {
        w * (f.ty - p[1])
    };
    (x, y)
}

#[inline(always)]
pub(super) fn stripes<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let (space, warp) = (p[0], p[1]);
    let roundx = T::cst((f.tx + 0.5).v().floor());
    let offsetx = f.tx - roundx;
    (
        w * (offsetx * (T::cst(1.0) - space) + roundx),
        w * (f.ty + offsetx * offsetx * warp),
    )
}

/// wedge: `p = [angle, hole, count, swirl]`.
#[inline(always)]
pub(super) fn wedge<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let (angle, hole, count, swirl) = (p[0], p[1], p[2], p[3]);
    let r = f.sqrt;
    let a = f.atan_yx() + swirl * r;
    let c = ((count * a + PI) * FRAC_1_PI * 0.5).v().floor();
    let comp_fac = T::cst(1.0) - angle * count * FRAC_1_PI * 0.5;
    let a = a * comp_fac + angle * c;
    let r = w * (r + hole);
    from_polar(r, a)
}

/// wedge_julia: `p = [angle, count, power, dist]`, `d = [1 − angle·count/(2π), |power|,
/// dist/power/2]`.
#[inline(always)]
pub(super) fn wedge_julia<T: FlameScalar, R: RngCore + ?Sized>(
    w: T,
    p: &[T; 8],
    d: &[T; 4],
    f: &Pre<T>,
    rng: &mut R,
) -> P<T> {
    let (angle, count, power) = (p[0], p[1], p[2]);
    let r = w * f.sumsq.pow(d[2]);
    let t = c_int(d[1].v() * rand01(rng));
    let a = (f.atan_yx() + 2.0 * PI * t) / power;
    let c = ((count * a + PI) * FRAC_1_PI * 0.5).v().floor();
    let a = a * d[0] + angle * c;
    from_polar(r, a)
}

/// wedge_sph: `p = [angle, count, hole, swirl]`.
#[inline(always)]
pub(super) fn wedge_sph<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let (angle, count, hole, swirl) = (p[0], p[1], p[2], p[3]);
    let r = T::cst(1.0) / (f.sqrt + EPS);
    let a = f.atan_yx() + swirl * r;
    let c = ((count * a + PI) * FRAC_1_PI * 0.5).v().floor();
    let comp_fac = T::cst(1.0) - angle * count * FRAC_1_PI * 0.5;
    let a = a * comp_fac + angle * c;
    let r = w * (r + hole);
    from_polar(r, a)
}

#[inline(always)]
pub(super) fn whorl<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    let r = f.sqrt;
    let a = if r.v() < w.v() {
        f.atan_yx() + p[0] / (w - r)
    } else {
        f.atan_yx() + p[1] / (w - r)
    };
    let (s, c) = a.sin_cos();
    (w * r * c, w * r * s)
}

/// waves2: `p = [freqx, scalex, freqy, scaley]`.
#[inline(always)]
pub(super) fn waves2<T: FlameScalar>(w: T, p: &[T; 8], f: &Pre<T>) -> P<T> {
    (
        w * (f.tx + p[1] * (f.ty * p[0]).sin()),
        w * (f.ty + p[3] * (f.tx * p[2]).sin()),
    )
}
