//! Forward-mode dual numbers: a value with `K` partial derivatives, propagated by the chain
//! rule through each arithmetic operation.
//!
//! The flame variations are written once over a scalar type
//! ([`FlameScalar`](crate::model::flame::FlameScalar)); instantiated with [`Dual`] the same
//! code yields their exact Jacobians (`model::flame::xform`, `render::flame_diff`). The
//! elementary functions on duals are [`FlameScalar`](crate::model::flame::FlameScalar)'s.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// A value with `K` partial derivatives: `v + Σ d[k]·ε_k`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dual<const K: usize> {
    /// The value.
    pub v: f64,
    /// Its partial derivatives.
    pub d: [f64; K],
}

impl<const K: usize> Dual<K> {
    /// The `k`-th input variable (derivative 1 along direction `k`).
    pub fn var(v: f64, k: usize) -> Self {
        let mut d = [0.0; K];
        d[k] = 1.0;
        Dual { v, d }
    }

    /// `f(self)` given `f(v)` and `f'(v)`.
    #[inline(always)]
    pub fn chain(self, value: f64, slope: f64) -> Self {
        let mut d = self.d;
        for x in &mut d {
            *x *= slope;
        }
        Dual { v: value, d }
    }
}

impl<const K: usize> Add for Dual<K> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        let mut d = self.d;
        for (x, y) in d.iter_mut().zip(o.d) {
            *x += y;
        }
        Dual { v: self.v + o.v, d }
    }
}

impl<const K: usize> Sub for Dual<K> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        let mut d = self.d;
        for (x, y) in d.iter_mut().zip(o.d) {
            *x -= y;
        }
        Dual { v: self.v - o.v, d }
    }
}

impl<const K: usize> Mul for Dual<K> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        let mut d = [0.0; K];
        for (k, x) in d.iter_mut().enumerate() {
            *x = self.d[k] * o.v + self.v * o.d[k];
        }
        Dual { v: self.v * o.v, d }
    }
}

impl<const K: usize> Div for Dual<K> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        let q = self.v / o.v;
        let mut d = [0.0; K];
        for (k, x) in d.iter_mut().enumerate() {
            *x = (self.d[k] - q * o.d[k]) / o.v;
        }
        Dual { v: q, d }
    }
}

impl<const K: usize> Neg for Dual<K> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        self.chain(-self.v, -1.0)
    }
}

impl<const K: usize> Add<f64> for Dual<K> {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: f64) -> Self {
        Dual {
            v: self.v + o,
            d: self.d,
        }
    }
}

impl<const K: usize> Sub<f64> for Dual<K> {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: f64) -> Self {
        Dual {
            v: self.v - o,
            d: self.d,
        }
    }
}

impl<const K: usize> Mul<f64> for Dual<K> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: f64) -> Self {
        self.chain(self.v * o, o)
    }
}

impl<const K: usize> Div<f64> for Dual<K> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: f64) -> Self {
        self.chain(self.v / o, 1.0 / o)
    }
}
