//! The elementary functions of the flame variations: the standard library (glibc) against
//! `model::flame::fast_math` (the FMA polynomials the renderer uses where the CPU has FMA),
//! in the same run.
//!
//! Two measures per function, each over the same 4096 arguments from the ranges a render
//! sees (angles within ±8, points within ±4 in every quadrant):
//! - `throughput`: independent calls, as many in flight as the core can overlap;
//! - `latency`: each call's argument depends on the previous result, as inside one chaos
//!   game trajectory, where a variation's result is the next step's input.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use ifslab::model::flame::fast_math;
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

fn bench_math(c: &mut Criterion) {
    let (angles, points) = arguments();
    eprintln!("FMA bodies in use: {}", fast_math::has_fma());
    let unary: [(&str, Unary, Unary); 2] = [
        ("sin", ("libm", f64::sin), ("ours", fast_math::sin)),
        ("cos", ("libm", f64::cos), ("ours", fast_math::cos)),
    ];
    for (name, a, b) in unary {
        let mut g = c.benchmark_group(format!("math_{name}"));
        g.throughput(Throughput::Elements(N as u64));
        for (who, f) in [a, b] {
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
    let sincos: [SinCos; 2] = [("libm", f64::sin_cos), ("ours", fast_math::sin_cos)];
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
    let atan2: [Binary; 2] = [("libm", f64::atan2), ("ours", fast_math::atan2)];
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
