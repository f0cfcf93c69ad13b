//! Distances from a point to the two-point primitives and their gradients with respect to
//! the two points.
//!
//! Every primitive is given by two points `a`, `b` (see
//! [`PrimitiveKind`](crate::model::segment::PrimitiveKind)): the segment `[a, b]`, the disk
//! with diameter `[a, b]`, the square with diagonal `[a, b]`. The distance is to the filled
//! shape, so it is 0 inside a disk or a square: the paper's pixel `exp(−d²/σ²)` is then 1
//! on the whole shape, and the minimum over primitives is the distance to their union. (A
//! signed distance would only matter inside, where the pixel is saturated and the
//! gradient 0.)
//!
//! The smallest disk containing each primitive is the one with diameter `[a, b]`, which the
//! renderer's bounds use.

use crate::model::segment::PrimitiveKind;
use crate::model::segment::complex::{abs, cmul, conj, div, mul, sub};

/// Distance from `p` to the primitive on `a`, `b`.
#[inline(always)]
pub fn distance(kind: PrimitiveKind, p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> f64 {
    match kind {
        PrimitiveKind::Segment => {
            let pa = sub(p, a);
            let ba = sub(b, a);
            let h =
                ((pa[0] * ba[0] + pa[1] * ba[1]) / (ba[0] * ba[0] + ba[1] * ba[1])).clamp(0.0, 1.0);
            (pa[0] - h * ba[0]).hypot(pa[1] - h * ba[1])
        }
        PrimitiveKind::Disk => {
            let c = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
            (abs(sub(p, c)) - 0.5 * abs(sub(b, a))).max(0.0)
        }
        PrimitiveKind::Box => {
            let (u, z) = box_frame(p, a, b);
            abs(u) * box_outside(z).0
        }
    }
}

/// The square's frame: `u = (b − a)·(1 + i)/4` and `z = (p − c)/u` with `c` the centre, so
/// the square becomes `[−1, 1]²` and world distances are `|u|` times frame distances.
#[inline(always)]
fn box_frame(p: [f64; 2], a: [f64; 2], b: [f64; 2]) -> ([f64; 2], [f64; 2]) {
    let c = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
    let u = mul(sub(b, a), [0.25, 0.25]);
    (u, div(sub(p, c), u))
}

/// Distance from `z` to `[−1, 1]²` and its gradient in `z`.
#[inline(always)]
fn box_outside(z: [f64; 2]) -> (f64, [f64; 2]) {
    let q = [(z[0].abs() - 1.0).max(0.0), (z[1].abs() - 1.0).max(0.0)];
    let f = q[0].hypot(q[1]);
    if f == 0.0 {
        return (0.0, [0.0, 0.0]);
    }
    (f, [z[0].signum() * q[0] / f, z[1].signum() * q[1] / f])
}

/// Distance from `p` to the primitive and its gradients with respect to `a` and `b`
/// (0 where the distance is 0: on a segment, inside a disk or a square).
#[inline(always)]
pub fn distance_grad(
    kind: PrimitiveKind,
    p: [f64; 2],
    a: [f64; 2],
    b: [f64; 2],
) -> (f64, [f64; 2], [f64; 2]) {
    match kind {
        PrimitiveKind::Segment => {
            // d = min_h |p − a − h·(b − a)|: by the envelope theorem ∂d/∂a = −n·(1 − h),
            // ∂d/∂b = −n·h at the minimising h, n the unit vector from the nearest point to p.
            let pa = sub(p, a);
            let ba = sub(b, a);
            let h =
                ((pa[0] * ba[0] + pa[1] * ba[1]) / (ba[0] * ba[0] + ba[1] * ba[1])).clamp(0.0, 1.0);
            let r = [pa[0] - h * ba[0], pa[1] - h * ba[1]];
            let d = r[0].hypot(r[1]);
            if d == 0.0 {
                return (0.0, [0.0, 0.0], [0.0, 0.0]);
            }
            let n = [r[0] / d, r[1] / d];
            (
                d,
                [-n[0] * (1.0 - h), -n[1] * (1.0 - h)],
                [-n[0] * h, -n[1] * h],
            )
        }
        PrimitiveKind::Disk => {
            // d = |p − c| − r, c = (a + b)/2, r = |b − a|/2.
            let c = [0.5 * (a[0] + b[0]), 0.5 * (a[1] + b[1])];
            let pc = sub(p, c);
            let l = abs(pc);
            let ba = sub(b, a);
            let len = abs(ba);
            let d = l - 0.5 * len;
            if d <= 0.0 || l == 0.0 {
                return (0.0, [0.0, 0.0], [0.0, 0.0]);
            }
            let n = [pc[0] / l, pc[1] / l];
            let u = [ba[0] / len, ba[1] / len];
            (
                d,
                [0.5 * (u[0] - n[0]), 0.5 * (u[1] - n[1])],
                [-0.5 * (u[0] + n[0]), -0.5 * (u[1] + n[1])],
            )
        }
        PrimitiveKind::Box => {
            // d = |u|·f(z), z = (p − c)/u: G_c = −|u|·G_f/conj(u),
            // G_u = f·u/|u| − |u|·G_f·conj(z)/conj(u); then c = (a + b)/2,
            // u = (b − a)·(1 + i)/4.
            let (u, z) = box_frame(p, a, b);
            let (f, gf) = box_outside(z);
            if f == 0.0 {
                return (0.0, [0.0, 0.0], [0.0, 0.0]);
            }
            let nu = abs(u);
            let gc = div(gf, conj(u));
            let gc = [-nu * gc[0], -nu * gc[1]];
            let t = div(mul(gf, conj(z)), conj(u));
            let gu = [f * u[0] / nu - nu * t[0], f * u[1] / nu - nu * t[1]];
            let gba = cmul([0.25, 0.25], gu);
            (
                nu * f,
                [0.5 * gc[0] - gba[0], 0.5 * gc[1] - gba[1]],
                [0.5 * gc[0] + gba[0], 0.5 * gc[1] + gba[1]],
            )
        }
    }
}
