//! The elementary functions of the flame variations: the standard library (glibc) against
//! `math::trig` (the polynomials the renderer uses), in the same run — `ours` as the
//! renderer's FMA copies compile them (one call into a function built with AVX2 and FMA,
//! the polynomial inlined in it), `ours_portable` as portable code does (each `mul_add` a
//! call to the runtime's `fma`).
//!
//! Two measures per function, each over the same 4096 arguments from the ranges a render
//! sees (angles within ±8, points within ±4 in every quadrant):
//! - `throughput`: independent calls, as many in flight as the core can overlap;
//! - `latency`: each call's argument depends on the previous result, as inside one chaos
//!   game trajectory, where a variation's result is the next step's input.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use ifslab::isa::Isa;
use ifslab::math::trig;
use rand::{Rng, SeedableRng};

const N: usize = 4096;

/// A named implementation of each kind of function.
type Unary = (&'static str, fn(f64) -> f64);
type SinCos = (&'static str, fn(f64) -> (f64, f64));
type Binary = (&'static str, fn(f64, f64) -> f64);

fn arguments() -> (Vec<f64>, Vec<(f64, f64)>) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let angles = (0..N).map(|_| rng.random_range(-8.0..8.0)).collect();
    let points = (0..N)
        .map(|_| (rng.random_range(-4.0..4.0), rng.random_range(-4.0..4.0)))
        .collect();
    (angles, points)
}

/// The polynomials compiled with FMA, each behind a plain function (what the portable
/// wrappers below call once the CPU is known to have the features).
#[cfg(target_arch = "x86_64")]
mod fma {
    use super::trig;

    #[target_feature(enable = "avx2,fma,bmi1,bmi2")]
    pub fn sin(x: f64) -> f64 {
        trig::sin(x)
    }

    #[target_feature(enable = "avx2,fma,bmi1,bmi2")]
    pub fn cos(x: f64) -> f64 {
        trig::cos(x)
    }

    #[target_feature(enable = "avx2,fma,bmi1,bmi2")]
    pub fn sin_cos(x: f64) -> (f64, f64) {
        trig::sin_cos(x)
    }

    #[target_feature(enable = "avx2,fma,bmi1,bmi2")]
    pub fn atan2(y: f64, x: f64) -> f64 {
        trig::atan2(y, x)
    }
}

#[cfg(target_arch = "x86_64")]
fn ours_sin(x: f64) -> f64 {
    // SAFETY: `bench_math` runs this only after `Isa::Fma.is_available()`.
    unsafe { fma::sin(x) }
}
#[cfg(target_arch = "x86_64")]
fn ours_cos(x: f64) -> f64 {
    // SAFETY: as above.
    unsafe { fma::cos(x) }
}
#[cfg(target_arch = "x86_64")]
fn ours_sin_cos(x: f64) -> (f64, f64) {
    // SAFETY: as above.
    unsafe { fma::sin_cos(x) }
}
#[cfg(target_arch = "x86_64")]
fn ours_atan2(y: f64, x: f64) -> f64 {
    // SAFETY: as above.
    unsafe { fma::atan2(y, x) }
}

#[cfg(not(target_arch = "x86_64"))]
use trig::{atan2 as ours_atan2, cos as ours_cos, sin as ours_sin, sin_cos as ours_sin_cos};

fn bench_math(c: &mut Criterion) {
    let (angles, points) = arguments();
    if !Isa::Fma.is_available() {
        eprintln!("this CPU has no FMA: the FMA copies cannot run; skipping");
        return;
    }
    let unary: [(&str, [Unary; 3]); 2] = [
        (
            "sin",
            [
                ("libm", f64::sin),
                ("ours", ours_sin),
                ("ours_portable", trig::sin),
            ],
        ),
        (
            "cos",
            [
                ("libm", f64::cos),
                ("ours", ours_cos),
                ("ours_portable", trig::cos),
            ],
        ),
    ];
    for (name, fs) in unary {
        let mut g = c.benchmark_group(format!("math_{name}"));
        g.throughput(Throughput::Elements(N as u64));
        for (who, f) in fs {
            g.bench_function(format!("{who}_throughput"), |bench| {
                bench.iter(|| {
                    let mut s = 0.0;
                    for &x in &angles {
                        s += f(black_box(x));
                    }
                    s
                })
            });
            g.bench_function(format!("{who}_latency"), |bench| {
                bench.iter(|| {
                    let mut s = 0.0;
                    for &x in &angles {
                        s = f(x + s);
                    }
                    s
                })
            });
        }
        g.finish();
    }
    let sincos: [SinCos; 3] = [
        ("libm", f64::sin_cos),
        ("ours", ours_sin_cos),
        ("ours_portable", trig::sin_cos),
    ];
    let mut g = c.benchmark_group("math_sin_cos");
    g.throughput(Throughput::Elements(N as u64));
    for (who, f) in sincos {
        g.bench_function(format!("{who}_throughput"), |bench| {
            bench.iter(|| {
                let mut s = 0.0;
                for &x in &angles {
                    let (a, b) = f(black_box(x));
                    s += a + b;
                }
                s
            })
        });
        g.bench_function(format!("{who}_latency"), |bench| {
            bench.iter(|| {
                let mut s = 0.0;
                for &x in &angles {
                    let (a, b) = f(x + s);
                    s = a * b;
                }
                s
            })
        });
    }
    g.finish();
    let atan2: [Binary; 3] = [
        ("libm", f64::atan2),
        ("ours", ours_atan2),
        ("ours_portable", trig::atan2),
    ];
    let mut g = c.benchmark_group("math_atan2");
    g.throughput(Throughput::Elements(N as u64));
    for (who, f) in atan2 {
        g.bench_function(format!("{who}_throughput"), |bench| {
            bench.iter(|| {
                let mut s = 0.0;
                for &(x, y) in &points {
                    s += f(black_box(y), black_box(x));
                }
                s
            })
        });
        g.bench_function(format!("{who}_latency"), |bench| {
            bench.iter(|| {
                let mut s = 0.0;
                for &(x, y) in &points {
                    s = f(y + s * 1e-3, x);
                }
                s
            })
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30);
    targets = bench_math
}
criterion_main!(benches);
