//! `sin`, `cos`, `sin_cos` and `atan2` as fdlibm's polynomials evaluated with fused
//! multiply–adds: the flame variations' elementary functions.
//!
//! These four calls are most of the work of a flame with trigonometric variations: `atan2`,
//! `sin`, `cos` and `sincos` took a quarter to 40 % of a render's CPU time, spent in glibc.
//! Compiled with the `fma` target feature, the polynomials below run in about half glibc's
//! time per call (`benches/flame_math.rs`, BENCHMARKS.md §5).
//!
//! **How they are compiled** ([`crate::isa`]): every function here is `#[inline(always)]`
//! and carries no target feature of its own, so it becomes part of the hot loop that calls
//! it. In a loop's [`Isa::Fma`](crate::isa::Isa::Fma) copy each `mul_add` is one `vfmadd`
//! instruction and the whole function inlines (no call, no feature check); in portable
//! code each `mul_add` is a call to the runtime's `fma`, which is exactly rounded too, so
//! **the results are the same bits on every CPU and in every copy** (tested below) — only
//! slower where the CPU lacks FMA.
//!
//! Accuracy: within 2 ulp of the correctly rounded result over the ranges the variations
//! use (tested against the standard library on millions of arguments, `tests` below);
//! flam3 itself is compiled with `-ffast-math`, and its orbits, like ours, are chaotic, so
//! agreement with flam3 was never bit-exact (`tests/flame_variations.rs` allows 1e-11
//! relative). Outside the fast range — `|x| > 2²⁰·π/2` for `sin`/`cos`, arguments whose
//! magnitudes are beyond 10±³⁰⁰ for `atan2`, zeros, infinities, NaN — the standard
//! library answers, so special values behave exactly as C's.
//!
//! The methods: Cody–Waite reduction of the argument by π/2 with a three-part π/2 (exact
//! first step by FMA), then fdlibm's minimax polynomials for `sin` and `cos` on
//! [−π/4, π/4]; `atan2` reduces `|y|/|x|` to `|t| ≤ tan(π/8)` by the identities
//! `atan(a) = π/4 + atan((a−1)/(a+1))` and `atan(a) = π/2 − atan(1/a)` (one division),
//! evaluates fdlibm's odd polynomial for `atan` on it, and places the result in its
//! quadrant. The coefficients are fdlibm's (Sun Microsystems, 1993), as every libm has them.

/// fdlibm's `__kernel_sin` coefficients (`S1`…`S6`).
#[allow(clippy::excessive_precision)] // fdlibm's digits, as published
const S: [f64; 6] = [
    -1.666_666_666_666_663_243_48e-1,
    8.333_333_333_322_489_461_24e-3,
    -1.984_126_982_985_794_931_34e-4,
    2.755_731_370_707_006_767_89e-6,
    -2.505_076_025_340_686_341_95e-8,
    1.589_690_995_211_550_102_21e-10,
];
/// fdlibm's `__kernel_cos` coefficients (`C1`…`C6`).
#[allow(clippy::excessive_precision)] // fdlibm's digits, as published
const C: [f64; 6] = [
    4.166_666_666_666_660_190_37e-2,
    -1.388_888_888_887_410_957_49e-3,
    2.480_158_728_947_672_941_78e-5,
    -2.755_731_435_139_066_330_35e-7,
    2.087_572_321_298_174_827_90e-9,
    -1.135_964_755_778_819_482_65e-11,
];
/// fdlibm's `atan` coefficients (`aT[0]`…`aT[10]`), for `|t| ≤ 7/16`.
#[allow(clippy::excessive_precision)] // fdlibm's digits, as published
const AT: [f64; 11] = [
    3.333_333_333_333_293_180_27e-1,
    -1.999_999_999_987_648_324_76e-1,
    1.428_571_427_250_346_637_11e-1,
    -1.111_111_040_546_235_578_80e-1,
    9.090_887_133_436_506_561_96e-2,
    -7.691_876_205_044_829_994_95e-2,
    6.661_073_137_387_531_206_69e-2,
    -5.833_570_133_790_573_486_45e-2,
    4.976_877_994_615_932_360_17e-2,
    -3.653_157_274_421_691_552_70e-2,
    1.628_582_011_536_578_236_23e-2,
];
/// π/2 as three doubles (`hi + mid + lo`, 159 bits).
const PIO2: [f64; 3] = [
    std::f64::consts::FRAC_PI_2,
    6.123_233_995_736_766e-17,
    -1.497_384_904_859_169_8e-33,
];
/// π/4 and π as two doubles each.
const PIO4: [f64; 2] = [std::f64::consts::FRAC_PI_4, 3.061_616_997_868_383e-17];
const PI: [f64; 2] = [std::f64::consts::PI, 1.224_646_799_147_353_2e-16];
/// Largest `|x|` reduced here: the quotient by π/2 stays below 2²⁰, so the first step of
/// the reduction is exact and the three-part π/2 leaves ≥ 100 correct bits.
const TRIG_LIMIT: f64 = 1_647_099.0;
/// `tan(π/8)` and `tan(3π/8)`: where `atan2` changes identity.
const TAN_PI_8: f64 = 0.414_213_562_373_095_03;
const TAN_3PI_8: f64 = 2.414_213_562_373_095;

/// `x` rounded to the nearest integer, ties to even (for `|x| < 2⁵¹`).
#[inline(always)]
fn round(x: f64) -> f64 {
    const SHIFT: f64 = 6_755_399_441_055_744.0; // 1.5 · 2⁵²
    (x + SHIFT) - SHIFT
}

/// Whether `x` is in the fast range (false for NaN and ±∞).
#[inline(always)]
fn reducible(x: f64) -> bool {
    x.abs() <= TRIG_LIMIT
}

/// `x − n·π/2` and `n mod 4`, for `|x| ≤ TRIG_LIMIT`.
#[inline(always)]
fn reduce(x: f64) -> (f64, u32) {
    let n = round(x * std::f64::consts::FRAC_2_PI);
    // Exact: x and n·PIO2[0] are multiples of 2⁻⁵³ whose difference is below π/2·2.
    let r = (-n).mul_add(PIO2[0], x);
    let r = (-n).mul_add(PIO2[1], r);
    let r = (-n).mul_add(PIO2[2], r);
    (r, (n as i64 & 3) as u32)
}

/// fdlibm's `__kernel_sin(r, 0, 0)` on `|r| ≤ π/4`.
#[inline(always)]
fn kernel_sin(r: f64) -> f64 {
    let z = r * r;
    let z2 = z * z;
    // S2 + z·S3 + z²·(S4 + z·S5) + z⁴·S6, by pairs (shorter dependency chain).
    let p = S[2].mul_add(z, S[1]) + z2 * S[4].mul_add(z, S[3]) + (z2 * z2) * S[5];
    (r * z).mul_add(z.mul_add(p, S[0]), r)
}

/// fdlibm's `__kernel_cos(r, 0)` on `|r| ≤ π/4`.
#[inline(always)]
fn kernel_cos(r: f64) -> f64 {
    let z = r * r;
    let z2 = z * z;
    let p = C[1].mul_add(z, C[0]) + z2 * C[3].mul_add(z, C[2]) + (z2 * z2) * C[5].mul_add(z, C[4]);
    let hz = 0.5 * z;
    let w = 1.0 - hz;
    w + (((1.0 - w) - hz) + z * (z * p))
}

/// `(sin x, cos x)` for `|x| ≤ TRIG_LIMIT`: both kernels (independent, so they overlap)
/// and the quadrant applied by selects rather than branches on a random quadrant.
#[inline(always)]
fn sin_cos_reduced(x: f64) -> (f64, f64) {
    let (r, q) = reduce(x);
    let (s, c) = (kernel_sin(r), kernel_cos(r));
    let (s, c) = if q & 1 == 0 { (s, c) } else { (c, -s) };
    if q & 2 == 0 { (s, c) } else { (-s, -c) }
}

/// `sin(x)`.
#[inline(always)]
pub fn sin(x: f64) -> f64 {
    if !reducible(x) {
        return x.sin();
    }
    sin_cos_reduced(x).0
}

/// `cos(x)`.
#[inline(always)]
pub fn cos(x: f64) -> f64 {
    if !reducible(x) {
        return x.cos();
    }
    sin_cos_reduced(x).1
}

/// `(sin(x), cos(x))`.
#[inline(always)]
pub fn sin_cos(x: f64) -> (f64, f64) {
    if !reducible(x) {
        return x.sin_cos();
    }
    sin_cos_reduced(x)
}

/// `atan(t)` for `|t| ≤ 7/16`, as `t − t·P(t²)`; returned as the correction
/// `t·P(t²)` so a caller can add a constant in two parts before it.
#[inline(always)]
fn atan_correction(t: f64) -> f64 {
    let z = t * t;
    let w = z * z;
    let w2 = w * w;
    let w4 = w2 * w2;
    // fdlibm's even/odd split, each half by pairs.
    let s1 = z
        * (AT[2].mul_add(w, AT[0]) + w2 * AT[6].mul_add(w, AT[4]) + w4 * AT[10].mul_add(w, AT[8]));
    let s2 = w * (AT[3].mul_add(w, AT[1]) + w2 * AT[7].mul_add(w, AT[5]) + w4 * AT[9]);
    t * (s1 + s2)
}

/// `atan2(y, x)` (C's argument order: the angle of the point `(x, y)`).
#[inline(always)]
pub fn atan2(y: f64, x: f64) -> f64 {
    let (u, v) = (x.abs(), y.abs());
    // Zeros, infinities, NaN and magnitudes near the ends of the range: C's answer.
    let finite = u < 1e300 && v < 1e300;
    let normal = (u > 1e-300 && (v > 1e-300 || v == 0.0)) || (u == 0.0 && v > 1e-300);
    if !(finite && normal) {
        return y.atan2(x);
    }
    // The angle of (u, v) in [0, π/2] as base + atan(num/den), |num/den| ≤ tan(π/8).
    let (num, den, base) = if v <= TAN_PI_8 * u {
        (v, u, [0.0, 0.0])
    } else if v <= TAN_3PI_8 * u {
        (v - u, v + u, PIO4)
    } else {
        (-u, v, [PIO2[0], PIO2[1]])
    };
    let t = num / den;
    let a = base[0] - ((atan_correction(t) - base[1]) - t);
    let a = if x.is_sign_negative() {
        (PI[0] - a) + PI[1]
    } else {
        a
    };
    a.copysign(y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Distance in units in the last place of `b`.
    fn ulps(a: f64, b: f64) -> f64 {
        if a == b {
            return 0.0;
        }
        let ulp = if b == 0.0 {
            f64::from_bits(1)
        } else {
            (f64::from_bits(b.abs().to_bits() + 1) - b.abs()).abs()
        };
        (a - b).abs() / ulp
    }

    /// A reference computed in higher precision: the standard library's result corrected
    /// by the derivative is not needed here, glibc's `sin`/`cos`/`atan2` are correctly
    /// rounded in all but rare cases, so within 2 ulp of glibc is within 3 of the truth.
    fn check(name: &str, ours: impl Fn(f64) -> f64, libm: impl Fn(f64) -> f64, xs: &[f64]) {
        let mut worst = (0.0, 0.0);
        for &x in xs {
            let e = ulps(ours(x), libm(x));
            if e > worst.0 {
                worst = (e, x);
            }
        }
        eprintln!("{name}: worst {} ulp at {:e}", worst.0, worst.1);
        assert!(
            worst.0 <= 2.0,
            "{name}: {} ulp from the standard library at x = {:e}",
            worst.0,
            worst.1
        );
    }

    fn arguments(seed: u64) -> Vec<f64> {
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let mut xs = Vec::new();
        for _ in 0..200_000 {
            xs.push(rng.random_range(-4.0..4.0));
            xs.push(rng.random_range(-100.0..100.0));
            // Log-uniform magnitudes, both signs, from 1e-12 to 1e7.
            let m = 10f64.powf(rng.random_range(-12.0..7.0));
            xs.push(if rng.random_bool(0.5) { m } else { -m });
        }
        // Multiples of π/2 and their neighbours, where the reduction cancels.
        for k in -2000i32..2000 {
            let x = k as f64 * std::f64::consts::FRAC_PI_2;
            xs.extend([
                x,
                f64::from_bits(x.to_bits() + 1),
                f64::from_bits(x.to_bits().wrapping_sub(1)),
            ]);
        }
        xs.extend([0.0, -0.0, 1e-310, TRIG_LIMIT, -TRIG_LIMIT, 1e300, f64::MAX]);
        xs
    }

    #[test]
    fn sin_and_cos_are_within_two_ulp() {
        let xs = arguments(1);
        check("sin", sin, f64::sin, &xs);
        check("cos", cos, f64::cos, &xs);
        check("sin_cos.0", |x| sin_cos(x).0, f64::sin, &xs);
        check("sin_cos.1", |x| sin_cos(x).1, f64::cos, &xs);
    }

    #[test]
    fn atan2_is_within_two_ulp_in_every_quadrant() {
        let xs = arguments(2);
        let mut rng = rand::rngs::StdRng::seed_from_u64(3);
        let mut worst = (0.0, 0.0, 0.0);
        for &y in &xs {
            let x = xs[rng.random_range(0..xs.len())];
            let e = ulps(atan2(y, x), y.atan2(x));
            if e > worst.0 {
                worst = (e, y, x);
            }
        }
        // Ratios at the identities' seams and on the axes.
        for &(y, x) in &[
            (TAN_PI_8, 1.0),
            (TAN_3PI_8, 1.0),
            (1.0, 1.0),
            (-1.0, -1.0),
            (0.0, -1.0),
            (-0.0, -1.0),
            (1.0, 0.0),
            (-1.0, -0.0),
        ] {
            let e = ulps(atan2(y, x), y.atan2(x));
            if e > worst.0 {
                worst = (e, y, x);
            }
        }
        eprintln!(
            "atan2: worst {} ulp at ({:e}, {:e})",
            worst.0, worst.1, worst.2
        );
        assert!(
            worst.0 <= 2.0,
            "atan2: {} ulp from the standard library at (y, x) = ({:e}, {:e})",
            worst.0,
            worst.1,
            worst.2
        );
    }

    #[test]
    fn special_values_are_the_standard_librarys() {
        let specials = [
            0.0,
            -0.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            1e-320,
            f64::MAX,
            -f64::MAX,
            1.0,
        ];
        let same = |a: f64, b: f64| a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan());
        for &x in &specials {
            assert!(
                same(sin(x), x.sin()) || ulps(sin(x), x.sin()) <= 2.0,
                "sin({x})"
            );
            assert!(
                same(cos(x), x.cos()) || ulps(cos(x), x.cos()) <= 2.0,
                "cos({x})"
            );
            for &y in &specials {
                let (a, b) = (atan2(y, x), y.atan2(x));
                assert!(
                    same(a, b) || ulps(a, b) <= 2.0,
                    "atan2({y}, {x}): {a} vs {b}"
                );
                assert_eq!(
                    a.is_sign_negative(),
                    b.is_sign_negative(),
                    "atan2({y}, {x}) sign"
                );
            }
        }
    }

    /// Every function on every argument, as the bits of `[sin, cos, sin_cos.0, sin_cos.1,
    /// atan2(x, next x)]`.
    #[inline(always)]
    fn all(xs: &[f64]) -> Vec<[u64; 5]> {
        xs.iter()
            .zip(xs.iter().cycle().skip(1))
            .map(|(&x, &y)| {
                let (s, c) = sin_cos(x);
                [sin(x), cos(x), s, c, atan2(x, y)].map(f64::to_bits)
            })
            .collect()
    }

    #[inline(never)]
    fn all_portable(xs: &[f64]) -> Vec<[u64; 5]> {
        all(xs)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2")]
    fn all_fma(xs: &[f64]) -> Vec<[u64; 5]> {
        all(xs)
    }

    /// The portable copy (each `mul_add` a call to the runtime's `fma`) and the FMA copy
    /// (each one instruction) give the same bits: what makes flame renders the same on
    /// every CPU and in both copies of the loops.
    #[test]
    #[cfg_attr(
        not(target_arch = "x86_64"),
        ignore = "the FMA copy exists on x86-64 only"
    )]
    fn portable_and_fma_copies_agree_bit_for_bit() {
        let xs = arguments(4);
        let portable = all_portable(&xs);
        #[cfg(target_arch = "x86_64")]
        {
            assert!(
                crate::isa::Isa::Fma.is_available(),
                "this x86-64 CPU has no FMA: the FMA copy cannot be checked"
            );
            // SAFETY: the CPU has AVX2, FMA and BMI1/2 (asserted just above).
            let fma = unsafe { all_fma(&xs) };
            for (i, (a, b)) in portable.iter().zip(&fma).enumerate() {
                assert_eq!(a, b, "argument {:e}", xs[i]);
            }
        }
    }
}
