//! Complex arithmetic on `[re, im]` pairs: a similitude of the plane without reflection is
//! `z ↦ w·z + t` with complex `w` and `t`, and its chain rule is complex multiplication.
//!
//! Gradients of a real loss `L` with respect to a complex quantity `z` are written as the
//! complex number `G_z = ∂L/∂re z + i·∂L/∂im z`. If `u = a·z` then `G_z += conj(a)·G_u`;
//! more generally, for `u = h(z)` holomorphic, `G_z += conj(h′(z))·G_u`.

/// `a·b`.
#[inline(always)]
pub fn mul(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] * b[0] - a[1] * b[1], a[0] * b[1] + a[1] * b[0]]
}

/// `conj(a)`.
#[inline(always)]
pub fn conj(a: [f64; 2]) -> [f64; 2] {
    [a[0], -a[1]]
}

/// `conj(a)·b`: the pull-back of the gradient `b` through multiplication by `a`.
#[inline(always)]
pub fn cmul(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    mul(conj(a), b)
}

/// `a / b` (`b ≠ 0`).
#[inline(always)]
pub fn div(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    let n = b[0] * b[0] + b[1] * b[1];
    let p = mul(a, conj(b));
    [p[0] / n, p[1] / n]
}

/// `a + b`.
#[inline(always)]
pub fn add(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] + b[0], a[1] + b[1]]
}

/// `a − b`.
#[inline(always)]
pub fn sub(a: [f64; 2], b: [f64; 2]) -> [f64; 2] {
    [a[0] - b[0], a[1] - b[1]]
}

/// `|a|`.
#[inline(always)]
pub fn abs(a: [f64; 2]) -> f64 {
    a[0].hypot(a[1])
}

/// `*acc += v`.
#[inline(always)]
pub fn acc(acc: &mut [f64; 2], v: [f64; 2]) {
    acc[0] += v[0];
    acc[1] += v[1];
}
