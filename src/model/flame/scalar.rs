//! The scalar the variation formulas are written over: `f64` for rendering, [`Dual`]
//! ([`crate::math::dual`]) for exact derivatives.
//!
//! Every variation is one generic function of a [`FlameScalar`]. Instantiated with `f64` it is the
//! renderer's forward pass (monomorphised, no overhead) and reproduces flam3's arithmetic
//! operation for operation. Instantiated with `Dual<K>` — a value carrying `K` partial
//! derivatives — the same code yields the exact Jacobian by the chain rule applied to each
//! elementary operation (forward-mode differentiation), so the forward formula and its
//! derivative can never disagree. Comparisons and `floor`-like steps act on the value and
//! contribute a zero derivative, which is the derivative of the piecewise formula away from
//! its jumps.

use std::ops::{Add, Div, Mul, Neg, Sub};

pub use crate::math::Dual;
use crate::math::trig;

/// Arithmetic and the elementary functions the flam3 variations use.
pub trait FlameScalar:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
{
    /// A constant (zero derivative).
    fn cst(v: f64) -> Self;
    /// The value, without derivatives.
    fn v(self) -> f64;
    /// `sin`.
    fn sin(self) -> Self;
    /// `cos`.
    fn cos(self) -> Self;
    /// `(sin, cos)`.
    fn sin_cos(self) -> (Self, Self);
    /// `tan`.
    fn tan(self) -> Self;
    /// `sqrt`.
    fn sqrt(self) -> Self;
    /// `exp`.
    fn exp(self) -> Self;
    /// Natural logarithm.
    fn ln(self) -> Self;
    /// Base-10 logarithm.
    fn log10(self) -> Self;
    /// `sinh`.
    fn sinh(self) -> Self;
    /// `cosh`.
    fn cosh(self) -> Self;
    /// `acos`.
    fn acos(self) -> Self;
    /// `atan2(self, x)`.
    fn atan2(self, x: Self) -> Self;
    /// `self^e` for a real exponent that may carry derivatives.
    fn pow(self, e: Self) -> Self;
    /// `|self|` (derivative `sign(self)`).
    fn abs(self) -> Self;
    /// C's `fmod(self, m)`: `self − m·trunc(self/m)` (derivative 1 in `self` and
    /// `−trunc(self/m)` in `m`).
    fn fmod(self, m: Self) -> Self;
}

impl FlameScalar for f64 {
    #[inline(always)]
    fn cst(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn v(self) -> f64 {
        self
    }
    #[inline(always)]
    fn sin(self) -> Self {
        trig::sin(self)
    }
    #[inline(always)]
    fn cos(self) -> Self {
        trig::cos(self)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        trig::sin_cos(self)
    }
    #[inline(always)]
    fn tan(self) -> Self {
        f64::tan(self)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline(always)]
    fn exp(self) -> Self {
        f64::exp(self)
    }
    #[inline(always)]
    fn ln(self) -> Self {
        f64::ln(self)
    }
    #[inline(always)]
    fn log10(self) -> Self {
        f64::log10(self)
    }
    #[inline(always)]
    fn sinh(self) -> Self {
        f64::sinh(self)
    }
    #[inline(always)]
    fn cosh(self) -> Self {
        f64::cosh(self)
    }
    #[inline(always)]
    fn acos(self) -> Self {
        f64::acos(self)
    }
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        trig::atan2(self, x)
    }
    #[inline(always)]
    fn pow(self, e: Self) -> Self {
        f64::powf(self, e)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        f64::abs(self)
    }
    #[inline(always)]
    fn fmod(self, m: Self) -> Self {
        self % m
    }
}

impl<const K: usize> FlameScalar for Dual<K> {
    #[inline(always)]
    fn cst(v: f64) -> Self {
        Dual { v, d: [0.0; K] }
    }
    #[inline(always)]
    fn v(self) -> f64 {
        self.v
    }
    #[inline(always)]
    fn sin(self) -> Self {
        let (s, c) = trig::sin_cos(self.v);
        self.chain(s, c)
    }
    #[inline(always)]
    fn cos(self) -> Self {
        let (s, c) = trig::sin_cos(self.v);
        self.chain(c, -s)
    }
    #[inline(always)]
    fn sin_cos(self) -> (Self, Self) {
        let (s, c) = trig::sin_cos(self.v);
        (self.chain(s, c), self.chain(c, -s))
    }
    #[inline(always)]
    fn tan(self) -> Self {
        let t = self.v.tan();
        self.chain(t, 1.0 + t * t)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let r = self.v.sqrt();
        self.chain(r, 0.5 / r)
    }
    #[inline(always)]
    fn exp(self) -> Self {
        let e = self.v.exp();
        self.chain(e, e)
    }
    #[inline(always)]
    fn ln(self) -> Self {
        self.chain(self.v.ln(), 1.0 / self.v)
    }
    #[inline(always)]
    fn log10(self) -> Self {
        self.chain(self.v.log10(), 1.0 / (self.v * std::f64::consts::LN_10))
    }
    #[inline(always)]
    fn sinh(self) -> Self {
        self.chain(self.v.sinh(), self.v.cosh())
    }
    #[inline(always)]
    fn cosh(self) -> Self {
        self.chain(self.v.cosh(), self.v.sinh())
    }
    #[inline(always)]
    fn acos(self) -> Self {
        self.chain(self.v.acos(), -1.0 / (1.0 - self.v * self.v).sqrt())
    }
    #[inline(always)]
    fn atan2(self, x: Self) -> Self {
        // d atan2(y, x) = (x·dy − y·dx) / (x² + y²)
        let y = self;
        let r2 = x.v * x.v + y.v * y.v;
        let mut d = [0.0; K];
        for (k, o) in d.iter_mut().enumerate() {
            *o = (x.v * y.d[k] - y.v * x.d[k]) / r2;
        }
        Dual {
            v: trig::atan2(y.v, x.v),
            d,
        }
    }
    #[inline(always)]
    fn pow(self, e: Self) -> Self {
        // d(b^e) = e·b^(e−1)·db + b^e·ln(b)·de; the ln term only where e carries a derivative.
        let p = self.v.powf(e.v);
        let db = if e.v == 0.0 {
            0.0
        } else {
            e.v * self.v.powf(e.v - 1.0)
        };
        let has_de = e.d.iter().any(|&x| x != 0.0);
        let de = if has_de { p * self.v.ln() } else { 0.0 };
        let mut d = [0.0; K];
        for (k, o) in d.iter_mut().enumerate() {
            *o = db * self.d[k] + if has_de { de * e.d[k] } else { 0.0 };
        }
        Dual { v: p, d }
    }
    #[inline(always)]
    fn abs(self) -> Self {
        if self.v < 0.0 { -self } else { self }
    }
    #[inline(always)]
    fn fmod(self, m: Self) -> Self {
        let q = (self.v / m.v).trunc();
        let v = self.v % m.v;
        let mut d = [0.0; K];
        for (k, o) in d.iter_mut().enumerate() {
            *o = self.d[k] - q * m.d[k];
        }
        Dual { v, d }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn product_rule_and_chain_rule() {
        // f(x, y) = sin(x·y) at (0.3, 2): ∂f/∂x = y·cos(xy), ∂f/∂y = x·cos(xy).
        let x = Dual::<2>::var(0.3, 0);
        let y = Dual::<2>::var(2.0, 1);
        let f = (x * y).sin();
        let c = (0.6f64).cos();
        assert!((f.d[0] - 2.0 * c).abs() < 1e-15);
        assert!((f.d[1] - 0.3 * c).abs() < 1e-15);
    }

    #[test]
    fn atan2_derivative_is_the_angle_gradient() {
        // θ = atan2(y, x): ∂θ/∂x = −y/r², ∂θ/∂y = x/r².
        let x = Dual::<2>::var(0.5, 0);
        let y = Dual::<2>::var(-1.5, 1);
        let t = y.atan2(x);
        let r2 = 0.25 + 2.25;
        assert!((t.d[0] - 1.5 / r2).abs() < 1e-15);
        assert!((t.d[1] - 0.5 / r2).abs() < 1e-15);
    }
}
