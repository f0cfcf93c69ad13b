//! Rotations of space from quaternions that need not be unit: `R(q) = P(q)/|q|²`, with `P`
//! the quadratic form of the unit-quaternion rotation formula. `R` is homogeneous of degree
//! 0 in `q`, so every non-zero 4-vector is a rotation and an optimiser may step `q` freely
//! (no projection is needed for validity; renormalising keeps the steps' scale steady).

use nalgebra::Matrix3;

/// `P(q)` for `q = (w, x, y, z)`: `|q|²·R` of the rotation `q` stands for.
#[inline]
fn quadratic(q: [f64; 4]) -> Matrix3<f64> {
    let [w, x, y, z] = q;
    Matrix3::new(
        w * w + x * x - y * y - z * z,
        2.0 * (x * y - w * z),
        2.0 * (x * z + w * y),
        2.0 * (x * y + w * z),
        w * w - x * x + y * y - z * z,
        2.0 * (y * z - w * x),
        2.0 * (x * z - w * y),
        2.0 * (y * z + w * x),
        w * w - x * x - y * y + z * z,
    )
}

/// `∂P/∂q_i` (each linear in `q`).
#[inline]
fn quadratic_derivatives(q: [f64; 4]) -> [Matrix3<f64>; 4] {
    let [w, x, y, z] = q;
    let two = |m: Matrix3<f64>| m * 2.0;
    [
        two(Matrix3::new(w, -z, y, z, w, -x, -y, x, w)),
        two(Matrix3::new(x, y, z, y, -x, -w, z, w, -x)),
        two(Matrix3::new(-y, x, w, x, y, z, -w, z, -y)),
        two(Matrix3::new(-z, -w, x, w, -z, y, x, y, z)),
    ]
}

/// `q` divided by its largest |entry| (so that `|q|²` neither overflows nor underflows),
/// with that divisor; `None` for the zero vector.
#[inline]
fn rescaled(q: [f64; 4]) -> Option<([f64; 4], f64)> {
    let t = q.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    (t > 0.0 && t.is_finite()).then(|| (q.map(|v| v / t), t))
}

/// The rotation `R(q/|q|)` of a quaternion `q = (w, x, y, z)` of any non-zero length; the
/// identity for `q = 0` (a degenerate θ still decodes to a rotation).
pub fn rotation_from_quaternion(q: [f64; 4]) -> Matrix3<f64> {
    match rescaled(q) {
        Some((q, _)) => {
            let n: f64 = q.iter().map(|v| v * v).sum();
            quadratic(q) / n
        }
        None => Matrix3::identity(),
    }
}

/// `R(q)` and its four partial derivatives `∂R/∂q_i = (∂P/∂q_i − 2·q_i·R)/|q|²` (zero at
/// `q = 0`, where `R` is defined as the identity).
pub fn rotation_jacobian(q: [f64; 4]) -> (Matrix3<f64>, [Matrix3<f64>; 4]) {
    let Some((qs, t)) = rescaled(q) else {
        return (Matrix3::identity(), [Matrix3::zeros(); 4]);
    };
    let n: f64 = qs.iter().map(|v| v * v).sum();
    let r = quadratic(qs) / n;
    let dp = quadratic_derivatives(qs);
    // R is homogeneous of degree 0: ∂R/∂q(q) = ∂R/∂q(q/t) / t.
    let d = std::array::from_fn(|i| (dp[i] - r * (2.0 * qs[i])) / (n * t));
    (r, d)
}

/// A unit quaternion `(w, x, y, z)` with `w ≥ 0` whose rotation is `r` (a proper rotation:
/// `rᵀr = I`, `det r = 1`), by Shepperd's method (the largest diagonal term first, so no
/// division by a small number).
pub fn quaternion_from_rotation(r: &Matrix3<f64>) -> [f64; 4] {
    let tr = r[(0, 0)] + r[(1, 1)] + r[(2, 2)];
    let q = if tr > r[(0, 0)].max(r[(1, 1)]).max(r[(2, 2)]) {
        let s = (1.0 + tr).max(0.0).sqrt() * 2.0;
        [
            0.25 * s,
            (r[(2, 1)] - r[(1, 2)]) / s,
            (r[(0, 2)] - r[(2, 0)]) / s,
            (r[(1, 0)] - r[(0, 1)]) / s,
        ]
    } else if r[(0, 0)] >= r[(1, 1)] && r[(0, 0)] >= r[(2, 2)] {
        let s = (1.0 + r[(0, 0)] - r[(1, 1)] - r[(2, 2)]).max(0.0).sqrt() * 2.0;
        [
            (r[(2, 1)] - r[(1, 2)]) / s,
            0.25 * s,
            (r[(0, 1)] + r[(1, 0)]) / s,
            (r[(0, 2)] + r[(2, 0)]) / s,
        ]
    } else if r[(1, 1)] >= r[(2, 2)] {
        let s = (1.0 + r[(1, 1)] - r[(0, 0)] - r[(2, 2)]).max(0.0).sqrt() * 2.0;
        [
            (r[(0, 2)] - r[(2, 0)]) / s,
            (r[(0, 1)] + r[(1, 0)]) / s,
            0.25 * s,
            (r[(1, 2)] + r[(2, 1)]) / s,
        ]
    } else {
        let s = (1.0 + r[(2, 2)] - r[(0, 0)] - r[(1, 1)]).max(0.0).sqrt() * 2.0;
        [
            (r[(1, 0)] - r[(0, 1)]) / s,
            (r[(0, 2)] + r[(2, 0)]) / s,
            (r[(1, 2)] + r[(2, 1)]) / s,
            0.25 * s,
        ]
    };
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    let sign = if q[0] < 0.0 { -1.0 } else { 1.0 };
    q.map(|v| sign * v / n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quaternions_give_rotations_and_round_trip() {
        for q in [
            [1.0, 0.0, 0.0, 0.0],
            [0.3, -1.2, 0.8, 0.4],
            [0.0, 0.0, 1.0, 0.0],
            [-0.01, 0.7, 0.0, -0.7],
            [1e-200, 3e-200, -2e-200, 0.0],
            [4e200, 1e200, -2e200, 3e200],
        ] {
            let r = rotation_from_quaternion(q);
            let e = (r.transpose() * r - Matrix3::identity()).abs().max();
            assert!(e < 1e-14, "{q:?}: RᵀR − I = {e}");
            assert!((r.determinant() - 1.0).abs() < 1e-14, "{q:?}");
            let back = rotation_from_quaternion(quaternion_from_rotation(&r));
            assert!((back - r).abs().max() < 1e-13, "{q:?}");
        }
        assert_eq!(rotation_from_quaternion([0.0; 4]), Matrix3::identity());
    }

    #[test]
    fn rotation_derivatives_match_finite_differences() {
        let q = [0.3, -1.2, 0.8, 0.4];
        let (_, d) = rotation_jacobian(q);
        let h = 1e-6;
        for i in 0..4 {
            let (mut up, mut down) = (q, q);
            up[i] += h;
            down[i] -= h;
            let fd = (rotation_from_quaternion(up) - rotation_from_quaternion(down)) / (2.0 * h);
            assert!((fd - d[i]).abs().max() < 1e-8, "∂R/∂q{i}");
        }
    }
}
