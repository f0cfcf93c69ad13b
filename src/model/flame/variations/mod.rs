//! The variation formulas, one file per family, each written once over [`FlameScalar`].
//!
//! - [`classic`]: the variations of Draves & Reckase's paper (linear … perspective);
//! - [`blurs`]: noise, julian, juliascope, the blurs and pie (random);
//! - [`zplus`]: ngon … cross (flam3's "Z+" set, several random);
//! - [`plugins`]: disc2 … waves2 (the Apophysis plugin pack);
//! - [`complex`]: exp, log and the complex trigonometric and hyperbolic functions;
//! - [`extra`]: auger, flux, mobius.
//!
//! **Compilation** ([`crate::isa`]): the formulas are `#[inline(always)]`; `eval_on` runs
//! them through one out-of-line function per instruction set that holds the whole `match`
//! over the 99 variations — the portable one, and one compiled with AVX2 and FMA, where the
//! trigonometry of [`crate::math::trig`] inlines into each formula with single-instruction
//! fused multiply–adds. A transform's variations cost one call each, as when every formula
//! was its own function; `linear` is inlined into the caller. Both copies give the same
//! bits.
//!
//! Each formula follows flam3 3.1.1 operation for operation (same evaluation order, same
//! ε, flam3's angle convention θ = atan2(x, y) where flam3 uses it), so renders agree with
//! flam3 to rounding. A random variation takes its draws from the trajectory's generator
//! through [`rand01`] and [`rand_bit`], which map a 32-bit draw exactly as flam3 maps its
//! ISAAC output.

mod blurs;
mod classic;
mod complex;
mod extra;
mod plugins;
mod zplus;

use rand::RngCore;

use crate::isa::{FmaIsa, Isa, IsaLevel, PortableIsa};
use crate::model::flame::scalar::FlameScalar;
use crate::model::flame::variation::{MAX_DERIVED, MAX_PARAMS, VariationKind};

/// flam3's ε (`EPS` in `private.h`).
pub(crate) const EPS: f64 = 1e-10;

/// The point a transform's variations act on (after the pre-affine map and pre_blur), with
/// the two values flam3 always precomputes.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Pre<T> {
    pub tx: T,
    pub ty: T,
    /// `tx² + ty²`.
    pub sumsq: T,
    /// `√(tx² + ty²)`.
    pub sqrt: T,
}

impl<T: FlameScalar> Pre<T> {
    #[inline(always)]
    pub(crate) fn new(tx: T, ty: T) -> Self {
        let sumsq = tx * tx + ty * ty;
        Pre {
            tx,
            ty,
            sumsq,
            sqrt: sumsq.sqrt(),
        }
    }

    /// Without the radius, for transforms none of whose variations read it
    /// ([`VariationKind::uses_radius`]); `sumsq` and `sqrt` are then NaN.
    #[inline(always)]
    pub(crate) fn without_radius(tx: T, ty: T) -> Self {
        let nan = T::cst(f64::NAN);
        Pre {
            tx,
            ty,
            sumsq: nan,
            sqrt: nan,
        }
    }

    /// flam3's `precalc_atan`: atan2(x, y), the angle from the +y axis.
    #[inline(always)]
    pub(crate) fn atan_xy(&self) -> T {
        self.tx.atan2(self.ty)
    }

    /// flam3's `precalc_atanyx`: atan2(y, x).
    #[inline(always)]
    pub(crate) fn atan_yx(&self) -> T {
        self.ty.atan2(self.tx)
    }

    /// flam3's `precalc_sina` = x / r.
    #[inline(always)]
    pub(crate) fn sina(&self) -> T {
        self.tx / self.sqrt
    }

    /// flam3's `precalc_cosa` = y / r.
    #[inline(always)]
    pub(crate) fn cosa(&self) -> T {
        self.ty / self.sqrt
    }
}

/// A uniform number in [0, 1] from one 32-bit draw, as flam3's `flam3_random_isaac_01`
/// (the low 28 bits over 2²⁸ − 1).
#[inline(always)]
pub fn rand01<R: RngCore + ?Sized>(rng: &mut R) -> f64 {
    ((rng.next_u32() as i32) & 0x0fff_ffff) as f64 / 0x0fff_ffff as f64
}

/// A uniform number in [−1, 1] from one draw, as flam3's `flam3_random_isaac_11`.
#[inline(always)]
pub fn rand11<R: RngCore + ?Sized>(rng: &mut R) -> f64 {
    (((rng.next_u32() as i32) & 0x0fff_ffff) - 0x07ff_ffff) as f64 / 0x07ff_ffff as f64
}

/// One random bit, as flam3's `flam3_random_isaac_bit` (the lowest bit of a draw).
#[inline(always)]
pub fn rand_bit<R: RngCore + ?Sized>(rng: &mut R) -> bool {
    rng.next_u32() & 1 == 1
}

/// C's `(int)x` on x86-64: truncation towards zero, and `i32::MIN` (the "integer
/// indefinite" value `cvttsd2si` returns) for NaN and values out of range, where Rust's
/// `as` would saturate. flam3 relies on it, e.g. rings2 with a tiny ring width.
#[inline(always)]
pub(crate) fn c_int32(x: f64) -> i32 {
    if x > -2_147_483_649.0 && x < 2_147_483_648.0 {
        x as i32
    } else {
        i32::MIN
    }
}

/// C's `rint` in the default rounding mode (to nearest, ties to even), inline: adding and
/// subtracting 2⁵² rounds any |x| < 2⁵² to an integer exactly that way.
#[inline(always)]
pub(crate) fn rint(x: f64) -> f64 {
    const TWO52: f64 = 4_503_599_627_370_496.0;
    if x.abs() < TWO52 {
        let r = (x.abs() + TWO52) - TWO52;
        r.copysign(x)
    } else {
        x
    }
}

/// [`c_int32`] as a float.
#[inline(always)]
pub(crate) fn c_int(x: f64) -> f64 {
    c_int32(x) as f64
}

/// [`eval`] compiled for instruction set `I`: `linear` inline, every other variation through
/// that instruction set's out-of-line copy of the `match`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn eval_on<I: IsaLevel, T: FlameScalar, R: RngCore + ?Sized>(
    _isa: I,
    kind: VariationKind,
    w: T,
    p: &[T; MAX_PARAMS],
    d: &[T; MAX_DERIVED],
    c: &[T; 6],
    f: &Pre<T>,
    rng: &mut R,
) -> (T, T) {
    if kind == VariationKind::Linear {
        return classic::linear(w, f);
    }
    match I::ISA {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: a value of an `IsaLevel` whose `ISA` is `Fma` exists only where the CPU
        // was found to have AVX2, FMA and BMI1/2 (`FmaIsa`'s constructors).
        Isa::Fma => unsafe { eval_fma(kind, w, p, d, c, f, rng) },
        _ => eval_portable(kind, w, p, d, c, f, rng),
    }
}

/// [`eval_on`] on the instruction set this CPU has best (one cached load per call: for
/// callers outside the renderers' loops).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn eval_detected<T: FlameScalar, R: RngCore + ?Sized>(
    kind: VariationKind,
    w: T,
    p: &[T; MAX_PARAMS],
    d: &[T; MAX_DERIVED],
    c: &[T; 6],
    f: &Pre<T>,
    rng: &mut R,
) -> (T, T) {
    match FmaIsa::detect() {
        Some(isa) => eval_on(isa, kind, w, p, d, c, f, rng),
        None => eval_on(PortableIsa, kind, w, p, d, c, f, rng),
    }
}

/// The portable copy of [`eval`].
#[allow(clippy::too_many_arguments)]
#[inline(never)]
fn eval_portable<T: FlameScalar, R: RngCore + ?Sized>(
    kind: VariationKind,
    w: T,
    p: &[T; MAX_PARAMS],
    d: &[T; MAX_DERIVED],
    c: &[T; 6],
    f: &Pre<T>,
    rng: &mut R,
) -> (T, T) {
    eval(kind, w, p, d, c, f, rng)
}

/// [`eval`] compiled with AVX2, FMA and BMI1/2.
#[cfg(target_arch = "x86_64")]
#[allow(clippy::too_many_arguments)]
#[inline(never)]
#[target_feature(enable = "avx2,fma,bmi1,bmi2")]
fn eval_fma<T: FlameScalar, R: RngCore + ?Sized>(
    kind: VariationKind,
    w: T,
    p: &[T; MAX_PARAMS],
    d: &[T; MAX_DERIVED],
    c: &[T; 6],
    f: &Pre<T>,
    rng: &mut R,
) -> (T, T) {
    eval(kind, w, p, d, c, f, rng)
}

/// The contribution `(Δx, Δy)` of variation `kind` with weight `w`, parameters `p`, values
/// derived from them `d`, the transform's pre-affine coefficients `c` (flam3 order
/// `a b c d e f`) at point `f`. `pre_blur` contributes nothing here: it moves the point
/// before the variations run (see the transform). Every formula is inlined here: callers go
/// through [`eval_on`], which keeps this `match` out of line once per instruction set.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn eval<T: FlameScalar, R: RngCore + ?Sized>(
    kind: VariationKind,
    w: T,
    p: &[T; MAX_PARAMS],
    d: &[T; MAX_DERIVED],
    c: &[T; 6],
    f: &Pre<T>,
    rng: &mut R,
) -> (T, T) {
    use VariationKind as V;
    match kind {
        V::Linear => classic::linear(w, f),
        V::Sinusoidal => classic::sinusoidal(w, f),
        V::Spherical => classic::spherical(w, f),
        V::Swirl => classic::swirl(w, f),
        V::Horseshoe => classic::horseshoe(w, f),
        V::Polar => classic::polar(w, f),
        V::Handkerchief => classic::handkerchief(w, f),
        V::Heart => classic::heart(w, f),
        V::Disc => classic::disc(w, f),
        V::Spiral => classic::spiral(w, f),
        V::Hyperbolic => classic::hyperbolic(w, f),
        V::Diamond => classic::diamond(w, f),
        V::Ex => classic::ex(w, f),
        V::Julia => classic::julia(w, f, rng),
        V::Bent => classic::bent(w, f),
        V::Waves => classic::waves(w, c, f),
        V::Fisheye => classic::fisheye(w, f),
        V::Popcorn => classic::popcorn(w, c, f),
        V::Exponential => classic::exponential(w, f),
        V::Power => classic::power(w, f),
        V::Cosine => classic::cosine(w, f),
        V::Rings => classic::rings(w, c, f),
        V::Fan => classic::fan(w, c, f),
        V::Blob => classic::blob(w, p, f),
        V::Pdj => classic::pdj(w, p, f),
        V::Fan2 => classic::fan2(w, p, f),
        V::Rings2 => classic::rings2(w, p, f),
        V::Eyefish => classic::eyefish(w, f),
        V::Bubble => classic::bubble(w, f),
        V::Cylinder => classic::cylinder(w, f),
        V::Perspective => classic::perspective(w, p, d, f),
        V::Noise => blurs::noise(w, f, rng),
        V::Julian => blurs::julian(w, p, d, f, rng),
        V::Juliascope => blurs::juliascope(w, p, d, f, rng),
        V::Blur => blurs::blur(w, rng),
        V::GaussianBlur => blurs::gaussian_blur(w, rng),
        V::RadialBlur => blurs::radial_blur(w, d, f, rng),
        V::Pie => blurs::pie(w, p, rng),
        V::Ngon => zplus::ngon(w, p, f),
        V::Curl => zplus::curl(w, p, f),
        V::Rectangles => zplus::rectangles(w, p, f),
        V::Arch => zplus::arch(w, rng),
        V::Tangent => zplus::tangent(w, f),
        V::Square => zplus::square(w, rng),
        V::Rays => zplus::rays(w, f, rng),
        V::Blade => zplus::blade(w, f, rng),
        V::Secant2 => zplus::secant2(w, f),
        V::Twintrian => zplus::twintrian(w, f, rng),
        V::Cross => zplus::cross(w, f),
        V::Disc2 => plugins::disc2(w, d, f),
        V::SuperShape => plugins::super_shape(w, p, d, f, rng),
        V::Flower => plugins::flower(w, p, f, rng),
        V::Conic => plugins::conic(w, p, f, rng),
        V::Parabola => plugins::parabola(w, p, f, rng),
        V::Bent2 => plugins::bent2(w, p, f),
        V::Bipolar => plugins::bipolar(w, p, f),
        V::Boarders => plugins::boarders(w, f, rng),
        V::Butterfly => plugins::butterfly(w, f),
        V::Cell => plugins::cell(w, p, f),
        V::Cpow => plugins::cpow(w, p, f, rng),
        V::Curve => plugins::curve(w, p, f),
        V::Edisc => plugins::edisc(w, f),
        V::Elliptic => plugins::elliptic(w, f),
        V::Escher => plugins::escher(w, p, f),
        V::Foci => plugins::foci(w, f),
        V::Lazysusan => plugins::lazysusan(w, p, f),
        V::Loonie => plugins::loonie(w, f),
        V::PreBlur => (T::cst(0.0), T::cst(0.0)),
        V::Modulus => plugins::modulus(w, p, f),
        V::Oscilloscope => plugins::oscilloscope(w, p, f),
        V::Polar2 => plugins::polar2(w, f),
        V::Popcorn2 => plugins::popcorn2(w, p, f),
        V::Scry => plugins::scry(w, f),
        V::Separation => plugins::separation(w, p, f),
        V::Split => plugins::split(w, p, f),
        V::Splits => plugins::splits(w, p, f),
        V::Stripes => plugins::stripes(w, p, f),
        V::Wedge => plugins::wedge(w, p, f),
        V::WedgeJulia => plugins::wedge_julia(w, p, d, f, rng),
        V::WedgeSph => plugins::wedge_sph(w, p, f),
        V::Whorl => plugins::whorl(w, p, f),
        V::Waves2 => plugins::waves2(w, p, f),
        V::Exp => complex::exp(w, f),
        V::Log => complex::log(w, f),
        V::Sin => complex::sin(w, f),
        V::Cos => complex::cos(w, f),
        V::Tan => complex::tan(w, f),
        V::Sec => complex::sec(w, f),
        V::Csc => complex::csc(w, f),
        V::Cot => complex::cot(w, f),
        V::Sinh => complex::sinh(w, f),
        V::Cosh => complex::cosh(w, f),
        V::Tanh => complex::tanh(w, f),
        V::Sech => complex::sech(w, f),
        V::Csch => complex::csch(w, f),
        V::Coth => complex::coth(w, f),
        V::Auger => extra::auger(w, p, f),
        V::Flux => extra::flux(w, p, f),
        V::Mobius => extra::mobius(w, p, f),
    }
}

/// `(r·cos a, r·sin a)`: the point at radius `r` and angle `a`, the last step of the
/// variations that work in polar coordinates.
#[inline(always)]
pub(crate) fn from_polar<T: FlameScalar>(r: T, a: T) -> (T, T) {
    let (s, c) = a.sin_cos();
    (r * c, r * s)
}

/// flam3's pseudo-Gaussian: the sum of four uniforms, centred.
#[inline(always)]
pub(crate) fn four_uniforms<R: RngCore + ?Sized>(rng: &mut R) -> f64 {
    rand01(rng) + rand01(rng) + rand01(rng) + rand01(rng) - 2.0
}

/// pre_blur (flam3 `var67_pre_blur`): a pseudo-Gaussian step of the point before the
/// variations run, `w·(u₁+u₂+u₃+u₄−2)` along a uniform angle.
#[inline(always)]
pub(crate) fn pre_blur<R: RngCore + ?Sized>(w: f64, tx: &mut f64, ty: &mut f64, rng: &mut R) {
    let g = w * four_uniforms(rng);
    let (dx, dy) = from_polar(g, rand01(rng) * 2.0 * std::f64::consts::PI);
    *tx += dx;
    *ty += dy;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rint_rounds_half_to_even_like_c() {
        for (x, r) in [
            (0.5, 0.0),
            (1.5, 2.0),
            (2.5, 2.0),
            (-0.5, -0.0),
            (-1.5, -2.0),
            (-2.4, -2.0),
            (3.7, 4.0),
            (1e300, 1e300),
        ] {
            assert_eq!(rint(x), r, "rint({x})");
            assert_eq!(rint(x), x.round_ties_even());
        }
    }

    #[test]
    fn c_int_gives_the_x86_indefinite_value_out_of_range() {
        assert_eq!(c_int32(-2.7), -2);
        assert_eq!(c_int32(1e10), i32::MIN);
        assert_eq!(c_int32(f64::NAN), i32::MIN);
    }
}
